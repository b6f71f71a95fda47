//! The RTU application data unit: `unit | PDU | CRC-16 (low byte first)`. A reply's
//! `unit | PDU` is measured and decoded by the PDU layer ([`super::reply`]); this module
//! adds the CRC to a request and checks it on a reply.
//!
//! Modbus over Serial Line V1.02, 2.5.1 (RTU frame: at most 256 bytes) and 6.2.2 (CRC-16,
//! polynomial 0xA001 reflected, initial value 0xFFFF, low byte sent first).

use super::error::FrameError;
use super::pdu::Request;
use super::reply::{self, Needed, Reply, Trailer, MAX_UNIT_PDU};
use crc::{Crc, CRC_16_MODBUS};

/// Longest RTU frame (serial line spec 2.5.1).
pub const MAX_ADU: usize = 256;
/// Length of the CRC that ends an RTU frame.
pub const CRC_LEN: usize = 2;
// The longest unit | PDU and its CRC are the longest frame.
const _: () = assert!(MAX_UNIT_PDU + CRC_LEN == MAX_ADU);
/// Unit address that every device accepts and none answers (serial line spec 2.2).
pub const BROADCAST: u8 = 0;

const CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_MODBUS);

/// The CRC after a reply's `unit | PDU`, as the PDU layer takes it.
const CRC: Trailer = Trailer {
    len: CRC_LEN,
    check: check_crc,
};

/// CRC-16/MODBUS of `data`.
pub fn crc16(data: &[u8]) -> u16 {
    CRC16.checksum(data)
}

/// The whole RTU frame for `request` to `unit`, CRC appended low byte first.
pub fn encode_request(unit: u8, request: &Request) -> Vec<u8> {
    let mut out = request.unit_pdu(unit);
    let crc = crc16(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// How many more bytes an RTU reply to `request` needs, given the bytes `buf` received so
/// far: [`reply::needed`] for `unit | PDU | CRC`. An exception reply is 5 bytes, known
/// after two.
pub fn reply_needed(request: &Request, buf: &[u8]) -> Needed {
    reply::needed(request, buf, CRC)
}

/// Decodes a complete RTU reply `frame` to `request` sent to `unit`: [`reply::decode`] for
/// `unit | PDU | CRC`.
///
/// Checks, in order: the header ([`reply::check_header`]: a byte count that disagrees with
/// the request), CRC, unit, function, then the length. The echo of a write is checked
/// separately by [`reply::check_echo`], so a caller may relax it.
///
/// # Errors
/// [`FrameError`] saying what is wrong with the frame.
pub fn decode_reply(unit: u8, request: &Request, frame: &[u8]) -> Result<Reply, FrameError> {
    reply::decode(unit, request, frame, CRC)
}

/// Checks the CRC (`crc`, low byte first) of `unit_pdu`.
fn check_crc(unit_pdu: &[u8], crc: &[u8]) -> Result<(), FrameError> {
    let received = u16::from_le_bytes([crc[0], crc[1]]);
    let computed = crc16(unit_pdu);
    if computed != received {
        return Err(FrameError::Crc { computed, received });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::error::unhex;
    use crate::codec::pdu::Response;
    use crate::codec::reply::{check_echo, check_header, Echo};

    #[test]
    fn crc_of_known_frame() {
        // 000 B.4: 01 06 20 00 00 01 43 CA (run forward)
        assert_eq!(crc16(&unhex("01 06 20 00 00 01")), 0xCA43);
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
            reply_needed(&req, &unhex("01 83 02 C0 F1")),
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
            let mut f = unhex("02 AB 01");
            f.extend(crc16(&f).to_le_bytes());
            f
        };
        assert_eq!(reply_needed(&req, &standard), Needed::Complete(5));
        // ATV31 (manual 004): unit, 2B + 80, MEI type 0E, error code 00..02, CRC.
        let atv31 = {
            let mut f = unhex("02 AB 0E 02");
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
        assert_eq!(reply_needed(&read, &unhex("02 83 0E")), Needed::More(2));
    }

    #[test]
    fn needed_walks_device_id_objects() {
        let req = Request::ReadDeviceIdentification {
            read_code: 1,
            object_id: 0,
        };
        let mut f = unhex("02 2B 0E 01 01 00 00 02 00 03 41 42 43 01 01 58");
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
    fn decode_checks_crc_then_unit_then_function() {
        let req = Request::ReadHoldingRegisters {
            address: 0x2100,
            count: 1,
        };
        let good = unhex("01 03 02 00 05 78 47");
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
        let mut f = unhex(body);
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
