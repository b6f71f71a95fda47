//! Protocol data units: the requests a master sends and the replies it gets back.
//!
//! Function codes and limits are those of the Modbus Application Protocol Specification
//! V1.1b3, section 6: 6.1 read coils, 6.2 read discrete inputs, 6.3 read holding registers,
//! 6.4 read input registers, 6.5 write single coil, 6.6 write single register, 6.7 read
//! exception status, 6.8 diagnostics, 6.11 write multiple coils, 6.12 write multiple
//! registers, 6.13 report server id, 6.16 mask write register, 6.17 read/write multiple
//! registers, 6.21 read device identification; 6.9 get comm event counter, 6.10 get comm
//! event log, 6.14 read file record, 6.15 write file record, 6.18 read FIFO queue; section
//! 7 exception responses.

use std::collections::BTreeMap;

pub mod decode;

/// Function 0x01, Read Coils (spec 6.1).
pub const READ_COILS: u8 = 0x01;
/// Function 0x02, Read Discrete Inputs (spec 6.2).
pub const READ_DISCRETE_INPUTS: u8 = 0x02;
/// Function 0x03, Read Holding Registers (spec 6.3).
pub const READ_HOLDING_REGISTERS: u8 = 0x03;
/// Function 0x04, Read Input Registers (spec 6.4).
pub const READ_INPUT_REGISTERS: u8 = 0x04;
/// Function 0x05, Write Single Coil (spec 6.5).
pub const WRITE_SINGLE_COIL: u8 = 0x05;
/// Function 0x07, Read Exception Status (spec 6.7, serial line only).
pub const READ_EXCEPTION_STATUS: u8 = 0x07;
/// Function 0x08, Diagnostics (spec 6.8, serial line only).
pub const DIAGNOSTICS: u8 = 0x08;
/// Function 0x0B, Get Comm Event Counter (spec 6.9, serial line only).
pub const GET_COMM_EVENT_COUNTER: u8 = 0x0B;
/// Function 0x0C, Get Comm Event Log (spec 6.10, serial line only).
pub const GET_COMM_EVENT_LOG: u8 = 0x0C;
/// Function 0x14, Read File Record (spec 6.14).
pub const READ_FILE_RECORD: u8 = 0x14;
/// Function 0x15, Write File Record (spec 6.15).
pub const WRITE_FILE_RECORD: u8 = 0x15;
/// Function 0x18, Read FIFO Queue (spec 6.18).
pub const READ_FIFO_QUEUE: u8 = 0x18;
/// Function 0x0F, Write Multiple Coils (spec 6.11).
pub const WRITE_MULTIPLE_COILS: u8 = 0x0F;
/// Function 0x11, Report Server ID (spec 6.13, serial line only).
pub const REPORT_SERVER_ID: u8 = 0x11;
/// Function 0x16, Mask Write Register (spec 6.16).
pub const MASK_WRITE_REGISTER: u8 = 0x16;
/// Function 0x17, Read/Write Multiple Registers (spec 6.17).
pub const READ_WRITE_REGISTERS: u8 = 0x17;
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
/// Most coils or discrete inputs one 0x01 / 0x02 request may read (spec 6.1, 6.2: 1 to 2000).
pub const MAX_READ_BITS: u16 = 2000;
/// Most coils one 0x0F request may write (spec 6.11: 1 to 1968).
pub const MAX_WRITE_BITS: u16 = 1968;
/// Most registers one 0x17 request may write (spec 6.17: 1 to 121; it reads 1 to 125).
pub const MAX_READ_WRITE_COUNT: u16 = 121;
/// Diagnostics sub-function 0x00, Return Query Data: the reply echoes the request (a line
/// test).
pub const DIAG_RETURN_QUERY_DATA: u16 = 0x0000;
/// Diagnostics sub-function 0x04, Force Listen Only Mode: the device answers nothing, to
/// this or any later request, until a restart (sub-function 0x01).
pub const DIAG_FORCE_LISTEN_ONLY: u16 = 0x0004;
/// The reference type of every file record group (spec 6.14, 6.15: it must be 6).
pub const FILE_REFERENCE_TYPE: u8 = 6;
/// Highest record number in a file (spec 6.14, 6.15: records 0 to 9999, 0x0000 to
/// 0x270F).
pub const MAX_FILE_RECORD: u16 = 0x270F;
/// Most values a FIFO queue holds, and so a 0x18 reply carries (spec 6.18: 31).
pub const MAX_FIFO_COUNT: u16 = 31;
/// Most events a 0x0C reply carries (spec 6.10: 0 to 64 bytes, one an event).
pub const MAX_COMM_EVENTS: usize = 64;
/// Most bytes a PDU holds (spec 4.1: 253, the longest RTU frame but unit and CRC).
pub const MAX_PDU: usize = 253;
/// Most data bytes after the function code, in a request or a reply.
pub const MAX_PDU_DATA: usize = MAX_PDU - 1;

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
    /// 0x01: read `count` coils from `address`.
    ReadCoils {
        /// First coil address.
        address: u16,
        /// Number of coils, 1..=2000.
        count: u16,
    },
    /// 0x02: read `count` discrete inputs from `address`.
    ReadDiscreteInputs {
        /// First input address.
        address: u16,
        /// Number of inputs, 1..=2000.
        count: u16,
    },
    /// 0x04: read `count` input registers from `address`.
    ReadInputRegisters {
        /// First register address.
        address: u16,
        /// Number of registers, 1..=125.
        count: u16,
    },
    /// 0x05: set one coil on (sent as 0xFF00) or off (0x0000).
    WriteSingleCoil {
        /// Coil address.
        address: u16,
        /// On or off.
        value: bool,
    },
    /// 0x0F: set consecutive coils.
    WriteMultipleCoils {
        /// First coil address.
        address: u16,
        /// Values, 1..=1968 of them.
        values: Vec<bool>,
    },
    /// 0x16: register = (register AND `and_mask`) OR (`or_mask` AND NOT `and_mask`).
    MaskWriteRegister {
        /// Register address.
        address: u16,
        /// The bits kept.
        and_mask: u16,
        /// The bits set among those not kept.
        or_mask: u16,
    },
    /// 0x17: write `values` from `write_address`, then read `read_count` registers from
    /// `read_address`, in one transaction.
    ReadWriteRegisters {
        /// First register read.
        read_address: u16,
        /// Number of registers read, 1..=125.
        read_count: u16,
        /// First register written.
        write_address: u16,
        /// Values written, 1..=121 of them.
        values: Vec<u16>,
    },
    /// 0x07: read the device's eight exception status outputs.
    ReadExceptionStatus,
    /// 0x08: a diagnostics sub-function and its data. The reply has the request's length
    /// (spec 6.8: every sub-function answers its sub-function code and as many data bytes);
    /// sub-function 0x04 (force listen only) is not answered.
    Diagnostics {
        /// Sub-function code.
        sub_function: u16,
        /// Data after the sub-function, at most 250 bytes.
        data: Vec<u8>,
    },
    /// 0x11: report server id.
    ReportServerId,
    /// 0x0B: the device's status word and event counter.
    GetCommEventCounter,
    /// 0x0C: the device's status word, event and message counters and its event log.
    GetCommEventLog,
    /// 0x14: read records from files, one group per `(file, record, length)`: `length`
    /// registers (1 or more) from record `record` (0..=0x270F) of file `file` (1..=0xFFFF).
    ReadFileRecord {
        /// The groups, one or more; the request and its reply fit a PDU.
        groups: Vec<(u16, u16, u16)>,
    },
    /// 0x15: write records to files, one group per `(file, record, values)`; the reply
    /// echoes the request.
    WriteFileRecord {
        /// The groups, one or more, each with one value or more; the request fits a PDU.
        groups: Vec<(u16, u16, Vec<u16>)>,
    },
    /// 0x18: the values queued in the FIFO whose count register is at `address`.
    ReadFifoQueue {
        /// FIFO pointer address (the count register).
        address: u16,
    },
    /// Any function code 1..=127 with its data as given: vendor functions, file records.
    Raw {
        /// Function code, 1..=127.
        function: u8,
        /// Bytes after the function code, at most 252.
        data: Vec<u8>,
        /// Bytes the reply carries after its function code, if known; None: the reply
        /// ends when the line falls quiet ([`super::Needed::Silence`]).
        reply_length: Option<usize>,
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
    /// A function code that is not a request's: 0, or 0x80 and up (an exception reply's).
    #[error(
        "function must be 1 to 127 (0x01 to 0x7F; 0x80 and up are exception replies), got {0}"
    )]
    Function(u8),
    /// A file record group outside the spec's ranges (file 1..=0xFFFF, record
    /// 0..=0x270F, at least one register, none past record 0x270F), or no group.
    #[error("{0}")]
    FileRecord(String),
    /// Request bytes of a form the function does not have: a length or byte count it does
    /// not take, a coil value other than on or off ([`decode::decode`]).
    #[error("{0}")]
    Form(String),
    /// More data than a PDU holds.
    #[error("{what} must be at most {max} bytes, got {len}")]
    DataLength {
        /// Which bytes: the request's data, or the reply's.
        what: &'static str,
        /// Their length.
        len: usize,
        /// The most the PDU holds.
        max: usize,
    },
}

/// What a request does to the device ([`Request`]'s table of kinds).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// It only reads: [`Request::is_read`].
    Read,
    /// It writes, and its reply only echoes it: [`Request::is_echoed_write`].
    EchoedWrite,
    /// Another: a write and a read (0x17), a write whose reply says more (0x15), a raw
    /// request (which may write).
    Other,
}

impl Request {
    /// The function code of this request and what it does to the device: a row a request.
    fn kind(&self) -> (u8, Kind) {
        use Kind::{EchoedWrite, Other, Read};
        match self {
            Request::ReadHoldingRegisters { .. } => (READ_HOLDING_REGISTERS, Read),
            Request::WriteSingleRegister { .. } => (WRITE_SINGLE_REGISTER, EchoedWrite),
            Request::WriteMultipleRegisters { .. } => (WRITE_MULTIPLE_REGISTERS, EchoedWrite),
            Request::ReadDeviceIdentification { .. } => (ENCAPSULATED_INTERFACE, Read),
            Request::ReadCoils { .. } => (READ_COILS, Read),
            Request::ReadDiscreteInputs { .. } => (READ_DISCRETE_INPUTS, Read),
            Request::ReadInputRegisters { .. } => (READ_INPUT_REGISTERS, Read),
            Request::WriteSingleCoil { .. } => (WRITE_SINGLE_COIL, EchoedWrite),
            Request::WriteMultipleCoils { .. } => (WRITE_MULTIPLE_COILS, EchoedWrite),
            Request::MaskWriteRegister { .. } => (MASK_WRITE_REGISTER, EchoedWrite),
            Request::ReadWriteRegisters { .. } => (READ_WRITE_REGISTERS, Other),
            Request::ReadExceptionStatus => (READ_EXCEPTION_STATUS, Read),
            Request::Diagnostics { .. } => (DIAGNOSTICS, Read),
            Request::ReportServerId => (REPORT_SERVER_ID, Read),
            Request::GetCommEventCounter => (GET_COMM_EVENT_COUNTER, Read),
            Request::GetCommEventLog => (GET_COMM_EVENT_LOG, Read),
            Request::ReadFileRecord { .. } => (READ_FILE_RECORD, Read),
            Request::WriteFileRecord { .. } => (WRITE_FILE_RECORD, Other),
            Request::ReadFifoQueue { .. } => (READ_FIFO_QUEUE, Read),
            Request::Raw { function, .. } => (*function, Other),
        }
    }

    /// The function code of this request.
    pub fn function(&self) -> u8 {
        self.kind().0
    }

    /// Whether the device answers this request: all but diagnostics sub-function 0x04
    /// (force listen only), which is sent once and not awaited.
    pub fn is_answered(&self) -> bool {
        !matches!(
            self,
            Request::Diagnostics {
                sub_function: DIAG_FORCE_LISTEN_ONLY,
                ..
            }
        )
    }

    /// Whether this request only reads (nothing in the device changes): reads are never
    /// paced as writes. A raw request may write, so it is not one.
    pub fn is_read(&self) -> bool {
        self.kind().1 == Kind::Read
    }

    /// Whether this is a write whose reply only echoes it (0x05, 0x06, 0x0F, 0x10, 0x16):
    /// what may be broadcast, and what a device set to answer no write leaves unanswered.
    pub fn is_echoed_write(&self) -> bool {
        self.kind().1 == Kind::EchoedWrite
    }

    /// The byte count a read reply must carry (0x01, 0x02, 0x03, 0x04, 0x17, and 0x14: a
    /// length and reference type, then the registers, for each group), known from the
    /// request.
    pub fn reply_byte_count(&self) -> Option<usize> {
        match self {
            Request::ReadHoldingRegisters { count, .. }
            | Request::ReadInputRegisters { count, .. }
            | Request::ReadWriteRegisters {
                read_count: count, ..
            } => Some(2 * usize::from(*count)),
            Request::ReadCoils { count, .. } | Request::ReadDiscreteInputs { count, .. } => {
                Some(usize::from(*count).div_ceil(8))
            }
            Request::ReadFileRecord { groups } => Some(
                groups
                    .iter()
                    .map(|&(_, _, length)| 2 + 2 * usize::from(length))
                    .sum(),
            ),
            _ => None,
        }
    }

    /// The reply that a write taken as done without an answer is deemed to have got (a
    /// device set to answer no write, force listen only): its echo.
    pub fn assumed_reply(&self) -> Response {
        match self {
            Request::WriteSingleRegister { address, value } => Response::WriteSingleRegister {
                address: *address,
                value: *value,
            },
            Request::WriteMultipleRegisters { address, values } => {
                Response::WriteMultipleRegisters {
                    address: *address,
                    count: count_of(values.len()),
                }
            }
            Request::WriteSingleCoil { address, value } => Response::WriteSingleCoil {
                address: *address,
                value: coil_word(*value),
            },
            Request::WriteMultipleCoils { address, values } => Response::WriteMultipleCoils {
                address: *address,
                count: count_of(values.len()),
            },
            Request::MaskWriteRegister {
                address,
                and_mask,
                or_mask,
            } => Response::MaskWriteRegister {
                address: *address,
                and_mask: *and_mask,
                or_mask: *or_mask,
            },
            Request::Diagnostics { sub_function, .. } => Response::Diagnostics {
                sub_function: *sub_function,
                data: Vec::new(),
            },
            _ => Response::Raw(Vec::new()),
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
            Request::ReadCoils { address, count }
            | Request::ReadDiscreteInputs { address, count } => {
                span(*address, usize::from(*count), MAX_READ_BITS)
            }
            Request::ReadInputRegisters { address, count } => {
                span(*address, usize::from(*count), MAX_READ_COUNT)
            }
            Request::WriteSingleCoil { .. }
            | Request::MaskWriteRegister { .. }
            | Request::ReadExceptionStatus
            | Request::ReportServerId
            | Request::GetCommEventCounter
            | Request::GetCommEventLog
            | Request::ReadFifoQueue { .. } => Ok(()),
            Request::ReadFileRecord { groups } => {
                if groups.is_empty() {
                    return Err(no_group());
                }
                for &(file, record, length) in groups {
                    file_group(file, record, usize::from(length))?;
                }
                // function, byte count, then 7 bytes a group.
                data_within(
                    "read file record request",
                    1 + 7 * groups.len(),
                    MAX_PDU_DATA,
                )?;
                let reply = 1 + self.reply_byte_count().unwrap_or(0);
                data_within("read file record reply", reply, MAX_PDU_DATA)
            }
            Request::WriteFileRecord { groups } => {
                if groups.is_empty() {
                    return Err(no_group());
                }
                for (file, record, values) in groups {
                    file_group(*file, *record, values.len())?;
                }
                data_within(
                    "write file record request",
                    1 + file_groups_len(groups),
                    MAX_PDU_DATA,
                )
            }
            Request::WriteMultipleCoils { address, values } => {
                span(*address, values.len(), MAX_WRITE_BITS)
            }
            Request::ReadWriteRegisters {
                read_address,
                read_count,
                write_address,
                values,
            } => {
                span(*read_address, usize::from(*read_count), MAX_READ_COUNT)?;
                span(*write_address, values.len(), MAX_READ_WRITE_COUNT)
            }
            Request::Diagnostics { data, .. } => {
                data_within("diagnostics data", data.len(), MAX_PDU_DATA - 2)
            }
            Request::Raw {
                function,
                data,
                reply_length,
            } => {
                if !(1..0x80).contains(function) {
                    return Err(RequestError::Function(*function));
                }
                data_within("data", data.len(), MAX_PDU_DATA)?;
                data_within("reply_length", reply_length.unwrap_or(0), MAX_PDU_DATA)
            }
        }
    }

    /// Appends the PDU (function code and data) to `out`. Call [`Request::validate`] first:
    /// an invalid request encodes a frame the device will refuse.
    pub fn encode(&self, out: &mut Vec<u8>) {
        out.push(self.function());
        match self {
            Request::ReadHoldingRegisters { address, count }
            | Request::ReadCoils { address, count }
            | Request::ReadDiscreteInputs { address, count }
            | Request::ReadInputRegisters { address, count } => {
                words(out, &[*address, *count]);
            }
            Request::WriteSingleRegister { address, value } => words(out, &[*address, *value]),
            Request::WriteMultipleRegisters { address, values } => {
                written_registers(out, &[*address], values, MAX_WRITE_COUNT);
            }
            Request::ReadDeviceIdentification {
                read_code,
                object_id,
            } => {
                out.extend_from_slice(&[MEI_READ_DEVICE_ID, *read_code, *object_id]);
            }
            Request::WriteSingleCoil { address, value } => {
                words(out, &[*address, coil_word(*value)]);
            }
            Request::WriteMultipleCoils { address, values } => {
                // validate() bounds the count to 1968, so the byte count fits a byte.
                let values = &values[..values.len().min(usize::from(MAX_WRITE_BITS))];
                words(out, &[*address, count_of(values.len())]);
                let packed = pack_bits(values);
                out.push(packed.len() as u8);
                out.extend_from_slice(&packed);
            }
            Request::MaskWriteRegister {
                address,
                and_mask,
                or_mask,
            } => words(out, &[*address, *and_mask, *or_mask]),
            Request::ReadWriteRegisters {
                read_address,
                read_count,
                write_address,
                values,
            } => {
                let head = [*read_address, *read_count, *write_address];
                written_registers(out, &head, values, MAX_READ_WRITE_COUNT);
            }
            Request::ReadExceptionStatus
            | Request::ReportServerId
            | Request::GetCommEventCounter
            | Request::GetCommEventLog => {}
            Request::ReadFileRecord { groups } => {
                // validate() bounds the groups to 35, so the byte count fits a byte.
                out.push(u8::try_from(7 * groups.len()).unwrap_or(u8::MAX));
                for &(file, record, length) in groups {
                    out.push(FILE_REFERENCE_TYPE);
                    words(out, &[file, record, length]);
                }
            }
            Request::WriteFileRecord { groups } => {
                // validate() bounds the request to a PDU, so the byte count fits a byte.
                out.push(u8::try_from(file_groups_len(groups)).unwrap_or(u8::MAX));
                for (file, record, values) in groups {
                    out.push(FILE_REFERENCE_TYPE);
                    words(out, &[*file, *record, count_of(values.len())]);
                    words(out, values);
                }
            }
            Request::ReadFifoQueue { address } => words(out, &[*address]),
            Request::Diagnostics { sub_function, data } => {
                words(out, &[*sub_function]);
                out.extend_from_slice(data);
            }
            Request::Raw { data, .. } => out.extend_from_slice(data),
        }
    }

    /// `unit | PDU`: the request to `unit` (0: broadcast) as every framing carries it, RTU
    /// with a CRC after it, Modbus ASCII as hex characters, Modbus TCP behind an MBAP header.
    pub fn unit_pdu(&self, unit: u8) -> Vec<u8> {
        let mut out = Vec::with_capacity(16);
        out.push(unit);
        self.encode(&mut out);
        out
    }
}

/// Appends `values` big-endian, as every Modbus field of two bytes goes.
fn words(out: &mut Vec<u8>, values: &[u16]) {
    for v in values {
        out.extend_from_slice(&v.to_be_bytes());
    }
}

/// Appends `head`, then the registers a 0x10 or 0x17 request writes: their count, their
/// byte count and `values`, at most `max` of them (validate() bounds them to that, so the
/// byte count fits a byte).
fn written_registers(out: &mut Vec<u8>, head: &[u16], values: &[u16], max: u16) {
    let values = &values[..values.len().min(usize::from(max))];
    let count = count_of(values.len());
    words(out, head);
    words(out, &[count]);
    out.push((count * 2) as u8);
    words(out, values);
}

/// Bytes the groups of a 0x15 request take after its byte count: reference type, file,
/// record and length (7), then the values, for each.
fn file_groups_len(groups: &[(u16, u16, Vec<u16>)]) -> usize {
    groups.iter().map(|(_, _, v)| 7 + 2 * v.len()).sum()
}

fn no_group() -> RequestError {
    RequestError::FileRecord("at least one file record group is needed".into())
}

/// Checks one file record group: file 1..=0xFFFF, record 0..=0x270F, 1 register or more,
/// none past record 0x270F (spec 6.14, 6.15).
fn file_group(file: u16, record: u16, length: usize) -> Result<(), RequestError> {
    let bad = |why: String| Err(RequestError::FileRecord(why));
    if file == 0 {
        return bad("file must be 1 to 65535 (0x0001 to 0xFFFF), got 0".into());
    }
    if record > MAX_FILE_RECORD {
        return bad(format!(
            "record must be 0 to 9999 (0x0000 to 0x270F), got {record}"
        ));
    }
    if length == 0 {
        return bad(format!(
            "file {file} record {record}: length must be at least 1"
        ));
    }
    if usize::from(record) + length > usize::from(MAX_FILE_RECORD) + 1 {
        return bad(format!(
            "file {file}: {length} registers from record {record} run past record 9999"
        ));
    }
    Ok(())
}

/// A length already bounded by validate() as a u16 count.
fn count_of(len: usize) -> u16 {
    u16::try_from(len).unwrap_or(u16::MAX)
}

/// The value field of a 0x05 request: 0xFF00 on, 0x0000 off (spec 6.5).
pub fn coil_word(on: bool) -> u16 {
    if on {
        0xFF00
    } else {
        0x0000
    }
}

/// Bits packed eight to a byte, the first in the lowest bit of the first byte, the last
/// byte padded with zeros (spec 6.1, 6.11).
pub fn pack_bits(bits: &[bool]) -> Vec<u8> {
    bits.chunks(8)
        .map(|c| {
            c.iter()
                .enumerate()
                .fold(0u8, |byte, (i, &on)| byte | (u8::from(on) << i))
        })
        .collect()
}

/// The first `count` bits of `bytes`, unpacked as [`pack_bits`] packs them.
pub fn unpack_bits(bytes: &[u8], count: usize) -> Vec<bool> {
    (0..count)
        .map(|i| bytes.get(i / 8).is_some_and(|b| b >> (i % 8) & 1 == 1))
        .collect()
}

/// `len` bytes of `what`, refused past `max`.
fn data_within(what: &'static str, len: usize, max: usize) -> Result<(), RequestError> {
    if len > max {
        return Err(RequestError::DataLength { what, len, max });
    }
    Ok(())
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
    /// 0x01 / 0x02: the coils or inputs read, as many as the request asked for.
    Bits(Vec<bool>),
    /// 0x05: the address and value field the device sent back (0xFF00 on, 0x0000 off).
    WriteSingleCoil {
        /// Address carried in the reply.
        address: u16,
        /// Value field carried in the reply.
        value: u16,
    },
    /// 0x0F: the address and count the device sent back.
    WriteMultipleCoils {
        /// Address carried in the reply.
        address: u16,
        /// Count carried in the reply.
        count: u16,
    },
    /// 0x16: the address and masks the device sent back.
    MaskWriteRegister {
        /// Address carried in the reply.
        address: u16,
        /// AND mask carried in the reply.
        and_mask: u16,
        /// OR mask carried in the reply.
        or_mask: u16,
    },
    /// 0x07: the eight exception status outputs.
    ExceptionStatus(u8),
    /// 0x08: the sub-function and data the device sent back.
    Diagnostics {
        /// Sub-function carried in the reply.
        sub_function: u16,
        /// Data after the sub-function.
        data: Vec<u8>,
    },
    /// 0x11: the data field after the byte count, as the device sent it (server id, run
    /// indicator and whatever else the device puts there).
    ServerId(Vec<u8>),
    /// 0x0B: the status word (0xFFFF busy, 0x0000 not) and the event counter.
    CommEventCounter {
        /// Status word.
        status: u16,
        /// Event counter.
        event_count: u16,
    },
    /// 0x0C: the status word, the counters and the events (newest first).
    CommEventLog {
        /// Status word.
        status: u16,
        /// Event counter.
        event_count: u16,
        /// Message counter.
        message_count: u16,
        /// The events, one byte each, 0 to 64 of them.
        events: Vec<u8>,
    },
    /// 0x14: the registers read, one list per group of the request.
    FileRecords(Vec<Vec<u16>>),
    /// 0x15: the data the device sent back after the function code (the request's, if it
    /// echoed it).
    FileRecordEcho(Vec<u8>),
    /// 0x18: the values queued, oldest first, at most 31.
    FifoQueue(Vec<u16>),
    /// A raw request's reply: the bytes after the function code.
    Raw(Vec<u8>),
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
