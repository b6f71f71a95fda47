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

    /// The registers of a 32-bit value.
    pub fn split32(self, value: u32) -> [u16; 2] {
        match self.to_registers(&value.to_be_bytes())[..] {
            [a, b] => [a, b],
            _ => [0, 0],
        }
    }

    /// The 32-bit value of two registers.
    pub fn join32(self, registers: [u16; 2]) -> u32 {
        let mut bytes = [0u8; 4];
        bytes.copy_from_slice(&self.from_registers(&registers));
        u32::from_be_bytes(bytes)
    }

    /// The registers of a 64-bit value.
    pub fn split64(self, value: u64) -> [u16; 4] {
        match self.to_registers(&value.to_be_bytes())[..] {
            [a, b, c, d] => [a, b, c, d],
            _ => [0; 4],
        }
    }

    /// The 64-bit value of four registers.
    pub fn join64(self, registers: [u16; 4]) -> u64 {
        let mut bytes = [0u8; 8];
        bytes.copy_from_slice(&self.from_registers(&registers));
        u64::from_be_bytes(bytes)
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
            assert_eq!(layout.split32(0x0102_0304), registers, "{}", layout.name());
            assert_eq!(layout.join32(registers), 0x0102_0304, "{}", layout.name());
        }
    }

    #[test]
    fn a_64_bit_value_lies_the_same_way_over_four_registers() {
        let v = 0x0102_0304_0506_0708;
        assert_eq!(Layout::Abcd.split64(v), [0x0102, 0x0304, 0x0506, 0x0708]);
        assert_eq!(Layout::Cdab.split64(v), [0x0708, 0x0506, 0x0304, 0x0102]);
        assert_eq!(Layout::Badc.split64(v), [0x0201, 0x0403, 0x0605, 0x0807]);
        assert_eq!(Layout::Dcba.split64(v), [0x0807, 0x0605, 0x0403, 0x0201]);
        for layout in Layout::ALL {
            assert_eq!(layout.join64(layout.split64(v)), v);
        }
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
