//! How a value wider than one register lies in consecutive registers: which register comes
//! first (word order) and which byte of each register (byte order). Modbus itself says only
//! that a register is sent high byte first; devices disagree on the rest, so the four
//! layouts are named as the trade names them, by where the value's bytes A (most
//! significant) to D land. For 0x01020304 in two registers:
//!
//! | layout | word order | byte order | registers |
//! |---|---|---|---|
//! | ABCD | big | big | `[0x0102, 0x0304]` |
//! | CDAB | little | big | `[0x0304, 0x0102]` |
//! | BADC | big | little | `[0x0201, 0x0403]` |
//! | DCBA | little | little | `[0x0403, 0x0201]` |
//!
//! A 64-bit value lies the same way over four registers (CDAB: `[GH, EF, CD, AB]`).

use crate::error::{Error, Result};

/// The IEEE 754 single of `bits` as the f64 of its shortest decimal: 229.9 for the single
/// nearest 229.9, not 229.89999389648438 (its exact value), so that a value read shows as
/// the device meant it, wherever it is printed. That decimal reads back as the same single
/// (`value as f32` gives `bits` again). NaN and the infinities stay as they are.
pub fn single(bits: u32) -> f64 {
    let value = f32::from_bits(bits);
    if !value.is_finite() {
        return f64::from(value);
    }
    // `{}` on an f32 writes the shortest decimal that reads back as the same f32.
    format!("{value}")
        .parse::<f64>()
        .unwrap_or_else(|_| f64::from(value))
}

/// The layout of a value over consecutive registers (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Layout {
    /// Most significant register first, high byte first in each: the Modbus convention.
    #[default]
    Abcd,
    /// Least significant register first, high byte first in each ("word swap").
    Cdab,
    /// Most significant register first, low byte first in each ("byte swap").
    Badc,
    /// Least significant register first, low byte first in each.
    Dcba,
}

impl Layout {
    /// Every layout, ABCD first.
    pub const ALL: [Layout; 4] = [Layout::Abcd, Layout::Cdab, Layout::Badc, Layout::Dcba];

    /// The layout of a word order and a byte order, each big (most significant first) or
    /// not.
    pub const fn new(words_big: bool, bytes_big: bool) -> Layout {
        match (words_big, bytes_big) {
            (true, true) => Layout::Abcd,
            (false, true) => Layout::Cdab,
            (true, false) => Layout::Badc,
            (false, false) => Layout::Dcba,
        }
    }

    /// The layout called `name` ("ABCD", "CDAB", "BADC", "DCBA"; any case), or None.
    pub fn from_name(name: &str) -> Option<Layout> {
        Layout::ALL
            .into_iter()
            .find(|l| l.name().eq_ignore_ascii_case(name))
    }

    /// Its name: "ABCD", "CDAB", "BADC" or "DCBA".
    pub const fn name(self) -> &'static str {
        match self {
            Layout::Abcd => "ABCD",
            Layout::Cdab => "CDAB",
            Layout::Badc => "BADC",
            Layout::Dcba => "DCBA",
        }
    }

    /// Whether the most significant register comes first.
    pub const fn words_big(self) -> bool {
        matches!(self, Layout::Abcd | Layout::Badc)
    }

    /// Whether each register holds its high byte first.
    pub const fn bytes_big(self) -> bool {
        matches!(self, Layout::Abcd | Layout::Cdab)
    }

    /// The registers that hold `value`, given as its bytes most significant first (an even
    /// number of them), in this layout.
    pub fn to_registers(self, value: &[u8]) -> Vec<u16> {
        let mut words: Vec<u16> = value
            .chunks(2)
            .map(|pair| match pair {
                [hi, lo] if self.bytes_big() => u16::from_be_bytes([*hi, *lo]),
                [hi, lo] => u16::from_le_bytes([*hi, *lo]),
                [only] => u16::from(*only),
                _ => 0,
            })
            .collect();
        if !self.words_big() {
            words.reverse();
        }
        words
    }

    /// The value's bytes, most significant first, that `registers` hold in this layout.
    pub fn from_registers(self, registers: &[u16]) -> Vec<u8> {
        let mut words = registers.to_vec();
        if !self.words_big() {
            words.reverse();
        }
        words
            .into_iter()
            .flat_map(|w| {
                if self.bytes_big() {
                    w.to_be_bytes()
                } else {
                    w.to_le_bytes()
                }
            })
            .collect()
    }

    /// The `count` registers (1 to 4) that hold the low `16 * count` bits of `value`.
    pub fn split(self, value: u64, count: usize) -> Vec<u16> {
        let bytes = value.to_be_bytes();
        self.to_registers(bytes.get(8 - 2 * count.min(4)..).unwrap_or(&bytes))
    }

    /// The value (up to 64 bits) that `registers` (1 to 4) hold.
    pub fn join(self, registers: &[u16]) -> u64 {
        self.from_registers(registers)
            .iter()
            .fold(0, |v, b| v << 8 | u64::from(*b))
    }
}

/// A number a register value stands for: an integer (of any width up to 64 bits, signed or
/// not) or a float.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Number {
    /// An integer.
    Int(i128),
    /// A float.
    Float(f64),
}

/// What one value over registers is: its width and kind, as the trade names them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// One register, 0..65535.
    U16,
    /// One register, two's complement.
    I16,
    /// Two registers, unsigned.
    U32,
    /// Two registers, two's complement.
    I32,
    /// Four registers, unsigned.
    U64,
    /// Four registers, two's complement.
    I64,
    /// Two registers, IEEE 754 single.
    F32,
    /// Four registers, IEEE 754 double.
    F64,
}

impl Kind {
    /// Every kind, in the order of their names' table.
    pub const ALL: [Kind; 8] = [
        Kind::U16,
        Kind::I16,
        Kind::U32,
        Kind::I32,
        Kind::U64,
        Kind::I64,
        Kind::F32,
        Kind::F64,
    ];

    /// Its name: "u16", "i16", "u32", "i32", "u64", "i64", "f32" or "f64".
    pub const fn name(self) -> &'static str {
        match self {
            Kind::U16 => "u16",
            Kind::I16 => "i16",
            Kind::U32 => "u32",
            Kind::I32 => "i32",
            Kind::U64 => "u64",
            Kind::I64 => "i64",
            Kind::F32 => "f32",
            Kind::F64 => "f64",
        }
    }

    /// The kind called `name` (any case), or None.
    pub fn from_name(name: &str) -> Option<Kind> {
        Kind::ALL
            .into_iter()
            .find(|k| k.name().eq_ignore_ascii_case(name))
    }

    /// How many registers a value takes.
    pub const fn registers(self) -> usize {
        match self {
            Kind::U16 | Kind::I16 => 1,
            Kind::U32 | Kind::I32 | Kind::F32 => 2,
            Kind::U64 | Kind::I64 | Kind::F64 => 4,
        }
    }

    const fn bits(self) -> u32 {
        16 * self.registers() as u32
    }

    const fn signed(self) -> bool {
        matches!(self, Kind::I16 | Kind::I32 | Kind::I64)
    }

    /// Whether it is an IEEE float (f32, f64).
    pub const fn is_float(self) -> bool {
        matches!(self, Kind::F32 | Kind::F64)
    }

    /// The values `registers` hold, one per [`registers`](Self::registers) of them, laid out
    /// as `layout` (a one-register value takes only the byte order).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] when `registers` is not a whole number of values.
    pub fn decode(self, registers: &[u16], layout: Layout) -> Result<Vec<Number>> {
        let width = self.registers();
        if registers.is_empty() || registers.len() % width != 0 {
            return Err(Error::InvalidArgument(format!(
                "{} registers do not make whole {} values ({width} registers each)",
                registers.len(),
                self.name()
            )));
        }
        Ok(registers
            .chunks(width)
            .map(|one| self.number(layout.join(one)))
            .collect())
    }

    /// The value of its raw bits.
    fn number(self, raw: u64) -> Number {
        match self {
            Kind::F32 => Number::Float(single(raw as u32)),
            Kind::F64 => Number::Float(f64::from_bits(raw)),
            _ if self.signed() => {
                let shift = 64 - self.bits();
                Number::Int(i128::from(((raw << shift) as i64) >> shift))
            }
            _ => Number::Int(i128::from(raw)),
        }
    }

    /// The registers that hold `value` laid out as `layout`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for an integer that does not fit the kind, a float given
    /// for an integer kind, or a float that is not finite (or, for f32, beyond a single's
    /// range).
    pub fn encode(self, value: Number, layout: Layout) -> Result<Vec<u16>> {
        let bits = self.bits();
        let raw: u64 = match (value, self.is_float()) {
            (Number::Int(v), false) => {
                let (lo, hi) = if self.signed() {
                    (-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1)
                } else {
                    (0, (1i128 << bits) - 1)
                };
                if !(lo..=hi).contains(&v) {
                    return Err(Error::InvalidArgument(format!(
                        "a {} value must be {lo} to {hi}, got {v}",
                        self.name()
                    )));
                }
                (v as u64) & (u64::MAX >> (64 - bits))
            }
            (Number::Float(v), false) => {
                return Err(Error::InvalidArgument(format!(
                    "a {} value must be an integer, got {v}",
                    self.name()
                )))
            }
            (value, true) => {
                let v = match value {
                    Number::Int(i) => i as f64,
                    Number::Float(f) => f,
                };
                let single = v as f32;
                match self {
                    Kind::F32 if single.is_finite() => u64::from(single.to_bits()),
                    Kind::F64 if v.is_finite() => v.to_bits(),
                    _ => {
                        return Err(Error::InvalidArgument(format!(
                            "a {} value must be a finite number within its range, got {v}",
                            self.name()
                        )))
                    }
                }
            }
        };
        Ok(layout.split(raw, self.registers()))
    }
}

/// How many bits a multi-register integer or float has: 32 (two registers) or 64 (four).
///
/// # Errors
/// [`Error::InvalidArgument`] for anything else.
pub fn registers_for_bits(bits: u32) -> Result<usize> {
    match bits {
        32 => Ok(2),
        64 => Ok(4),
        _ => Err(Error::InvalidArgument(format!(
            "bits must be 32 or 64, got {bits}"
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_four_layouts_of_0x01020304() {
        let cases = [
            (Layout::Abcd, [0x0102, 0x0304]),
            (Layout::Cdab, [0x0304, 0x0102]),
            (Layout::Badc, [0x0201, 0x0403]),
            (Layout::Dcba, [0x0403, 0x0201]),
        ];
        for (layout, registers) in cases {
            assert_eq!(layout.split(0x0102_0304, 2), registers, "{}", layout.name());
            assert_eq!(layout.join(&registers), 0x0102_0304, "{}", layout.name());
        }
    }

    #[test]
    fn a_64_bit_value_lies_the_same_way_over_four_registers() {
        let v = 0x0102_0304_0506_0708;
        assert_eq!(Layout::Abcd.split(v, 4), [0x0102, 0x0304, 0x0506, 0x0708]);
        assert_eq!(Layout::Cdab.split(v, 4), [0x0708, 0x0506, 0x0304, 0x0102]);
        assert_eq!(Layout::Badc.split(v, 4), [0x0201, 0x0403, 0x0605, 0x0807]);
        assert_eq!(Layout::Dcba.split(v, 4), [0x0807, 0x0605, 0x0403, 0x0201]);
        for layout in Layout::ALL {
            assert_eq!(layout.join(&layout.split(v, 4)), v);
        }
    }

    #[test]
    fn kinds_decode_and_encode_in_every_layout() {
        let cases: [(Kind, Number, &[u16]); 8] = [
            (Kind::U16, Number::Int(0xFFFE), &[0xFFFE]),
            (Kind::I16, Number::Int(-2), &[0xFFFE]),
            (Kind::U32, Number::Int(0x0102_0304), &[0x0102, 0x0304]),
            (Kind::I32, Number::Int(-2), &[0xFFFF, 0xFFFE]),
            (Kind::U64, Number::Int(u64::MAX.into()), &[0xFFFF; 4]),
            (Kind::I64, Number::Int(i64::MIN.into()), &[0x8000, 0, 0, 0]),
            (Kind::F32, Number::Float(21.5), &[0x41AC, 0x0000]),
            (Kind::F64, Number::Float(1.0), &[0x3FF0, 0, 0, 0]),
        ];
        for (kind, value, abcd) in cases {
            assert_eq!(kind.encode(value, Layout::Abcd).ok().as_deref(), Some(abcd));
            assert_eq!(kind.decode(abcd, Layout::Abcd).ok(), Some(vec![value]));
            for layout in Layout::ALL {
                let registers = kind.encode(value, layout).unwrap_or_default();
                assert_eq!(kind.decode(&registers, layout).ok(), Some(vec![value]));
            }
        }
        // One register: only the byte order applies.
        assert_eq!(
            Kind::U16.encode(Number::Int(0x0102), Layout::Cdab).ok(),
            Some(vec![0x0102])
        );
        assert_eq!(
            Kind::U16.encode(Number::Int(0x0102), Layout::Badc).ok(),
            Some(vec![0x0201])
        );
        // Several values at once.
        let two = Kind::I16
            .decode(&[1, 0xFFFF], Layout::Abcd)
            .unwrap_or_default();
        assert_eq!(two, vec![Number::Int(1), Number::Int(-1)]);
    }

    #[test]
    fn a_single_reads_as_its_shortest_decimal() {
        for (bits, shown) in [
            (229.9f32.to_bits(), 229.9),
            (231.7f32.to_bits(), 231.7),
            (0.1f32.to_bits(), 0.1),
            (f32::MAX.to_bits(), 3.402_823_5e38),
            (f32::MIN_POSITIVE.to_bits(), 1.175_494_4e-38),
            (1u32, 1e-45),
        ] {
            assert_eq!(single(bits), shown);
            assert_eq!((single(bits) as f32).to_bits(), bits);
        }
        assert!(single(f32::NAN.to_bits()).is_nan());
        assert_eq!(single(f32::NEG_INFINITY.to_bits()), f64::NEG_INFINITY);
        let read = Kind::F32.decode(&[0x4365, 0xE666], Layout::Abcd);
        assert_eq!(read.ok(), Some(vec![Number::Float(229.9)]));
    }

    #[test]
    fn kinds_refuse_what_does_not_fit() {
        let refused = |kind: Kind, value: Number| kind.encode(value, Layout::Abcd).is_err();
        assert!(refused(Kind::U16, Number::Int(65536)));
        assert!(refused(Kind::U16, Number::Int(-1)));
        assert!(refused(Kind::I16, Number::Int(32768)));
        assert!(refused(Kind::I64, Number::Int(i128::from(i64::MAX) + 1)));
        assert!(refused(Kind::U32, Number::Float(1.0)));
        assert!(refused(Kind::F32, Number::Float(1e39)));
        assert!(refused(Kind::F64, Number::Float(f64::NAN)));
        assert!(Kind::U32.decode(&[1, 2, 3], Layout::Abcd).is_err());
        assert!(Kind::U32.decode(&[], Layout::Abcd).is_err());
        assert_eq!(Kind::from_name("F32"), Some(Kind::F32));
        assert_eq!(Kind::from_name("u8"), None);
    }

    #[test]
    fn names_and_orders() {
        for layout in Layout::ALL {
            assert_eq!(Layout::from_name(layout.name()), Some(layout));
            assert_eq!(Layout::new(layout.words_big(), layout.bytes_big()), layout);
        }
        assert_eq!(Layout::from_name("cdab"), Some(Layout::Cdab));
        assert_eq!(Layout::from_name("ACBD"), None);
        assert_eq!(Layout::default(), Layout::Abcd);
        assert_eq!(registers_for_bits(64).ok(), Some(4));
        assert!(registers_for_bits(16).is_err());
    }
}
