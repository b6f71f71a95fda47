//! PBL-series BLDC drives (manual 002): parameters 0..222 as holding registers of the same
//! number, 115200 8E1 by default.
//!
//! Parameter 0 is the control word (bit 0 start, bit 1 reverse), 2 the status (bit 0 running,
//! bit 1 reverse), 4 and 5 the low and high words of the alarm bits; 50..54 are the measured
//! speed, bus voltage, analog speed input, current and power; 100..222 are settings. The
//! manual gives no scaling: values are the raw words, in the units it names. Its drives
//! answer a 0x06 write with a register count of 1 instead of the echo, which is accepted for
//! this family only; they also act on and answer a broadcast, which the Bus never waits for.

use super::family;
use super::profile::{Profile, ProfileRegister};
use super::suggest::did_you_mean;
use super::{on_station, Tabled};
use super::{Device, Register, Station};
use crate::bus::{Bus, TxOptions};
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

const START: u16 = 0x0001;
const REVERSE: u16 = 0x0002;

/// The parameter table, 0..=222 in number order: the family's file (`families/pbl.toml`).
///
/// # Errors
/// As [`family::profile`].
pub fn table() -> Result<&'static [ProfileRegister]> {
    family::registers("pbl")
}

/// The parameter called `name`.
///
/// # Errors
/// [`Error::InvalidArgument`] if there is none.
pub fn by_name(name: &str) -> Result<&'static Register<String>> {
    Ok(&table()?[index(name)?].register)
}

/// The index in [`table`] (its number) of the parameter called `name`.
///
/// # Errors
/// [`Error::InvalidArgument`] if there is none, naming close ones.
pub fn index(name: &str) -> Result<usize> {
    let profile = family::profile("pbl")?;
    profile.index(name).ok_or_else(|| {
        let names = profile.registers.iter().map(|p| p.register.name.as_str());
        let hint = did_you_mean(name, names);
        Error::InvalidArgument(format!("a PBL drive has no parameter {name:?}{hint}"))
    })
}

/// Parameter `number`.
///
/// # Errors
/// [`Error::InvalidArgument`] if it is not 0..=222.
pub fn by_number(number: u16) -> Result<&'static Register<String>> {
    let table = table()?;
    table
        .get(usize::from(number))
        .map(|p| &p.register)
        .ok_or_else(|| {
            let last = table.len().saturating_sub(1);
            Error::InvalidArgument(format!("PBL parameters are 0 to {last}, got {number}"))
        })
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

on_station!(Pbl);

impl Tabled for Pbl {
    fn table(&self) -> Result<&'static Profile> {
        family::profile("pbl")
    }

    fn index(&self, name: &str) -> Result<usize> {
        index(name)
    }

    /// Writes `value` to the parameter called `name`, checked before anything is sent.
    fn set(&self, name: &str, value: f64) -> Result<()> {
        let p = by_name(name)?;
        let raw = p.encode(value)?;
        self.write(p.address, raw)
    }
}

impl Pbl {
    /// The drive at `unit` on `bus`.
    pub fn new(bus: Arc<Bus>, unit: u8) -> Pbl {
        // The file's echo rule: a 0x06 write is answered with a register count (a file the
        // parser refused fails every call anyway).
        let opts = TxOptions {
            echo: family::profile("pbl")
                .map(Profile::echo)
                .unwrap_or_default(),
            ..TxOptions::default()
        };
        Pbl {
            station: Station::new(bus, unit, opts),
        }
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
        if count == 0 || usize::from(start) + usize::from(count) > table()?.len() {
            return Err(Error::InvalidArgument(format!(
                "parameters {start}+{count} are not within 0 to 222"
            )));
        }
        // The profiles' planner: the file lists every number, so its blocks are the
        // stretch in order, each of at most the file's max_read (the manual's frame holds
        // 1..123 data bytes: 61 registers).
        let wanted: Vec<usize> =
            (usize::from(start)..usize::from(start) + usize::from(count)).collect();
        let mut words = Vec::with_capacity(count.into());
        for block in family::profile("pbl")?.plan(&wanted) {
            words.extend(self.station.read(block.start, block.count)?);
        }
        Ok(words)
    }

    /// Every parameter the manual documents (not the reserved ones), `(name, value)` in
    /// number order, read in blocks of the file's `max_read` (four requests).
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn parameters(&self) -> Result<Vec<(&'static str, u16)>> {
        let table = table()?;
        let words = self.read_parameters(0, u16::try_from(table.len()).unwrap_or(u16::MAX))?;
        Ok(table
            .iter()
            .map(|p| &p.register)
            .zip(words)
            .filter(|(p, _)| !p.name.starts_with("reserved_"))
            .map(|(p, w)| (p.name.as_str(), w))
            .collect())
    }

    /// Parameters 0..=99 (status and measurements but the reserved ones), `(name, value,
    /// unit)`, in blocks of the file's `max_read` (two requests).
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn telemetry(&self) -> Result<Vec<(&'static str, u16, &'static str)>> {
        let count = *MEASUREMENTS.end() + 1;
        let words = self.read_parameters(0, count)?;
        Ok(table()?
            .iter()
            .map(|p| &p.register)
            .zip(words)
            .filter(|(p, _)| !p.name.starts_with("reserved_"))
            .map(|(p, w)| (p.name.as_str(), w, p.unit.as_str()))
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
    use crate::device::Access;

    #[test]
    fn the_table_is_the_manuals_list() {
        let table = table().unwrap();
        for (i, p) in table.iter().map(|p| &p.register).enumerate() {
            assert_eq!(usize::from(p.address), i, "{}", p.name);
            assert_eq!(
                p.access == Access::Read,
                (2..=99).contains(&i),
                "{}",
                p.name
            );
            assert!(p.range.0 <= p.range.1 && p.range.1 <= 65535.0, "{}", p.name);
        }
        assert_eq!(table.len(), 223);
        let mut names: Vec<&str> = table.iter().map(|p| p.register.name.as_str()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), table.len());
        assert_eq!(
            by_name("acceleration")
                .map(|p| (p.address, p.unit.as_str()))
                .ok(),
            Some((209, "rpm/s"))
        );
        assert_eq!(by_name("internal_speed").map(|p| p.address).ok(), Some(201));
        let is_reserved = |n| by_number(n).is_ok_and(|p| p.name.starts_with("reserved_"));
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
