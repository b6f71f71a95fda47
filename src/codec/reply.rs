//! The PDU layer's reading of a reply: how many bytes a reply to a request needs, what it
//! says, and whether a write's reply echoes its request.
//!
//! Every framing carries the same `unit | PDU` (MODBUS Application Protocol V1.1b3, section
//! 6 for each function's reply; section 7 for exception replies): [`super::rtu`] with a CRC
//! after it, [`super::ascii`] as hex characters between `:` and CR LF, [`super::mbap`]
//! behind an MBAP header. Each framing unwraps its frames and hands the `unit | PDU` here,
//! followed by the bytes it puts after it, if any ([`Trailer`]): [`needed`] tells how many
//! more bytes a reply needs, [`decode`] what a whole one says, [`check_echo`] whether a
//! write's reply echoes it. Like the rest of the codec, this touches no port and no clock.

use super::error::{hex, FrameError};
use super::pdu::{
    coil_word, unpack_bits, DeviceIdentification, Request, Response, DIAG_RETURN_QUERY_DATA,
    FILE_REFERENCE_TYPE, MAX_COMM_EVENTS, MAX_FIFO_COUNT, MAX_PDU, MEI_READ_DEVICE_ID,
};

/// Longest `unit | PDU`: a unit address and the longest PDU (spec 4.1: 253 bytes). It is
/// the longest RTU frame but its CRC, the most a Modbus ASCII frame carries, and the most an
/// MBAP header's length counts.
pub const MAX_UNIT_PDU: usize = 1 + MAX_PDU;

/// What a framing puts after a reply's `unit | PDU` in the bytes it hands to [`needed`] and
/// [`decode`], and its check of them: an RTU frame's CRC (see [`super::rtu`]). A Modbus
/// ASCII frame hands over its `unit | PDU` alone (its LRC is checked with its characters),
/// and so does Modbus TCP (TCP checks the bytes): [`Trailer::NONE`].
#[derive(Debug, Clone, Copy)]
pub struct Trailer {
    /// How many bytes it is.
    pub len: usize,
    /// Checks it (the second slice) against the `unit | PDU` it follows (the first).
    pub check: fn(&[u8], &[u8]) -> Result<(), FrameError>,
}

impl Trailer {
    /// No trailer: the `unit | PDU` alone.
    pub const NONE: Trailer = Trailer {
        len: 0,
        check: |_, _| Ok(()),
    };
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
    /// the request does not call for, or a length past the longest `unit | PDU`,
    /// [`MAX_UNIT_PDU`]): the length is unknown; read until the line is silent.
    Unknown,
    /// A reply whose length its bytes do not tell (a raw request's, without a reply
    /// length): it ends when the line has been quiet for the silence gap, and is then
    /// decoded.
    Silence,
}

/// How many more bytes a reply to `request` needs, given the bytes `buf` received so far:
/// its `unit | PDU`, followed by the framing's `trailer`.
///
/// An exception reply (unit, function | 0x80, code: 3 bytes) is known after two bytes, for
/// every function; a read reply (0x01..0x04, 0x17) after three (its byte count, which must be the
/// request's), as a Report Server ID reply (0x11, any byte count); 0x05, 0x06, 0x0F and
/// 0x10 replies are 6 bytes of `unit | PDU`, 0x16 8, 0x07 3, 0x0B 6, a Diagnostics reply
/// (0x08) and a Write File Record reply (0x15) the request's length; a Read File Record
/// reply (0x14) by its byte count, which must be the request's, a Get Comm Event Log reply
/// (0x0C) by its byte count and a Read FIFO Queue reply (0x18) by its two-byte byte count;
/// a Read Device Identification reply is walked object by object; a raw request's reply is
/// its `reply_length` after the function code, or read until the line is silent.
pub fn needed(request: &Request, buf: &[u8], trailer: Trailer) -> Needed {
    // unit, function | 0x80, code.
    let exception = 3 + trailer.len;
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
            | Request::WriteMultipleCoils { .. }
            | Request::MaskWriteRegister { .. }
            | Request::ReadExceptionStatus
            | Request::GetCommEventCounter
            | Request::WriteFileRecord { .. }
            | Request::Diagnostics { .. }
            | Request::Raw {
                reply_length: Some(_),
                ..
            } => match data_len(request) {
                // unit, function, then the data.
                Some(n) => 2 + n,
                None => return Needed::Unknown,
            },
            // A byte count of two bytes, then the FIFO count and the values.
            Request::ReadFifoQueue { .. } => match buf.get(2..4) {
                Some(&[hi, lo]) => 4 + usize::from(u16::from_be_bytes([hi, lo])),
                _ => return Needed::More(4 + trailer.len - buf.len()),
            },
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
    let total = unit_pdu + trailer.len;
    if unit_pdu > MAX_UNIT_PDU {
        Needed::Unknown
    } else if buf.len() >= total {
        Needed::Complete(total)
    } else {
        Needed::More(total - buf.len())
    }
}

/// How many bytes the normal reply to `request` carries after its function code, when the
/// request alone tells it: the byte count a read calls for (and its byte), a write's echo
/// (0x05, 0x06, 0x0F, 0x10: 4 bytes; 0x16: 6; 0x15: the request's data), 0x07's status
/// byte, 0x0B's status and count, a Diagnostics echo, a raw request's `reply_length`. None
/// when the reply carries its own length (0x0C, 0x11, 0x18, device identification) or ends
/// when the line falls quiet (a raw request without a reply length).
pub fn data_len(request: &Request) -> Option<usize> {
    if let Some(count) = request.reply_byte_count() {
        return Some(1 + count);
    }
    match request {
        Request::WriteSingleRegister { .. }
        | Request::WriteMultipleRegisters { .. }
        | Request::WriteSingleCoil { .. }
        | Request::WriteMultipleCoils { .. }
        | Request::GetCommEventCounter => Some(4),
        Request::MaskWriteRegister { .. } => Some(6),
        Request::ReadExceptionStatus => Some(1),
        // The echo: byte count and groups, as sent (the PDU but its function code).
        Request::WriteFileRecord { .. } => {
            let mut pdu = Vec::new();
            request.encode(&mut pdu);
            Some(pdu.len().saturating_sub(1))
        }
        // Sub-function and data.
        Request::Diagnostics { data, .. } => Some(2 + data.len()),
        Request::Raw { reply_length, .. } => *reply_length,
        _ => None,
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

/// What the first bytes of a reply from `unit` to `request` already show to be wrong: a
/// read reply whose byte count disagrees with the request ([`FrameError::ByteCount`]). Its
/// length is then unknown ([`needed`] says [`Needed::Unknown`]), so the caller takes the
/// rest until the line is quiet and reports this, not the CRC of a length it cannot trust.
/// Bytes from another unit, or too few to tell, are not judged here.
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

/// Decodes a complete reply `frame` to `request` sent to `unit`: its `unit | PDU`, followed
/// by the framing's `trailer`.
///
/// Checks, in order: the header ([`check_header`]: a byte count that disagrees with the
/// request), the trailer (an RTU frame's CRC), unit, function, then the length. The echo of
/// a write is checked separately by [`check_echo`], so a caller may relax it.
///
/// # Errors
/// [`FrameError`] saying what is wrong with the frame.
pub fn decode(
    unit: u8,
    request: &Request,
    frame: &[u8],
    trailer: Trailer,
) -> Result<Reply, FrameError> {
    if frame.len() < 3 + trailer.len {
        return Err(FrameError::TooShort(frame.len()));
    }
    check_header(unit, request, frame)?;
    let (body, end) = frame.split_at(frame.len() - trailer.len);
    (trailer.check)(body, end)?;
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

/// An echo is right when `same`; otherwise the error shows what was `sent` and what was
/// `received`, each said by `say`.
fn echoed<T>(same: bool, sent: T, received: T, say: fn(T) -> String) -> Result<(), FrameError> {
    if same {
        return Ok(());
    }
    Err(FrameError::Echo {
        sent: say(sent),
        received: say(received),
    })
}

/// A single write's echo: its address and value.
fn address_value((address, value): (u16, u16)) -> String {
    format!("address {address:#06x} value {value:#06x}")
}

/// Checks the echo of a multiple write: the address and count `sent`, as `received`.
fn count_echo(sent: (u16, usize), (address, count): (u16, u16)) -> Result<(), FrameError> {
    let received = (address, usize::from(count));
    echoed(sent == received, sent, received, |(address, count)| {
        format!("address {address:#06x} count {count}")
    })
}

/// Checks that a write reply echoes its request.
///
/// # Errors
/// [`FrameError::Echo`] when address, value or count differ.
pub fn check_echo(request: &Request, response: &Response, echo: Echo) -> Result<(), FrameError> {
    match (request, response) {
        (
            Request::WriteSingleRegister { address, value },
            &Response::WriteSingleRegister {
                address: a,
                value: v,
            },
        ) => {
            let value_ok = v == *value || (echo == Echo::CountForSingleWrite && v == 1);
            let same = a == *address && value_ok;
            echoed(same, (*address, *value), (a, v), address_value)
        }
        (
            Request::WriteMultipleRegisters { address, values },
            &Response::WriteMultipleRegisters {
                address: a,
                count: c,
            },
        ) => count_echo((*address, values.len()), (a, c)),
        (
            Request::WriteMultipleCoils { address, values },
            &Response::WriteMultipleCoils {
                address: a,
                count: c,
            },
        ) => count_echo((*address, values.len()), (a, c)),
        (
            Request::WriteSingleCoil { address, value },
            &Response::WriteSingleCoil {
                address: a,
                value: v,
            },
        ) => {
            let sent = (*address, coil_word(*value));
            echoed(sent == (a, v), sent, (a, v), address_value)
        }
        (
            &Request::MaskWriteRegister {
                address,
                and_mask,
                or_mask,
            },
            &Response::MaskWriteRegister {
                address: a,
                and_mask: and,
                or_mask: or,
            },
        ) => {
            let sent = (address, and_mask, or_mask);
            echoed(sent == (a, and, or), sent, (a, and, or), |(a, and, or)| {
                format!("address {a:#06x} and {and:#06x} or {or:#06x}")
            })
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
            let same = s == sub_function && data_ok;
            echoed(same, (*sub_function, data), (*s, d), |(s, d)| {
                format!("sub-function {s:#06x} data {}", hex(d))
            })
        }
        (Request::WriteFileRecord { .. }, Response::FileRecordEcho(received)) => {
            let mut pdu = Vec::new();
            request.encode(&mut pdu);
            let sent = pdu.get(1..).unwrap_or_default();
            echoed(received.as_slice() == sent, sent, received, hex)
        }
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
