//! Generic Modbus RTU instruments (the Taisong v2.1 panel meters of manual 004 and anything
//! else with holding registers): per-device request limits applied for the caller, values
//! with decimals and sign, 32- and 64-bit integers and IEEE floats over two or four registers
//! in any of the four layouts ([`Layout`]), strings, and Read Device Identification.

use super::on_station;
use super::value::{registers_for_bits, single, Layout};
use super::{Device, Station, Table};
use crate::bus::{Bus, TxOptions};
use crate::codec::pdu::{MAX_READ_BITS, MAX_READ_COUNT, MAX_WRITE_BITS, MAX_WRITE_COUNT};
use crate::codec::DeviceIdentification;
use crate::error::{Error, Result};
use std::sync::Arc;
use std::time::Duration;

/// The most decimals a register's value may be given with.
pub const MAX_DECIMALS: u8 = 9;

/// A register's raw word for `value` with `decimals` (value x 10^decimals, rounded to a
/// whole number that must be the value to within rounding error), signed or not.
///
/// # Errors
/// [`Error::InvalidArgument`] for a value that is not finite, has more decimals than given,
/// or does not fit 16 bits.
pub fn to_raw(value: f64, decimals: u8, signed: bool) -> Result<u16> {
    let (lo, hi) = if signed {
        (f64::from(i16::MIN), f64::from(i16::MAX))
    } else {
        (0.0, f64::from(u16::MAX))
    };
    let raw = scaled(value, decimals, lo, hi)?;
    Ok(if signed {
        raw as i16 as u16
    } else {
        raw as u16
    })
}

/// The value of a raw word with `decimals`, signed (two's complement) or not.
pub fn from_raw(raw: u16, decimals: u8, signed: bool) -> f64 {
    let v = if signed {
        f64::from(raw as i16)
    } else {
        f64::from(raw)
    };
    unscaled(v, decimals)
}

/// `value` x 10^`decimals` as a whole number within `lo..=hi`.
fn scaled(value: f64, decimals: u8, lo: f64, hi: f64) -> Result<f64> {
    check_decimals(decimals)?;
    let factor = 10f64.powi(i32::from(decimals));
    let steps = value * factor;
    let whole = steps.round();
    if !value.is_finite() || whole < lo || whole > hi {
        return Err(Error::InvalidArgument(format!(
            "value {value} with {decimals} decimals does not fit the register ({} to {})",
            lo / factor,
            hi / factor
        )));
    }
    // A few units in the last place: 0.1 + 0.2 with one decimal is 3 steps, 30000.02 is not.
    if (steps - whole).abs() > 4.0 * f64::EPSILON * steps.abs().max(1.0) {
        return Err(Error::InvalidArgument(format!(
            "value {value} has more than {decimals} decimals"
        )));
    }
    Ok(whole)
}

fn unscaled(v: f64, decimals: u8) -> f64 {
    if decimals == 0 {
        v
    } else {
        // Divide, not multiply by 0.1: 3 with one decimal reads 0.3.
        v / 10f64.powi(i32::from(decimals))
    }
}

fn check_decimals(decimals: u8) -> Result<()> {
    if decimals > MAX_DECIMALS {
        return Err(Error::InvalidArgument(format!(
            "decimals must be 0 to {MAX_DECIMALS}, got {decimals}"
        )));
    }
    Ok(())
}

/// A generic instrument on a bus, with its own request limits and write pacing.
#[derive(Debug)]
pub struct Instrument {
    station: Station,
    max_read: u16,
    max_write: u16,
    max_read_bits: u16,
    max_write_bits: u16,
}

on_station!(Instrument);

impl Instrument {
    /// The instrument at `unit` on `bus`, reading at most `max_read` and writing at most
    /// `max_write` registers a request, with writes at least `min_write_interval` apart.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if `max_read` is not 1..=125 or `max_write` not 1..=123.
    pub fn new(
        bus: Arc<Bus>,
        unit: u8,
        max_read: u16,
        max_write: u16,
        min_write_interval: Duration,
    ) -> Result<Instrument> {
        check_limit("max_read", max_read, MAX_READ_COUNT)?;
        check_limit("max_write", max_write, MAX_WRITE_COUNT)?;
        let opts = TxOptions {
            write_interval: min_write_interval,
            ..TxOptions::default()
        };
        Ok(Instrument {
            station: Station::new(bus, unit, opts),
            max_read,
            max_write,
            max_read_bits: MAX_READ_BITS,
            max_write_bits: MAX_WRITE_BITS,
        })
    }

    /// The same instrument reading at most `max_read_bits` and writing at most
    /// `max_write_bits` coils or inputs a request (the protocol's 2000 and 1968 unless the
    /// device allows fewer).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if `max_read_bits` is not 1..=2000 or `max_write_bits` not
    /// 1..=1968.
    pub fn with_bit_limits(mut self, max_read_bits: u16, max_write_bits: u16) -> Result<Self> {
        check_limit("max_read_bits", max_read_bits, MAX_READ_BITS)?;
        check_limit("max_write_bits", max_write_bits, MAX_WRITE_BITS)?;
        self.max_read_bits = max_read_bits;
        self.max_write_bits = max_write_bits;
        Ok(self)
    }

    /// Most registers one read asks for.
    pub fn max_read(&self) -> u16 {
        self.max_read
    }

    /// Most registers one write carries.
    pub fn max_write(&self) -> u16 {
        self.max_write
    }

    /// Most coils or discrete inputs one read asks for.
    pub fn max_read_bits(&self) -> u16 {
        self.max_read_bits
    }

    /// Most coils one write carries.
    pub fn max_write_bits(&self) -> u16 {
        self.max_write_bits
    }

    /// Least time between two writes.
    pub fn min_write_interval(&self) -> Duration {
        self.station.opts().write_interval
    }

    /// `count` registers of `table` (holding or input) from `address`, in requests of at
    /// most `max_read`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for an empty span or one past 0xFFFF, or a table of bits
    /// (nothing sent); any [`Error`] of a request (the registers read before it are lost).
    pub fn read_registers(&self, table: Table, address: u16, count: usize) -> Result<Vec<u16>> {
        read_in_parts(address, count, self.max_read, |at, n| {
            self.station.read_table(table, at, n)
        })
    }

    /// `count` bits of `table` (coils or discrete inputs) from `address`, in requests of at
    /// most `max_read_bits`.
    ///
    /// # Errors
    /// As [`read_registers`](Self::read_registers), for a table of registers too.
    pub fn read_bits(&self, table: Table, address: u16, count: usize) -> Result<Vec<bool>> {
        read_in_parts(address, count, self.max_read_bits, |at, n| {
            self.station.read_bits(table, at, n)
        })
    }

    /// Sets one coil (0x05).
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn write_coil(&self, address: u16, value: bool) -> Result<()> {
        self.station.write_coil(address, value)
    }

    /// Sets `values` on the coils from `address` with 0x0F, in requests of at most
    /// `max_write_bits`.
    ///
    /// # Errors
    /// As [`write_registers`](Self::write_registers).
    pub fn write_coils(&self, address: u16, values: &[bool]) -> Result<()> {
        write_in_parts(address, values, self.max_write_bits, |at, part| {
            self.station.write_coils(at, part)
        })
    }

    /// Writes `values` from `address` with 0x10, in requests of at most `max_write`.
    ///
    /// # Errors
    /// As [`read_registers`](Self::read_registers); a failed request leaves the earlier
    /// ones written.
    pub fn write_registers(&self, address: u16, values: &[u16]) -> Result<()> {
        write_in_parts(address, values, self.max_write, |at, part| {
            self.station.write_many(at, part)
        })
    }

    /// One register of `table` (holding or input): its raw word.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn read_word(&self, table: Table, address: u16) -> Result<u16> {
        match self.read_registers(table, address, 1)?[..] {
            [w] => Ok(w),
            _ => Err(self.station.short_reply()),
        }
    }

    /// Writes one register with 0x06, or with 0x10 if `multiple`.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn write_word(&self, address: u16, value: u16, multiple: bool) -> Result<()> {
        if multiple {
            self.station.write_many(address, &[value])
        } else {
            self.station.write(address, value)
        }
    }

    /// A register of `table` as a value with `decimals`, signed or not.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for decimals over 9; any [`Error`].
    pub fn read_value(
        &self,
        table: Table,
        address: u16,
        decimals: u8,
        signed: bool,
    ) -> Result<f64> {
        check_decimals(decimals)?;
        Ok(from_raw(self.read_word(table, address)?, decimals, signed))
    }

    /// Writes a value with `decimals`, signed or not, checked before anything is sent.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a value that does not fit; any [`Error`].
    pub fn write_value(
        &self,
        address: u16,
        value: f64,
        decimals: u8,
        signed: bool,
        multiple: bool,
    ) -> Result<()> {
        let raw = to_raw(value, decimals, signed)?;
        self.write_word(address, raw, multiple)
    }

    /// An unsigned integer of `bits` (32 or 64) over the 2 or 4 registers from `address`,
    /// laid out as `layout` (its two's complement bits, for a signed value).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for other `bits` or registers past 0xFFFF (nothing sent);
    /// any other [`Error`].
    pub fn read_uint(&self, table: Table, address: u16, bits: u32, layout: Layout) -> Result<u64> {
        let count = registers_for_bits(bits)?;
        check_span(address, count)?;
        let registers = self.read_registers(table, address, count)?;
        if registers.len() != count {
            return Err(self.station.short_reply());
        }
        Ok(layout.join(&registers))
    }

    /// Writes an unsigned integer of `bits` (32 or 64; a signed value as its two's
    /// complement bits) over 2 or 4 registers from `address`, laid out as `layout`, in one
    /// request (more if `max_write` is smaller).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for other `bits`, a value that does not fit them or
    /// registers past 0xFFFF (nothing sent); any other [`Error`].
    pub fn write_uint(&self, address: u16, value: u64, bits: u32, layout: Layout) -> Result<()> {
        let count = registers_for_bits(bits)?;
        check_span(address, count)?;
        if bits < 64 && value >> bits != 0 {
            return Err(Error::InvalidArgument(format!(
                "value must fit {bits} bits, got {value}"
            )));
        }
        self.write_registers(address, &layout.split(value, count))
    }

    /// An IEEE 754 float of `bits` (32: single, 64: double) over 2 or 4 registers from
    /// `address`, laid out as `layout`.
    ///
    /// # Errors
    /// As [`read_uint`](Self::read_uint).
    pub fn read_float(&self, table: Table, address: u16, bits: u32, layout: Layout) -> Result<f64> {
        let raw = self.read_uint(table, address, bits, layout)?;
        Ok(if bits == 32 {
            single(raw as u32)
        } else {
            f64::from_bits(raw)
        })
    }

    /// Writes an IEEE 754 float of `bits` (32 or 64) over 2 or 4 registers from `address`,
    /// laid out as `layout`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for NaN, an infinity or, in 32 bits, a number beyond a
    /// single's range (nothing sent); otherwise as [`write_uint`](Self::write_uint).
    pub fn write_float(&self, address: u16, value: f64, bits: u32, layout: Layout) -> Result<()> {
        registers_for_bits(bits)?;
        let single = value as f32;
        let raw = match bits {
            32 if single.is_finite() => u64::from(single.to_bits()),
            32 => {
                return Err(Error::InvalidArgument(format!(
                    "value must be a finite number within a 32-bit float's range, got {value}"
                )))
            }
            _ if value.is_finite() => value.to_bits(),
            _ => {
                return Err(Error::InvalidArgument(format!(
                    "value must be a finite number, got {value}"
                )))
            }
        };
        self.write_uint(address, raw, bits, layout)
    }

    /// `count` registers as text, two characters a register (high byte first), without
    /// the NULs that pad it.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn read_string(&self, table: Table, address: u16, count: usize) -> Result<String> {
        let words = self.read_registers(table, address, count)?;
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_be_bytes()).collect();
        let end = bytes.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
        // Latin-1: every byte is a character.
        Ok(bytes[..end].iter().map(|&b| char::from(b)).collect())
    }

    /// Writes `text` (Latin-1) into `count` registers, two characters a register, padded
    /// with NULs.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for text longer than `2 * count` bytes or a character
    /// outside Latin-1 (nothing sent); any [`Error`].
    pub fn write_string(&self, address: u16, text: &str, count: usize) -> Result<()> {
        check_span(address, count)?;
        let bytes: Option<Vec<u8>> = text
            .chars()
            .map(|c| u8::try_from(u32::from(c)).ok())
            .collect();
        let mut bytes = match bytes {
            Some(bytes) if bytes.len() <= 2 * count => bytes,
            _ => {
                return Err(Error::InvalidArgument(format!(
                    "text must be Latin-1 and at most {} characters for {count} registers, \
                     got {text:?}",
                    2 * count
                )))
            }
        };
        bytes.resize(2 * count, 0);
        let words: Vec<u16> = bytes
            .chunks_exact(2)
            .map(|p| u16::from_be_bytes([p[0], p[1]]))
            .collect();
        self.write_registers(address, &words)
    }

    /// Read Device Identification (0x2B / MEI 0x0E) from object 0 with `read_code` (1
    /// basic, 2 regular, 3 extended), following "more follows".
    ///
    /// # Errors
    /// [`Error::Exception`] code 1 (with a meaning that says so) for a device without the
    /// function; any [`Error`].
    pub fn identify(&self, read_code: u8) -> Result<DeviceIdentification> {
        if !(1..=3).contains(&read_code) {
            return Err(Error::InvalidArgument(format!(
                "read_code must be 1 (basic), 2 (regular) or 3 (extended), got {read_code}"
            )));
        }
        self.bus()
            .read_device_identification(self.unit(), read_code, 0, self.station.opts())
            .map_err(|e| match e {
                Error::Exception {
                    unit,
                    function,
                    code: 1,
                    meaning,
                    frame,
                } => Error::Exception {
                    unit,
                    function,
                    code: 1,
                    meaning: format!(
                        "{meaning}: the device does not support Read Device Identification \
                         (0x2B / MEI 0x0E) or this read code"
                    ),
                    frame,
                },
                other => other,
            })
    }
}

/// The comm event counter and log, file records and the FIFO queue (0x0B, 0x0C, 0x14,
/// 0x15, 0x18) of the instrument, with its own timing and write pacing.
impl Instrument {
    /// The status word and event counter (0x0B): [`Bus::get_comm_event_counter`].
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn get_comm_event_counter(&self) -> Result<(u16, u16)> {
        self.bus()
            .get_comm_event_counter(self.unit(), self.station.opts())
    }

    /// The status word, both counters and the events (0x0C): [`Bus::get_comm_event_log`].
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn get_comm_event_log(&self) -> Result<(u16, u16, u16, Vec<u8>)> {
        self.bus()
            .get_comm_event_log(self.unit(), self.station.opts())
    }

    /// File records, one list per `(file, record, length)` group (0x14):
    /// [`Bus::read_file_record`].
    ///
    /// # Errors
    /// Any [`Error`]; [`Error::InvalidArgument`] before anything is sent.
    pub fn read_file_record(&self, groups: &[(u16, u16, u16)]) -> Result<Vec<Vec<u16>>> {
        self.bus()
            .read_file_record(self.unit(), groups, self.station.opts())
    }

    /// Writes file records, `(file, record, values)` groups (0x15), paced as the
    /// instrument's other writes: [`Bus::write_file_record`].
    ///
    /// # Errors
    /// Any [`Error`]; [`Error::InvalidArgument`] before anything is sent.
    pub fn write_file_record(&self, groups: &[(u16, u16, Vec<u16>)]) -> Result<()> {
        self.bus()
            .write_file_record(self.unit(), groups, self.station.opts())
    }

    /// The values queued in the FIFO at `address` (0x18): [`Bus::read_fifo_queue`].
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn read_fifo_queue(&self, address: u16) -> Result<Vec<u16>> {
        self.bus()
            .read_fifo_queue(self.unit(), address, self.station.opts())
    }
}

/// A span of `count` registers from `address`: 1 or more, within 0..=0xFFFF.
fn check_span(address: u16, count: usize) -> Result<()> {
    if count == 0 || usize::from(address) + count > 0x1_0000 {
        return Err(Error::InvalidArgument(format!(
            "{count} registers from {address:#06x} are not a span within 0x0000 to 0xFFFF \
             (at least 1)"
        )));
    }
    Ok(())
}

/// A request limit `value` of `name`: 1 to `max`.
fn check_limit(name: &str, value: u16, max: u16) -> Result<()> {
    if !(1..=max).contains(&value) {
        return Err(Error::InvalidArgument(format!(
            "{name} must be 1 to {max}, got {value}"
        )));
    }
    Ok(())
}

/// `count` items (registers or bits) from `address`, each request of at most `max` made by
/// `read(address, count)`.
fn read_in_parts<T>(
    address: u16,
    count: usize,
    max: u16,
    mut read: impl FnMut(u16, u16) -> Result<Vec<T>>,
) -> Result<Vec<T>> {
    check_span(address, count)?;
    let mut items = Vec::with_capacity(count);
    for (at, n) in chunks(address, count, max) {
        items.extend(read(at, n)?);
    }
    Ok(items)
}

/// Writes `values` from `address`, each request of at most `max` made by `write(address,
/// part)`; a failed request leaves the earlier ones written.
fn write_in_parts<T>(
    address: u16,
    values: &[T],
    max: u16,
    mut write: impl FnMut(u16, &[T]) -> Result<()>,
) -> Result<()> {
    check_span(address, values.len())?;
    let mut at = address;
    for part in values.chunks(usize::from(max.max(1))) {
        write(at, part)?;
        at = at.wrapping_add(part.len() as u16);
    }
    Ok(())
}

/// `(address, count)` of each request that covers `count` registers from `address` in
/// requests of at most `max`.
pub fn chunks(address: u16, count: usize, max: u16) -> Vec<(u16, u16)> {
    let max = usize::from(max.max(1));
    (0..count)
        .step_by(max)
        .map(|offset| {
            let n = (count - offset).min(max);
            (address.wrapping_add(offset as u16), n as u16)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_split_at_the_limit() {
        assert_eq!(chunks(0, 100, 37), vec![(0, 37), (37, 37), (74, 26)]);
        assert_eq!(chunks(8, 20, 20), vec![(8, 20)]);
        assert_eq!(chunks(0xFFFE, 2, 1), vec![(0xFFFE, 1), (0xFFFF, 1)]);
        assert!(chunks(0, 0, 5).is_empty());
    }

    #[test]
    fn values_with_decimals_and_sign() {
        assert_eq!(to_raw(100.0, 0, false).ok(), Some(100));
        assert_eq!(to_raw(-5.0, 1, true).ok(), Some(0xFFCE));
        assert_eq!(to_raw(12.34, 2, false).ok(), Some(1234));
        assert_eq!(to_raw(0.1 + 0.2, 1, false).ok(), Some(3));
        assert_eq!(to_raw(1.1, 2, false).ok(), Some(110));
        assert_eq!(to_raw(-0.0, 0, true).ok(), Some(0));
        assert_eq!(from_raw(0xFFCE, 1, true), -5.0);
        assert_eq!(from_raw(3, 1, false), 0.3);
        assert_eq!(from_raw(0xFFFF, 0, false), 65535.0);
        for (v, d, s) in [
            (65536.0, 0, false),
            (-1.0, 0, false),
            (3276.8, 1, true),
            (1.25, 1, false),
            (f64::NAN, 0, false),
            (1.0, 10, false),
            (30000.02, 0, false),
            (65534.95, 0, false),
            (6553.496, 1, false),
        ] {
            assert!(to_raw(v, d, s).is_err(), "{v} {d} {s}");
        }
    }
}
