//! J2-series PID process/temperature controllers (manual 003): two parameter tables at even
//! addresses, 9600 or 19200 8N1, stations 1..=255.
//!
//! The signed table (MV at 0 .. DIE at 62) holds signed 16-bit words in tenths, the unsigned
//! table (AM at 128 .. FST at 156) plain integers: the family's file, `families/j2.toml`
//! ([`table`]), with its request size (16 registers) and its write pacing (150 ms, paced by
//! the Bus per unit). The manual's rules are applied here, not left to the caller: MV
//! written only in manual mode (AM = 0), RAPNF written 0 before a ramp parameter, SV held
//! to the limits, LSP never above USP.
//!
//! The manual's ranges are in engineering units; a signed register in tenths only reaches
//! -3276.8..=3276.7, so its upper limits of 3600 and 9999 stop there. SV is checked against
//! the limits LSP..USP the controller holds, read just before the write. The manual gives
//! "LSP~USP" for HY1, HY2, HYS, RAP, TRL, TRH, SRT and TOP too, but for a hysteresis or a
//! ramp rate that cannot be meant literally: those are checked against the widest range,
//! -1999..=3276.7, and the controller itself refuses what it does not take.

use super::family;
use super::profile::{Profile, ProfileRegister};
use super::suggest::did_you_mean;
use super::{on_station, Tabled};
use super::{Access, Device, Register, Station};
use crate::bus::{Bus, TxOptions};
use crate::error::{Error, Result};
use std::sync::Arc;

/// Highest value a signed register in tenths holds: the manual's upper limits of 3600 and
/// 9999 stop here.
const WORD_MAX: f64 = 3276.7;

/// The parameter held to the limits LSP..USP the controller holds, read just before a
/// write of it.
pub const HELD_TO_LIMITS: &str = "SV";

/// The family's file (`families/j2.toml`): both tables, their request size and pacing.
///
/// # Errors
/// As [`family::profile`].
pub fn profile() -> Result<&'static Profile> {
    family::profile("j2")
}

/// Both tables, in address order; the manual's "NC" (empty) addresses are left out.
///
/// # Errors
/// As [`family::profile`].
pub fn table() -> Result<&'static [ProfileRegister]> {
    family::registers("j2")
}

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

/// The raw word for `value` of parameter `p`, checked against its range and what the
/// register holds; a value past what a signed word in tenths holds says so.
///
/// # Errors
/// [`Error::InvalidArgument`] for a read-only parameter or a value it cannot take.
pub fn encode(p: &Register<String>, value: f64) -> Result<u16> {
    p.encode(value).map_err(|e| match e {
        Error::InvalidArgument(m)
            if p.access != Access::Read
                && p.signed
                && p.range.1 == WORD_MAX
                && value > WORD_MAX =>
        {
            Error::InvalidArgument(format!(
                "{m} (a signed 16-bit register in tenths holds -3276.8 to 3276.7)"
            ))
        }
        other => other,
    })
}

/// The parameter called `name` (any case: "sv" is SV).
///
/// # Errors
/// [`Error::InvalidArgument`] if there is none.
pub fn by_name(name: &str) -> Result<&'static Register<String>> {
    Ok(&table()?[index(name)?].register)
}

/// The index in [`table`] of the parameter called `name` (any case).
///
/// # Errors
/// [`Error::InvalidArgument`] if there is none.
pub fn index(name: &str) -> Result<usize> {
    let table = table()?;
    table
        .iter()
        .position(|p| p.register.name.eq_ignore_ascii_case(name))
        .ok_or_else(|| {
            let names = table.iter().map(|p| p.register.name.as_str());
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

on_station!(J2);

impl Tabled for J2 {
    fn table(&self) -> Result<&'static Profile> {
        profile()
    }

    fn index(&self, name: &str) -> Result<usize> {
        index(name)
    }

    /// Writes `value` to the parameter called `name`, applying the manual's rules: the range
    /// is checked first (an "LSP~USP" range against the limits read from the controller);
    /// MV needs manual mode; RAPNF is written 0 before a ramp parameter; LSP may not go
    /// above USP nor USP below LSP. Writes are paced 150 ms apart by the Bus.
    fn set(&self, name: &str, value: f64) -> Result<()> {
        self.set_as(name, value, false)
    }
}

impl J2 {
    /// The controller at `unit` on `bus`.
    pub fn new(bus: Arc<Bus>, unit: u8) -> J2 {
        // The file's pacing (a file the parser refused fails every call anyway).
        let opts = TxOptions {
            write_interval: profile().map(Profile::write_interval).unwrap_or_default(),
            ..TxOptions::default()
        };
        J2 {
            station: Station::new(bus, unit, opts),
        }
    }

    /// Every parameter of both tables, `(name, value)` in address order, in six requests
    /// of at most 16 registers.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn parameters(&self) -> Result<Vec<(&'static str, f64)>> {
        let names: Vec<&str> = table()?.iter().map(|p| p.register.name.as_str()).collect();
        let values = self.get_many(&names)?;
        Ok(names.into_iter().zip(values).collect())
    }

    /// As [`Tabled::set`], with function 0x10 (one register) instead of 0x06 when
    /// `multiple`: the manual shows both for SV.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a bad name or value (nothing sent);
    /// [`Error::State`] for MV in automatic mode (nothing written); any other [`Error`].
    pub fn set_as(&self, name: &str, value: f64, multiple: bool) -> Result<()> {
        let p = by_name(name)?;
        let raw = encode(p, value)?;
        let rapnf = by_name(RAPNF)?.address;
        self.sequence(|| {
            if p.name == "MV" && self.automatic()? {
                return Err(self.mv_in_auto());
            }
            self.check_against_limits(p, value)?;
            if RAMP_PARAMETERS.contains(&p.name.as_str()) {
                self.write_word(rapnf, 0)?;
            }
            if multiple {
                self.station.write_many(p.address, &[raw])
            } else {
                self.write_word(p.address, raw)
            }
        })
    }

    /// Writes several parameters in order, each as [`set`](Self::set) does. Every value
    /// is checked against its fixed range before the first is sent; the checks that need
    /// the controller (SV within the limits, MV in manual mode) are made write by write.
    ///
    /// # Errors
    /// As [`set`](Self::set); a failure stops the sequence (the earlier writes stay).
    pub fn set_many(&self, values: &[(&str, f64)]) -> Result<()> {
        for (name, value) in values {
            encode(by_name(name)?, *value)?;
        }
        for (name, value) in values {
            self.set(name, *value)?;
        }
        Ok(())
    }

    /// Sets the output MV to `percent`. In automatic mode this is refused with
    /// [`Error::State`], unless `switch_to_manual`: then AM is written 0 first.
    ///
    /// # Errors
    /// As [`set`](Self::set).
    pub fn set_output(&self, percent: f64, switch_to_manual: bool) -> Result<()> {
        let mv = by_name("MV")?;
        let raw = encode(mv, percent)?;
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
        let (raw_low, raw_high) = (encode(lsp, low)?, encode(usp, high)?);
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
        match self.get_many(&LIMITS)?[..] {
            [low, high] => Ok((low, high)),
            _ => Err(self.station.short_reply()),
        }
    }

    /// Whether the controller is in automatic mode (AM = 1).
    fn automatic(&self) -> Result<bool> {
        Ok(self.get(AM)? != 0.0)
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
    fn check_against_limits(&self, p: &Register<String>, value: f64) -> Result<()> {
        let bounded = [HELD_TO_LIMITS, "LSP", "USP"].contains(&p.name.as_str());
        if !bounded {
            return Ok(());
        }
        let (low, high) = self.limits()?;
        let refused = match p.name.as_str() {
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

    fn write_word(&self, address: u16, raw: u16) -> Result<()> {
        self.station.write(address, raw)
    }

    /// Runs a check-then-write (AM before MV, RAPNF before a ramp parameter, the limits
    /// before SV) as one sequence for this unit, whichever J2 object runs it.
    fn sequence<R>(&self, f: impl FnOnce() -> Result<R>) -> Result<R> {
        self.station.exclusive(f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_is_in_address_order_at_even_addresses_within_the_tables() {
        let table: Vec<&Register<String>> = table().unwrap().iter().map(|p| &p.register).collect();
        assert_eq!(table.len(), 43);
        for pair in table.windows(2) {
            assert!(pair[0].address < pair[1].address, "{:?}", pair[1]);
        }
        for p in table {
            assert_eq!(p.address % 2, 0, "{}", p.name);
            assert!(TABLES.iter().any(|(a, b)| (*a..=*b).contains(&p.address)));
            assert_eq!(p.signed, p.address < 0x80, "{}", p.name);
            assert_eq!(p.scale, if p.signed { 0.1 } else { 1.0 }, "{}", p.name);
            assert_eq!(p.access == Access::Read, p.name == "PV", "{}", p.name);
        }
        let p = profile().unwrap();
        assert_eq!(
            (p.limits.max_read, p.limits.max_write),
            (Some(16), Some(16))
        );
        assert_eq!(p.write_interval(), std::time::Duration::from_millis(150));
    }

    #[test]
    fn negative_tenths_are_twos_complement() {
        let Some(al1) = by_name("AL1").ok().filter(|p| p.signed) else {
            panic!("AL1 is in the signed table");
        };
        assert_eq!(encode(al1, -50.0).ok(), Some(0xFE0C));
        assert_eq!(al1.decode(0xFE0C), -50.0);
        assert_eq!(encode(al1, 100.0).ok(), Some(1000));
        assert_eq!(al1.decode(3), 0.3);
    }

    #[test]
    fn ranges_are_cut_to_what_the_register_holds() {
        let check = |name: &str, v: f64| by_name(name).and_then(|p| encode(p, v)).is_ok();
        assert!(check("AL1", 3276.7) && !check("AL1", 3276.8) && !check("AL1", 9999.0));
        assert!(check("AL1", -1999.0) && !check("AL1", -1999.1));
        assert!(check("P", 0.1) && !check("P", 0.0) && !check("P", 3600.0));
        assert!(check("DIE", 0.5) && !check("DIE", 0.4) && !check("DIE", 5.1));
        assert!(check("FST", 20.0) && !check("FST", 19.0) && !check("FST", 20.5));
        assert!(!check("PV", 1.0) && !check("MV", 100.1) && !check("MV", f64::NAN));
        let msg = by_name("AL1").and_then(|p| encode(p, 5000.0)).err();
        assert!(msg.is_some_and(|e| e.to_string().contains("holds -3276.8 to 3276.7")));
        let msg = by_name("DIE").and_then(|p| encode(p, 5000.0)).err();
        assert!(msg.is_some_and(|e| !e.to_string().contains("3276.7")));
        let msg = by_name("PV").and_then(|p| encode(p, 4000.0)).err();
        assert!(msg.is_some_and(|e| e.to_string() == "PV is read-only"));
    }

    #[test]
    fn the_groups_name_parameters_of_the_table() {
        let groups: [&[&str]; 5] = [&STATUS, &SAMPLE, &PID, &PID2, &LIMITS];
        for name in groups.iter().flat_map(|g| g.iter()) {
            assert!(by_name(name).is_ok(), "{name}");
        }
        // Each small group is one request: within 16 registers.
        for group in [&SAMPLE[..], &PID, &PID2, &LIMITS] {
            let indices: Vec<usize> = group.iter().filter_map(|n| index(n).ok()).collect();
            assert_eq!(profile().unwrap().plan(&indices).len(), 1, "{group:?}");
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
