//! Typed device APIs over the [`Bus`]. A device is a table of registers
//! (address, scale, signedness, unit, access, range) plus the few behaviours its manual adds;
//! it holds no I/O of its own.

pub mod drive;
pub mod export;
pub mod family;
pub mod instrument;
pub mod j2;
pub mod pbl;
pub mod profile;
pub mod profiled;
pub mod suggest;
pub mod value;

use crate::bus::{Bus, TxOptions};
use crate::codec::FrameError;
use crate::error::{Error, Result};
use profile::{Profile, ProfileRegister, ProfileValue};
use profiled::{read_block, read_planned, Block};
use std::sync::Arc;
use std::time::Duration;

/// Which of a device's four tables a value lives in (the Modbus data model): registers that
/// may be written (holding) or only read (input), bits that may be written (coils) or only
/// read (discrete inputs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Table {
    /// Holding registers: read with 0x03, written with 0x06 / 0x10.
    #[default]
    Holding,
    /// Input registers: read with 0x04.
    Input,
    /// Coils: read with 0x01, written with 0x05 / 0x0F.
    Coils,
    /// Discrete inputs: read with 0x02.
    Discrete,
}

impl Table {
    /// Whether the table holds bits (coils, discrete inputs) rather than registers.
    pub const fn holds_bits(self) -> bool {
        matches!(self, Table::Coils | Table::Discrete)
    }
}

/// Where a device is and how its requests go: the Bus, the unit address and the family's
/// options (echo rule, write pacing, exception meanings, the device's own timeout and
/// retries). Every device holds one and talks to the Bus only through it.
#[derive(Debug)]
pub struct Station {
    bus: Arc<Bus>,
    unit: u8,
    opts: TxOptions,
    vouch: Option<Arc<dyn Vouch>>,
}

/// What a device's unit must pass before each of the device's requests goes out: a check
/// its user gives (the Python bindings check that the unit is of the device's family, once,
/// before its first exchange). It runs after the call's arguments are checked, so that bad
/// input is refused before anything is sent, the check's reads included.
pub trait Vouch: Send + Sync + std::fmt::Debug {
    /// Ok to send; else the error the call fails with ([`Error::Unvouched`] for a unit
    /// found to be another kind of device), nothing of the call sent.
    ///
    /// # Errors
    /// Whatever the check finds, or fails with.
    fn vouch(&self, unit: u8) -> Result<()>;
}

impl Station {
    /// The device at `unit` on `bus`, its requests sent with `opts`.
    pub fn new(bus: Arc<Bus>, unit: u8, opts: TxOptions) -> Station {
        Station {
            bus,
            unit,
            opts,
            vouch: None,
        }
    }

    /// Ok if the unit is vouched for (see [`Vouch`]); what every request runs first.
    fn vouched(&self) -> Result<()> {
        self.vouch.as_ref().map_or(Ok(()), |v| v.vouch(self.unit))
    }

    /// The bus the device is on.
    pub fn bus(&self) -> &Arc<Bus> {
        &self.bus
    }

    /// The device's unit address.
    pub fn unit(&self) -> u8 {
        self.unit
    }

    /// The options every request of the device is sent with.
    pub fn opts(&self) -> &TxOptions {
        &self.opts
    }

    /// The reply timeout of the device's requests: its own, or the Bus's.
    pub fn timeout(&self) -> Duration {
        self.opts.timeout.unwrap_or_else(|| self.bus.timeout())
    }

    /// The retries of the device's requests: its own, or the Bus's.
    pub fn retries(&self) -> u32 {
        self.opts.retries.unwrap_or_else(|| self.bus.retries())
    }

    /// Exactly `count` holding registers from `address` (a reply of another length is a
    /// frame error).
    ///
    /// # Errors
    /// Any [`Error`] of the request.
    pub fn read(&self, address: u16, count: u16) -> Result<Vec<u16>> {
        self.read_table(Table::Holding, address, count)
    }

    /// Exactly `count` registers of `table` (holding or input) from `address`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a table of bits; any [`Error`] of the request.
    pub fn read_table(&self, table: Table, address: u16, count: u16) -> Result<Vec<u16>> {
        self.vouched()?;
        let (unit, opts) = (self.unit, &self.opts);
        let words = match table {
            Table::Holding => self
                .bus
                .read_holding_registers(unit, address, count, opts)?,
            Table::Input => self.bus.read_input_registers(unit, address, count, opts)?,
            Table::Coils | Table::Discrete => {
                return Err(Error::InvalidArgument(
                    "coils and discrete inputs hold bits, not registers".into(),
                ))
            }
        };
        self.exactly(words, count)
    }

    /// Exactly `count` bits of `table` (coils or discrete inputs) from `address`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a table of registers; any [`Error`] of the request.
    pub fn read_bits(&self, table: Table, address: u16, count: u16) -> Result<Vec<bool>> {
        self.vouched()?;
        let (unit, opts) = (self.unit, &self.opts);
        let bits = match table {
            Table::Coils => self.bus.read_coils(unit, address, count, opts)?,
            Table::Discrete => self.bus.read_discrete_inputs(unit, address, count, opts)?,
            Table::Holding | Table::Input => {
                return Err(Error::InvalidArgument(
                    "holding and input registers hold registers, not bits".into(),
                ))
            }
        };
        self.exactly(bits, count)
    }

    /// Sets one coil (0x05).
    ///
    /// # Errors
    /// Any [`Error`] of the request.
    pub fn write_coil(&self, address: u16, value: bool) -> Result<()> {
        self.vouched()?;
        self.bus.write_coil(self.unit, address, value, &self.opts)
    }

    /// Sets consecutive coils from `address` (0x0F).
    ///
    /// # Errors
    /// Any [`Error`] of the request.
    pub fn write_coils(&self, address: u16, values: &[bool]) -> Result<()> {
        self.vouched()?;
        self.bus.write_coils(self.unit, address, values, &self.opts)
    }

    /// `items` if there are `count` of them, else the short-reply error.
    fn exactly<T>(&self, items: Vec<T>, count: u16) -> Result<Vec<T>> {
        if items.len() == usize::from(count) {
            Ok(items)
        } else {
            Err(self.short_reply())
        }
    }

    /// Writes one register with function 0x06.
    ///
    /// # Errors
    /// Any [`Error`] of the request.
    pub fn write(&self, address: u16, value: u16) -> Result<()> {
        self.vouched()?;
        self.bus
            .write_register(self.unit, address, value, &self.opts)
    }

    /// Writes one register with function 0x06, sent once and at once (see
    /// [`TxOptions::urgent`]), without the unit's [`Vouch`]: a stop on the way out of an
    /// error.
    ///
    /// # Errors
    /// Any [`Error`] of the request.
    pub fn write_urgent(&self, address: u16, value: u16) -> Result<()> {
        let opts = TxOptions {
            urgent: true,
            ..self.opts
        };
        self.bus.write_register(self.unit, address, value, &opts)
    }

    /// Writes `values` from `address` with function 0x10.
    ///
    /// # Errors
    /// Any [`Error`] of the request.
    pub fn write_many(&self, address: u16, values: &[u16]) -> Result<()> {
        self.vouched()?;
        self.bus
            .write_registers(self.unit, address, values, &self.opts)
    }

    /// Runs `f` as one sequence for this unit (a check-then-write, a read-modify-write),
    /// whichever device object on the Bus runs it.
    pub fn exclusive<R>(&self, f: impl FnOnce() -> R) -> R {
        self.bus.exclusive(self.unit, f)
    }

    /// The error of a read answered with fewer registers than asked.
    pub fn short_reply(&self) -> Error {
        Error::Frame {
            unit: self.unit,
            function: 0x03,
            kind: FrameError::Length("the reply held fewer registers than asked".into()),
            frame: Vec::new(),
        }
    }
}

/// `impl Device` for a device struct whose `station` field is its [`Station`] (every
/// device's is).
macro_rules! on_station {
    ($device:ty) => {
        impl $crate::device::Device for $device {
            fn station(&self) -> &$crate::device::Station {
                &self.station
            }

            fn station_mut(&mut self) -> &mut $crate::device::Station {
                &mut self.station
            }
        }
    };
}
pub(crate) use on_station;

/// What every device is: a [`Station`] plus its family's table and behaviours. The Bus, the
/// unit and the per-device timing come from here, once for all families.
pub trait Device: Send + Sync {
    /// The device's station.
    fn station(&self) -> &Station;

    /// The device's station, to set it up before the device is shared.
    fn station_mut(&mut self) -> &mut Station;

    /// The same device with its own reply timeout and retries instead of the Bus's.
    fn with_timing(mut self, timeout: Option<Duration>, retries: Option<u32>) -> Self
    where
        Self: Sized,
    {
        let opts = &mut self.station_mut().opts;
        opts.timeout = timeout;
        opts.retries = retries;
        self
    }

    /// The same device with `vouch` run before each of its requests (see [`Vouch`]).
    fn with_vouch(mut self, vouch: Arc<dyn Vouch>) -> Self
    where
        Self: Sized,
    {
        self.station_mut().vouch = Some(vouch);
        self
    }

    /// The bus the device is on.
    fn bus(&self) -> &Arc<Bus> {
        self.station().bus()
    }

    /// The device's unit address.
    fn unit(&self) -> u8 {
        self.station().unit()
    }
}

/// A device family whose registers are a table (its profile file): any row read and
/// written by name, in engineering units, with the family's rules. What the bindings'
/// `get` and `set` serve, once for every family; reads go through the one block-read
/// planner ([`Profile::plan`]).
pub trait Tabled: Device {
    /// The table (this model's, for a family with models).
    ///
    /// # Errors
    /// As [`family::profile`].
    fn table(&self) -> Result<&'static Profile>;

    /// The index in [`table`](Self::table) of the row called `name`, as the family spells
    /// its names (the J2's in any case).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if there is none (on this model), naming close ones.
    fn index(&self, name: &str) -> Result<usize>;

    /// The row called `name`.
    ///
    /// # Errors
    /// As [`index`](Self::index).
    fn row(&self, name: &str) -> Result<&'static ProfileRegister> {
        Ok(&self.table()?.registers[self.index(name)?])
    }

    /// Writes `value` (engineering units) to the row called `name`, checked (range, steps,
    /// access and the family's rules) before anything is sent.
    ///
    /// # Errors
    /// Any [`Error`]; [`Error::InvalidArgument`] for a bad value or a read-only row.
    fn set(&self, name: &str, value: f64) -> Result<()>;

    /// Reads one block of a plan: the station's read, unless the family reads its own way
    /// (a drive that refuses block reads, one register a request).
    ///
    /// # Errors
    /// Any [`Error`] of a request.
    fn read_block(&self, block: &Block) -> Result<Vec<u16>> {
        read_block(self.station(), block)
    }

    /// Reads the row called `name`, in engineering units (a bool as 1 or 0).
    ///
    /// # Errors
    /// Any [`Error`].
    fn get(&self, name: &str) -> Result<f64> {
        let values = self.get_many(&[name])?;
        values
            .first()
            .copied()
            .ok_or_else(|| self.station().short_reply())
    }

    /// Reads the rows called `names`, in that order, in as few requests as the table's
    /// limits allow ([`Profile::plan`]); every name is looked up before the first is read.
    ///
    /// # Errors
    /// Any [`Error`]; the first stops the reads.
    fn get_many<S: AsRef<str>>(&self, names: &[S]) -> Result<Vec<f64>> {
        let indices = names
            .iter()
            .map(|name| self.index(name.as_ref()))
            .collect::<Result<Vec<_>>>()?;
        read_planned(self.station(), self.table()?, &indices, |b| {
            self.read_block(b)
        })?
        .iter()
        .map(ProfileValue::number)
        .collect()
    }

    /// Writes `values` in order, each as [`set`](Self::set) does. Every value is checked
    /// against its row (range, steps, access) before the first is sent; the checks that need
    /// the device (a family's rules) are made write by write.
    ///
    /// # Errors
    /// As [`set`](Self::set); a failure stops the sequence (the earlier writes stay).
    fn set_many(&self, values: &[(String, f64)]) -> Result<()> {
        for (name, value) in values {
            self.row(name)?.register.encode(*value)?;
        }
        values
            .iter()
            .try_for_each(|(name, value)| self.set(name, *value))
    }
}

/// `raw` x `scale`, exactly where `scale` is one over a whole number: divided by 10 rather
/// than multiplied by 0.1, so 3 tenths are 0.3, not 0.30000000000000004.
pub(crate) fn scaled(raw: f64, scale: f64) -> f64 {
    let per_unit = (1.0 / scale).round();
    if scale < 1.0 && (per_unit * scale - 1.0).abs() < 1e-12 {
        raw / per_unit
    } else {
        raw * scale
    }
}

/// Who may write a register, in the manuals' terms.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    /// `R`: read-only.
    Read,
    /// `W/R`: writable in any state.
    ReadWrite,
    /// `W/R*`: writable only while the motor is stopped.
    WriteWhenStopped,
    /// `W`: write-only (a command register, which reads back nothing useful).
    Write,
}

/// One register: where it is and how its raw word maps to an engineering value. A profile
/// ([`profile`], the built-in families' files too) holds its own `String`s; a `const` row
/// (`&'static str`, the default) serves tests and code that names a register at compile time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Register<S = &'static str> {
    /// The name it has in the Python API (`speed_setpoint`).
    pub name: S,
    /// Register address.
    pub address: u16,
    /// Engineering value = raw word x scale (0.1 for a value in tenths).
    pub scale: f64,
    /// Whether the raw word is a two's complement signed value.
    pub signed: bool,
    /// Unit of the engineering value ("rpm", "s", "V", ""...).
    pub unit: S,
    /// Who may write it.
    pub access: Access,
    /// The engineering values a write may carry (inclusive).
    pub range: (f64, f64),
}

impl<S: AsRef<str>> Register<S> {
    /// The engineering value of a raw word.
    pub fn decode(&self, raw: u16) -> f64 {
        let raw = if self.signed {
            f64::from(raw as i16)
        } else {
            f64::from(raw)
        };
        scaled(raw, self.scale)
    }

    /// Whether values of this register are whole numbers (a scale of 1).
    pub fn is_integer(&self) -> bool {
        self.scale == 1.0
    }

    /// The raw word for an engineering value.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a read-only register, a value outside
    /// [`range`](Self::range) or one that is not a whole number of steps of the scale.
    pub fn encode(&self, value: f64) -> Result<u16> {
        if self.access == Access::Read {
            return Err(Error::InvalidArgument(format!(
                "{} is read-only",
                self.name.as_ref()
            )));
        }
        let (lo, hi) = self.range;
        let steps = value / self.scale;
        let whole = steps.round();
        let tolerance = 1e-6;
        if !value.is_finite()
            || value < lo - tolerance * self.scale
            || value > hi + tolerance * self.scale
        {
            return Err(Error::InvalidArgument(format!(
                "{} must be {} to {}{}, got {}",
                self.name.as_ref(),
                fmt_num(lo),
                fmt_num(hi),
                unit_suffix(self.unit.as_ref()),
                fmt_num(value)
            )));
        }
        if (steps - whole).abs() > tolerance {
            return Err(Error::InvalidArgument(format!(
                "{} is set in steps of {}{}: {} is not a whole number of steps",
                self.name.as_ref(),
                fmt_num(self.scale),
                unit_suffix(self.unit.as_ref()),
                fmt_num(value)
            )));
        }
        // In range, so it fits a register (the ranges are checked against 16 bits in tests).
        Ok(if self.signed {
            whole as i16 as u16
        } else {
            whole as u16
        })
    }
}

pub(crate) fn unit_suffix(unit: &str) -> String {
    if unit.is_empty() {
        String::new()
    } else {
        format!(" {unit}")
    }
}

/// A number the way a person writes it: 3000, 0.1, 600.
pub(crate) fn fmt_num(v: f64) -> String {
    let s = format!("{v:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".to_string()
    } else {
        s.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TENTHS: Register = Register {
        name: "accel_time",
        address: 0x2003,
        scale: 0.1,
        signed: false,
        unit: "s",
        access: Access::ReadWrite,
        range: (0.1, 600.0),
    };

    #[test]
    fn encode_scales_and_checks() {
        assert_eq!(TENTHS.encode(2.5).ok(), Some(25));
        assert_eq!(TENTHS.encode(0.3).ok(), Some(3)); // 0.3 / 0.1 is 2.9999999999999996
        assert_eq!(TENTHS.encode(600.0).ok(), Some(6000));
        for bad in [0.0, 600.1, 2.55, f64::NAN, f64::INFINITY, -1.0] {
            assert!(TENTHS.encode(bad).is_err(), "{bad}");
        }
        let msg = TENTHS.encode(700.0).err().map(|e| e.to_string());
        assert_eq!(
            msg.as_deref(),
            Some("accel_time must be 0.1 to 600 s, got 700")
        );
    }

    #[test]
    fn signed_words_decode_as_twos_complement() {
        let temp = Register {
            name: "temperature",
            address: 0x300C,
            scale: 0.1,
            signed: true,
            unit: "degC",
            access: Access::Read,
            range: (-3276.8, 3276.7),
        };
        assert!((temp.decode(0xFFCE) - -5.0).abs() < 1e-9);
        assert!((temp.decode(250) - 25.0).abs() < 1e-9);
        assert!(temp.encode(1.0).is_err());
    }
}
