//! J2-series PID process/temperature controllers (manual 003): two parameter tables at even
//! addresses, 9600 or 19200 8N1, stations 1..=255.
//!
//! The signed table (MV at 0 .. DIE at 62) holds signed 16-bit words in tenths, the unsigned
//! table (AM at 128 .. FST at 156) plain integers. The manual's rules are applied here, not
//! left to the caller: write commands at least [`WRITE_INTERVAL`] apart (paced by the Bus per
//! unit), at most [`MAX_BLOCK`] registers a request, MV written only in manual mode (AM = 0),
//! and RAPNF written 0 before a ramp parameter.
//!
//! The manual's ranges are in engineering units; a signed register in tenths only reaches
//! -3276.8..=3276.7, so its upper limits of 3600 and 9999 stop there. SV is checked against
//! the limits LSP..USP the controller holds, read just before the write. The manual gives
//! "LSP~USP" for HY1, HY2, HYS, RAP, TRL, TRH, SRT and TOP too, but for a hysteresis or a
//! ramp rate that cannot be meant literally: those are checked against the widest range,
//! -1999..=3276.7, and the controller itself refuses what it does not take.

use super::suggest::did_you_mean;
use super::{Access, Device, Register, Station};
use crate::bus::{Bus, TxOptions};
use crate::error::{Error, Result};
use std::sync::Arc;
use std::time::Duration;

/// Least time between two write commands to one controller (manual: "不小於 150 毫秒").
pub const WRITE_INTERVAL: Duration = Duration::from_millis(150);
/// Most registers one read or write may carry.
pub const MAX_BLOCK: u16 = 16;

/// Lowest value a signed register in tenths holds.
const WORD_MIN: f64 = -3276.8;
/// Highest value a signed register in tenths holds.
const WORD_MAX: f64 = 3276.7;

/// One parameter of either table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Param {
    /// The manual's name ("SV").
    pub name: &'static str,
    /// Register address.
    pub address: u16,
    /// Signed table (tenths, two's complement) or unsigned table (whole numbers).
    pub signed: bool,
    /// Whether it can be written.
    pub writable: bool,
    /// The manual's range in engineering units; ignored when `within_limits`.
    pub range: (f64, f64),
    /// Held to the limits LSP..USP the controller holds (SV).
    pub within_limits: bool,
    /// The unit of its value ("" for none): percent for the output, °C for the process
    /// value and the parameters in its scale (a linear input, INP = LN, reads in its own).
    pub unit: &'static str,
}

impl Param {
    /// The parameter with `unit`.
    const fn with_unit(self, unit: &'static str) -> Param {
        Param { unit, ..self }
    }
}

const LIMITS_RANGE: (f64, f64) = (-1999.0, 9999.0);
/// The unit of the output and its limits.
const PERCENT: &str = "%";
/// The unit of the process value, and of the parameters in its scale.
const PROCESS: &str = "°C";

const fn s(name: &'static str, address: u16, lo: f64, hi: f64) -> Param {
    Param {
        name,
        address,
        signed: true,
        writable: true,
        range: (lo, hi),
        within_limits: false,
        unit: "",
    }
}

/// A signed parameter the manual gives "LSP~USP" for; `held` to the limits the controller
/// holds, or else to their widest range.
const fn lim(name: &'static str, address: u16, held: bool) -> Param {
    Param {
        name,
        address,
        signed: true,
        writable: true,
        range: LIMITS_RANGE,
        within_limits: held,
        unit: "",
    }
}

const fn u(name: &'static str, address: u16, lo: f64, hi: f64) -> Param {
    Param {
        name,
        address,
        signed: false,
        writable: true,
        range: (lo, hi),
        within_limits: false,
        unit: "",
    }
}

/// Both tables, in address order; the manual's "NC" (empty) addresses are left out.
#[rustfmt::skip]
pub const PARAMETERS: [Param; 43] = [
    s("MV", 0x00, 0.0, 100.0).with_unit(PERCENT),
    Param { name: "PV", address: 0x02, signed: true, writable: false, range: (WORD_MIN, WORD_MAX), within_limits: false, unit: PROCESS },
    lim("SV", 0x06, true).with_unit(PROCESS),
    s("AL1", 0x08, -1999.0, 9999.0).with_unit(PROCESS),
    s("AL2", 0x0A, -1999.0, 9999.0).with_unit(PROCESS),
    s("P", 0x0E, 0.1, 3600.0),
    s("I", 0x10, 0.0, 3600.0),
    s("D", 0x12, 0.0, 3600.0),
    s("LSP", 0x14, -1999.0, 9999.0).with_unit(PROCESS),
    s("USP", 0x16, -1999.0, 9999.0).with_unit(PROCESS),
    lim("HY1", 0x18, false),
    lim("HY2", 0x1A, false),
    lim("HYS", 0x1E, false),
    s("OUL", 0x20, 0.0, 100.0).with_unit(PERCENT),
    s("OUH", 0x22, 0.0, 100.0).with_unit(PERCENT),
    s("GAP", 0x24, -50.0, 50.0),
    lim("RAP", 0x26, false),
    s("RTM", 0x28, 0.0, 3600.0),
    s("P1", 0x2A, 0.1, 3600.0),
    s("I1", 0x2C, 0.0, 3600.0),
    s("D1", 0x2E, 0.0, 3600.0),
    lim("TRL", 0x30, false),
    lim("TRH", 0x32, false),
    s("PVOS", 0x34, -50.0, 50.0).with_unit(PROCESS),
    lim("SRT", 0x36, false),
    s("LMO", 0x38, 0.0, 100.0),
    lim("TOP", 0x3A, false),
    s("U0", 0x3C, 0.0, 100.0),
    s("DIE", 0x3E, 0.5, 5.0),
    u("AM", 0x80, 0.0, 1.0),
    u("RAPNF", 0x82, 0.0, 1.0),
    u("AT", 0x84, 0.0, 1.0),
    u("CYT", 0x86, 0.0, 250.0),
    u("AD1", 0x88, 0.0, 9.0),
    u("AD2", 0x8A, 0.0, 9.0),
    u("CYT1", 0x8E, 0.0, 250.0),
    u("MAN", 0x90, 0.0, 1.0),
    u("SFT", 0x92, 0.0, 99.0),
    u("DP", 0x94, 0.0, 3.0),
    u("TH", 0x96, 0.0, 2.0),
    u("INP", 0x98, 0.0, 9.0),
    u("OUD", 0x9A, 0.0, 1.0),
    u("FST", 0x9C, 20.0, 120.0),
];

/// The address spans of the two tables: `(first, last)`.
pub const TABLES: [(u16, u16); 2] = [(0x00, 0x3E), (0x80, 0x9C)];

/// AM: 0 manual, 1 automatic.
pub const AM: &str = "AM";
/// RAPNF: reads 1 while a ramp runs; written 1 starts it, 0 ends it.
pub const RAPNF: &str = "RAPNF";
/// One status snapshot, read in two requests, in the order of its fields: process value,
/// setpoint, output, mode, autotune, ramp, alarm values.
pub const STATUS: [&str; 8] = ["PV", "SV", "MV", "AM", "AT", "RAPNF", "AL1", "AL2"];
/// The main measurements, read in one request: process value, setpoint and output.
pub const SAMPLE: [&str; 3] = ["PV", "SV", "MV"];
/// The first PID set: proportional band, integral time, derivative time.
pub const PID: [&str; 3] = ["P", "I", "D"];
/// The second PID set.
pub const PID2: [&str; 3] = ["P1", "I1", "D1"];
/// The setpoint limits, low and high.
pub const LIMITS: [&str; 2] = ["LSP", "USP"];

/// The parameters the manual calls ramp parameters (RAPNF is written 0 before them).
pub const RAMP_PARAMETERS: [&str; 2] = ["RAP", "RTM"];

impl Param {
    /// The Register this parameter is on the wire: tenths and signed, or whole and unsigned,
    /// with its range cut to what the register can hold.
    pub fn register(&self) -> Register {
        let (scale, (lo, hi)) = if self.signed {
            (
                0.1,
                (self.range.0.max(WORD_MIN), self.range.1.min(WORD_MAX)),
            )
        } else {
            (1.0, self.range)
        };
        Register {
            name: self.name,
            address: self.address,
            scale,
            signed: self.signed,
            unit: self.unit,
            access: if self.writable {
                Access::ReadWrite
            } else {
                Access::Read
            },
            range: (lo, hi),
        }
    }

    /// The engineering value of a raw word (tenths decoded by division, so 0.3 reads 0.3).
    pub fn decode(&self, raw: u16) -> f64 {
        self.register().decode(raw)
    }

    /// The raw word for `value`, checked against the manual's range (for an "LSP~USP"
    /// parameter, the widest limits) and what the register can hold.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a read-only parameter or a value it cannot take.
    pub fn encode(&self, value: f64) -> Result<u16> {
        let register = self.register();
        register.encode(value).map_err(|e| {
            let (lo, hi) = register.range;
            let cut_off =
                (self.range.0..=self.range.1).contains(&value) && !(lo..=hi).contains(&value);
            match e {
                Error::InvalidArgument(m) if cut_off => Error::InvalidArgument(format!(
                    "{m} (the manual gives {} to {}, but a signed 16-bit register in tenths \
                         holds -3276.8 to 3276.7)",
                    self.range.0, self.range.1
                )),
                other => other,
            }
        })
    }
}

/// The parameter called `name` (any case: "sv" is SV).
///
/// # Errors
/// [`Error::InvalidArgument`] if there is none.
pub fn by_name(name: &str) -> Result<&'static Param> {
    PARAMETERS
        .iter()
        .find(|p| p.name.eq_ignore_ascii_case(name))
        .ok_or_else(|| {
            let names = PARAMETERS.iter().map(|p| p.name);
            let mut hint = did_you_mean(name, names.clone());
            if hint.is_empty() {
                hint = format!("; it has {}", names.collect::<Vec<_>>().join(", "));
            }
            Error::InvalidArgument(format!("a J2 controller has no parameter {name:?}{hint}"))
        })
}

/// A J2 controller on a bus.
#[derive(Debug)]
pub struct J2 {
    station: Station,
}

impl Device for J2 {
    fn station(&self) -> &Station {
        &self.station
    }

    fn station_mut(&mut self) -> &mut Station {
        &mut self.station
    }
}

impl J2 {
    /// The controller at `unit` on `bus`.
    pub fn new(bus: Arc<Bus>, unit: u8) -> J2 {
        let opts = TxOptions {
            write_interval: WRITE_INTERVAL,
            ..TxOptions::default()
        };
        J2 {
            station: Station::new(bus, unit, opts),
        }
    }

    /// Reads the parameter called `name`, in engineering units.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn read(&self, name: &str) -> Result<f64> {
        let p = by_name(name)?;
        let words = self.station.read(p.address, 1)?;
        Ok(p.decode(words[0]))
    }

    /// Reads the parameters called `names`, in as few requests as the 16-register limit
    /// allows (see [`blocks`]).
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn read_many(&self, names: &[&str]) -> Result<Vec<f64>> {
        let params = names
            .iter()
            .map(|n| by_name(n))
            .collect::<Result<Vec<_>>>()?;
        let words = self.read_addresses(params.iter().map(|p| p.address))?;
        params
            .iter()
            .map(|p| match words.get(&p.address) {
                Some(&w) => Ok(p.decode(w)),
                None => Err(self.station.short_reply()),
            })
            .collect()
    }

    /// Every parameter of both tables, `(name, value)` in address order, in six requests
    /// of at most 16 registers.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn parameters(&self) -> Result<Vec<(&'static str, f64)>> {
        let names: Vec<&str> = PARAMETERS.iter().map(|p| p.name).collect();
        let values = self.read_many(&names)?;
        Ok(names.into_iter().zip(values).collect())
    }

    /// Writes `value` to the parameter called `name`, applying the manual's rules: the range
    /// is checked first (an "LSP~USP" range against the limits read from the controller);
    /// MV needs manual mode; RAPNF is written 0 before a ramp parameter; LSP may not go
    /// above USP nor USP below LSP. Writes are paced 150 ms apart by the Bus.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a bad name or value (nothing sent);
    /// [`Error::State`] for MV in automatic mode (nothing written); any other [`Error`].
    pub fn write(&self, name: &str, value: f64) -> Result<()> {
        self.write_as(name, value, false)
    }

    /// As [`write`](Self::write), with function 0x10 (one register) instead of 0x06 when
    /// `multiple`: the manual shows both for SV.
    ///
    /// # Errors
    /// As [`write`](Self::write).
    pub fn write_as(&self, name: &str, value: f64, multiple: bool) -> Result<()> {
        let p = by_name(name)?;
        let raw = p.encode(value)?;
        let rapnf = by_name(RAPNF)?.address;
        self.sequence(|| {
            if p.name == "MV" && self.automatic()? {
                return Err(self.mv_in_auto());
            }
            self.check_against_limits(p, value)?;
            if RAMP_PARAMETERS.contains(&p.name) {
                self.write_word(rapnf, 0)?;
            }
            if multiple {
                self.station.write_many(p.address, &[raw])
            } else {
                self.write_word(p.address, raw)
            }
        })
    }

    /// Writes several parameters in order, each as [`write`](Self::write) does. Every value
    /// is checked against its fixed range before the first is sent; the checks that need
    /// the controller (SV within the limits, MV in manual mode) are made write by write.
    ///
    /// # Errors
    /// As [`write`](Self::write); a failure stops the sequence (the earlier writes stay).
    pub fn write_many(&self, values: &[(&str, f64)]) -> Result<()> {
        for (name, value) in values {
            by_name(name)?.encode(*value)?;
        }
        for (name, value) in values {
            self.write(name, *value)?;
        }
        Ok(())
    }

    /// Sets the output MV to `percent`. In automatic mode this is refused with
    /// [`Error::State`], unless `switch_to_manual`: then AM is written 0 first.
    ///
    /// # Errors
    /// As [`write`](Self::write).
    pub fn set_output(&self, percent: f64, switch_to_manual: bool) -> Result<()> {
        let mv = by_name("MV")?;
        let raw = mv.encode(percent)?;
        let am = by_name(AM)?.address;
        self.sequence(|| {
            if self.automatic()? {
                if !switch_to_manual {
                    return Err(self.mv_in_auto());
                }
                self.write_word(am, 0)?;
            }
            self.write_word(mv.address, raw)
        })
    }

    /// Sets LSP and USP together, in the order that never leaves LSP above USP.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if `low > high` or either is out of range; any [`Error`].
    pub fn set_limits(&self, low: f64, high: f64) -> Result<()> {
        let (lsp, usp) = (by_name("LSP")?, by_name("USP")?);
        let (raw_low, raw_high) = (lsp.encode(low)?, usp.encode(high)?);
        if low > high {
            return Err(Error::InvalidArgument(format!(
                "limits must be low <= high, got ({low}, {high})"
            )));
        }
        self.sequence(|| {
            let (_, current_high) = self.limits()?;
            if low > current_high {
                self.write_word(usp.address, raw_high)?;
                self.write_word(lsp.address, raw_low)
            } else {
                self.write_word(lsp.address, raw_low)?;
                self.write_word(usp.address, raw_high)
            }
        })
    }

    /// LSP and USP, in one request.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn limits(&self) -> Result<(f64, f64)> {
        match self.read_many(&LIMITS)?[..] {
            [low, high] => Ok((low, high)),
            _ => Err(self.station.short_reply()),
        }
    }

    /// Whether the controller is in automatic mode (AM = 1).
    fn automatic(&self) -> Result<bool> {
        Ok(self.read(AM)? != 0.0)
    }

    fn mv_in_auto(&self) -> Error {
        Error::State {
            unit: self.unit(),
            message: "MV can be written only in manual mode (AM = 0), and the controller is \
                      in automatic mode; switch with mode = manual, or set_output(percent, \
                      switch_to_manual=True)"
                .into(),
        }
    }

    /// For an "LSP~USP" parameter, LSP or USP: refuses a value the limits do not allow.
    fn check_against_limits(&self, p: &Param, value: f64) -> Result<()> {
        let bounded = p.within_limits || p.name == "LSP" || p.name == "USP";
        if !bounded {
            return Ok(());
        }
        let (low, high) = self.limits()?;
        let refused = match p.name {
            "LSP" if value > high => Some(format!("LSP must stay <= USP = {high}")),
            "USP" if value < low => Some(format!("USP must stay >= LSP = {low}")),
            "LSP" | "USP" => None,
            _ if value < low || value > high => Some(format!(
                "{} must be within the setpoint limits LSP to USP, {low} to {high}",
                p.name
            )),
            _ => None,
        };
        match refused {
            Some(m) => Err(Error::InvalidArgument(format!(
                "{m}, got {value} (set both with j2.limits = (low, high))"
            ))),
            None => Ok(()),
        }
    }

    /// The words at `addresses`, `{address: word}`, read in the [`blocks`] that cover them.
    fn read_addresses(
        &self,
        addresses: impl Iterator<Item = u16>,
    ) -> Result<std::collections::BTreeMap<u16, u16>> {
        let mut words = std::collections::BTreeMap::new();
        for (first, count) in blocks(addresses) {
            let read = self.station.read(first, count)?;
            words.extend((first..).zip(read));
        }
        Ok(words)
    }

    fn write_word(&self, address: u16, raw: u16) -> Result<()> {
        self.station.write(address, raw)
    }

    /// Runs a check-then-write (AM before MV, RAPNF before a ramp parameter, the limits
    /// before SV) as one sequence for this unit, whichever J2 object runs it.
    fn sequence<R>(&self, f: impl FnOnce() -> Result<R>) -> Result<R> {
        self.station.exclusive(f)
    }
}

/// The fewest reads of at most [`MAX_BLOCK`] registers that cover `addresses`, as
/// `(first, count)`: each block starts at the lowest address not yet covered and ends at the
/// last wanted address within reach, so no register past it is read.
pub fn blocks(addresses: impl Iterator<Item = u16>) -> Vec<(u16, u16)> {
    let wanted: std::collections::BTreeSet<u16> = addresses.collect();
    let mut out: Vec<(u16, u16)> = Vec::new();
    for a in wanted {
        match out.last_mut() {
            Some((first, count)) if a - *first < MAX_BLOCK => *count = a - *first + 1,
            _ => out.push((a, 1)),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_is_in_address_order_at_even_addresses_within_the_tables() {
        for pair in PARAMETERS.windows(2) {
            assert!(pair[0].address < pair[1].address, "{:?}", pair[1]);
        }
        for p in &PARAMETERS {
            assert_eq!(p.address % 2, 0, "{}", p.name);
            assert!(TABLES.iter().any(|(a, b)| (*a..=*b).contains(&p.address)));
            assert_eq!(p.signed, p.address < 0x80, "{}", p.name);
        }
    }

    #[test]
    fn negative_tenths_are_twos_complement() {
        let Some(al1) = by_name("AL1").ok().filter(|p| p.signed) else {
            panic!("AL1 is in the signed table");
        };
        assert_eq!(al1.encode(-50.0).ok(), Some(0xFE0C));
        assert_eq!(al1.decode(0xFE0C), -50.0);
        assert_eq!(al1.encode(100.0).ok(), Some(1000));
        assert_eq!(al1.decode(3), 0.3);
    }

    #[test]
    fn ranges_are_cut_to_what_the_register_holds() {
        let check = |name: &str, v: f64| by_name(name).and_then(|p| p.encode(v)).is_ok();
        assert!(check("AL1", 3276.7) && !check("AL1", 3276.8) && !check("AL1", 9999.0));
        assert!(check("AL1", -1999.0) && !check("AL1", -1999.1));
        assert!(check("P", 0.1) && !check("P", 0.0) && !check("P", 3600.0));
        assert!(check("DIE", 0.5) && !check("DIE", 0.4) && !check("DIE", 5.1));
        assert!(check("FST", 20.0) && !check("FST", 19.0) && !check("FST", 20.5));
        assert!(!check("PV", 1.0) && !check("MV", 100.1) && !check("MV", f64::NAN));
        let msg = by_name("AL1").and_then(|p| p.encode(5000.0)).err();
        assert!(msg.is_some_and(|e| e.to_string().contains("the manual gives -1999 to 9999")));
    }

    #[test]
    fn the_groups_name_parameters_of_the_table() {
        let groups: [&[&str]; 5] = [&STATUS, &SAMPLE, &PID, &PID2, &LIMITS];
        for name in groups.iter().flat_map(|g| g.iter()) {
            assert!(by_name(name).is_ok(), "{name}");
        }
        // Each small group is one request: within 16 registers.
        for group in [&SAMPLE[..], &PID, &PID2, &LIMITS] {
            let addresses = group
                .iter()
                .filter_map(|n| by_name(n).ok().map(|p| p.address));
            assert_eq!(blocks(addresses).len(), 1, "{group:?}");
        }
    }

    #[test]
    fn names_are_found_in_any_case() {
        assert_eq!(by_name("sv").ok().map(|p| p.address), Some(6));
        assert_eq!(by_name("Rapnf").ok().map(|p| p.address), Some(0x82));
        let err = by_name("XX")
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(err.contains("no parameter \"XX\"") && err.contains("FST"));
    }
}
