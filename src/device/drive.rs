//! BLD2 / BLD3H and ZBLD.C20 brushless DC drives (manuals 000 and 001, register list B.3).
//!
//! Commands go to 0x2000, settings live at 0x2001..0x2012, status at 0x2100..0x2103 and
//! measurements at 0x3000..0x3014: the family's file, `families/drive.toml` ([`table`]),
//! whose rows are the BLD's and say where the C20 differs (it lacks 0x2010..0x2012 and
//! 0x3012..0x3014 and has other ranges for some enumerations). Function-code parameters
//! Fgg.nn sit at `gg << 8 | nn` and take a write only while 0x200E = 1. The C20 also lacks
//! the brake command and reads status word 2 bit 4 with the opposite polarity.

use super::family;
use super::profile::Profile;
use super::profiled::Block;
use super::suggest::did_you_mean;
use super::{on_station, Tabled};
use super::{Device, Register, Station};
use crate::bus::{Bus, TxOptions};
use crate::codec::pdu::WRITE_SINGLE_REGISTER;
use crate::codec::{exception_meaning, FrameError};
use crate::error::{Error, Result};
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::{Arc, OnceLock};

/// Which manual the drive follows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// BLD2 and BLD3H (manual 000).
    Bld,
    /// ZBLD.C20 (manual 001).
    C20,
}

impl Family {
    /// "BLD" or "C20".
    pub fn name(self) -> &'static str {
        match self {
            Family::Bld => "BLD",
            Family::C20 => "C20",
        }
    }

    /// The family of a name ("BLD", "BLD2", "BLD3H", "C20", "ZBLD.C20"; any case).
    pub fn from_name(name: &str) -> Option<Family> {
        match name.to_ascii_uppercase().as_str() {
            "BLD" | "BLD2" | "BLD3H" => Some(Family::Bld),
            "C20" | "ZBLD.C20" => Some(Family::C20),
            _ => None,
        }
    }
}

/// The command table, declared once: each row is the [`Command`] variant, its code (the
/// value written to the command register 0x2000), the name of the method that sends it and
/// what it does. `drive_commands!(then! { args })` expands to `then! { { args } rows... }`,
/// so that the enum here and the methods of the Python binding come from the same rows.
macro_rules! drive_commands {
    ($then:ident ! { $($pass:tt)* }) => {
        $then! {
            { $($pass)* }
            Forward = 1, forward, "Run forward at the speed setpoint";
            Reverse = 2, reverse, "Run in reverse at the speed setpoint";
            JogForward = 3, jog_forward, "Jog forward";
            JogReverse = 4, jog_reverse, "Jog in reverse";
            Stop = 5, stop, "Stop: decelerate, or as :attr:`stop_mode` says";
            Coast = 6, coast, "Free stop (emergency stop): cut the output and let the motor coast";
            ResetFault = 7, reset_fault, "Reset a fault";
            JogStop = 8, jog_stop, "End a jog";
            Brake = 9, brake, "Brake stop, BLD only; ValueError on a C20";
        }
    };
}
#[allow(unused_imports)] // used by the Python binding only
pub(crate) use drive_commands;

/// The docstring of a command from its row: what it does and its code ("Jog forward
/// (command 3).").
macro_rules! command_doc {
    ($doc:literal, $code:literal) => {
        concat!($doc, " (command ", stringify!($code), ").")
    };
}
#[allow(unused_imports)] // used by the Python binding only
pub(crate) use command_doc;

/// The `Command` enum and its `ALL` / `name` from the rows of [`drive_commands`].
macro_rules! command_enum {
    ({} $($variant:ident = $code:literal, $method:ident, $doc:literal;)*) => {
        /// A value written to the command register 0x2000.
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        #[repr(u16)]
        pub enum Command {
            $(
                #[doc = command_doc!($doc, $code)]
                $variant = $code,
            )*
        }

        impl Command {
            /// Every command, in code order.
            pub const ALL: [Command; [$($code),*].len()] = [$(Command::$variant),*];

            /// The name of the method that sends it ("forward", "jog_stop"...).
            pub fn name(self) -> &'static str {
                match self {
                    $(Command::$variant => stringify!($method),)*
                }
            }
        }
    };
}

drive_commands!(command_enum! {});

impl Command {
    /// The command of its register value.
    pub fn from_code(code: u16) -> Option<Command> {
        Command::ALL.into_iter().find(|c| *c as u16 == code)
    }

    /// The value written to the command register.
    pub fn code(self) -> u16 {
        self as u16
    }

    /// The command called `name` (see [`name`](Self::name)).
    pub fn from_name(name: &str) -> Option<Command> {
        Command::ALL.into_iter().find(|c| c.name() == name)
    }

    /// Whether the C20 manual lists it (all but the brake stop).
    pub fn on_c20(self) -> bool {
        self != Command::Brake
    }

    /// Whether it starts a jog (that a jog stop ends).
    pub fn starts_jog(self) -> bool {
        matches!(self, Command::JogForward | Command::JogReverse)
    }
}

/// Address of the command register, where every [`Command`] is written (the register just
/// before the table's first row, which the file leaves out).
pub const COMMAND: u16 = 0x2000;

/// Line speeds by the code of 0x2009 / F08.01 (the C20 stops at 57600).
pub const BAUD_RATES: [u32; 8] = [1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200];

/// The row of the function-code write enable (0 = parameters not writable, 1 = writable).
const WRITE_ENABLE: &str = "parameter_write_enable";
/// The row of the first status register (0x2100 state, 0x2101 status word 2, 0x2102 fault
/// code).
const STATE: &str = "state";
/// The row of the first measurement register.
const FIRST_MEASUREMENT: &str = "set_frequency";
/// The rows 0x3012..0x3014, which a BLD's firmware may lack ("software version dependent"
/// in 000): a reserved word, then the hall count's high and low words.
const HALL_ROWS: [&str; 3] = ["reserved_3012", "hall_count_high", "hall_count_low"];

/// The family's file (`families/drive.toml`) as drives of `family` have it: the BLD's rows,
/// or the C20's (fewer registers, other ranges).
///
/// # Errors
/// As [`family::profile`]; [`Error::Internal`] if the file does not name the model.
pub fn table(family: Family) -> Result<&'static Profile> {
    static MODELS: [OnceLock<std::result::Result<Profile, String>>; 2] =
        [const { OnceLock::new() }; 2];
    let file = family::profile("drive")?;
    let at = match family {
        Family::Bld => 0,
        Family::C20 => 1,
    };
    MODELS[at]
        .get_or_init(|| {
            file.for_model(family.name())
                .ok_or_else(|| format!("the drive file has no model {}", family.name()))
        })
        .as_ref()
        .map_err(|e| Error::Internal(e.clone()))
}

/// The measurement rows of `family`'s table, 0x3000 on, in address order (with the hall
/// rows or without).
fn measurements(family: Family, hall: bool) -> Result<Vec<&'static Register<String>>> {
    let table = table(family)?;
    let first = table
        .registers
        .iter()
        .position(|r| r.register.name == FIRST_MEASUREMENT)
        .ok_or_else(|| Error::Internal(format!("the drive file has no {FIRST_MEASUREMENT}")))?;
    Ok(table.registers[first..]
        .iter()
        .map(|r| &r.register)
        .filter(|r| hall || !HALL_ROWS.contains(&r.name.as_str()))
        .collect())
}

/// The vendor's meaning of an exception code (B.2.4; the same list in the C20 manual).
pub fn meaning(code: u8) -> &'static str {
    match code {
        0x01 => "illegal command, or the drive is in a state that refuses it (a fault?)",
        0x02 => "illegal data address",
        0x03 => "illegal data value (out of range)",
        0x04 => "operation failed (a function-code write without 0x200E write enable?)",
        0x05 => "wrong password",
        0x06 => "frame error (length or CRC)",
        0x07 => "parameter is read-only",
        0x08 => "not changeable while running",
        other => exception_meaning(other),
    }
}

/// The name of a fault code (0x2102, 0x300B). The manuals name only 0x0A.
pub fn fault_name(code: u16) -> String {
    match code {
        0x0A => "undervoltage".to_string(),
        other => format!("unknown fault 0x{other:02X}"),
    }
}

/// The drive's model from its identification code (0x2103).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Model {
    /// BLD2 (0x0020 on a BLD-family drive).
    Bld2,
    /// BLD3H (0x0030).
    Bld3h,
    /// ZBLD.C20 (0x0020 on a C20-family drive).
    C20,
}

impl Model {
    /// Every model, in the order of the manuals.
    pub const ALL: [Model; 3] = [Model::Bld2, Model::Bld3h, Model::C20];

    /// Its identification code (0x2103).
    pub fn id(self) -> u16 {
        match self {
            Model::Bld2 | Model::C20 => 0x0020,
            Model::Bld3h => 0x0030,
        }
    }

    /// The manual it follows.
    pub fn family(self) -> Family {
        match self {
            Model::Bld2 | Model::Bld3h => Family::Bld,
            Model::C20 => Family::C20,
        }
    }

    /// The model of an identification code, as `family` reads it: the family's own model
    /// with that code, else the one model of any family that has it (0x0030 is a BLD3H
    /// whichever family the drive was opened as).
    pub fn from_id(family: Family, id: u16) -> Option<Model> {
        let mut with_id = Model::ALL.into_iter().filter(|m| m.id() == id);
        if let Some(own) = with_id.clone().find(|m| m.family() == family) {
            return Some(own);
        }
        match (with_id.next(), with_id.next()) {
            (Some(only), None) => Some(only),
            _ => None,
        }
    }

    /// "BLD2", "BLD3H" or "C20".
    pub fn name(self) -> &'static str {
        match self {
            Model::Bld2 => "BLD2",
            Model::Bld3h => "BLD3H",
            Model::C20 => "C20",
        }
    }
}

/// Status registers 0x2100..0x2102, decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Status {
    /// 0x2100: 1 forward, 2 reverse, 3 stopped, 4 fault, 5 off, 6 electronic braking.
    pub state: u16,
    /// 0x2101 bit 0: the DC bus voltage is established.
    pub bus_voltage_ready: bool,
    /// 0x2101 bit 4 (1 = overloaded on the BLD, 0 = overloaded on the C20).
    pub overloaded: bool,
    /// 0x2101 bits 5..6: 0 keypad, 1 terminals, 2 communication (3 is not in the manuals).
    pub control_source: u16,
    /// 0x2101 bit 7 (BLD only): a keypad is connected.
    pub keypad_connected: Option<bool>,
    /// 0x2102: the fault code, 0 for none.
    pub fault_code: u16,
}

impl Status {
    /// The rows a status read takes, in order (the BLD's table adds `keypad_connected`):
    /// 0x2100..0x2102 and the fields of status word 2 the drive file declares.
    const ROWS: [&'static str; 5] = [
        STATE,
        "status_word",
        "fault_code",
        "bus_voltage_ready",
        "control_source",
    ];

    /// Status word 2 bit 4 as `family` gives it: 1 is overloaded on the BLD, 0 on the C20.
    pub fn overloaded(family: Family, word: u16) -> bool {
        let bit4 = word & 0x10 != 0;
        match family {
            Family::Bld => bit4,
            Family::C20 => !bit4,
        }
    }
}

/// One snapshot of the measurement registers, in engineering units; `hall_count` joins
/// 0x3013 (high) and 0x3014 (low) and is None on the C20.
#[derive(Debug, Clone, PartialEq)]
pub struct Telemetry {
    /// `(name, value, unit)` of 0x3000..0x3011 in address order.
    pub values: Vec<(&'static str, f64, &'static str)>,
    /// The 32-bit hall count (BLD only).
    pub hall_count: Option<u32>,
}

impl Telemetry {
    /// The names a snapshot holds, in order: each value of 0x3000..0x3011, then
    /// `hall_count` (the registers 0x3012..0x3014 are read but not values of their own).
    ///
    /// # Errors
    /// As [`table`].
    pub fn fields() -> Result<Vec<&'static str>> {
        Ok(measurements(Family::Bld, false)?
            .into_iter()
            .map(|r| r.name.as_str())
            .chain(["hall_count"])
            .collect())
    }
}

/// Parses a function-code parameter name, "F00.10" (group 00..10, index 00..99, two digits
/// each as the manuals write them; the index is decimal, so F00.50 is 0x0032), into its
/// register address `gg << 8 | nn`.
///
/// # Errors
/// [`Error::InvalidArgument`] for anything else.
pub fn parameter_address(code: &str) -> Result<u16> {
    let bad = || {
        Error::InvalidArgument(format!(
            "a function-code parameter is written like \"F00.10\" (groups F00..F10, index \
             00..99), got {code:?}"
        ))
    };
    let rest = code
        .strip_prefix('F')
        .or_else(|| code.strip_prefix('f'))
        .ok_or_else(bad)?;
    let (group, index) = rest.split_once('.').ok_or_else(bad)?;
    let number = |s: &str| -> Option<u16> {
        if s.len() == 2 && s.bytes().all(|b| b.is_ascii_digit()) {
            s.parse().ok()
        } else {
            None
        }
    };
    match (number(group), number(index)) {
        (Some(g), Some(n)) if g <= 10 => Ok(g << 8 | n),
        _ => Err(bad()),
    }
}

/// A function-code parameter read and written in engineering units, through
/// [`Drive::read_setting`] and [`Drive::write_setting`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Setting {
    /// Its name in the Python API (`comm_loss_timeout`).
    pub name: &'static str,
    /// The parameter, as the manual writes it ("F08.04").
    pub code: &'static str,
    /// What the manual calls it.
    pub what: &'static str,
    /// Engineering value = raw word x scale; a write is rounded to the nearest step.
    pub scale: f64,
    /// Unit of the engineering value.
    pub unit: &'static str,
    /// The values a write may carry besides 0 (off), inclusive.
    pub range: (f64, f64),
    /// Whether the C20 manual lists it.
    pub on_c20: bool,
}

impl Setting {
    /// Steps per unit of the engineering value (10 for tenths).
    fn per_unit(&self) -> f64 {
        (1.0 / self.scale).round()
    }

    /// The engineering value of a raw word.
    pub fn decode(&self, raw: u16) -> f64 {
        f64::from(raw) / self.per_unit()
    }

    /// The raw word for an engineering value: 0, or one in [`range`](Self::range) rounded
    /// to the nearest step (half to even).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for anything else (NaN and the infinities included).
    pub fn encode(&self, value: f64) -> Result<u16> {
        let (lo, hi) = self.range;
        if !(value == 0.0 || (lo..=hi).contains(&value)) {
            return Err(Error::InvalidArgument(format!(
                "{} ({}) must be 0 (off) or {lo:?} to {hi:?} {}, got {value:?}",
                self.name, self.code, self.unit
            )));
        }
        // In range, so it fits a register (checked against 16 bits in the tests).
        Ok((value * self.per_unit()).round_ties_even() as u16)
    }
}

/// F08.04, the communication-loss timeout: a drive that hears no request for that long
/// trips and stops its motor; 0 = off (the default), else 0.1..60.0 s in tenths. The
/// ZBLD.C20 manual lists no F08.04.
pub const COMM_LOSS_TIMEOUT: Setting = Setting {
    name: "comm_loss_timeout",
    code: "F08.04",
    what: "communication-loss timeout",
    scale: 0.1,
    unit: "s",
    range: (0.1, 60.0),
    on_c20: false,
};

/// Every [`Setting`] of the drive.
pub const SETTINGS: &[Setting] = &[COMM_LOSS_TIMEOUT];

fn find_setting(name: &str) -> Result<Setting> {
    SETTINGS
        .iter()
        .find(|s| s.name == name)
        .copied()
        .ok_or_else(|| {
            let hint = did_you_mean(name, SETTINGS.iter().map(|s| s.name));
            Error::InvalidArgument(format!("the drive has no setting {name:?}{hint}"))
        })
}

/// Whether a drive does something the manuals leave open (block reads, the hall count
/// registers): not tried yet, or learned from its first answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Support {
    /// Not tried yet.
    Unknown = 0,
    /// It does.
    Yes = 1,
    /// It does not.
    No = 2,
}

impl Support {
    /// True or false once learned, None while unknown.
    pub fn known(self) -> Option<bool> {
        match self {
            Support::Unknown => None,
            Support::Yes => Some(true),
            Support::No => Some(false),
        }
    }
}

/// A [`Support`] that threads sharing a drive learn together.
#[derive(Debug)]
struct AtomicSupport(AtomicU8);

impl AtomicSupport {
    fn new(support: Support) -> AtomicSupport {
        AtomicSupport(AtomicU8::new(support as u8))
    }

    fn get(&self) -> Support {
        match self.0.load(Ordering::Relaxed) {
            1 => Support::Yes,
            2 => Support::No,
            _ => Support::Unknown,
        }
    }

    fn set(&self, support: Support) {
        self.0.store(support as u8, Ordering::Relaxed);
    }
}

/// A BLD2 / BLD3H / C20 drive on a bus.
#[derive(Debug)]
pub struct Drive {
    station: Station,
    family: Family,
    block_reads: AtomicSupport,
    /// Whether the firmware has 0x3012..0x3014 ("software version dependent" in 000).
    hall_registers: AtomicSupport,
    /// Whether this object started a jog that no jog stop has ended yet.
    jogging: AtomicBool,
}

on_station!(Drive);

impl Tabled for Drive {
    fn table(&self) -> Result<&'static Profile> {
        table(self.family)
    }

    fn index(&self, name: &str) -> Result<usize> {
        let own = table(self.family)?;
        if let Some(i) = own.index(name) {
            return Ok(i);
        }
        let file = family::profile("drive")?;
        match file.index(name).map(|i| &file.registers[i]) {
            Some(r) => Err(Error::InvalidArgument(format!(
                "{name} ({:#06x}) exists on {} drives only, not on the {}",
                r.register.address,
                r.models.join(" and "),
                self.family.name()
            ))),
            None => {
                let names = own.registers.iter().map(|r| r.register.name.as_str());
                let hint = did_you_mean(name, names);
                Err(Error::InvalidArgument(format!(
                    "the drive has no register {name:?}{hint}"
                )))
            }
        }
    }

    /// Writes `value` (engineering units) to the register called `name`, checked against
    /// its range and resolution before anything is sent.
    fn set(&self, name: &str, value: f64) -> Result<()> {
        let register = self.register(name)?;
        let raw = register.encode(value)?;
        self.write(register.address, raw)
    }

    /// A block of holding registers as the drive allows: in one request, or one register a
    /// request on a drive that refuses block reads ([`Drive::block_reads`]).
    fn read_block(&self, block: &Block) -> Result<Vec<u16>> {
        self.read(block.start, block.count)
    }
}

impl Drive {
    /// The drive at `unit` on `bus`. `write_ack` is false for a drive set to F08.06 = 1,
    /// which answers no write. Its own reply timeout and retries (for a reply delay F08.03
    /// longer than the Bus allows) come from [`Device::with_timing`].
    pub fn new(bus: Arc<Bus>, unit: u8, family: Family, write_ack: bool) -> Drive {
        let opts = TxOptions {
            meaning,
            write_ack,
            ..TxOptions::default()
        };
        Drive {
            station: Station::new(bus, unit, opts),
            family,
            block_reads: AtomicSupport::new(Support::Unknown),
            hall_registers: AtomicSupport::new(if family == Family::Bld {
                Support::Unknown
            } else {
                Support::No
            }),
            jogging: AtomicBool::new(false),
        }
    }

    /// Which manual the drive follows.
    pub fn family(&self) -> Family {
        self.family
    }

    /// Whether writes are answered (false when set to F08.06 = 1).
    pub fn write_ack(&self) -> bool {
        self.station.opts().write_ack
    }

    /// Whether a jog this object started is still on (no jog stop sent since).
    pub fn jogging(&self) -> bool {
        self.jogging.load(Ordering::Relaxed)
    }

    /// Whether the drive answers multi-register reads: None until one was tried.
    pub fn block_reads(&self) -> Option<bool> {
        self.block_reads.get().known()
    }

    /// The register called `name`, as this drive's family has it.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if there is no such register, or not on this family.
    pub fn register(&self, name: &str) -> Result<&'static Register<String>> {
        Ok(&self.row(name)?.register)
    }

    /// The address of the row called `name` of this drive's table.
    fn address(&self, name: &str) -> Result<u16> {
        Ok(self.register(name)?.address)
    }

    /// Sends a command to 0x2000.
    ///
    /// # Errors
    /// Any [`Error`]; [`Error::InvalidArgument`] for the brake on a C20.
    pub fn command(&self, command: Command) -> Result<()> {
        if !command.on_c20() && self.family == Family::C20 {
            return Err(Error::InvalidArgument(
                "the brake stop (command 0x0009) exists on BLD drives only, not on the C20".into(),
            ));
        }
        self.write(COMMAND, command.code())?;
        if command.starts_jog() {
            self.jogging.store(true, Ordering::Relaxed);
        } else if command == Command::JogStop {
            self.jogging.store(false, Ordering::Relaxed);
        }
        Ok(())
    }

    /// What leaving a `with` block sends: a jog stop if this object started a jog, then the
    /// stop. `urgent` (leaving on an error, Ctrl-C): each is sent once and at once (see
    /// [`TxOptions::urgent`](crate::bus::TxOptions::urgent)), and the stop is sent even if
    /// the jog stop failed, but for one case: the drive did not answer the jog stop and the
    /// caller asks to stop meanwhile ([`Bus::interrupted`], a second Ctrl-C), which ends it
    /// there ([`Error::Interrupted`], `attempts` 0).
    ///
    /// # Errors
    /// Any [`Error`] of either command (urgent: the stop's, else the jog stop's).
    pub fn stop_on_exit(&self, urgent: bool) -> Result<()> {
        if !urgent {
            if self.jogging() {
                self.command(Command::JogStop)?;
            }
            return self.command(Command::Stop);
        }
        let jog = if self.jogging() {
            let sent = self.station.write_urgent(COMMAND, Command::JogStop.code());
            if sent.is_ok() {
                self.jogging.store(false, Ordering::Relaxed);
            }
            sent
        } else {
            Ok(())
        };
        // A drive silent to the jog stop, and a second Ctrl-C meanwhile: the stop would wait
        // out one more timeout, and the user asked to be out. A drive that answered the jog
        // stop is sent the stop all the same.
        if matches!(jog, Err(Error::Timeout { .. })) && self.station.bus().interrupted() {
            return Err(Error::Interrupted {
                unit: self.station.unit(),
                function: WRITE_SINGLE_REGISTER,
                attempts: 0,
            });
        }
        self.station.write_urgent(COMMAND, Command::Stop.code())?;
        jog
    }

    /// Reads 0x2100..0x2102.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn status(&self) -> Result<Status> {
        let keypad = (self.family == Family::Bld).then_some("keypad_connected");
        let names: Vec<&str> = Status::ROWS.into_iter().chain(keypad).collect();
        match self.get_many(&names)?[..] {
            [state, word, fault, ready, source, ref keypad @ ..] => Ok(Status {
                state: state as u16,
                bus_voltage_ready: ready != 0.0,
                overloaded: Status::overloaded(self.family, word as u16),
                control_source: source as u16,
                keypad_connected: keypad.first().map(|k| *k != 0.0),
                fault_code: fault as u16,
            }),
            _ => Err(self.station.short_reply()),
        }
    }

    /// The model from 0x2103, or the raw code when it is none the manuals name.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn model(&self) -> Result<std::result::Result<Model, u16>> {
        let id = self.get("model_id")? as u16;
        Ok(Model::from_id(self.family, id).ok_or(id))
    }

    /// Reads every measurement register in one snapshot (one request where the drive allows).
    /// On a BLD whose firmware lacks 0x3012..0x3014 (the manual says they depend on the
    /// software version), the snapshot is taken without them and `hall_count` is None.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn telemetry(&self) -> Result<Telemetry> {
        let with_hall = self.hall_registers.get() != Support::No;
        let read = match self.measured(with_hall) {
            Ok(read) => {
                if with_hall {
                    self.hall_registers.set(Support::Yes);
                }
                read
            }
            Err(Error::Exception { code: 0x02, .. })
                if with_hall && self.hall_registers.get() == Support::Unknown =>
            {
                let read = self.measured(false)?;
                log::debug!(
                    target: "benchbus::device",
                    "unit {}: no registers 0x3012 to 0x3014 on this firmware", self.unit()
                );
                self.hall_registers.set(Support::No);
                read
            }
            Err(e) => return Err(e),
        };
        let mut values = Vec::with_capacity(read.len());
        let mut hall = (None, None);
        for (register, value) in read {
            match register.name.as_str() {
                "reserved_3012" => {}
                "hall_count_high" => hall.0 = Some(value as u32),
                "hall_count_low" => hall.1 = Some(value as u32),
                name => values.push((name, value, register.unit.as_str())),
            }
        }
        let hall_count = match hall {
            (Some(high), Some(low)) => Some(high << 16 | low),
            _ => None,
        };
        Ok(Telemetry { values, hall_count })
    }

    /// The measurement registers (with 0x3012..0x3014 if `hall`) and their values, read as
    /// the planner groups them (one request where the drive allows).
    fn measured(&self, hall: bool) -> Result<Vec<(&'static Register<String>, f64)>> {
        let wanted = measurements(self.family, hall)?;
        let names: Vec<&str> = wanted.iter().map(|r| r.name.as_str()).collect();
        let values = self.get_many(&names)?;
        Ok(wanted.into_iter().zip(values).collect())
    }

    /// The line speed stored in 0x2009, in bits per second (None for a code the manuals do
    /// not list).
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn baud_rate(&self) -> Result<Option<u32>> {
        let code = self.get("baud_code")?;
        Ok(BAUD_RATES.get(code as usize).copied())
    }

    /// Stores a new line speed in 0x2009 (the drive talks at it from then on).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a speed the family does not have; any [`Error`].
    pub fn set_baud_rate(&self, bps: u32) -> Result<()> {
        let register = self.register("baud_code")?;
        let top = register.range.1 as usize;
        match BAUD_RATES[..=top.min(BAUD_RATES.len() - 1)]
            .iter()
            .position(|&b| b == bps)
        {
            Some(code) => self.write(register.address, code as u16),
            None => Err(Error::InvalidArgument(format!(
                "baud rate must be one of {:?} on a {} drive, got {bps}",
                &BAUD_RATES[..=top.min(BAUD_RATES.len() - 1)],
                self.family.name()
            ))),
        }
    }

    /// The [`Setting`] called `name`, if this drive's family has it.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if there is no such setting, or not on this family.
    pub fn setting(&self, name: &str) -> Result<Setting> {
        let setting = find_setting(name)?;
        if self.family == Family::C20 && !setting.on_c20 {
            return Err(Error::InvalidArgument(format!(
                "{name}: the ZBLD.C20 manual lists no {} ({}); it is a BLD2 / BLD3H parameter",
                setting.code, setting.what
            )));
        }
        Ok(setting)
    }

    /// Reads the setting called `name`, in engineering units.
    ///
    /// # Errors
    /// Any [`Error`]; [`Error::InvalidArgument`] for a setting this family lacks.
    pub fn read_setting(&self, name: &str) -> Result<f64> {
        let setting = self.setting(name)?;
        Ok(setting.decode(self.read_parameter(setting.code)?))
    }

    /// Writes `value` (engineering units) to the setting called `name`, as
    /// [`write_parameter`](Self::write_parameter) does; the value is checked before the
    /// family, and both before anything is sent.
    ///
    /// # Errors
    /// Any [`Error`]; [`Error::InvalidArgument`] for a bad value or a setting this family
    /// lacks.
    pub fn write_setting(&self, name: &str, value: f64) -> Result<()> {
        let raw = find_setting(name)?.encode(value)?;
        self.write_parameter(self.setting(name)?.code, raw)
    }

    /// Reads the raw value of function-code parameter `code` ("F00.10").
    ///
    /// # Errors
    /// Any [`Error`]; a parameter the drive lacks answers exception 2.
    pub fn read_parameter(&self, code: &str) -> Result<u16> {
        let address = parameter_address(code)?;
        Ok(self.read(address, 1)?.first().copied().unwrap_or_default())
    }

    /// Writes the raw `value` to function-code parameter `code` ("F00.10"). Sets 0x200E to 1
    /// first when it is not, and puts it back afterwards (also when the write fails).
    ///
    /// # Errors
    /// Any [`Error`]; an exception reply says which parameter the drive refused.
    pub fn write_parameter(&self, code: &str, value: u16) -> Result<()> {
        let address = parameter_address(code)?;
        // One sequence per unit, whichever Drive object runs it.
        self.station
            .exclusive(|| self.write_enabled(code, address, value))
    }

    fn write_enabled(&self, code: &str, address: u16, value: u16) -> Result<()> {
        let enable_at = self.address(WRITE_ENABLE)?;
        let enable = self.read(enable_at, 1)?;
        let was = enable.first().copied().unwrap_or_default();
        if was != 1 {
            self.write(enable_at, 1)?;
        }
        let written = self.write(address, value);
        let restored = if was != 1 {
            self.write(enable_at, was)
        } else {
            Ok(())
        };
        match written {
            Err(Error::Exception {
                unit,
                function,
                code: exc,
                meaning,
                frame,
            }) => Err(Error::Exception {
                unit,
                function,
                code: exc,
                meaning: format!(
                    "{meaning}; the drive refused {code} = {value} with 0x200E write enable = 1"
                ),
                frame,
            }),
            Err(e) => Err(e),
            Ok(()) => restored,
        }
    }

    /// Reads `count` registers from `address`: one request, or one per register when the
    /// drive has refused a block read that it then answered register by register.
    fn read(&self, address: u16, count: u16) -> Result<Vec<u16>> {
        if count > 1 && self.block_reads.get() != Support::No {
            match self.station.read(address, count) {
                Ok(words) => {
                    self.block_reads.set(Support::Yes);
                    return Ok(words);
                }
                // A refusal: an exception reply, or a reply of the wrong shape (a drive that
                // answers one register whatever the count). Not a timeout or a bad CRC.
                Err(e) if self.block_reads.get() == Support::Unknown && is_refusal(&e) => {}
                Err(e) => return Err(e),
            }
            let words = self.read_singly(address, count)?;
            log::debug!(
                target: "benchbus::device",
                "unit {}: block reads refused, reading one register per request", self.unit()
            );
            self.block_reads.set(Support::No);
            return Ok(words);
        }
        self.read_singly(address, count)
    }

    fn read_singly(&self, address: u16, count: u16) -> Result<Vec<u16>> {
        let mut words = Vec::with_capacity(count.into());
        for offset in 0..count {
            words.extend(self.station.read(address + offset, 1)?);
        }
        Ok(words)
    }

    fn write(&self, address: u16, value: u16) -> Result<()> {
        self.station.write(address, value)
    }
}

/// Whether a failed block read is the drive saying no (an exception reply, or a reply of
/// the wrong shape), rather than a lost or corrupted reply.
fn is_refusal(e: &Error) -> bool {
    match e {
        Error::Exception { .. } => true,
        Error::Frame { kind, .. } => !matches!(
            kind,
            FrameError::Crc { .. }
                | FrameError::Ascii(_)
                | FrameError::LocalEcho { .. }
                | FrameError::UnexpectedEcho
                | FrameError::TooSoon { .. }
        ),
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::Access;

    #[test]
    fn parameter_addresses_follow_the_manual() {
        assert_eq!(parameter_address("F00.10").ok(), Some(0x000A));
        assert_eq!(parameter_address("F00.50").ok(), Some(0x0032));
        assert_eq!(parameter_address("F08.06").ok(), Some(0x0806));
        assert_eq!(parameter_address("f10.99").ok(), Some(0x0A63));
        for bad in [
            "F11.00", "F00.100", "00.10", "F00", "F0a.10", "F00.", "", "F.1", "F+1.2",
        ] {
            assert!(parameter_address(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn status_word_2_bit_4_polarity_differs_by_family() {
        // The manuals' example: 0x0041 has bit 4 = 0.
        assert!(!Status::overloaded(Family::Bld, 0x0041));
        assert!(Status::overloaded(Family::C20, 0x0041));
        assert!(!Status::overloaded(Family::C20, 0x0051));
        assert!(Status::overloaded(Family::Bld, 0x0051));
    }

    #[test]
    fn table_is_sorted_unique_and_fits_sixteen_bits() {
        let file = family::profile("drive").unwrap();
        assert_eq!(file.models, ["BLD", "C20"]);
        // In address order; one address twice only for status word 2 and its fields.
        for pair in file.registers.windows(2) {
            let (a, b) = (&pair[0].register, &pair[1].register);
            assert!(a.address <= b.address, "{}", b.name);
            assert!(a.address < b.address || b.address == 0x2101, "{}", b.name);
        }
        for entry in &file.registers {
            let r = &entry.register;
            assert!(r.range.0 <= r.range.1, "{}", r.name);
            assert!(r.range.0 / r.scale >= -32768.0 && r.range.1 / r.scale <= 65535.0);
            let measured = r.address >= 0x2100;
            assert_eq!(r.access == Access::Read, measured, "{}", r.name);
            assert!(entry.models.iter().all(|m| m == "BLD"), "{}", r.name);
        }
        let (bld, c20) = (table(Family::Bld).unwrap(), table(Family::C20).unwrap());
        assert_eq!(bld.registers.len(), file.registers.len());
        assert_eq!(c20.registers.len(), file.registers.len() - 7);
        let on = |t: &Profile, name: &str| {
            t.registers
                .iter()
                .find(|r| r.register.name == name)
                .map(|r| r.register.range)
        };
        assert_eq!(on(bld, "control_mode"), Some((0.0, 5.0)));
        assert_eq!(on(c20, "control_mode"), Some((0.0, 3.0)));
        assert_eq!(on(c20, "stop_mode"), None);
    }

    #[test]
    fn comm_loss_timeout_is_off_or_tenths_of_0_1_to_60_s() {
        let s = COMM_LOSS_TIMEOUT;
        for (seconds, raw) in [
            (0.0, 0),
            (0.1, 1),
            (0.25, 2),
            (0.35, 4),
            (12.34, 123),
            (60.0, 600),
        ] {
            assert_eq!(s.encode(seconds).ok(), Some(raw), "{seconds}");
        }
        for bad in [-0.1, 0.05, 60.1, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert!(s.encode(bad).is_err(), "{bad}");
        }
        assert_eq!(s.decode(25), 2.5);
        assert_eq!(parameter_address(s.code).ok(), Some(0x0804));
        for setting in SETTINGS {
            assert!(
                setting.range.1 / setting.scale <= 65535.0,
                "{}",
                setting.name
            );
        }
    }

    #[test]
    fn support_is_learned_once_per_state() {
        let learned = AtomicSupport::new(Support::Unknown);
        assert_eq!(learned.get().known(), None);
        for support in [Support::Yes, Support::No, Support::Unknown] {
            learned.set(support);
            assert_eq!(learned.get(), support);
        }
        assert_eq!(Support::Yes.known(), Some(true));
        assert_eq!(Support::No.known(), Some(false));
    }

    #[test]
    fn the_rows_the_code_names_are_in_the_file() {
        let rows = &table(Family::Bld).unwrap().registers;
        let address = |name: &str| {
            rows.iter()
                .find(|r| r.register.name == name)
                .map(|r| r.register.address)
        };
        assert_eq!(address(WRITE_ENABLE), Some(0x200E));
        assert_eq!(address(STATE), Some(0x2100));
        assert_eq!(address(FIRST_MEASUREMENT), Some(0x3000));
        let hall: Vec<Option<u16>> = HALL_ROWS.iter().map(|n| address(n)).collect();
        assert_eq!(hall, [Some(0x3012), Some(0x3013), Some(0x3014)]);
        // The command register sits just before the table's first row.
        assert_eq!(rows[0].register.address, COMMAND + 1);
        assert!(address("command").is_none());
    }

    #[test]
    fn telemetry_fields_are_the_measurement_rows_and_the_hall_count() {
        let fields = Telemetry::fields().unwrap();
        assert_eq!(fields.len(), 19);
        assert_eq!(fields[0], "set_frequency");
        assert_eq!(fields[17], "ai3_voltage");
        assert_eq!(fields[18], "hall_count");
        assert!(!fields
            .iter()
            .any(|f| f.starts_with("hall_count_") || f.starts_with("reserved")));
    }

    #[test]
    fn names_of_faults_models_and_commands() {
        assert_eq!(fault_name(0x0A), "undervoltage");
        assert_eq!(fault_name(0x1B), "unknown fault 0x1B");
        assert_eq!(Model::from_id(Family::Bld, 0x20), Some(Model::Bld2));
        assert_eq!(Model::from_id(Family::C20, 0x20), Some(Model::C20));
        assert_eq!(Model::from_id(Family::C20, 0x30), Some(Model::Bld3h));
        assert_eq!(Model::from_id(Family::Bld, 0x40), None);
        for model in Model::ALL {
            assert_eq!(Model::from_id(model.family(), model.id()), Some(model));
        }
        assert_eq!(Command::from_code(9), Some(Command::Brake));
        assert_eq!(Command::from_code(10), None);
        for (code, command) in (1..).zip(Command::ALL) {
            assert_eq!(command.code(), code);
            assert_eq!(Command::from_name(command.name()), Some(command));
        }
        assert_eq!(Command::from_name("Forward"), None);
        assert_eq!(Command::Brake.name(), "brake");
        assert_eq!(Command::JogStop.name(), "jog_stop");
        assert!(Command::JogForward.starts_jog() && !Command::JogStop.starts_jog());
        assert_eq!(meaning(8), "not changeable while running");
        assert_eq!(meaning(0x0B), exception_meaning(0x0B));
    }

    #[test]
    fn a_corrupt_ascii_reply_is_no_refusal_but_a_wrong_shape_is() {
        use crate::codec::ascii::AsciiError;
        let frame = |kind| Error::Frame {
            unit: 1,
            function: 3,
            kind,
            frame: Vec::new(),
        };
        let lrc = AsciiError::Lrc {
            computed: 1,
            received: 2,
        };
        assert!(!is_refusal(&frame(FrameError::Ascii(lrc))));
        assert!(!is_refusal(&frame(FrameError::Ascii(
            AsciiError::OddLength(5)
        ))));
        assert!(is_refusal(&frame(FrameError::Length("short".into()))));
    }
}
