//! The RTU application data unit: `unit | PDU | CRC-16 (low byte first)`, and the
//! incremental reply decoder that tells the caller how many more bytes a reply needs.
//!
//! Modbus over Serial Line V1.02, 2.5.1 (RTU frame: at most 256 bytes) and 6.2.2 (CRC-16,
//! polynomial 0xA001 reflected, initial value 0xFFFF, low byte sent first).

use super::pdu::{
    coil_word, unpack_bits, DeviceIdentification, Request, Response, DIAG_RETURN_QUERY_DATA,
    FILE_REFERENCE_TYPE, MAX_COMM_EVENTS, MAX_FIFO_COUNT, MEI_READ_DEVICE_ID,
};
use super::Framing;
use crate::error::hex;
use crc::{Crc, CRC_16_MODBUS};

/// Longest RTU frame (serial line spec 2.5.1).
pub const MAX_ADU: usize = 256;
/// Length of the CRC that ends an RTU frame.
pub const CRC_LEN: usize = 2;
/// Longest unit + PDU: the longest RTU frame but its CRC, also the most an MBAP header's
/// length counts.
pub const MAX_UNIT_PDU: usize = MAX_ADU - CRC_LEN;
/// Length of an exception reply: unit, function | 0x80, code, CRC (2).
pub const EXCEPTION_LEN: usize = 5;
/// Unit address that every device accepts and none answers (serial line spec 2.2).
pub const BROADCAST: u8 = 0;

const CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_MODBUS);

/// CRC-16/MODBUS of `data`.
pub fn crc16(data: &[u8]) -> u16 {
    CRC16.checksum(data)
}

/// The whole RTU frame for `request` to `unit`, CRC appended low byte first.
pub fn encode_request(unit: u8, request: &Request) -> Vec<u8> {
    encode_in(Framing::Rtu, unit, request)
}

/// `unit | PDU` of `request`, then the framing's trailer (the CRC in RTU).
pub(super) fn encode_in(framing: Framing, unit: u8, request: &Request) -> Vec<u8> {
    let mut out = Vec::with_capacity(16);
    out.push(unit);
    request.encode(&mut out);
    if framing == Framing::Rtu {
        let crc = crc16(&out);
        out.extend_from_slice(&crc.to_le_bytes());
    }
    out
}

/// What the incremental decoder knows about a reply from the bytes received so far.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Needed {
    /// At least this many more bytes are needed; reading exactly this many never reads past
    /// the end of the reply.
    More(usize),
    /// The reply is complete and is this many bytes long (the buffer may hold more).
    Complete(usize),
    /// These bytes cannot begin a reply to the request (another function code, a byte count
    /// the request does not call for, or a length past the longest RTU frame): the length is
    /// unknown; read until the line is silent.
    Unknown,
    /// A reply whose length its bytes do not tell (a raw request's, without a reply
    /// length): it ends when the line has been quiet for the silence gap, and is then
    /// decoded.
    Silence,
}

/// How many more bytes a reply to `request` needs, given the bytes `buf` received so far.
///
/// An exception reply is known after two bytes (5 bytes long), for every function; a read
/// reply (0x01..0x04, 0x17) after three (its byte count, which must be the request's), as a
/// Report Server ID reply (0x11, any byte count); 0x05, 0x06, 0x0F and 0x10 replies are 8
/// bytes, 0x16 10, 0x07 5, 0x0B 8, a Diagnostics reply (0x08) and a Write File Record
/// reply (0x15) the request's length; a Read File Record reply (0x14) by its byte count,
/// which must be the request's, a Get Comm Event Log reply (0x0C) by its byte count and a
/// Read FIFO Queue reply (0x18) by its two-byte byte count; a Read Device
/// Identification reply is walked object by object; a raw request's reply is its
/// `reply_length` after the function code, or read until the line is silent.
pub fn reply_needed(request: &Request, buf: &[u8]) -> Needed {
    needed_in(CRC_LEN, request, buf)
}

/// [`reply_needed`] for `unit | PDU` with no trailer: the reply inside an ASCII frame or an
/// MBAP frame.
pub(super) fn unit_pdu_needed(request: &Request, buf: &[u8]) -> Needed {
    needed_in(0, request, buf)
}

/// [`reply_needed`] for `unit | PDU` followed by `trailer` bytes (the CRC's 2, or none).
fn needed_in(trailer: usize, request: &Request, buf: &[u8]) -> Needed {
    // unit, function | 0x80, code.
    let exception = 3 + trailer;
    if buf.len() < 2 {
        return Needed::More(exception - buf.len());
    }
    let function = request.function();
    let unit_pdu = if buf[1] == function | 0x80 {
        if !matches!(request, Request::ReadDeviceIdentification { .. }) {
            3
        } else {
            match buf.get(2) {
                None => return Needed::More(exception - buf.len()),
                // ATV31 style: unit, 0xAB, MEI type 0x0E, error code.
                Some(&MEI_READ_DEVICE_ID) => 4,
                Some(_) => 3,
            }
        }
    } else if buf[1] != function {
        return Needed::Unknown;
    } else {
        match request {
            Request::ReadHoldingRegisters { .. }
            | Request::ReadInputRegisters { .. }
            | Request::ReadCoils { .. }
            | Request::ReadDiscreteInputs { .. }
            | Request::ReadWriteRegisters { .. }
            | Request::ReadFileRecord { .. }
            | Request::GetCommEventLog
            | Request::ReportServerId => match buf.get(2) {
                None => return Needed::More(exception - buf.len()),
                // Not the length this request's reply has: see `check_header`.
                Some(&n)
                    if request
                        .reply_byte_count()
                        .is_some_and(|b| b != usize::from(n)) =>
                {
                    return Needed::Unknown
                }
                Some(&n) => 3 + usize::from(n),
            },
            Request::WriteSingleRegister { .. }
            | Request::WriteMultipleRegisters { .. }
            | Request::WriteSingleCoil { .. }
            | Request::WriteMultipleCoils { .. } => 6,
            Request::MaskWriteRegister { .. } => 8,
            Request::ReadExceptionStatus => 3,
            Request::GetCommEventCounter => 6,
            // The echo: byte count and groups, as sent.
            Request::WriteFileRecord { .. } => {
                let mut pdu = Vec::new();
                request.encode(&mut pdu);
                1 + pdu.len()
            }
            // A byte count of two bytes, then the FIFO count and the values.
            Request::ReadFifoQueue { .. } => match buf.get(2..4) {
                Some(&[hi, lo]) => 4 + usize::from(u16::from_be_bytes([hi, lo])),
                _ => return Needed::More(4 + trailer - buf.len()),
            },
            Request::Diagnostics { data, .. } => 4 + data.len(),
            Request::Raw {
                reply_length: Some(n),
                ..
            } => 2 + n,
            Request::Raw {
                reply_length: None, ..
            } => return Needed::Silence,
            Request::ReadDeviceIdentification { .. } => match device_id_len(buf) {
                Ok(unit_pdu) => unit_pdu,
                Err(Some(more)) => return Needed::More(more),
                Err(None) => return Needed::Unknown,
            },
        }
    };
    let total = unit_pdu + trailer;
    if unit_pdu > MAX_UNIT_PDU {
        Needed::Unknown
    } else if buf.len() >= total {
        Needed::Complete(total)
    } else {
        Needed::More(total - buf.len())
    }
}

/// Length of a Read Device Identification reply's unit + PDU, or how many more bytes are
/// needed to know it (`Err(Some(n))`), or `Err(None)` if the header is not MEI 0x0E.
fn device_id_len(buf: &[u8]) -> Result<usize, Option<usize>> {
    // unit, 0x2B, 0x0E, read code, conformity, more follows, next object, object count
    const HEADER: usize = 8;
    if let Some(&mei) = buf.get(2) {
        if mei != MEI_READ_DEVICE_ID {
            return Err(None);
        }
    }
    if buf.len() < HEADER {
        return Err(Some(HEADER - buf.len()));
    }
    let mut pos = HEADER;
    for _ in 0..buf[7] {
        match buf.get(pos + 1) {
            None => return Err(Some(pos + 2 - buf.len())),
            Some(&len) => pos += 2 + usize::from(len),
        }
        if pos > MAX_UNIT_PDU {
            return Err(None);
        }
    }
    Ok(pos)
}

/// A decoded reply: a normal response, or the device's exception response (which is data,
/// not a transport failure).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Reply {
    /// A normal response.
    Normal(Response),
    /// An exception response: the request's function and the exception code.
    Exception {
        /// The request's function code (without the 0x80 bit).
        function: u8,
        /// The exception code.
        code: u8,
    },
}

/// Why a reply frame was rejected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// Fewer bytes than the shortest reply.
    #[error("reply too short ({0} bytes)")]
    TooShort(usize),
    /// The CRC does not match the frame's contents.
    #[error("CRC mismatch: computed {computed:#06x}, received {received:#06x}")]
    Crc {
        /// CRC computed over the frame.
        computed: u16,
        /// CRC carried by the frame.
        received: u16,
    },
    /// The reply came from another unit.
    #[error("reply from unit {received}, expected {expected}")]
    WrongUnit {
        /// Unit asked.
        expected: u8,
        /// Unit in the reply.
        received: u8,
    },
    /// The reply carries another function code.
    #[error("reply function {received:#04x}, expected {expected:#04x}")]
    WrongFunction {
        /// Function asked.
        expected: u8,
        /// Function in the reply.
        received: u8,
    },
    /// The reply's byte count or length does not fit the request.
    #[error("reply length wrong: {0}")]
    Length(String),
    /// The byte count of a read reply from the addressed unit disagrees with the count the
    /// request asked for (known from the reply's third byte, before the rest arrives).
    #[error("reply byte count {received}, but the request asked for {expected} bytes")]
    ByteCount {
        /// Data bytes the request's count calls for.
        expected: usize,
        /// Byte count the reply carries.
        received: u8,
    },
    /// A write reply does not echo the request.
    #[error("write not echoed: sent {sent}, reply carries {received}")]
    Echo {
        /// What the request carried (address, value or count).
        sent: String,
        /// What the reply carried.
        received: String,
    },
    /// The adapter's local echo of the request (a Bus opened with `echo`) is wrong from
    /// byte `at` on, or broke off there: another talker on the line (a collision), or
    /// noise.
    #[error(
        "local echo of the request is wrong from byte {at} of {len} (a collision on the \
         line, or noise)"
    )]
    LocalEcho {
        /// Index of the first byte missing or different.
        at: usize,
        /// Length of the request.
        len: usize,
    },
    /// What came back begins with the request itself: the adapter echoes what it sends, and
    /// the Bus was not told so.
    #[error(
        "the reply begins with the request itself: an adapter that echoes what it sends? \
         then open the Bus with echo=True"
    )]
    UnexpectedEcho,
    /// A frame of the addressed unit came sooner after the request than the unit answers
    /// (a copy of an earlier reply, or an earlier request's answer come late), was dropped,
    /// and no other followed within the attempt.
    #[error(
        "a reply came {after:?} after the request began, sooner than this unit answers \
         ({usual:?} lately): a copy of an earlier reply or an earlier request's answer, not \
         taken, and no other reply followed"
    )]
    TooSoon {
        /// When the frame began to arrive, from the start of the request.
        after: std::time::Duration,
        /// The unit's least time lately, from the start of a request to its reply.
        usual: std::time::Duration,
    },
    /// A Modbus ASCII frame is malformed: a character, its length or its LRC.
    #[error(transparent)]
    Ascii(#[from] super::ascii::AsciiError),
}

/// What the first bytes of a reply from `unit` to `request` already show to be wrong: a
/// read reply whose byte count disagrees with the request ([`FrameError::ByteCount`]). Its
/// length is then unknown ([`reply_needed`] says [`Needed::Unknown`]), so the caller takes
/// the rest until the line is quiet and reports this, not the CRC of a length it cannot
/// trust. Bytes from another unit, or too few to tell, are not judged here.
///
/// # Errors
/// [`FrameError::ByteCount`] naming both counts.
pub fn check_header(unit: u8, request: &Request, buf: &[u8]) -> Result<(), FrameError> {
    match (request.reply_byte_count(), buf) {
        (Some(expected), &[u, f, n, ..])
            if u == unit && f == request.function() && usize::from(n) != expected =>
        {
            Err(FrameError::ByteCount {
                expected,
                received: n,
            })
        }
        _ => Ok(()),
    }
}

/// Decodes a complete reply `frame` to `request` sent to `unit`.
///
/// Checks, in order: the header ([`check_header`]: a byte count that disagrees with the
/// request), CRC, unit, function, then the length. The echo of a write is checked
/// separately by [`check_echo`], so a caller may relax it.
///
/// # Errors
/// [`FrameError`] saying what is wrong with the frame.
pub fn decode_reply(unit: u8, request: &Request, frame: &[u8]) -> Result<Reply, FrameError> {
    decode_in(true, unit, request, frame)
}

/// [`decode_reply`] for `unit | PDU` with no CRC: the reply inside an ASCII frame (its LRC
/// checked already) or an MBAP frame (TCP checks the bytes).
pub(super) fn decode_unit_pdu(
    unit: u8,
    request: &Request,
    frame: &[u8],
) -> Result<Reply, FrameError> {
    decode_in(false, unit, request, frame)
}

/// [`decode_reply`] for `unit | PDU`, followed by its CRC if `crc`.
fn decode_in(crc: bool, unit: u8, request: &Request, frame: &[u8]) -> Result<Reply, FrameError> {
    let trailer = if crc { CRC_LEN } else { 0 };
    if frame.len() < 3 + trailer {
        return Err(FrameError::TooShort(frame.len()));
    }
    check_header(unit, request, frame)?;
    let body = if crc {
        let (body, crc) = frame.split_at(frame.len() - CRC_LEN);
        let received = u16::from_le_bytes([crc[0], crc[1]]);
        let computed = crc16(body);
        if computed != received {
            return Err(FrameError::Crc { computed, received });
        }
        body
    } else {
        frame
    };
    if body[0] != unit {
        return Err(FrameError::WrongUnit {
            expected: unit,
            received: body[0],
        });
    }
    let function = request.function();
    if body[1] == function | 0x80 {
        let mei_form = matches!(request, Request::ReadDeviceIdentification { .. })
            && body.len() == 4
            && body[2] == MEI_READ_DEVICE_ID;
        if mei_form {
            // ATV31 style: the MEI type before the code (00 none, 01 bad request code, MEI
            // type or read code, 02 bad object id).
            return Ok(Reply::Exception {
                function,
                code: body[3],
            });
        }
        if body.len() != 3 {
            return Err(FrameError::Length(format!(
                "exception reply of {} bytes",
                frame.len()
            )));
        }
        return Ok(Reply::Exception {
            function,
            code: body[2],
        });
    }
    if body[1] != function {
        return Err(FrameError::WrongFunction {
            expected: function,
            received: body[1],
        });
    }
    let data = &body[2..];
    let response = match request {
        Request::ReadHoldingRegisters { .. }
        | Request::ReadInputRegisters { .. }
        | Request::ReadWriteRegisters { .. } => {
            Response::Registers(counted(data, request.reply_byte_count())?.collect_words())
        }
        Request::ReadCoils { count, .. } | Request::ReadDiscreteInputs { count, .. } => {
            let bytes = counted(data, request.reply_byte_count())?;
            Response::Bits(unpack_bits(bytes.0, usize::from(*count)))
        }
        Request::ReportServerId => Response::ServerId(counted(data, None)?.0.to_vec()),
        Request::GetCommEventCounter => {
            let [status, event_count] = fixed_words(data)?;
            Response::CommEventCounter {
                status,
                event_count,
            }
        }
        Request::GetCommEventLog => decode_event_log(counted(data, None)?.0)?,
        Request::ReadFileRecord { groups } => {
            let bytes = counted(data, request.reply_byte_count())?;
            Response::FileRecords(decode_file_records(bytes.0, groups)?)
        }
        Request::WriteFileRecord { .. } => Response::FileRecordEcho(data.to_vec()),
        Request::ReadFifoQueue { .. } => Response::FifoQueue(decode_fifo(data)?),
        Request::WriteSingleRegister { .. } => {
            let [address, value] = fixed_words(data)?;
            Response::WriteSingleRegister { address, value }
        }
        Request::WriteMultipleRegisters { .. } => {
            let [address, count] = fixed_words(data)?;
            Response::WriteMultipleRegisters { address, count }
        }
        Request::WriteSingleCoil { .. } => {
            let [address, value] = fixed_words(data)?;
            Response::WriteSingleCoil { address, value }
        }
        Request::WriteMultipleCoils { .. } => {
            let [address, count] = fixed_words(data)?;
            Response::WriteMultipleCoils { address, count }
        }
        Request::MaskWriteRegister { .. } => {
            let [address, and_mask, or_mask] = fixed_words(data)?;
            Response::MaskWriteRegister {
                address,
                and_mask,
                or_mask,
            }
        }
        Request::ReadExceptionStatus => match data {
            &[status] => Response::ExceptionStatus(status),
            _ => return Err(data_length(data.len(), 1)),
        },
        Request::Diagnostics { data: sent, .. } => match data {
            [hi, lo, rest @ ..] if rest.len() == sent.len() => Response::Diagnostics {
                sub_function: u16::from_be_bytes([*hi, *lo]),
                data: rest.to_vec(),
            },
            _ => return Err(data_length(data.len(), 2 + sent.len())),
        },
        Request::Raw { reply_length, .. } => match reply_length {
            Some(n) if data.len() != *n => return Err(data_length(data.len(), *n)),
            _ => Response::Raw(data.to_vec()),
        },
        Request::ReadDeviceIdentification { .. } => {
            Response::DeviceIdentification(decode_device_id(data)?)
        }
    };
    Ok(Reply::Normal(response))
}

/// The data bytes of a reply that begins with a byte count: after it, exactly that many
/// (and as many as `expected`, when the request fixes it).
struct Counted<'a>(&'a [u8]);

impl Counted<'_> {
    /// The bytes as big-endian registers.
    fn collect_words(&self) -> Vec<u16> {
        self.0
            .chunks_exact(2)
            .map(|c| u16::from_be_bytes([c[0], c[1]]))
            .collect()
    }
}

fn counted(data: &[u8], expected: Option<usize>) -> Result<Counted<'_>, FrameError> {
    match data.split_first() {
        Some((&n, rest))
            if rest.len() == usize::from(n) && expected.is_none_or(|e| e == rest.len()) =>
        {
            Ok(Counted(rest))
        }
        _ => Err(FrameError::Length(format!(
            "byte count {} with {} data bytes",
            data.first().copied().unwrap_or_default(),
            data.len().saturating_sub(1)
        ))),
    }
}

/// The data of a reply made of `N` two-byte fields (an echo of a write).
fn fixed_words<const N: usize>(data: &[u8]) -> Result<[u16; N], FrameError> {
    if data.len() != 2 * N {
        return Err(data_length(data.len(), 2 * N));
    }
    Ok(std::array::from_fn(|i| {
        u16::from_be_bytes([data[2 * i], data[2 * i + 1]])
    }))
}

fn data_length(got: usize, expected: usize) -> FrameError {
    FrameError::Length(format!("{got} data bytes, expected {expected}"))
}

/// The data of a Get Comm Event Log reply after its byte count: status, event count and
/// message count (2 bytes each), then 0 to 64 events (spec 6.10).
fn decode_event_log(data: &[u8]) -> Result<Response, FrameError> {
    match data {
        [s0, s1, e0, e1, m0, m1, events @ ..] if events.len() <= MAX_COMM_EVENTS => {
            Ok(Response::CommEventLog {
                status: u16::from_be_bytes([*s0, *s1]),
                event_count: u16::from_be_bytes([*e0, *e1]),
                message_count: u16::from_be_bytes([*m0, *m1]),
                events: events.to_vec(),
            })
        }
        _ => Err(FrameError::Length(format!(
            "comm event log of {} bytes: 6 to {} expected",
            data.len(),
            6 + MAX_COMM_EVENTS
        ))),
    }
}

/// The registers of a Read File Record reply's groups (after the byte count), one list
/// per group of the request: each group's length byte must be 1 + twice the registers
/// asked, and its reference type 6 (spec 6.14).
fn decode_file_records(
    mut data: &[u8],
    groups: &[(u16, u16, u16)],
) -> Result<Vec<Vec<u16>>, FrameError> {
    let mut out = Vec::with_capacity(groups.len());
    for (i, &(file, record, length)) in groups.iter().enumerate() {
        let want = 1 + 2 * usize::from(length);
        let bad = |what: String| {
            FrameError::Length(format!(
                "file record group {i} (file {file} record {record}): {what}"
            ))
        };
        let Some((&[len, reference], rest)) = data.split_first_chunk::<2>() else {
            return Err(bad("missing".into()));
        };
        if usize::from(len) != want {
            return Err(bad(format!("length {len}, expected {want}")));
        }
        if reference != FILE_REFERENCE_TYPE {
            return Err(bad(format!("reference type {reference}, expected 6")));
        }
        let Some((values, tail)) = rest.split_at_checked(want - 1) else {
            return Err(bad("cut short".into()));
        };
        out.push(
            values
                .chunks_exact(2)
                .map(|c| u16::from_be_bytes([c[0], c[1]]))
                .collect(),
        );
        data = tail;
    }
    if !data.is_empty() {
        return Err(FrameError::Length(format!(
            "{} bytes after the file record groups",
            data.len()
        )));
    }
    Ok(out)
}

/// The values of a Read FIFO Queue reply: byte count (2 bytes), FIFO count (2 bytes, at
/// most 31), then that many registers (spec 6.18).
fn decode_fifo(data: &[u8]) -> Result<Vec<u16>, FrameError> {
    let bad = |what: String| FrameError::Length(format!("FIFO queue: {what}"));
    let Some((&[b0, b1, c0, c1], values)) = data.split_first_chunk::<4>() else {
        return Err(bad(format!(
            "{} data bytes, at least 4 expected",
            data.len()
        )));
    };
    let byte_count = usize::from(u16::from_be_bytes([b0, b1]));
    let count = u16::from_be_bytes([c0, c1]);
    if count > MAX_FIFO_COUNT {
        return Err(bad(format!("count {count}, more than {MAX_FIFO_COUNT}")));
    }
    let count = usize::from(count);
    if byte_count != 2 + 2 * count || values.len() != 2 * count {
        return Err(bad(format!(
            "byte count {byte_count} with count {count} and {} value bytes",
            values.len()
        )));
    }
    Ok(values
        .chunks_exact(2)
        .map(|c| u16::from_be_bytes([c[0], c[1]]))
        .collect())
}

/// Parses the data of a Read Device Identification reply (after the function code).
fn decode_device_id(data: &[u8]) -> Result<DeviceIdentification, FrameError> {
    let bad = |what: &str| FrameError::Length(format!("device identification: {what}"));
    if data.len() < 6 || data[0] != MEI_READ_DEVICE_ID {
        return Err(bad("header"));
    }
    let mut id = DeviceIdentification {
        read_code: data[1],
        conformity: data[2],
        more_follows: data[3] == 0xFF,
        next_object: data[4],
        objects: Default::default(),
    };
    let mut rest = &data[6..];
    for _ in 0..data[5] {
        let (&[obj, len], tail) = rest.split_first_chunk::<2>().ok_or_else(|| bad("object"))?;
        let len = usize::from(len);
        if tail.len() < len {
            return Err(bad("object length"));
        }
        id.objects.insert(obj, tail[..len].to_vec());
        rest = &tail[len..];
    }
    if !rest.is_empty() {
        return Err(bad("trailing bytes"));
    }
    Ok(id)
}

/// Whether a write reply must echo the request exactly.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Echo {
    /// The reply to 0x06 and 0x10 must echo address and value / count (the Modbus rule).
    #[default]
    Strict,
    /// As `Strict`, but a 0x06 reply may carry a register count of 1 in place of the value,
    /// as PBL drives do (`11 06 00 01 00 01 1B 5A` answering a write of 3).
    CountForSingleWrite,
}

/// Checks the echo of a multiple write: the address and count `sent`, as `received`.
fn count_echo(sent: (u16, usize), received: (u16, u16)) -> Result<(), FrameError> {
    let ((address, count), (a, c)) = (sent, received);
    if a != address || usize::from(c) != count {
        return Err(FrameError::Echo {
            sent: format!("address {address:#06x} count {count}"),
            received: format!("address {a:#06x} count {c}"),
        });
    }
    Ok(())
}

/// Checks that a write reply echoes its request.
///
/// # Errors
/// [`FrameError::Echo`] when address, value or count differ.
pub fn check_echo(request: &Request, response: &Response, echo: Echo) -> Result<(), FrameError> {
    let mismatch = |sent: String, received: String| Err(FrameError::Echo { sent, received });
    match (request, response) {
        (
            Request::WriteSingleRegister { address, value },
            Response::WriteSingleRegister {
                address: a,
                value: v,
            },
        ) => {
            let value_ok = v == value || (echo == Echo::CountForSingleWrite && *v == 1);
            if a != address || !value_ok {
                return mismatch(
                    format!("address {address:#06x} value {value:#06x}"),
                    format!("address {a:#06x} value {v:#06x}"),
                );
            }
            Ok(())
        }
        (
            Request::WriteMultipleRegisters { address, values },
            Response::WriteMultipleRegisters {
                address: a,
                count: c,
            },
        ) => count_echo((*address, values.len()), (*a, *c)),
        (
            Request::WriteMultipleCoils { address, values },
            Response::WriteMultipleCoils {
                address: a,
                count: c,
            },
        ) => count_echo((*address, values.len()), (*a, *c)),
        (
            Request::WriteSingleCoil { address, value },
            Response::WriteSingleCoil {
                address: a,
                value: v,
            },
        ) => {
            let sent = coil_word(*value);
            if a != address || *v != sent {
                return mismatch(
                    format!("address {address:#06x} value {sent:#06x}"),
                    format!("address {a:#06x} value {v:#06x}"),
                );
            }
            Ok(())
        }
        (
            Request::MaskWriteRegister {
                address,
                and_mask,
                or_mask,
            },
            Response::MaskWriteRegister {
                address: a,
                and_mask: and,
                or_mask: or,
            },
        ) => {
            if (a, and, or) != (address, and_mask, or_mask) {
                return mismatch(
                    format!("address {address:#06x} and {and_mask:#06x} or {or_mask:#06x}"),
                    format!("address {a:#06x} and {and:#06x} or {or:#06x}"),
                );
            }
            Ok(())
        }
        (
            Request::Diagnostics { sub_function, data },
            Response::Diagnostics {
                sub_function: s,
                data: d,
            },
        ) => {
            // Every sub-function answers its own code; Return Query Data also its data.
            let data_ok = *sub_function != DIAG_RETURN_QUERY_DATA || d == data;
            if s != sub_function || !data_ok {
                return mismatch(
                    format!("sub-function {sub_function:#06x} data {}", hex(data)),
                    format!("sub-function {s:#06x} data {}", hex(d)),
                );
            }
            Ok(())
        }
        (Request::WriteFileRecord { .. }, Response::FileRecordEcho(received)) => {
            let mut pdu = Vec::new();
            request.encode(&mut pdu);
            let sent = pdu.get(1..).unwrap_or_default();
            if received.as_slice() != sent {
                return mismatch(hex(sent), hex(received));
            }
            Ok(())
        }
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hex(s: &str) -> Vec<u8> {
        s.split_whitespace()
            .map(|b| u8::from_str_radix(b, 16).unwrap())
            .collect()
    }

    #[test]
    fn crc_of_known_frame() {
        // 000 B.4: 01 06 20 00 00 01 43 CA (run forward)
        assert_eq!(crc16(&hex("01 06 20 00 00 01")), 0xCA43);
    }

    #[test]
    fn needed_for_exception_is_known_after_two_bytes() {
        let req = Request::ReadHoldingRegisters {
            address: 0x32,
            count: 1,
        };
        assert_eq!(reply_needed(&req, &[]), Needed::More(5));
        assert_eq!(reply_needed(&req, &[1, 0x83]), Needed::More(3));
        assert_eq!(
            reply_needed(&req, &hex("01 83 02 C0 F1")),
            Needed::Complete(5)
        );
        assert_eq!(reply_needed(&req, &[1, 0x03]), Needed::More(3));
        assert_eq!(reply_needed(&req, &[1, 0x03, 2]), Needed::More(4));
        assert_eq!(reply_needed(&req, &[1, 0x04]), Needed::Unknown);
    }

    #[test]
    fn device_id_exceptions_come_in_both_forms() {
        let req = Request::ReadDeviceIdentification {
            read_code: 1,
            object_id: 0,
        };
        assert_eq!(reply_needed(&req, &[2, 0xAB]), Needed::More(3));
        let standard = {
            let mut f = hex("02 AB 01");
            f.extend(crc16(&f).to_le_bytes());
            f
        };
        assert_eq!(reply_needed(&req, &standard), Needed::Complete(5));
        // ATV31 (manual 004): unit, 2B + 80, MEI type 0E, error code 00..02, CRC.
        let atv31 = {
            let mut f = hex("02 AB 0E 02");
            f.extend(crc16(&f).to_le_bytes());
            f
        };
        assert_eq!(reply_needed(&req, &atv31[..5]), Needed::More(1));
        assert_eq!(reply_needed(&req, &atv31), Needed::Complete(6));
        for (frame, code) in [(standard, 1), (atv31, 2)] {
            assert_eq!(
                decode_reply(2, &req, &frame),
                Ok(Reply::Exception {
                    function: 0x2B,
                    code
                })
            );
        }
        // Only for 0x2B: a read's exception is 5 bytes whatever its code.
        let read = Request::ReadHoldingRegisters {
            address: 0,
            count: 1,
        };
        assert_eq!(reply_needed(&read, &hex("02 83 0E")), Needed::More(2));
    }

    #[test]
    fn needed_walks_device_id_objects() {
        let req = Request::ReadDeviceIdentification {
            read_code: 1,
            object_id: 0,
        };
        let mut f = hex("02 2B 0E 01 01 00 00 02 00 03 41 42 43 01 01 58");
        let crc = crc16(&f);
        f.extend_from_slice(&crc.to_le_bytes());
        assert_eq!(reply_needed(&req, &f[..8]), Needed::More(2));
        assert_eq!(reply_needed(&req, &f[..10]), Needed::More(5));
        assert_eq!(reply_needed(&req, &f[..15]), Needed::More(3));
        assert_eq!(reply_needed(&req, &f[..17]), Needed::More(1));
        assert_eq!(reply_needed(&req, &f), Needed::Complete(f.len()));
        let Ok(Reply::Normal(Response::DeviceIdentification(id))) = decode_reply(2, &req, &f)
        else {
            panic!("not decoded");
        };
        assert_eq!(id.objects[&0], b"ABC");
        assert_eq!(id.objects[&1], b"X");
    }

    #[test]
    fn echo_rules() {
        let req = Request::WriteSingleRegister {
            address: 1,
            value: 3,
        };
        let count_reply = Response::WriteSingleRegister {
            address: 1,
            value: 1,
        };
        assert!(check_echo(&req, &count_reply, Echo::Strict).is_err());
        assert!(check_echo(&req, &count_reply, Echo::CountForSingleWrite).is_ok());
        let wrong_addr = Response::WriteSingleRegister {
            address: 2,
            value: 3,
        };
        assert!(check_echo(&req, &wrong_addr, Echo::CountForSingleWrite).is_err());
    }

    #[test]
    fn decode_checks_crc_then_unit_then_function() {
        let req = Request::ReadHoldingRegisters {
            address: 0x2100,
            count: 1,
        };
        let good = hex("01 03 02 00 05 78 47");
        assert_eq!(
            decode_reply(1, &req, &good),
            Ok(Reply::Normal(Response::Registers(vec![5])))
        );
        let mut bad = good.clone();
        bad[4] ^= 1;
        assert!(matches!(
            decode_reply(1, &req, &bad),
            Err(FrameError::Crc { .. })
        ));
        assert!(matches!(
            decode_reply(2, &req, &good),
            Err(FrameError::WrongUnit {
                expected: 2,
                received: 1
            })
        ));
        let req2 = Request::ReadHoldingRegisters {
            address: 0x2100,
            count: 2,
        };
        assert_eq!(
            decode_reply(1, &req2, &good),
            Err(FrameError::ByteCount {
                expected: 4,
                received: 2
            })
        );
    }

    /// The frame: `01 03 01 00 07` + CRC is a valid frame with byte count 1, the
    /// answer to no one-register read. Known from its third byte; the CRC of a length the
    /// request would give (6 bytes) is not what is reported.
    #[test]
    fn byte_count_that_disagrees_is_known_from_the_header() {
        let req = Request::ReadHoldingRegisters {
            address: 0,
            count: 1,
        };
        let frame = [0x01, 0x03, 0x01, 0x00, 0x07, 0x09, 0x86];
        assert_eq!(crc16(&frame[..5]).to_le_bytes(), [0x09, 0x86]);
        let wrong = FrameError::ByteCount {
            expected: 2,
            received: 1,
        };
        assert_eq!(reply_needed(&req, &frame[..3]), Needed::Unknown);
        assert_eq!(check_header(1, &req, &frame[..3]), Err(wrong.clone()));
        assert_eq!(decode_reply(1, &req, &frame), Err(wrong.clone()));
        // From another unit, or another function: not judged by the header.
        assert_eq!(check_header(2, &req, &frame), Ok(()));
        assert_eq!(check_header(1, &req, &[0x01, 0x83, 0x02]), Ok(()));
        assert_eq!(
            wrong.to_string(),
            "reply byte count 1, but the request asked for 2 bytes"
        );
    }

    fn framed(body: &str) -> Vec<u8> {
        let mut f = hex(body);
        f.extend(crc16(&f).to_le_bytes());
        f
    }

    #[test]
    fn file_record_limits_are_checked_before_sending() {
        let read = |groups: Vec<(u16, u16, u16)>| Request::ReadFileRecord { groups }.validate();
        assert!(read(vec![(1, 0, 1), (0xFFFF, 0x270F, 1)]).is_ok());
        assert!(read(vec![]).is_err());
        assert!(read(vec![(0, 0, 1)]).is_err());
        assert!(read(vec![(1, 0x2710, 1)]).is_err());
        assert!(read(vec![(1, 0, 0)]).is_err());
        assert!(read(vec![(1, 0x270F, 2)]).is_err());
        // 35 groups fill a request (2 + 35 * 7 = 247 bytes), 36 do not.
        assert!(read(vec![(1, 0, 1); 35]).is_ok());
        assert!(read(vec![(1, 0, 1); 36]).is_err());
        // The reply: 2 + (2 + 2 * 124) = 252 bytes fits a PDU, a register more does not.
        assert!(read(vec![(1, 0, 124)]).is_ok());
        assert!(read(vec![(1, 0, 125)]).is_err());
        let write =
            |groups: Vec<(u16, u16, Vec<u16>)>| Request::WriteFileRecord { groups }.validate();
        assert!(write(vec![(1, 0, vec![1])]).is_ok());
        assert!(write(vec![]).is_err());
        assert!(write(vec![(0, 0, vec![1])]).is_err());
        assert!(write(vec![(1, 0x2710, vec![1])]).is_err());
        assert!(write(vec![(1, 0, vec![])]).is_err());
        // 2 + 7 + 2 * 122 = 253 bytes is a whole PDU; one value more is not.
        assert!(write(vec![(1, 0, vec![0; 122])]).is_ok());
        assert!(write(vec![(1, 0, vec![0; 123])]).is_err());
    }

    #[test]
    fn fifo_reply_over_31_values_is_a_frame_error() {
        let req = Request::ReadFifoQueue { address: 0x04DE };
        let mut body = String::from("01 18 00 42 00 20");
        for _ in 0..32 {
            body.push_str(" 00 01");
        }
        let f = framed(&body);
        assert_eq!(reply_needed(&req, &f[..3]), Needed::More(3));
        assert_eq!(reply_needed(&req, &f), Needed::Complete(f.len()));
        assert!(
            matches!(decode_reply(1, &req, &f), Err(FrameError::Length(m)) if m.contains("32"))
        );
        let empty = framed("01 18 00 02 00 00");
        assert_eq!(
            decode_reply(1, &req, &empty),
            Ok(Reply::Normal(Response::FifoQueue(vec![])))
        );
        // A byte count that disagrees with the FIFO count.
        assert!(decode_reply(1, &req, &framed("01 18 00 04 00 02 00 01")).is_err());
    }

    #[test]
    fn file_record_reply_must_answer_each_group() {
        let req = Request::ReadFileRecord {
            groups: vec![(4, 1, 1)],
        };
        assert_eq!(
            decode_reply(1, &req, &framed("01 14 04 03 06 00 2A")),
            Ok(Reply::Normal(Response::FileRecords(vec![vec![42]])))
        );
        // Another reference type, or a byte count another request would get.
        assert!(decode_reply(1, &req, &framed("01 14 04 03 07 00 2A")).is_err());
        assert_eq!(
            reply_needed(&req, &framed("01 14 06 05 06 00 2A 00 2B")),
            Needed::Unknown
        );
        let write = Request::WriteFileRecord {
            groups: vec![(4, 7, vec![0x06AF])],
        };
        let echo = framed("01 15 09 06 00 04 00 07 00 01 06 AF");
        assert_eq!(reply_needed(&write, &echo), Needed::Complete(echo.len()));
        let Ok(Reply::Normal(resp)) = decode_reply(1, &write, &echo) else {
            panic!("not decoded");
        };
        assert!(check_echo(&write, &resp, Echo::Strict).is_ok());
        let other = framed("01 15 09 06 00 04 00 07 00 01 06 AE");
        let Ok(Reply::Normal(resp)) = decode_reply(1, &write, &other) else {
            panic!("not decoded");
        };
        assert!(check_echo(&write, &resp, Echo::Strict).is_err());
    }

    #[test]
    fn comm_event_log_is_read_by_its_byte_count() {
        let req = Request::GetCommEventLog;
        let f = framed("01 0C 08 00 00 01 08 01 21 20 00");
        assert_eq!(reply_needed(&req, &f[..3]), Needed::More(10));
        assert_eq!(reply_needed(&req, &f), Needed::Complete(f.len()));
        assert!(decode_reply(1, &req, &framed("01 0C 04 00 00 01 08")).is_err());
    }
}
