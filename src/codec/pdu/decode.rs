//! Requests read back from their PDU bytes, as a server gets them: what the gateway checks
//! a client's request against before it forwards it, by the same rules as the requests
//! benchbus builds itself ([`Request::validate`]), and what it needs to forward it.

use super::{
    unpack_bits, Request, RequestError, DIAGNOSTICS, ENCAPSULATED_INTERFACE, FILE_REFERENCE_TYPE,
    GET_COMM_EVENT_COUNTER, GET_COMM_EVENT_LOG, MASK_WRITE_REGISTER, MEI_READ_DEVICE_ID,
    READ_COILS, READ_DISCRETE_INPUTS, READ_EXCEPTION_STATUS, READ_FIFO_QUEUE, READ_FILE_RECORD,
    READ_HOLDING_REGISTERS, READ_INPUT_REGISTERS, READ_WRITE_REGISTERS, REPORT_SERVER_ID,
    WRITE_FILE_RECORD, WRITE_MULTIPLE_COILS, WRITE_MULTIPLE_REGISTERS, WRITE_SINGLE_COIL,
    WRITE_SINGLE_REGISTER,
};

/// The request whose PDU is `function` and `data` (the bytes after the function code), as
/// [`Request::encode`] writes it: each of the specification's functions as its own variant,
/// checked by [`Request::validate`]; 0x2B with an MEI type other than 0x0E, and any other
/// function code 1..=0x7F, as [`Request::Raw`] without a reply length (its reply ends when
/// the line falls quiet).
///
/// # Errors
/// [`RequestError::Function`] for function 0 or 0x80 and up; [`RequestError::Form`] for
/// data of a length or byte count the function does not take, a coil value other than on
/// (0xFF00) or off (0x0000) or a file record reference type other than 6; else what
/// [`Request::validate`] finds (a count or a file record past the specification's limits).
pub fn decode(function: u8, data: &[u8]) -> Result<Request, RequestError> {
    let request = match function {
        0 | 0x80.. => return Err(RequestError::Function(function)),
        READ_COILS | READ_DISCRETE_INPUTS | READ_HOLDING_REGISTERS | READ_INPUT_REGISTERS => {
            let [address, count] = fixed(function, data)?;
            match function {
                READ_COILS => Request::ReadCoils { address, count },
                READ_DISCRETE_INPUTS => Request::ReadDiscreteInputs { address, count },
                READ_HOLDING_REGISTERS => Request::ReadHoldingRegisters { address, count },
                _ => Request::ReadInputRegisters { address, count },
            }
        }
        WRITE_SINGLE_COIL => match fixed(function, data)? {
            [address, 0xFF00] => Request::WriteSingleCoil {
                address,
                value: true,
            },
            [address, 0x0000] => Request::WriteSingleCoil {
                address,
                value: false,
            },
            _ => return Err(form("0x05 takes 0xFF00 (on) or 0x0000 (off)")),
        },
        WRITE_SINGLE_REGISTER => {
            let [address, value] = fixed(function, data)?;
            Request::WriteSingleRegister { address, value }
        }
        READ_EXCEPTION_STATUS | GET_COMM_EVENT_COUNTER | GET_COMM_EVENT_LOG | REPORT_SERVER_ID => {
            let [] = fixed(function, data)?;
            match function {
                READ_EXCEPTION_STATUS => Request::ReadExceptionStatus,
                GET_COMM_EVENT_COUNTER => Request::GetCommEventCounter,
                GET_COMM_EVENT_LOG => Request::GetCommEventLog,
                _ => Request::ReportServerId,
            }
        }
        DIAGNOSTICS => match data {
            [hi, lo, rest @ ..] => Request::Diagnostics {
                sub_function: u16::from_be_bytes([*hi, *lo]),
                data: rest.to_vec(),
            },
            _ => return Err(form("0x08 takes its sub-function (2 bytes)")),
        },
        WRITE_MULTIPLE_COILS => {
            let ([address, count], bits) = counted(function, data, |n| n.div_ceil(8))?;
            Request::WriteMultipleCoils {
                address,
                values: unpack_bits(bits, usize::from(count)),
            }
        }
        WRITE_MULTIPLE_REGISTERS => {
            let ([address, _], values) = counted(function, data, |n| 2 * n)?;
            Request::WriteMultipleRegisters {
                address,
                values: words(values),
            }
        }
        MASK_WRITE_REGISTER => {
            let [address, and_mask, or_mask] = fixed(function, data)?;
            Request::MaskWriteRegister {
                address,
                and_mask,
                or_mask,
            }
        }
        READ_WRITE_REGISTERS => {
            let ([read_address, read_count, write_address, _], values) =
                counted(function, data, |n| 2 * n)?;
            Request::ReadWriteRegisters {
                read_address,
                read_count,
                write_address,
                values: words(values),
            }
        }
        READ_FIFO_QUEUE => {
            let [address] = fixed(function, data)?;
            Request::ReadFifoQueue { address }
        }
        READ_FILE_RECORD => Request::ReadFileRecord {
            groups: file_groups(function, data)?
                .into_iter()
                .map(|(file, record, length, _)| (file, record, length))
                .collect(),
        },
        WRITE_FILE_RECORD => Request::WriteFileRecord {
            groups: file_groups(function, data)?
                .into_iter()
                .map(|(file, record, _, values)| (file, record, words(values)))
                .collect(),
        },
        ENCAPSULATED_INTERFACE => match data {
            [] => return Err(form("0x2B takes its MEI type")),
            [MEI_READ_DEVICE_ID, rest @ ..] => match *rest {
                [read_code, object_id] => Request::ReadDeviceIdentification {
                    read_code,
                    object_id,
                },
                _ => return Err(size(function, 3, data.len())),
            },
            _ => raw(function, data),
        },
        _ => raw(function, data),
    };
    request.validate()?;
    Ok(request)
}

/// The exception a server answers a request with that [`decode`] refused (spec section
/// 7): 0x01, illegal function, for a function code no request has; else 0x03, illegal data
/// value.
pub fn refusal(error: &RequestError) -> u8 {
    match error {
        RequestError::Function(_) => 0x01,
        _ => 0x03,
    }
}

fn form(why: impl Into<String>) -> RequestError {
    RequestError::Form(why.into())
}

fn size(function: u8, expected: usize, got: usize) -> RequestError {
    form(format!(
        "function {function:#04x} takes {expected} data bytes, not {got}"
    ))
}

fn raw(function: u8, data: &[u8]) -> Request {
    Request::Raw {
        function,
        data: data.to_vec(),
        reply_length: None,
    }
}

/// `data` read as big-endian words (a last odd byte is left out: callers check lengths).
fn words(data: &[u8]) -> Vec<u16> {
    data.chunks_exact(2)
        .map(|w| u16::from_be_bytes([w[0], w[1]]))
        .collect()
}

/// The `N` words that are all of `data`.
fn fixed<const N: usize>(function: u8, data: &[u8]) -> Result<[u16; N], RequestError> {
    if data.len() != 2 * N {
        return Err(size(function, 2 * N, data.len()));
    }
    let mut out = [0; N];
    for (word, value) in out.iter_mut().zip(words(data)) {
        *word = value;
    }
    Ok(out)
}

/// The `N` words before a byte count, the last of them a count, and the bytes after the
/// byte count, which must be `bytes(count)` and the rest of `data` (spec 6.11, 6.12, 6.17).
fn counted<const N: usize>(
    function: u8,
    data: &[u8],
    bytes: impl Fn(usize) -> usize,
) -> Result<([u16; N], &[u8]), RequestError> {
    let Some((head, [byte_count, rest @ ..])) = data.split_at_checked(2 * N) else {
        return Err(form(format!(
            "function {function:#04x} takes at least {} data bytes, not {}",
            2 * N + 1,
            data.len()
        )));
    };
    let head: [u16; N] = fixed(function, head)?;
    let count = head.last().map_or(0, |&n| usize::from(n));
    let byte_count = usize::from(*byte_count);
    if byte_count != bytes(count) || rest.len() != byte_count {
        return Err(form(format!(
            "function {function:#04x}: the byte count does not match the count"
        )));
    }
    Ok((head, rest))
}

/// One group of a file record request: file, record, length, and the registers' bytes
/// (none in a read).
type FileGroup<'a> = (u16, u16, u16, &'a [u8]);

/// A file record request's groups (spec 6.14, 6.15): a byte count that is the rest of
/// `data`, then for each group its reference type (6), file, record and length, and in a
/// write (0x15) as many registers' bytes as the length says.
fn file_groups(function: u8, data: &[u8]) -> Result<Vec<FileGroup<'_>>, RequestError> {
    let wrong = |why: &str| form(format!("function {function:#04x}: {why}"));
    let Some((&byte_count, mut rest)) = data.split_first() else {
        return Err(wrong("the byte count is missing"));
    };
    if usize::from(byte_count) != rest.len() {
        return Err(wrong("the byte count does not match the groups"));
    }
    let mut groups = Vec::new();
    while !rest.is_empty() {
        let Some((head, after)) = rest.split_at_checked(7) else {
            return Err(wrong("a group is cut short"));
        };
        if head[0] != FILE_REFERENCE_TYPE {
            return Err(wrong("the reference type must be 6"));
        }
        let [file, record, length] = fixed(function, &head[1..])?;
        let values = if function == WRITE_FILE_RECORD {
            2 * usize::from(length)
        } else {
            0
        };
        let Some((values, after)) = after.split_at_checked(values) else {
            return Err(wrong("a group is cut short"));
        };
        groups.push((file, record, length, values));
        rest = after;
    }
    Ok(groups)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::error::unhex;

    /// `decode` of a PDU written as hex.
    fn pdu(text: &str) -> Result<Request, RequestError> {
        let bytes = unhex(text);
        decode(bytes[0], &bytes[1..])
    }

    fn encoded(request: &Request) -> Vec<u8> {
        let mut out = Vec::new();
        request.encode(&mut out);
        out
    }

    #[test]
    fn the_specifications_requests_read_back_as_what_encodes_them() {
        // The request examples of the specification (6.1 to 6.21), and raw ones.
        for text in [
            "01 00 13 00 13",
            "02 00 C4 00 16",
            "03 00 6B 00 03",
            "04 00 08 00 01",
            "05 00 AC FF 00",
            "05 00 AC 00 00",
            "06 00 01 00 03",
            "07",
            "08 00 00 A5 37",
            "0B",
            "0C",
            "0F 00 13 00 0A 02 CD 01",
            "10 00 01 00 02 04 00 0A 01 02",
            "11",
            "14 0E 06 00 04 00 01 00 02 06 00 03 00 09 00 02",
            "15 0D 06 00 04 00 07 00 03 06 AF 04 BE 10 0D",
            "16 00 04 00 F2 00 25",
            "17 00 03 00 06 00 0E 00 03 06 00 FF 00 FF 00 FF",
            "18 04 DE",
            "2B 0E 01 00",
            "2B 0D 01 00",
            "41 01 02 03",
        ] {
            let request = pdu(text).unwrap();
            assert_eq!(encoded(&request), unhex(text), "{text}");
            // What each does, by its function code; a raw request may write.
            let function = request.function();
            let raw = matches!(request, Request::Raw { .. });
            let reads = [
                0x01, 0x02, 0x03, 0x04, 0x07, 0x08, 0x0B, 0x0C, 0x11, 0x14, 0x18, 0x2B,
            ];
            let echoed_writes = [0x05, 0x06, 0x0F, 0x10, 0x16];
            assert_eq!(function, unhex(text)[0], "{text}");
            assert_eq!(
                request.is_read(),
                !raw && reads.contains(&function),
                "{text}"
            );
            assert_eq!(
                request.is_echoed_write(),
                echoed_writes.contains(&function),
                "{text}"
            );
        }
        assert_eq!(
            pdu("16 00 04 00 F2 00 25"),
            Ok(Request::MaskWriteRegister {
                address: 4,
                and_mask: 0xF2,
                or_mask: 0x25
            })
        );
        assert_eq!(
            pdu("2B 0D 01 00"),
            Ok(raw(ENCAPSULATED_INTERFACE, &[0x0D, 0x01, 0x00]))
        );
    }

    #[test]
    fn counts_are_held_to_the_specifications_limits() {
        let count = |max: u16| RequestError::Count {
            count: usize::from(max) + 1,
            max,
        };
        // 6.1 to 6.4: 2000 bits, 125 registers.
        assert!(pdu("01 00 00 07 D0").is_ok());
        assert_eq!(pdu("01 00 00 07 D1"), Err(count(2000)));
        assert_eq!(pdu("02 00 00 07 D1"), Err(count(2000)));
        assert_eq!(pdu("03 00 00 00 7E"), Err(count(125)));
        assert_eq!(pdu("04 00 00 00 7E"), Err(count(125)));
        assert_eq!(
            pdu("03 00 00 00 00"),
            Err(RequestError::Count { count: 0, max: 125 })
        );
        assert_eq!(
            pdu("02 FF FF 00 02"),
            Err(RequestError::AddressRange {
                address: 0xFFFF,
                count: 2
            })
        );
        assert!(pdu("03 FF FF 00 01").is_ok());
        // 6.11: 1968 coils, 6.12: 123 registers, 6.17: 125 read, 121 written.
        let coils = |n: usize| {
            let mut data = vec![0x00, 0x00];
            data.extend_from_slice(&u16::try_from(n).unwrap().to_be_bytes());
            data.push(u8::try_from(n.div_ceil(8)).unwrap());
            data.resize(data.len() + n.div_ceil(8), 0);
            decode(WRITE_MULTIPLE_COILS, &data)
        };
        assert!(coils(1968).is_ok());
        assert_eq!(coils(1969), Err(count(1968)));
        let registers = |n: u16| {
            let mut data = vec![0x00, 0x00];
            data.extend_from_slice(&n.to_be_bytes());
            data.push(u8::try_from(2 * n).unwrap_or(0));
            data.resize(data.len() + 2 * usize::from(n), 0);
            decode(WRITE_MULTIPLE_REGISTERS, &data)
        };
        assert!(registers(123).is_ok());
        assert_eq!(registers(124), Err(count(123)));
        assert_eq!(pdu("17 00 00 00 7E 00 00 00 01 02 00 00"), Err(count(125)));
        let mut rw = unhex("00 00 00 01 00 00 00 7A F4");
        rw.resize(rw.len() + 244, 0);
        assert_eq!(decode(READ_WRITE_REGISTERS, &rw), Err(count(121)));
    }

    #[test]
    fn a_wrong_length_byte_count_or_value_is_a_form_error() {
        for bad in [
            "03 0C 1E 00",
            "03 00 00 00 01 00",
            "06 00 01",
            "10 00 00",
            "10 00 00 00 02 02 00 01",
            "0F 00 00 00 0A 01 FF",
            "0F 00 00 00 0A 02 FF",
            "16 00 00 00 F2",
            "17 00 00 00 01 00 00 00 01 01 00",
            "05 00 00 12 34",
            "07 00",
            "0B 00",
            "0C 00",
            "11 00",
            "18 04",
            "08 00",
            "2B",
            "2B 0E 01",
            "2B 0E 01 00 00",
            "14 0E 06 00 04 00 01 00 02",
            "14 07 07 00 04 00 01 00 01",
            "14 08 06 00 04 00 01 00 01 00",
            "15 09 06 00 04 00 07 00 02 06 AF",
        ] {
            assert!(
                matches!(pdu(bad), Err(RequestError::Form(_))),
                "{bad}: {:?}",
                pdu(bad)
            );
        }
        // A file record past record 0x270F, file 0, no group: validate's own.
        for bad in [
            "14 07 06 00 04 27 0F 00 02",
            "14 07 06 00 00 00 01 00 01",
            "14 00",
        ] {
            assert!(
                matches!(pdu(bad), Err(RequestError::FileRecord(_))),
                "{bad}"
            );
        }
        assert_eq!(pdu("2B 0E 05 00"), Err(RequestError::ReadCode(5)));
    }

    #[test]
    fn function_0_and_0x80_up_have_no_request_and_are_refused_as_illegal() {
        assert_eq!(decode(0, &[]), Err(RequestError::Function(0)));
        assert_eq!(decode(0x84, &[0, 0]), Err(RequestError::Function(0x84)));
        assert_eq!(refusal(&RequestError::Function(0xFF)), 0x01);
        assert_eq!(refusal(&RequestError::ReadCode(9)), 0x03);
        assert_eq!(refusal(&RequestError::Form(String::new())), 0x03);
        assert_eq!(
            decode(0x7F, &[]),
            Ok(Request::Raw {
                function: 0x7F,
                data: vec![],
                reply_length: None
            })
        );
    }

    #[test]
    fn the_reply_length_is_known_where_the_request_tells_it() {
        let len = |text: &str| crate::codec::reply::data_len(&pdu(text).unwrap());
        // Reads: byte count and data (6.1 to 6.4, 6.17); 0x14: its groups (6.14).
        assert_eq!(len("01 00 13 00 13"), Some(1 + 3));
        assert_eq!(len("02 00 C4 00 16"), Some(1 + 3));
        assert_eq!(len("03 00 6B 00 03"), Some(1 + 6));
        assert_eq!(len("04 00 08 00 01"), Some(1 + 2));
        assert_eq!(
            len("17 00 03 00 06 00 0E 00 03 06 00 FF 00 FF 00 FF"),
            Some(13)
        );
        assert_eq!(
            len("14 0E 06 00 04 00 01 00 02 06 00 03 00 09 00 02"),
            Some(0x0C + 1)
        );
        // Echoes and fixed replies (6.5 to 6.9, 6.11, 6.12, 6.15, 6.16).
        assert_eq!(len("05 00 AC FF 00"), Some(4));
        assert_eq!(len("06 00 01 00 03"), Some(4));
        assert_eq!(len("07"), Some(1));
        assert_eq!(len("08 00 00 A5 37"), Some(4));
        assert_eq!(len("0B"), Some(4));
        assert_eq!(len("0F 00 13 00 0A 02 CD 01"), Some(4));
        assert_eq!(len("10 00 01 00 02 04 00 0A 01 02"), Some(4));
        assert_eq!(
            len("15 0D 06 00 04 00 07 00 03 06 AF 04 BE 10 0D"),
            Some(14)
        );
        assert_eq!(len("16 00 04 00 F2 00 25"), Some(6));
        // Replies that carry their own length (6.10, 6.13, 6.18, 6.21), and raw ones.
        for own in [
            "0C",
            "11",
            "18 04 DE",
            "2B 0E 01 00",
            "2B 0D 01 00",
            "41 01",
        ] {
            assert_eq!(len(own), None, "{own}");
        }
    }
}
