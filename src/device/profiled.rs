//! A device described by a [`Profile`]: its registers read in the fewest requests the
//! profile's limits allow, and written in engineering units after every check, on a
//! [`Station`] like the built-in families.

use super::instrument::MAX_DECIMALS;
use super::on_station;
use super::profile::{field_top, Profile, ProfileRegister, ProfileValue, ValueType};
use super::value::Number;
use super::{fmt_num, unit_suffix, Access, Station, Table};
use crate::bus::{Bus, TxOptions};
use crate::codec::pdu::{MAX_READ_BITS, MAX_READ_COUNT, MAX_WRITE_BITS, MAX_WRITE_COUNT};
use crate::codec::Echo;
use crate::error::{Error, Result};
use std::collections::HashMap;
use std::sync::Arc;
use std::time::Duration;

/// One read request of a plan: `count` registers (or bits) of `table` from `start`, holding
/// the registers `members` (indices into the profile's registers).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Block {
    /// The table read.
    pub table: Table,
    /// The first address.
    pub start: u16,
    /// How many registers (or bits).
    pub count: u16,
    /// The profile registers it holds, by index, in address order.
    pub members: Vec<usize>,
}

impl Block {
    fn end(&self) -> u32 {
        u32::from(self.start) + u32::from(self.count)
    }
}

impl Profile {
    /// The index of the register called `name`, by a scan of the registers (to look up
    /// many names, map them once).
    pub fn index(&self, name: &str) -> Option<usize> {
        self.registers.iter().position(|r| r.register.name == name)
    }

    /// The index of the register giving register `index` its decimal places (its
    /// `decimals`), if it has one.
    pub fn places_register(&self, index: usize) -> Option<usize> {
        let name = self.registers.get(index)?.decimals.as_deref()?;
        self.index(name)
    }

    /// `indices` and, after them, the registers giving any of them their decimal places
    /// (each once): what reading them reads.
    pub fn with_places(&self, indices: &[usize]) -> Vec<usize> {
        let mut wanted = indices.to_vec();
        for i in indices {
            if let Some(at) = self.places_register(*i) {
                if !wanted.contains(&at) {
                    wanted.push(at);
                }
            }
        }
        wanted
    }

    /// The checks of a write of `value` to register `index` that can be made before
    /// anything is read: all of [`ProfileRegister::encode`]'s, or for a register with
    /// `decimals` its access, the kind of value, a finite number, and the widest range its
    /// places allow (its digits' at no places and at the most).
    ///
    /// # Errors
    /// As [`ProfileRegister::encode`].
    pub fn precheck(&self, index: usize, value: &ProfileValue) -> Result<()> {
        let r = register(self, index)?;
        let Some(at) = self.places_register(index) else {
            return r.encode(value).map(|_| ());
        };
        if r.register.access == Access::Read {
            return Err(Error::InvalidArgument(format!("{} is read-only", r.name())));
        }
        let number = match value {
            ProfileValue::Int(_) | ProfileValue::Float(_) => value.number()?,
            other => {
                return Err(Error::InvalidArgument(format!(
                    "{} takes a number, not {}",
                    r.name(),
                    shown(other)
                )))
            }
        };
        let most = register(self, at)?.most_places().unwrap_or(MAX_DECIMALS);
        let (low, high) = r.register.range;
        // Divided, as a read divides: 3 digits at one place is 0.3, not 0.30000000000000004.
        let finest = 10f64.powi(i32::from(most));
        let (low, high) = (low.min(low / finest), high.max(high / finest));
        let slack = 1e-6 / finest;
        if !number.is_finite() || number < low - slack || number > high + slack {
            return Err(Error::InvalidArgument(format!(
                "{} must be {} to {}{} (at its decimal places), got {}",
                r.name(),
                fmt_num(low),
                fmt_num(high),
                unit_suffix(&r.register.unit),
                shown(value)
            )));
        }
        Ok(())
    }

    /// Most registers (or bits) one read of `table` asks for: `max_read`, within Modbus's.
    pub fn read_limit(&self, table: Table) -> u16 {
        let protocol = if table.holds_bits() {
            MAX_READ_BITS
        } else {
            MAX_READ_COUNT
        };
        self.limits.max_read.map_or(protocol, |m| m.min(protocol))
    }

    /// Most registers (or bits) one write to `table` carries: `max_write`, within Modbus's.
    pub fn write_limit(&self, table: Table) -> u16 {
        let protocol = if table.holds_bits() {
            MAX_WRITE_BITS
        } else {
            MAX_WRITE_COUNT
        };
        self.limits.max_write.map_or(protocol, |m| m.min(protocol))
    }

    /// The least time between two writes: `min_write_interval` (none where not given).
    pub fn write_interval(&self) -> Duration {
        let interval = self.limits.min_write_interval.unwrap_or(0.0);
        Duration::try_from_secs_f64(interval).unwrap_or_default()
    }

    /// What a write's reply must carry: `[limits] write_echo` (the Modbus echo if not
    /// given).
    pub fn echo(&self) -> Echo {
        self.limits.write_echo.unwrap_or_default()
    }

    /// Whether a write-only register of `table` has a word at an address in `addresses`.
    fn write_only_in(&self, table: Table, addresses: std::ops::Range<u32>) -> bool {
        self.registers.iter().any(|r| {
            let first = u32::from(r.register.address);
            r.table == table
                && r.register.access == Access::Write
                && first < addresses.end
                && first + r.value.width() > addresses.start
        })
    }

    /// The requests that read the registers `wanted` (indices; repeats read once): each
    /// table apart, in address order; with `block_reads` (the default), neighbouring and
    /// overlapping registers share a request up to [`read_limit`](Self::read_limit),
    /// otherwise only registers at the same address do (bits of one register); with
    /// `read_gaps`, registers with unlisted addresses between them share one too (never
    /// across a write-only register, which a read may not touch).
    pub fn plan(&self, wanted: &[usize]) -> Vec<Block> {
        let mut order: Vec<usize> = wanted
            .iter()
            .copied()
            .filter(|i| *i < self.registers.len())
            .collect();
        order.sort_by_key(|i| {
            let r = &self.registers[*i];
            (r.table as u8, r.register.address, *i)
        });
        order.dedup();
        let merge = self.limits.block_reads.unwrap_or(true);
        let gaps = merge && self.limits.read_gaps.unwrap_or(false);
        let mut blocks: Vec<Block> = Vec::new();
        for i in order {
            let r = &self.registers[i];
            let start = u32::from(r.register.address);
            let end = start + r.value.width();
            if let Some(last) = blocks.last_mut() {
                // A gap read may not cover a write-only register.
                let across = gaps && !self.write_only_in(r.table, last.end()..start);
                let joins = last.table == r.table
                    && (start < last.end() || (merge && start == last.end()) || across)
                    && end.max(last.end()) - u32::from(last.start)
                        <= u32::from(self.read_limit(r.table));
                if joins {
                    last.count = (end.max(last.end()) - u32::from(last.start)) as u16;
                    last.members.push(i);
                    continue;
                }
            }
            blocks.push(Block {
                table: r.table,
                start: r.register.address,
                count: r.value.width() as u16,
                members: vec![i],
            });
        }
        blocks
    }
}

/// What a write of one profile register sends.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Encoded {
    /// Registers from the register's address (0x06 for one, 0x10 for more).
    Words(Vec<u16>),
    /// One coil (0x05).
    Coil(bool),
    /// Bits of a holding register (a bool's bit, a field's bits): read the word, put
    /// `value` in place of its bits `mask`, write it back.
    Bits {
        /// The bits written.
        mask: u16,
        /// Their new value, in place (bits outside `mask` are 0).
        value: u16,
    },
}

impl ProfileValue {
    /// The value as a number: an int or a float as itself, a bool as 1 or 0.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for text.
    pub fn number(&self) -> Result<f64> {
        match self {
            ProfileValue::Int(n) => Ok(*n as f64),
            ProfileValue::Float(f) => Ok(*f),
            ProfileValue::Bool(b) => Ok(f64::from(u8::from(*b))),
            ProfileValue::Text(t) => Err(Error::InvalidArgument(format!(
                "{t:?} is text, not a number"
            ))),
        }
    }
}

impl ProfileRegister {
    fn name(&self) -> &str {
        &self.register.name
    }

    /// Whether it is an unscaled integer (a count, a code, a whole word or a field of
    /// bits): what may give another register its decimal places.
    pub fn is_count(&self) -> bool {
        matches!(self.value, ValueType::Number(k) if !k.is_float())
            && self.register.scale == 1.0
            && self.offset == 0.0
    }

    /// The most decimal places it may give (its range's top, or its enum's largest
    /// number), if every value it may hold, on every model, is a count of places
    /// (0..[`MAX_DECIMALS`]); None otherwise.
    pub fn most_places(&self) -> Option<u8> {
        let top = f64::from(MAX_DECIMALS);
        let fits = |(low, high): (f64, f64)| low >= 0.0 && high <= top;
        if !self.members.is_empty() {
            let all = self
                .members
                .iter()
                .all(|(n, _)| (0..=i128::from(MAX_DECIMALS)).contains(n));
            return all
                .then(|| self.members.iter().map(|(n, _)| *n as u8).max())
                .flatten();
        }
        let ranges =
            std::iter::once(self.register.range).chain(self.ranges.iter().map(|(_, r)| *r));
        let ranges: Vec<(f64, f64)> = ranges.collect();
        ranges
            .iter()
            .all(|r| fits(*r))
            .then(|| ranges.iter().map(|r| r.1 as u8).max())
            .flatten()
    }

    /// Whether every value it may hold is a count of decimal places (see
    /// [`most_places`](Self::most_places)).
    pub fn places_only(&self) -> bool {
        self.most_places().is_some()
    }

    /// The register as it reads with `places` decimal places (its `decimals` register's
    /// value): its scale 10^-places, its range the raw digits' at that scale.
    ///
    /// # Errors
    /// [`Error::State`] (`unit` said) for a value that is no count of places
    /// (0..[`MAX_DECIMALS`]): nothing is read or written on it.
    pub fn at_places(&self, places: &ProfileValue, unit: u8) -> Result<ProfileRegister> {
        let n = match places {
            ProfileValue::Int(n) if (0..=i128::from(MAX_DECIMALS)).contains(n) => *n as i32,
            other => {
                return Err(Error::State {
                    unit,
                    message: format!(
                        "{}'s decimal places ({}) read {}, not 0..{MAX_DECIMALS}: its value \
                         is not trusted",
                        self.name(),
                        self.decimals.as_deref().unwrap_or("?"),
                        shown(other)
                    ),
                })
            }
        };
        let scale = 10f64.powi(-n);
        let mut view = self.clone();
        view.register.scale = scale;
        let (low, high) = self.register.range;
        view.register.range = (low * scale, high * scale);
        view.decimals = None;
        Ok(view)
    }

    /// The engineering value of `raw` (the register's decode, unscaled) at `places`: a
    /// float whatever the places, so that a value's type does not change with them.
    ///
    /// # Errors
    /// As [`at_places`](Self::at_places).
    pub fn read_at_places(
        &self,
        raw: &ProfileValue,
        places: &ProfileValue,
        unit: u8,
    ) -> Result<ProfileValue> {
        let view = self.at_places(places, unit)?;
        Ok(match raw {
            ProfileValue::Int(n) => match view.engineering(Number::Int(*n)) {
                ProfileValue::Int(v) => ProfileValue::Float(v as f64),
                other => other,
            },
            other => other.clone(),
        })
    }

    /// The bits of its register it is, `(first, last)`: a bool's `bit`, a field's `bits`;
    /// None for whole words.
    pub fn part_of_word(&self) -> Option<(u8, u8)> {
        match self.value {
            ValueType::Bool { bit: Some(bit) } => Some((bit, bit)),
            _ => self.bits,
        }
    }

    /// The engineering value of the register's words (for a bool on a table of bits, the
    /// one word 0 or 1).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] when `words` is not the register's width.
    pub fn decode(&self, words: &[u16]) -> Result<ProfileValue> {
        if words.len() != self.value.width() as usize {
            return Err(Error::InvalidArgument(format!(
                "{} takes {} registers, got {}",
                self.name(),
                self.value.width(),
                words.len()
            )));
        }
        if let Some((first, last)) = self.part_of_word() {
            let word = words[0].checked_shr(u32::from(first)).unwrap_or(0);
            let part = word & field_top(first, last);
            return Ok(match self.value {
                ValueType::Bool { .. } => ProfileValue::Bool(part != 0),
                _ => self.engineering(Number::Int(i128::from(part))),
            });
        }
        Ok(match self.value {
            ValueType::Bool { .. } => ProfileValue::Bool(words[0] != 0),
            ValueType::Text { .. } => {
                let bytes = self.layout.from_registers(words);
                let kept = bytes.len() - bytes.iter().rev().take_while(|b| **b == 0).count();
                ProfileValue::Text(bytes[..kept].iter().map(|b| char::from(*b)).collect())
            }
            ValueType::Number(kind) => {
                let number = kind
                    .decode(words, self.layout)?
                    .first()
                    .copied()
                    .unwrap_or(Number::Int(0));
                self.engineering(number)
            }
        })
    }

    /// The engineering value of a raw number: itself when unscaled, else raw x scale +
    /// offset as a float.
    fn engineering(&self, raw: Number) -> ProfileValue {
        let (scale, offset) = (self.register.scale, self.offset);
        if scale == 1.0 && offset == 0.0 {
            return match raw {
                Number::Int(v) => ProfileValue::Int(v),
                Number::Float(v) => ProfileValue::Float(v),
            };
        }
        let raw = match raw {
            Number::Int(v) => v as f64,
            Number::Float(v) => v,
        };
        // Divide by 100 rather than multiply by 0.01: 123456 hundredths read 1234.56.
        let per_unit = (1.0 / scale).round();
        let value = if scale.abs() < 1.0 && (per_unit * scale - 1.0).abs() < 1e-12 {
            raw / per_unit
        } else {
            raw * scale
        };
        ProfileValue::Float(value + offset)
    }

    /// What writing `value` sends, checked first: access, type, enum member, range, the
    /// scale's steps and what the type holds.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a read-only register or a value it cannot take.
    pub fn encode(&self, value: &ProfileValue) -> Result<Encoded> {
        let whole = self.encode_whole(value)?;
        match (self.part_of_word(), whole) {
            (Some((first, last)), Encoded::Words(words)) if words.len() == 1 => {
                let shift = |w: u16| w.checked_shl(u32::from(first)).unwrap_or(0);
                let mask = shift(field_top(first, last));
                Ok(Encoded::Bits {
                    mask,
                    value: shift(words[0]) & mask,
                })
            }
            (_, whole) => Ok(whole),
        }
    }

    /// What writing `value` sends to the whole of the register's words (see
    /// [`encode`](Self::encode)).
    fn encode_whole(&self, value: &ProfileValue) -> Result<Encoded> {
        let name = self.name();
        if self.register.access == Access::Read {
            return Err(Error::InvalidArgument(format!("{name} is read-only")));
        }
        let wrong = |what: &str| {
            Error::InvalidArgument(format!("{name} takes {what}, got {}", shown(value)))
        };
        match (self.value, value) {
            (ValueType::Bool { .. }, ProfileValue::Bool(on)) => {
                Ok(match (self.table, self.value) {
                    (Table::Coils, _) => Encoded::Coil(*on),
                    _ => Encoded::Words(vec![u16::from(*on)]),
                })
            }
            (ValueType::Bool { .. }, _) => Err(wrong("True or False")),
            (ValueType::Text { length }, ProfileValue::Text(text)) => {
                let mut bytes = Vec::with_capacity(2 * usize::from(length));
                for c in text.chars() {
                    let byte = u8::try_from(u32::from(c)).map_err(|_| {
                        Error::InvalidArgument(format!(
                            "{name} holds Latin-1 text; {c:?} is not Latin-1"
                        ))
                    })?;
                    bytes.push(byte);
                }
                if bytes.len() > 2 * usize::from(length) {
                    return Err(Error::InvalidArgument(format!(
                        "{name} holds at most {} characters, got {}",
                        2 * length,
                        bytes.len()
                    )));
                }
                bytes.resize(2 * usize::from(length), 0);
                Ok(Encoded::Words(self.layout.to_registers(&bytes)))
            }
            (ValueType::Text { .. }, _) => Err(wrong("a string")),
            (ValueType::Number(kind), _) if !self.members.is_empty() => {
                let number = match value {
                    ProfileValue::Int(n) => self.members.iter().find(|(m, _)| m == n),
                    ProfileValue::Text(t) => self.members.iter().find(|(_, m)| m == t),
                    _ => None,
                };
                let Some((number, _)) = number else {
                    let names: Vec<&str> = self.members.iter().map(|(_, m)| m.as_str()).collect();
                    return Err(Error::InvalidArgument(format!(
                        "{name} is one of {}, got {}",
                        names.join(", "),
                        shown(value)
                    )));
                };
                Ok(Encoded::Words(
                    kind.encode(Number::Int(*number), self.layout)?,
                ))
            }
            (ValueType::Number(kind), ProfileValue::Int(_) | ProfileValue::Float(_)) => {
                let v = match value {
                    ProfileValue::Int(n) => *n as f64,
                    ProfileValue::Float(f) => *f,
                    _ => 0.0,
                };
                let (lo, hi) = self.register.range;
                let (scale, offset) = (self.register.scale, self.offset);
                let slack = 1e-6 * scale.abs();
                if !v.is_finite() || v < lo - slack || v > hi + slack {
                    return Err(Error::InvalidArgument(format!(
                        "{name} must be {} to {}{}, got {}",
                        fmt_num(lo),
                        fmt_num(hi),
                        unit_suffix(&self.register.unit),
                        shown(value)
                    )));
                }
                let number = match (value, scale == 1.0 && offset == 0.0) {
                    // Unscaled integers go as they are: 2^63 - 1 is not a float.
                    (ProfileValue::Int(n), true) => Number::Int(*n),
                    _ if kind.is_float() => Number::Float((v - offset) / scale),
                    _ => {
                        let steps = (v - offset) / scale;
                        let whole = steps.round();
                        if (steps - whole).abs() > 1e-6 * whole.abs().max(1.0) {
                            return Err(Error::InvalidArgument(format!(
                                "{name} goes in steps of {}{}, got {}",
                                fmt_num(scale),
                                unit_suffix(&self.register.unit),
                                shown(value)
                            )));
                        }
                        Number::Int(whole as i128)
                    }
                };
                Ok(Encoded::Words(kind.encode(number, self.layout)?))
            }
            (ValueType::Number(_), _) => Err(wrong("a number")),
        }
    }
}

/// A value as an error message shows it.
fn shown(value: &ProfileValue) -> String {
    match value {
        ProfileValue::Int(n) => n.to_string(),
        ProfileValue::Float(f) => fmt_num(*f),
        ProfileValue::Bool(b) => if *b { "True" } else { "False" }.to_string(),
        ProfileValue::Text(t) => format!("{t:?}"),
    }
}

/// The register of `profile` at `index`.
fn register(profile: &Profile, index: usize) -> Result<&ProfileRegister> {
    profile
        .registers
        .get(index)
        .ok_or_else(|| Error::InvalidArgument(format!("no register {index}")))
}

/// The words of one block of a plan, read from `station` (bits as words of 0 or 1).
///
/// # Errors
/// Any [`Error`] of the request.
pub fn read_block(station: &Station, block: &Block) -> Result<Vec<u16>> {
    if block.table.holds_bits() {
        let bits = station.read_bits(block.table, block.start, block.count)?;
        return Ok(bits.into_iter().map(u16::from).collect());
    }
    station.read_table(block.table, block.start, block.count)
}

/// The engineering values of the registers `indices` of `profile`, in that order, read from
/// `station` as [`Profile::plan`] groups them (the one block-read planner of every device
/// with a table), each block by `read` ([`read_block`], or a family's own way of reading
/// one).
///
/// # Errors
/// [`Error::InvalidArgument`] for an index past the profile; any [`Error`] of a request
/// (the values read before it are lost).
pub fn read_planned(
    station: &Station,
    profile: &Profile,
    indices: &[usize],
    mut read: impl FnMut(&Block) -> Result<Vec<u16>>,
) -> Result<Vec<ProfileValue>> {
    // Only those asked for, by index (a slot for every register of the profile made each
    // read cost the profile's length).
    let mut values: HashMap<usize, ProfileValue> = HashMap::with_capacity(indices.len());
    for block in profile.plan(indices) {
        let words = read(&block)?;
        for i in &block.members {
            let r = register(profile, *i)?;
            let from = usize::from(r.register.address - block.start);
            let to = from + r.value.width() as usize;
            let own = words.get(from..to).ok_or_else(|| station.short_reply())?;
            values.insert(*i, r.decode(own)?);
        }
    }
    indices
        .iter()
        .map(|i| {
            values
                .get(i)
                .cloned()
                .ok_or_else(|| Error::InvalidArgument(format!("no register {i}")))
        })
        .collect()
}

/// A device described by a profile, on a bus.
#[derive(Debug)]
pub struct ProfiledDevice {
    station: Station,
    profile: Arc<Profile>,
}

on_station!(ProfiledDevice);

impl ProfiledDevice {
    /// The device `profile` describes, at `unit` on `bus`, its writes at least the
    /// profile's `min_write_interval` apart.
    pub fn new(bus: Arc<Bus>, unit: u8, profile: Arc<Profile>) -> ProfiledDevice {
        let opts = TxOptions {
            write_interval: profile.write_interval(),
            echo: profile.echo(),
            ..TxOptions::default()
        };
        ProfiledDevice {
            station: Station::new(bus, unit, opts),
            profile,
        }
    }

    /// The profile.
    pub fn profile(&self) -> &Arc<Profile> {
        &self.profile
    }

    /// The register at `index`.
    fn register(&self, index: usize) -> Result<&ProfileRegister> {
        register(&self.profile, index)
    }

    /// The engineering values of the registers `indices`, in that order, read as
    /// [`Profile::plan`] groups them, with the registers giving the decimal places of any
    /// of them ([`Profile::with_places`]; then as one sequence for the unit).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a write-only register (nothing sent);
    /// [`Error::State`] for decimal places read outside 0..9; any [`Error`] of a request
    /// (the values read before it are lost).
    pub fn read(&self, indices: &[usize]) -> Result<Vec<ProfileValue>> {
        for i in indices {
            let r = self.register(*i)?;
            if r.register.access == Access::Write {
                return Err(Error::InvalidArgument(format!(
                    "{} is write-only",
                    r.register.name
                )));
            }
        }
        if indices
            .iter()
            .all(|i| self.profile.places_register(*i).is_none())
        {
            return self.read_values(indices);
        }
        let wanted = self.profile.with_places(indices);
        let read = self.station.exclusive(|| self.read_values(&wanted))?;
        let unit = self.station.unit();
        indices
            .iter()
            .zip(&read)
            .map(|(i, value)| match self.profile.places_register(*i) {
                None => Ok(value.clone()),
                Some(at) => {
                    let places = wanted
                        .iter()
                        .position(|w| *w == at)
                        .and_then(|p| read.get(p))
                        .ok_or_else(|| Error::InvalidArgument(format!("no register {at}")))?;
                    self.register(*i)?.read_at_places(value, places, unit)
                }
            })
            .collect()
    }

    /// The values of `indices` as their registers decode them (decimal places not
    /// applied), read as [`Profile::plan`] groups them; no sequence of its own.
    fn read_values(&self, indices: &[usize]) -> Result<Vec<ProfileValue>> {
        read_planned(&self.station, &self.profile, indices, |b| {
            read_block(&self.station, b)
        })
    }

    /// Writes `values` (register index, value) in order, each as [`write`](Self::write)
    /// does. Every value is checked before the first is sent; one for a register with
    /// `decimals` is checked in full once its places are read (the sequence's own write of
    /// them counting for the values after it), and only then is anything written: the
    /// whole sequence, reads and writes, is one sequence for the unit.
    ///
    /// # Errors
    /// As [`write`](Self::write); a failure while writing stops the sequence (the earlier
    /// writes stay).
    pub fn write_many(&self, values: &[(usize, ProfileValue)]) -> Result<()> {
        for (index, value) in values {
            self.profile.precheck(*index, value)?;
        }
        let mut needed: Vec<usize> = Vec::new();
        for (index, _) in values {
            if let Some(at) = self.profile.places_register(*index) {
                if !needed.contains(&at) {
                    needed.push(at);
                }
            }
        }
        if needed.is_empty() {
            return values.iter().try_for_each(|(index, value)| {
                let r = self.register(*index)?;
                let encoded = r.encode(value)?;
                self.send(r.register.address, encoded)
            });
        }
        // A register sharing a word with a places register (its whole word, another field
        // of it) would change the places behind the sequence's back: written apart.
        for (index, _) in values {
            let r = self.register(*index)?;
            for at in &needed {
                let p = self.register(*at)?;
                let span = |x: &ProfileRegister| {
                    let start = u32::from(x.register.address);
                    start..start + x.value.width()
                };
                let (a, b) = (span(r), span(p));
                if *index != *at && r.table == p.table && a.start < b.end && b.start < a.end {
                    return Err(Error::InvalidArgument(format!(
                        "{} shares its register with {}, which gives the decimal places of a \
                         value written with it: write it in a call of its own",
                        r.name(),
                        p.name()
                    )));
                }
            }
        }
        self.station.exclusive(|| {
            let read = self.read_values(&needed)?;
            let mut places: HashMap<usize, ProfileValue> =
                needed.iter().copied().zip(read).collect();
            let unit = self.station.unit();
            let mut sends = Vec::with_capacity(values.len());
            for (index, value) in values {
                let r = self.register(*index)?;
                let encoded = match self.profile.places_register(*index) {
                    None => r.encode(value)?,
                    Some(at) => {
                        let now = places.get(&at).ok_or_else(|| self.station.short_reply())?;
                        r.at_places(now, unit)?.encode(value)?
                    }
                };
                // A write of a places register gives the values after it their places.
                if places.contains_key(index) {
                    let written = match &encoded {
                        Encoded::Words(words) => r.decode(words)?,
                        Encoded::Bits { value, .. } => r.decode(&[*value])?,
                        Encoded::Coil(_) => {
                            return Err(Error::InvalidArgument(format!(
                                "{} is a coil, not a count of places",
                                r.name()
                            )))
                        }
                    };
                    places.insert(*index, written);
                }
                sends.push((r.register.address, encoded));
            }
            sends
                .into_iter()
                .try_for_each(|(address, encoded)| self.send(address, encoded))
        })
    }

    /// Writes `value` to the register at `index`, every check made before anything is
    /// sent; a bit or a field of bits of a holding register is read, changed and written
    /// back as one sequence. A register with `decimals` is written as one sequence too:
    /// its places read, then the value checked and encoded at them (refused, nothing
    /// written, if they do not take it), then written.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a read-only register or a value it cannot take
    /// (nothing sent, but the read of its decimal places for a register with `decimals`);
    /// [`Error::State`] for decimal places read outside 0..9; any [`Error`] of a request.
    pub fn write(&self, index: usize, value: &ProfileValue) -> Result<()> {
        self.write_many(&[(index, value.clone())])
    }

    /// Sends `encoded` to `address`; a bit or field of a word is read, changed and written
    /// back as one sequence (within the caller's, if it holds one: [`Bus::exclusive`]
    /// nests).
    fn send(&self, address: u16, encoded: Encoded) -> Result<()> {
        match encoded {
            Encoded::Coil(on) => self.station.write_coil(address, on),
            Encoded::Words(words) => self.write_words(address, &words),
            Encoded::Bits { mask, value } => self.station.exclusive(|| {
                let word = *self
                    .station
                    .read(address, 1)?
                    .first()
                    .ok_or_else(|| self.station.short_reply())?;
                self.write_words(address, &[word & !mask | value])
            }),
        }
    }

    /// Writes `words` from `address`: one word with 0x06 unless the profile says
    /// `write_multiple`, more (or every write then) with 0x10.
    fn write_words(&self, address: u16, words: &[u16]) -> Result<()> {
        match words {
            [word] if self.profile.limits.write_multiple != Some(true) => {
                self.station.write(address, *word)
            }
            _ => self.station.write_many(address, words),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn profile(extra: &str, registers: &str) -> Profile {
        let text = format!("[device]\nname = \"T\"\n{extra}\n{registers}");
        Profile::parse("t.toml", &text).unwrap()
    }

    const SENSOR: &str = r#"
[[register]]
name = "a"
address = 0
table = "input"
[[register]]
name = "b"
address = 1
table = "input"
type = "f32"
[[register]]
name = "c"
address = 10
table = "input"
[[register]]
name = "d"
address = 3
[[register]]
name = "e"
address = 4
"#;

    fn spans(p: &Profile, wanted: &[usize]) -> Vec<(Table, u16, u16, Vec<usize>)> {
        p.plan(wanted)
            .into_iter()
            .map(|b| (b.table, b.start, b.count, b.members))
            .collect()
    }

    #[test]
    fn neighbours_share_a_request_and_tables_stay_apart() {
        let p = profile("", SENSOR);
        assert_eq!(
            spans(&p, &[4, 0, 2, 1, 3]),
            vec![
                (Table::Holding, 3, 2, vec![3, 4]),
                (Table::Input, 0, 3, vec![0, 1]),
                (Table::Input, 10, 1, vec![2]),
            ]
        );
    }

    #[test]
    fn max_read_and_block_reads_split_the_plan() {
        let p = profile("[limits]\nmax_read = 2\n", SENSOR);
        assert_eq!(
            spans(&p, &[0, 1]),
            vec![(Table::Input, 0, 1, vec![0]), (Table::Input, 1, 2, vec![1])]
        );
        let p = profile("[limits]\nblock_reads = false\n", SENSOR);
        assert_eq!(spans(&p, &[3, 4]).len(), 2);
    }

    #[test]
    fn read_gaps_reads_across_unlisted_addresses_within_max_read() {
        // Input registers 0 (f32: 0..=1) and 10: apart without read_gaps, one read with it.
        let p = profile("", SENSOR);
        assert_eq!(spans(&p, &[0, 2]).len(), 2);
        let p = profile("[limits]\nread_gaps = true\n", SENSOR);
        assert_eq!(spans(&p, &[0, 2]), vec![(Table::Input, 0, 11, vec![0, 2])]);
        let p = profile("[limits]\nread_gaps = true\nmax_read = 10\n", SENSOR);
        assert_eq!(spans(&p, &[0, 2]).len(), 2);
        // Never across a write-only register: 5 lies between 0 and 10.
        let only = "[[register]]\nname = \"w\"\naddress = 5\ntable = \"holding\"\naccess = \"w\"\n";
        let gapped =
            "[[register]]\nname = \"a\"\naddress = 0\n[[register]]\nname = \"b\"\naddress = 10\n";
        let p = profile("[limits]\nread_gaps = true\n", &format!("{gapped}{only}"));
        assert_eq!(spans(&p, &[0, 1]).len(), 2);
        let p = profile("[limits]\nread_gaps = true\n", gapped);
        assert_eq!(
            spans(&p, &[0, 1]),
            vec![(Table::Holding, 0, 11, vec![0, 1])]
        );
    }

    #[test]
    fn bits_of_one_register_are_read_once_even_without_block_reads() {
        let p = profile(
            "[limits]\nblock_reads = false\n",
            "[[register]]\nname = \"x\"\naddress = 7\ntype = \"bool\"\nbit = 0\n\
             [[register]]\nname = \"y\"\naddress = 7\ntype = \"bool\"\nbit = 3\n",
        );
        assert_eq!(
            spans(&p, &[1, 0, 1]),
            vec![(Table::Holding, 7, 1, vec![0, 1])]
        );
    }

    #[test]
    fn values_decode_and_encode_in_engineering_units() {
        let p = profile(
            "",
            "[[register]]\nname = \"t\"\naddress = 0\ntype = \"i16\"\nscale = 0.1\n\
             min = -40.0\nmax = 125.0\nunit = \"degC\"\n\
             [[register]]\nname = \"k\"\naddress = 1\ntype = \"i32\"\norder = \"DCBA\"\n\
             scale = 0.01\noffset = -273.15\n\
             [[register]]\nname = \"m\"\naddress = 3\nenum = { 0 = \"off\", 2 = \"cool\" }\n\
             [[register]]\nname = \"s\"\naddress = 4\ntype = \"string\"\nlength = 2\n",
        );
        let t = &p.registers[0];
        assert_eq!(t.decode(&[0xFF9C]).unwrap(), ProfileValue::Float(-10.0));
        assert_eq!(
            t.encode(&ProfileValue::Float(21.5)).unwrap(),
            Encoded::Words(vec![215])
        );
        let err = t.encode(&ProfileValue::Float(130.0)).unwrap_err();
        assert!(
            err.to_string()
                .contains("t must be -40 to 125 degC, got 130"),
            "{err}"
        );
        let err = t.encode(&ProfileValue::Float(21.55)).unwrap_err();
        assert!(err.to_string().contains("steps of 0.1"), "{err}");
        // 295.65 K in centikelvin, DCBA: 29565 = 0x0000737D.
        let k = &p.registers[1];
        let words = vec![0x7D73, 0x0000];
        assert_eq!(
            k.encode(&ProfileValue::Float(22.5)).unwrap(),
            Encoded::Words(words.clone())
        );
        match k.decode(&words).unwrap() {
            ProfileValue::Float(v) => assert!((v - 22.5).abs() < 1e-9, "{v}"),
            other => panic!("{other:?}"),
        }
        let m = &p.registers[2];
        assert_eq!(
            m.encode(&ProfileValue::Text("cool".into())).unwrap(),
            Encoded::Words(vec![2])
        );
        assert!(m.encode(&ProfileValue::Int(1)).is_err());
        assert_eq!(m.decode(&[2]).unwrap(), ProfileValue::Int(2));
        let s = &p.registers[3];
        assert_eq!(
            s.encode(&ProfileValue::Text("AB".into())).unwrap(),
            Encoded::Words(vec![0x4142, 0])
        );
        assert_eq!(
            s.decode(&[0x4142, 0x4300]).unwrap(),
            ProfileValue::Text("ABC".into())
        );
        assert!(s.encode(&ProfileValue::Text("ABCDE".into())).is_err());
        assert!(s.encode(&ProfileValue::Text("\u{263A}".into())).is_err());
    }

    #[test]
    fn a_field_of_bits_decodes_and_encodes_in_place() {
        let p = profile(
            "",
            "[[register]]\nname = \"source\"\naddress = 0\nbits = [5, 6]\n\
             enum = { 0 = \"keypad\", 1 = \"terminals\", 2 = \"communication\" }\n\
             [[register]]\nname = \"level\"\naddress = 0\nbits = [8, 11]\nscale = 0.5\n\
             [[register]]\nname = \"ready\"\naddress = 0\ntype = \"bool\"\nbit = 0\n",
        );
        let (source, level, ready) = (&p.registers[0], &p.registers[1], &p.registers[2]);
        // 0x4141: bits 5..6 = 2, bits 8..11 = 1, bit 0 set, bit 14 (no field) set too.
        let word = 0x4000 | 0x0100 | 0x0040 | 0x0001;
        assert_eq!(source.decode(&[word]).unwrap(), ProfileValue::Int(2));
        assert_eq!(level.decode(&[word]).unwrap(), ProfileValue::Float(0.5));
        assert_eq!(ready.decode(&[word]).unwrap(), ProfileValue::Bool(true));
        assert_eq!(
            source
                .encode(&ProfileValue::Text("terminals".into()))
                .unwrap(),
            Encoded::Bits {
                mask: 0x0060,
                value: 0x0020
            }
        );
        assert_eq!(
            level.encode(&ProfileValue::Float(7.5)).unwrap(),
            Encoded::Bits {
                mask: 0x0F00,
                value: 0x0F00
            }
        );
        assert_eq!(
            ready.encode(&ProfileValue::Bool(false)).unwrap(),
            Encoded::Bits {
                mask: 0x0001,
                value: 0
            }
        );
        assert!(level.encode(&ProfileValue::Float(8.0)).is_err());
        assert!(source.encode(&ProfileValue::Int(3)).is_err());
    }

    #[test]
    fn read_only_and_wrong_types_are_refused() {
        let p = profile(SENSOR, "");
        let a = &p.registers[0];
        assert!(a.encode(&ProfileValue::Int(1)).is_err());
        let d = &p.registers[3];
        assert!(d.encode(&ProfileValue::Bool(true)).is_err());
        assert!(d.encode(&ProfileValue::Text("1".into())).is_err());
        assert_eq!(
            d.encode(&ProfileValue::Int(7)).unwrap(),
            Encoded::Words(vec![7])
        );
    }
}
