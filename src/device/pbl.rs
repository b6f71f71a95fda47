//! PBL-series BLDC drives (manual 002): parameters 0..222 as holding registers of the same
//! number, 115200 8E1 by default.
//!
//! Parameter 0 is the control word (bit 0 start, bit 1 reverse), 2 the status (bit 0 running,
//! bit 1 reverse), 4 and 5 the low and high words of the alarm bits; 50..54 are the measured
//! speed, bus voltage, analog speed input, current and power; 100..222 are settings. The
//! manual gives no scaling: values are the raw words, in the units it names. Its drives
//! answer a 0x06 write with a register count of 1 instead of the echo, which is accepted for
//! this family only; they also act on and answer a broadcast, which the Bus never waits for.

use super::suggest::did_you_mean;
use super::{Access, Device, Register, Station};
use crate::bus::{Bus, TxOptions};
use crate::codec::Echo;
use crate::error::{Error, Result};
use std::sync::Arc;

/// Number of the control word (bit 0: 0 stop / 1 start; bit 1: 0 forward / 1 reverse).
pub const CONTROL: u16 = 0;
/// Number of the status word (bit 0: 0 standby / 1 moving; bit 1: 0 forward / 1 reverse).
pub const STATUS: u16 = 2;
/// Number of the alarm word's low half (the high half follows at 5).
pub const ALARMS: u16 = 4;
/// Number of "restore defaults": 1511 restores them at the next power-up.
pub const RESTORE_DEFAULTS: u16 = 214;
/// The value that asks for the defaults.
pub const RESTORE_MAGIC: u16 = 1511;
/// Parameters 0..=99 are status and measurements.
pub const MEASUREMENTS: std::ops::RangeInclusive<u16> = 0..=99;

/// The main measurements, parameters 50..=54 in order, read in one request by
/// [`Pbl::sample`]: speed (rpm), bus voltage (V), analog speed input (mV), current (A) and
/// power (W).
pub const SAMPLE: [&str; 5] = [
    "speed",
    "bus_voltage",
    "analog_speed_input",
    "current",
    "power",
];

/// Most parameters one read may ask for: the manual's frame holds 1..123 data bytes, so a
/// reply carries at most 61 registers.
pub const MAX_BLOCK: u16 = 61;

const START: u16 = 0x0001;
const REVERSE: u16 = 0x0002;

const fn ro(number: u16, name: &'static str, unit: &'static str) -> Register {
    Register {
        name,
        address: number,
        scale: 1.0,
        signed: false,
        unit,
        access: Access::Read,
        range: (0.0, 0.0),
    }
}

const fn rw(number: u16, name: &'static str, unit: &'static str, lo: f64, hi: f64) -> Register {
    Register {
        name,
        address: number,
        scale: 1.0,
        signed: false,
        unit,
        access: Access::ReadWrite,
        range: (lo, hi),
    }
}

/// The manual's parameter list, 0..=222, indexed by number. Names are English renderings of
/// the manual's descriptions; where it repeats a description (72..99 mirror 52..69), the
/// number is appended. `reserved_N` marks the ones it calls reserved.
#[rustfmt::skip]
pub const PARAMETERS: [Register; 223] = [
    rw(0, "control_word", "", 0.0, 65535.0),
    rw(1, "control_word_high", "", 0.0, 65535.0),
    ro(2, "status", ""),
    ro(3, "status_high", ""),
    ro(4, "alarm_low", ""),
    ro(5, "alarm_high", ""),
    ro(6, "hall_state", ""),
    ro(7, "motor_position", ""),
    ro(8, "motor_speed", ""),
    ro(9, "motor_current", ""),
    ro(10, "u_phase_current", ""),
    ro(11, "v_phase_current", ""),
    ro(12, "w_phase_current", ""),
    ro(13, "dc_bus_voltage", ""),
    ro(14, "digital_input_1", ""),
    ro(15, "digital_input_2", ""),
    ro(16, "digital_output_1", ""),
    ro(17, "digital_output_2", ""),
    ro(18, "analog_input_1", ""),
    ro(19, "analog_input_2", ""),
    ro(20, "analog_input_3", ""),
    ro(21, "analog_input_4", ""),
    ro(22, "reserved_22", ""),
    ro(23, "reserved_23", ""),
    ro(24, "reserved_24", ""),
    ro(25, "reserved_25", ""),
    ro(26, "reserved_26", ""),
    ro(27, "reserved_27", ""),
    ro(28, "reserved_28", ""),
    ro(29, "reserved_29", ""),
    ro(30, "reserved_30", ""),
    ro(31, "reserved_31", ""),
    ro(32, "reserved_32", ""),
    ro(33, "reserved_33", ""),
    ro(34, "reserved_34", ""),
    ro(35, "reserved_35", ""),
    ro(36, "reserved_36", ""),
    ro(37, "reserved_37", ""),
    ro(38, "reserved_38", ""),
    ro(39, "reserved_39", ""),
    ro(40, "reserved_40", ""),
    ro(41, "reserved_41", ""),
    ro(42, "reserved_42", ""),
    ro(43, "reserved_43", ""),
    ro(44, "reserved_44", ""),
    ro(45, "reserved_45", ""),
    ro(46, "reserved_46", ""),
    ro(47, "reserved_47", ""),
    ro(48, "reserved_48", ""),
    ro(49, "reserved_49", ""),
    ro(50, "speed", "rpm"),
    ro(51, "bus_voltage", "V"),
    ro(52, "analog_speed_input", "mV"),
    ro(53, "current", "A"),
    ro(54, "power", "W"),
    ro(55, "u_phase_current_ad", ""),
    ro(56, "v_phase_current_ad", ""),
    ro(57, "w_phase_current_calc", ""),
    ro(58, "duty_cycle", ""),
    ro(59, "speed_loop_output", ""),
    ro(60, "hall_bridge_state", ""),
    ro(61, "ad_channel_0", ""),
    ro(62, "ad_channel_1", ""),
    ro(63, "ad_channel_2", ""),
    ro(64, "ad_channel_3", ""),
    ro(65, "planned_speed", "rpm"),
    ro(66, "pwm_limit", ""),
    ro(67, "overload_current", ""),
    ro(68, "current_loop_output", ""),
    ro(69, "speed_loop_integral", ""),
    ro(70, "motor_current_ad", ""),
    ro(71, "pwm_input_duty", ""),
    ro(72, "analog_speed_input_72", "mV"),
    ro(73, "current_73", "A"),
    ro(74, "power_74", "W"),
    ro(75, "u_phase_current_ad_75", ""),
    ro(76, "v_phase_current_ad_76", ""),
    ro(77, "w_phase_current_calc_77", ""),
    ro(78, "duty_cycle_78", ""),
    ro(79, "speed_loop_output_79", ""),
    ro(80, "hall_bridge_state_80", ""),
    ro(81, "ad_channel_0_81", ""),
    ro(82, "ad_channel_1_82", ""),
    ro(83, "ad_channel_2_83", ""),
    ro(84, "ad_channel_3_84", ""),
    ro(85, "planned_speed_85", "rpm"),
    ro(86, "pwm_limit_86", ""),
    ro(87, "overload_current_87", ""),
    ro(88, "current_loop_output_88", ""),
    ro(89, "speed_loop_integral_89", ""),
    ro(90, "hall_bridge_state_90", ""),
    ro(91, "ad_channel_0_91", ""),
    ro(92, "ad_channel_1_92", ""),
    ro(93, "ad_channel_2_93", ""),
    ro(94, "ad_channel_3_94", ""),
    ro(95, "planned_speed_95", "rpm"),
    ro(96, "pwm_limit_96", ""),
    ro(97, "overload_current_97", ""),
    ro(98, "current_loop_output_98", ""),
    ro(99, "speed_loop_integral_99", ""),
    rw(100, "control_mode", "", 0.0, 2.0),
    rw(101, "use_current_loop", "", 0.0, 1.0),
    rw(102, "min_pulse_width", "", 0.0, 65535.0),
    rw(103, "dead_time", "", 0.0, 65535.0),
    rw(104, "update_rate", "", 0.0, 65535.0),
    rw(105, "pole_pairs_105", "", 0.0, 65535.0),
    rw(106, "acceleration_106", "", 0.0, 65535.0),
    rw(107, "deceleration_107", "", 0.0, 65535.0),
    rw(108, "v_current_offset", "", 0.0, 65535.0),
    rw(109, "w_current_offset", "", 0.0, 65535.0),
    rw(110, "precharge_time", "ms", 0.0, 65535.0),
    rw(111, "max_temperature", "", 0.0, 65535.0),
    rw(112, "hall_angle", "", 0.0, 1.0),
    rw(113, "pwm_frequency", "", 0.0, 3.0),
    rw(114, "decel_mode", "", 0.0, 1.0),
    rw(115, "waveform", "", 0.0, 1.0),
    rw(116, "motion_direction", "", 0.0, 1.0),
    rw(117, "use_encoder", "", 0.0, 1.0),
    rw(118, "use_brake", "", 0.0, 1.0),
    rw(119, "use_dc_brake", "", 0.0, 1.0),
    rw(120, "has_speed_sensor", "", 0.0, 1.0),
    rw(121, "speed_sensor_type", "", 0.0, 1.0),
    rw(122, "encoder_lines", "", 0.0, 65535.0),
    rw(123, "min_speed", "rpm", 0.0, 65535.0),
    rw(124, "max_speed", "rpm", 0.0, 65535.0),
    rw(125, "min_bus_voltage", "", 0.0, 65535.0),
    rw(126, "max_bus_voltage", "", 0.0, 65535.0),
    rw(127, "brake_on_bus_voltage", "", 0.0, 65535.0),
    rw(128, "brake_off_bus_voltage", "", 0.0, 65535.0),
    rw(129, "decel_bus_voltage_limit", "", 0.0, 65535.0),
    rw(130, "speed_kp", "", 0.0, 65535.0),
    rw(131, "speed_ki", "", 0.0, 65535.0),
    rw(132, "speed_kd", "", 0.0, 65535.0),
    rw(133, "max_brake_time", "ms", 0.0, 65535.0),
    rw(134, "brake_cooling_time", "ms", 0.0, 65535.0),
    rw(135, "accel_current", "", 0.0, 65535.0),
    rw(136, "comm_timeout", "", 0.0, 65535.0),
    rw(137, "version", "", 0.0, 65535.0),
    rw(138, "bus_voltage_scale", "", 0.0, 65535.0),
    rw(139, "use_overcurrent_protection", "", 0.0, 1.0),
    rw(140, "rated_current", "", 0.0, 65535.0),
    rw(141, "overload_ratio", "%", 0.0, 65535.0),
    rw(142, "continuous_current", "%", 0.0, 65535.0),
    rw(143, "overload_time", "ms", 0.0, 65535.0),
    rw(144, "current_offset_reserved", "", 0.0, 65535.0),
    rw(145, "overcurrent_reserved", "", 0.0, 65535.0),
    rw(146, "bus_voltage_protection", "", 0.0, 1.0),
    rw(147, "mcu_overheat_protection", "", 0.0, 1.0),
    rw(148, "hall_fault_protection", "", 0.0, 1.0),
    rw(149, "stall_protection", "", 0.0, 1.0),
    rw(150, "current_limit_protection", "", 0.0, 1.0),
    rw(151, "overload_protection_old", "", 0.0, 2.0),
    rw(152, "overheat_protection", "", 0.0, 1.0),
    rw(153, "current_kp", "", 0.0, 65535.0),
    rw(154, "current_ki", "", 0.0, 65535.0),
    rw(155, "test_parameter", "", 0.0, 65535.0),
    rw(156, "speed_loop_output_limit", "", 0.0, 65535.0),
    rw(157, "current_loop_limit", "", 0.0, 65535.0),
    rw(158, "power_overload_protection", "", 0.0, 1.0),
    rw(159, "speed_integral_limit", "", 0.0, 65535.0),
    rw(160, "current_integral_limit", "", 0.0, 65535.0),
    rw(161, "speed_integral_period", "", 0.0, 999.0),
    rw(162, "current_integral_period", "", 0.0, 999.0),
    rw(163, "speed_pi_follows_plan", "", 0.0, 65535.0),
    rw(164, "kp_speed_coefficient", "", 0.0, 65535.0),
    rw(165, "kp_speed_offset", "", 0.0, 65535.0),
    rw(166, "bus_current_average_ratio", "", 0.0, 65535.0),
    rw(167, "reserved_167", "", 0.0, 65535.0),
    rw(168, "reserved_168", "", 0.0, 65535.0),
    rw(169, "min_speed_loop_output", "", 0.0, 65535.0),
    rw(170, "start_speed", "rpm", 0.0, 65535.0),
    rw(171, "pwm_duty_limit", "", 0.0, 65535.0),
    rw(172, "max_negative_current", "", 0.0, 65535.0),
    rw(173, "max_positive_current", "", 0.0, 65535.0),
    rw(174, "speed_pi_offset", "", 0.0, 65535.0),
    rw(175, "current_pi_offset", "", 0.0, 65535.0),
    rw(176, "low_speed_filter_time", "ms", 0.0, 65535.0),
    rw(177, "low_speed_decel", "rpm", 0.0, 65535.0),
    rw(178, "min_current_loop_duty", "", 0.0, 65535.0),
    rw(179, "duty_limit_ramp", "", 0.0, 65535.0),
    rw(180, "invert_current_feedback", "", 0.0, 1.0),
    rw(181, "speed_loop_rate_limit", "", 0.0, 65535.0),
    rw(182, "current_loop_rate_limit", "", 0.0, 65535.0),
    rw(183, "current_loop_output_offset", "", 0.0, 65535.0),
    rw(184, "reserved_184", "", 0.0, 65535.0),
    rw(185, "back_emf_coefficient", "", 0.0, 65535.0),
    rw(186, "rated_power", "W", 0.0, 65535.0),
    rw(187, "average_current_ratio", "", 0.0, 65535.0),
    rw(188, "bus_voltage_offset", "", 0.0, 65535.0),
    rw(189, "stop_on_zero_duty", "", 0.0, 1.0),
    rw(190, "current_sampling", "", 0.0, 1.0),
    rw(191, "zero_current_at_low_duty", "", 0.0, 1.0),
    rw(192, "low_duty_threshold", "", 0.0, 65535.0),
    rw(193, "max_computed_acceleration", "", 0.0, 65535.0),
    rw(194, "bus_voltage_filter", "", 0.0, 65535.0),
    rw(195, "pwm_active_level", "", 0.0, 1.0),
    rw(196, "current_sampling_196", "", 0.0, 1.0),
    rw(197, "zero_current_at_low_duty_197", "", 0.0, 1.0),
    rw(198, "low_duty_threshold_198", "", 0.0, 65535.0),
    rw(199, "max_computed_acceleration_199", "", 0.0, 65535.0),
    rw(200, "display_select", "", 0.0, 65535.0),
    rw(201, "internal_speed", "rpm", 0.0, 65535.0),
    rw(202, "speed_source", "", 0.0, 65535.0),
    rw(203, "direction_setting", "", 0.0, 1.0),
    rw(204, "start_stop_source", "", 0.0, 2.0),
    rw(205, "pole_pairs", "", 0.0, 65535.0),
    rw(206, "p2_group_switch", "", 0.0, 65535.0),
    rw(207, "speed_gain", "", 0.0, 65535.0),
    rw(208, "speed_integral_gain", "", 0.0, 65535.0),
    rw(209, "acceleration", "rpm/s", 0.0, 65535.0),
    rw(210, "deceleration", "rpm/s", 0.0, 65535.0),
    rw(211, "analog_max_speed", "rpm", 0.0, 65535.0),
    rw(212, "analog_zero_offset", "mV", 0.0, 3299.0),
    rw(213, "key_speed_step", "rpm", 0.0, 65535.0),
    rw(214, "restore_defaults", "", 0.0, 65535.0),
    rw(215, "drive_address", "", 1.0, 255.0),
    rw(216, "start_speed_216", "rpm", 0.0, 65535.0),
    rw(217, "hold_mode", "", 0.0, 2.0),
    rw(218, "hold_duty", "", 0.0, 65535.0),
    rw(219, "speed_display_filter", "", 0.0, 65535.0),
    rw(220, "current_display_ratio", "", 0.0, 65535.0),
    rw(221, "analog_max_voltage", "mV", 0.0, 3299.0),
    rw(222, "analog_min_voltage", "mV", 0.0, 3299.0),
];

/// Whether the manual calls parameter `number` reserved.
pub fn is_reserved(number: u16) -> bool {
    PARAMETERS
        .get(usize::from(number))
        .is_some_and(|p| p.name.starts_with("reserved_"))
}

/// The parameter called `name`.
///
/// # Errors
/// [`Error::InvalidArgument`] if there is none.
pub fn by_name(name: &str) -> Result<&'static Register> {
    PARAMETERS.iter().find(|p| p.name == name).ok_or_else(|| {
        let hint = did_you_mean(name, PARAMETERS.iter().map(|p| p.name));
        Error::InvalidArgument(format!("a PBL drive has no parameter {name:?}{hint}"))
    })
}

/// Parameter `number`.
///
/// # Errors
/// [`Error::InvalidArgument`] if it is not 0..=222.
pub fn by_number(number: u16) -> Result<&'static Register> {
    PARAMETERS
        .get(usize::from(number))
        .ok_or_else(|| Error::InvalidArgument(format!("PBL parameters are 0 to 222, got {number}")))
}

/// The names of the alarm bits set in `word` (the manual names none: "alarm bit N").
pub fn alarm_names(word: u32) -> Vec<String> {
    (0..32)
        .filter(|bit| word & (1 << bit) != 0)
        .map(|bit| format!("alarm bit {bit}"))
        .collect()
}

/// A PBL drive on a bus.
#[derive(Debug)]
pub struct Pbl {
    station: Station,
}

impl Device for Pbl {
    fn station(&self) -> &Station {
        &self.station
    }

    fn station_mut(&mut self) -> &mut Station {
        &mut self.station
    }
}

impl Pbl {
    /// The drive at `unit` on `bus`.
    pub fn new(bus: Arc<Bus>, unit: u8) -> Pbl {
        let opts = TxOptions {
            echo: Echo::CountForSingleWrite,
            ..TxOptions::default()
        };
        Pbl {
            station: Station::new(bus, unit, opts),
        }
    }

    /// Reads the parameter called `name`.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn get(&self, name: &str) -> Result<f64> {
        let p = by_name(name)?;
        Ok(p.decode(self.read_parameter(p.address)?))
    }

    /// Writes `value` to the parameter called `name`, checked before anything is sent.
    ///
    /// # Errors
    /// Any [`Error`]; [`Error::InvalidArgument`] for a read-only parameter or a bad value.
    pub fn set(&self, name: &str, value: f64) -> Result<()> {
        let p = by_name(name)?;
        let raw = p.encode(value)?;
        self.write(p.address, raw)
    }

    /// Reads parameter `number`.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn read_parameter(&self, number: u16) -> Result<u16> {
        by_number(number)?;
        let words = self.station.read(number, 1)?;
        words
            .first()
            .copied()
            .ok_or_else(|| self.station.short_reply())
    }

    /// Writes parameter `number`, checked against the table first.
    ///
    /// # Errors
    /// Any [`Error`]; [`Error::InvalidArgument`] for a read-only parameter or a bad value.
    pub fn write_parameter(&self, number: u16, value: u16) -> Result<()> {
        let raw = by_number(number)?.encode(f64::from(value))?;
        self.write(number, raw)
    }

    /// Reads `count` parameters from `start`, in as few requests as the protocol allows.
    ///
    /// # Errors
    /// Any [`Error`]; [`Error::InvalidArgument`] past parameter 222.
    pub fn read_parameters(&self, start: u16, count: u16) -> Result<Vec<u16>> {
        if count == 0 || usize::from(start) + usize::from(count) > PARAMETERS.len() {
            return Err(Error::InvalidArgument(format!(
                "parameters {start}+{count} are not within 0 to 222"
            )));
        }
        let mut words = Vec::with_capacity(count.into());
        let end = start + count;
        let mut at = start;
        while at < end {
            let n = (end - at).min(MAX_BLOCK);
            words.extend(self.station.read(at, n)?);
            at += n;
        }
        Ok(words)
    }

    /// Every parameter the manual documents (not the reserved ones), `(name, value)` in
    /// number order, read in blocks of [`MAX_BLOCK`] (four requests).
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn parameters(&self) -> Result<Vec<(&'static str, u16)>> {
        let words = self.read_parameters(0, PARAMETERS.len() as u16)?;
        Ok(PARAMETERS
            .iter()
            .zip(words)
            .filter(|(p, _)| !p.name.starts_with("reserved_"))
            .map(|(p, w)| (p.name, w))
            .collect())
    }

    /// Parameters 0..=99 (status and measurements but the reserved ones), `(name, value,
    /// unit)`, in blocks of [`MAX_BLOCK`] (two requests).
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn telemetry(&self) -> Result<Vec<(&'static str, u16, &'static str)>> {
        let count = *MEASUREMENTS.end() + 1;
        let words = self.read_parameters(0, count)?;
        Ok(PARAMETERS[..usize::from(count)]
            .iter()
            .zip(words)
            .filter(|(p, _)| !p.name.starts_with("reserved_"))
            .map(|(p, w)| (p.name, w, p.unit))
            .collect())
    }

    /// The [`SAMPLE`] parameters, `(name, value)`, in one request.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn sample(&self) -> Result<Vec<(&'static str, u16)>> {
        let first = by_name(SAMPLE[0])?.address;
        let words = self.station.read(first, SAMPLE.len() as u16)?;
        Ok(SAMPLE.iter().copied().zip(words).collect())
    }

    /// Sets bit 0 of the control word (start), keeping the other bits.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn start(&self) -> Result<()> {
        self.update_control(|w| w | START)
    }

    /// Clears bit 0 of the control word (stop), keeping the other bits. The stop is always
    /// written: when the control word cannot be read, 0 (stop, forward) is written instead
    /// (but nothing to a unit its [`Vouch`](super::Vouch) refuses).
    ///
    /// # Errors
    /// Any [`Error`] of the write.
    pub fn stop(&self) -> Result<()> {
        self.station.exclusive(|| {
            let word = match self.read_parameter(CONTROL) {
                Ok(word) => word & !START,
                // A unit not vouched for takes no write at all.
                Err(e @ Error::Unvouched { .. }) => return Err(e),
                Err(e) => {
                    log::warn!(
                        target: "benchbus::device",
                        "unit {}: control word unread ({e}): writing 0 to stop", self.unit()
                    );
                    0
                }
            };
            self.write(CONTROL, word)
        })
    }

    /// What leaving a `with` block sends: [`stop`](Self::stop), or when `urgent` (leaving on
    /// an error, Ctrl-C) a control word of 0 (stop, forward), sent once and at once (see
    /// [`TxOptions::urgent`](crate::bus::TxOptions::urgent)): the control word is not read
    /// first, as a read cannot skip the answers the drive still owes.
    ///
    /// # Errors
    /// Any [`Error`] of the write (or of [`stop`](Self::stop)).
    pub fn stop_on_exit(&self, urgent: bool) -> Result<()> {
        if urgent {
            self.station.write_urgent(CONTROL, 0)
        } else {
            self.stop()
        }
    }

    /// Sets bit 1 of the control word: the direction asked for (true = reverse).
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn set_reverse(&self, reverse: bool) -> Result<()> {
        self.update_control(|w| if reverse { w | REVERSE } else { w & !REVERSE })
    }

    /// The control word: `(started, reverse)` as asked for.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn control(&self) -> Result<(bool, bool)> {
        let w = self.read_parameter(CONTROL)?;
        Ok((w & START != 0, w & REVERSE != 0))
    }

    /// The status word: `(running, reverse)` as the drive reports it.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn status(&self) -> Result<(bool, bool)> {
        let w = self.read_parameter(STATUS)?;
        Ok((w & START != 0, w & REVERSE != 0))
    }

    /// The 32-bit alarm word (parameter 5 high, 4 low), in one request.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn alarms(&self) -> Result<u32> {
        match self.station.read(ALARMS, 2)?[..] {
            [low, high] => Ok(u32::from(high) << 16 | u32::from(low)),
            _ => Err(self.station.short_reply()),
        }
    }

    /// Writes 1511 to parameter 214: the drive restores its defaults at the next power-up.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn restore_defaults(&self) -> Result<()> {
        self.write(RESTORE_DEFAULTS, RESTORE_MAGIC)
    }

    /// Read-modify-write of the control word, as one sequence per unit (whichever Pbl
    /// object runs it).
    fn update_control(&self, change: impl Fn(u16) -> u16) -> Result<()> {
        self.station.exclusive(|| {
            let word = self.read_parameter(CONTROL)?;
            let new = change(word);
            if new == word {
                return Ok(());
            }
            self.write(CONTROL, new)
        })
    }

    fn write(&self, number: u16, value: u16) -> Result<()> {
        self.station.write(number, value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_is_the_manuals_list() {
        for (i, p) in PARAMETERS.iter().enumerate() {
            assert_eq!(usize::from(p.address), i, "{}", p.name);
            assert_eq!(
                p.access == Access::Read,
                (2..=99).contains(&i),
                "{}",
                p.name
            );
            assert!(p.range.0 <= p.range.1 && p.range.1 <= 65535.0, "{}", p.name);
        }
        let mut names: Vec<&str> = PARAMETERS.iter().map(|p| p.name).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), PARAMETERS.len());
        assert_eq!(
            by_name("acceleration").map(|p| (p.address, p.unit)).ok(),
            Some((209, "rpm/s"))
        );
        assert_eq!(by_name("internal_speed").map(|p| p.address).ok(), Some(201));
        assert!(is_reserved(22) && is_reserved(49) && !is_reserved(50) && is_reserved(184));
        assert!(by_number(223).is_err());
    }

    #[test]
    fn ranges_the_manual_gives_are_checked() {
        let check = |n: u16, v: f64| by_number(n).and_then(|p| p.encode(v)).is_ok();
        assert!(check(100, 2.0) && !check(100, 3.0));
        assert!(check(204, 2.0) && !check(204, 3.0));
        assert!(!check(215, 0.0) && check(215, 255.0));
        assert!(!check(212, 3300.0));
        assert!(!check(50, 1.0)); // measured: read-only
    }

    #[test]
    fn the_sample_is_one_block_of_measurements() {
        for (i, name) in SAMPLE.iter().enumerate() {
            let p = by_name(name).ok().map(|p| (p.address, p.access));
            assert_eq!(p, Some((50 + i as u16, Access::Read)), "{name}");
        }
    }

    #[test]
    fn alarm_bits_are_named_by_number() {
        assert_eq!(
            alarm_names(0x0002_0001),
            vec!["alarm bit 0", "alarm bit 17"]
        );
        assert!(alarm_names(0).is_empty());
    }
}
