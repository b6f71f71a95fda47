//! Protocol data units: the requests a master sends and the replies it gets back.
//!
//! Function codes and limits are those of the Modbus Application Protocol Specification
//! V1.1b3 (section 6.3 read holding registers, 6.6 write single register, 6.12 write multiple
//! registers, 6.21 read device identification, section 7 exception responses).

use std::collections::BTreeMap;

/// Function 0x03, Read Holding Registers (spec 6.3).
pub const READ_HOLDING_REGISTERS: u8 = 0x03;
/// Function 0x06, Write Single Register (spec 6.6).
pub const WRITE_SINGLE_REGISTER: u8 = 0x06;
/// Function 0x10, Write Multiple Registers (spec 6.12).
pub const WRITE_MULTIPLE_REGISTERS: u8 = 0x10;
/// Function 0x2B, Encapsulated Interface Transport (spec 6.19).
pub const ENCAPSULATED_INTERFACE: u8 = 0x2B;
/// MEI type 0x0E, Read Device Identification (spec 6.21).
pub const MEI_READ_DEVICE_ID: u8 = 0x0E;

/// Most registers one 0x03 request may read (spec 6.3: 1 to 125).
pub const MAX_READ_COUNT: u16 = 125;
/// Most registers one 0x10 request may write (spec 6.12: 1 to 123).
pub const MAX_WRITE_COUNT: u16 = 123;

/// A request PDU, validated when built by [`Request::validate`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Request {
    /// 0x03: read `count` holding registers from `address`.
    ReadHoldingRegisters {
        /// First register address.
        address: u16,
        /// Number of registers, 1..=125.
        count: u16,
    },
    /// 0x06: write one register.
    WriteSingleRegister {
        /// Register address.
        address: u16,
        /// Value written.
        value: u16,
    },
    /// 0x10: write consecutive registers.
    WriteMultipleRegisters {
        /// First register address.
        address: u16,
        /// Values, 1..=123 of them.
        values: Vec<u16>,
    },
    /// 0x2B / 0x0E: read device identification.
    ReadDeviceIdentification {
        /// Read Device ID code: 1 basic, 2 regular, 3 extended, 4 one object.
        read_code: u8,
        /// First object to read.
        object_id: u8,
    },
}

/// Why a request cannot be built; raised before anything is sent.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RequestError {
    /// A register count outside what the function allows.
    #[error("count must be 1 to {max}, got {count}")]
    Count {
        /// The count asked for.
        count: usize,
        /// The function's limit.
        max: u16,
    },
    /// The registers asked for run past address 0xFFFF.
    #[error("registers {address:#06x}+{count} run past address 0xFFFF")]
    AddressRange {
        /// First address.
        address: u16,
        /// Number of registers.
        count: usize,
    },
    /// A Read Device ID code other than 1..=4.
    #[error("read device id code must be 1 to 4, got {0}")]
    ReadCode(u8),
}

impl Request {
    /// The function code of this request.
    pub fn function(&self) -> u8 {
        match self {
            Request::ReadHoldingRegisters { .. } => READ_HOLDING_REGISTERS,
            Request::WriteSingleRegister { .. } => WRITE_SINGLE_REGISTER,
            Request::WriteMultipleRegisters { .. } => WRITE_MULTIPLE_REGISTERS,
            Request::ReadDeviceIdentification { .. } => ENCAPSULATED_INTERFACE,
        }
    }

    /// Checks the spec's limits on counts and addresses.
    ///
    /// # Errors
    /// [`RequestError`] naming the argument that is out of range.
    pub fn validate(&self) -> Result<(), RequestError> {
        let span = |address: u16, count: usize, max: u16| {
            if count == 0 || count > usize::from(max) {
                Err(RequestError::Count { count, max })
            } else if usize::from(address) + count > 0x1_0000 {
                Err(RequestError::AddressRange { address, count })
            } else {
                Ok(())
            }
        };
        match self {
            Request::ReadHoldingRegisters { address, count } => {
                span(*address, usize::from(*count), MAX_READ_COUNT)
            }
            Request::WriteSingleRegister { .. } => Ok(()),
            Request::WriteMultipleRegisters { address, values } => {
                span(*address, values.len(), MAX_WRITE_COUNT)
            }
            Request::ReadDeviceIdentification { read_code, .. } => match read_code {
                1..=4 => Ok(()),
                _ => Err(RequestError::ReadCode(*read_code)),
            },
        }
    }

    /// Appends the PDU (function code and data) to `out`. Call [`Request::validate`] first:
    /// an invalid request encodes a frame the device will refuse.
    pub fn encode(&self, out: &mut Vec<u8>) {
        out.push(self.function());
        match self {
            Request::ReadHoldingRegisters { address, count } => {
                out.extend_from_slice(&address.to_be_bytes());
                out.extend_from_slice(&count.to_be_bytes());
            }
            Request::WriteSingleRegister { address, value } => {
                out.extend_from_slice(&address.to_be_bytes());
                out.extend_from_slice(&value.to_be_bytes());
            }
            Request::WriteMultipleRegisters { address, values } => {
                // validate() bounds the count to 123, so both casts are lossless.
                let count = values.len().min(usize::from(MAX_WRITE_COUNT)) as u16;
                out.extend_from_slice(&address.to_be_bytes());
                out.extend_from_slice(&count.to_be_bytes());
                out.push((count * 2) as u8);
                for v in values.iter().take(usize::from(count)) {
                    out.extend_from_slice(&v.to_be_bytes());
                }
            }
            Request::ReadDeviceIdentification {
                read_code,
                object_id,
            } => {
                out.extend_from_slice(&[MEI_READ_DEVICE_ID, *read_code, *object_id]);
            }
        }
    }
}

/// A normal (non-exception) reply, decoded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Response {
    /// 0x03: the register values.
    Registers(Vec<u16>),
    /// 0x06: the address and value the device sent back (normally an echo).
    WriteSingleRegister {
        /// Address carried in the reply.
        address: u16,
        /// Value carried in the reply.
        value: u16,
    },
    /// 0x10: the address and count the device sent back.
    WriteMultipleRegisters {
        /// Address carried in the reply.
        address: u16,
        /// Count carried in the reply.
        count: u16,
    },
    /// 0x2B / 0x0E: one page of device identification objects.
    DeviceIdentification(DeviceIdentification),
}

/// One reply to Read Device Identification (spec 6.21).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct DeviceIdentification {
    /// Read Device ID code carried in the reply.
    pub read_code: u8,
    /// Conformity level of the device.
    pub conformity: u8,
    /// True when more objects follow in another request.
    pub more_follows: bool,
    /// The object id to ask for next when `more_follows`.
    pub next_object: u8,
    /// Object id to raw value, the bytes as the device sent them.
    pub objects: BTreeMap<u8, Vec<u8>>,
}

impl DeviceIdentification {
    /// The objects as text, each decoded by [`identification_text`].
    pub fn texts(&self) -> BTreeMap<u8, String> {
        self.objects
            .iter()
            .map(|(&id, raw)| (id, identification_text(raw)))
            .collect()
    }
}

/// An identification object's bytes as text: the one decoding of them in the library.
///
/// The spec (6.21) makes the objects ASCII strings, but a device may send any byte. Each
/// byte is read as the character of the same number (Latin-1), which takes every byte
/// string and loses nothing: ASCII reads as ASCII, and encoding the text as Latin-1 gives
/// back the bytes the device sent (a device that sends UTF-8 can be read with
/// `text.encode("latin-1").decode("utf-8")`). UTF-8 would turn bytes that are not UTF-8
/// into U+FFFD, and a fallback from it would let two byte strings read as one text. The
/// same rule reads text registers (`Instrument::read_string`).
pub fn identification_text(raw: &[u8]) -> String {
    raw.iter().map(|&b| char::from(b)).collect()
}

/// Whether exception `code` is a gateway's answer for a unit behind it (spec section 7:
/// 0x0A no path to the unit, 0x0B no answer from it) rather than the unit's own.
pub fn is_gateway_exception(code: u8) -> bool {
    matches!(code, 0x0A | 0x0B)
}

/// Standard meaning of a Modbus exception code (spec section 7).
pub fn exception_meaning(code: u8) -> &'static str {
    match code {
        0x01 => "illegal function",
        0x02 => "illegal data address",
        0x03 => "illegal data value",
        0x04 => "server device failure",
        0x05 => "acknowledge",
        0x06 => "server device busy",
        0x08 => "memory parity error",
        0x0A => "gateway path unavailable",
        0x0B => "gateway target device failed to respond",
        _ => "unknown exception code",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identification_text_reads_every_byte_and_gives_it_back() {
        let raw: Vec<u8> = (0..=255).collect();
        let text = identification_text(&raw);
        assert_eq!(text.chars().count(), 256);
        let back: Vec<u8> = text
            .chars()
            .map(|c| u8::try_from(u32::from(c)).unwrap())
            .collect();
        assert_eq!(back, raw);
        assert_eq!(identification_text(b"ACME 25\xb5A"), "ACME 25\u{b5}A");
        let id = DeviceIdentification {
            objects: BTreeMap::from([(0, b"ACME".to_vec()), (1, vec![0xC3, 0xBC])]),
            ..DeviceIdentification::default()
        };
        assert_eq!(
            id.texts(),
            BTreeMap::from([(0, "ACME".to_string()), (1, "\u{c3}\u{bc}".to_string())])
        );
    }
}
