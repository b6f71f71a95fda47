//! Sans-IO Modbus codec: requests to bytes, bytes to replies. No clock, no port, no Python.
//!
//! [`pdu`] holds the protocol data units (function codes and their data) and [`reply`] the
//! PDU layer's reading of replies (how many bytes a reply needs, what it says, a write's
//! echo), for `unit | PDU` as every framing carries it. The framings only wrap and unwrap
//! it: [`rtu`] the serial framing (unit address and CRC), [`ascii`] Modbus ASCII (hex
//! characters and LRC), [`mbap`] the Modbus TCP framing (MBAP header, transaction ids) and
//! the session that carries requests and replies over it. Which framing an endpoint speaks
//! is [`Framing`]. Why a frame is refused is a [`FrameError`].

mod error;

pub mod ascii;
pub mod mbap;
pub mod pdu;
pub mod reply;
pub mod rtu;

pub use error::{hex, FrameError};
pub use pdu::{
    exception_meaning, is_gateway_exception, DeviceIdentification, Request, RequestError, Response,
};
pub use reply::{check_echo, check_header, Echo, Needed, Reply};
pub use rtu::{crc16, decode_reply, encode_request, reply_needed, BROADCAST};

// The longest reply the Bus reads over Modbus TCP (`length | unit | PDU`, as the session
// hands it out) fits in the longest frame it reads (an RTU frame).
const _: () = assert!(mbap::LENGTH_FIELD + *mbap::LENGTH.end() <= rtu::MAX_ADU);

/// What frames cross a connection. The Bus builds `unit | PDU` and the framing's trailer:
/// RTU frames go to the wire as they are, and over Modbus TCP the [`mbap`] session puts the
/// MBAP header in front (no CRC: TCP checks the bytes). It reads replies the same way, but
/// over Modbus TCP from the MBAP length field on (`length | unit | PDU`, [`mbap::reply_needed`]),
/// as the session hands them out: the length says where the frame ends, and is checked
/// against the reply the request calls for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Framing {
    /// RTU frames (unit, PDU, CRC), byte for byte: a serial line, or RTU over TCP.
    Rtu,
    /// Modbus TCP: MBAP header + PDU ([`mbap`]); a reply as `length | unit | PDU`.
    Mbap,
    /// Modbus ASCII frames (`:`, hex, LRC, CR LF; [`ascii`]) on a serial line.
    Ascii,
}

impl Framing {
    /// The bytes after `unit | PDU`: the CRC's 2 in RTU, none over Modbus TCP.
    pub const fn trailer(self) -> usize {
        match self {
            Framing::Rtu => rtu::CRC_LEN,
            Framing::Mbap | Framing::Ascii => 0,
        }
    }

    /// `request` to `unit` as the Bus hands it to the transport: an RTU frame, or
    /// `unit | PDU` for the Modbus TCP session.
    pub fn encode_request(self, unit: u8, request: &Request) -> Vec<u8> {
        match self {
            Framing::Rtu => rtu::encode_request(unit, request),
            Framing::Mbap => request.unit_pdu(unit),
            Framing::Ascii => ascii::encode_request(unit, request),
        }
    }

    /// [`reply_needed`] for a reply in this framing.
    pub fn reply_needed(self, request: &Request, buf: &[u8]) -> Needed {
        match self {
            Framing::Rtu => rtu::reply_needed(request, buf),
            Framing::Mbap => mbap::reply_needed(buf),
            Framing::Ascii => ascii::reply_needed(request, buf),
        }
    }

    /// [`decode_reply`] for a reply in this framing.
    ///
    /// # Errors
    /// [`FrameError`] saying what is wrong with the frame.
    pub fn decode_reply(
        self,
        unit: u8,
        request: &Request,
        frame: &[u8],
    ) -> Result<Reply, FrameError> {
        match self {
            Framing::Rtu => rtu::decode_reply(unit, request, frame),
            Framing::Mbap => mbap::decode_reply(unit, request, frame),
            Framing::Ascii => ascii::decode_reply(unit, request, frame),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const READ_ONE: Request = Request::ReadHoldingRegisters {
        address: 0,
        count: 1,
    };

    #[test]
    fn over_modbus_tcp_requests_are_unit_and_pdu_and_replies_come_from_the_length_on() {
        assert_eq!(
            Framing::Mbap.encode_request(1, &READ_ONE),
            [0x01, 0x03, 0x00, 0x00, 0x00, 0x01]
        );
        assert_eq!(
            Framing::Rtu.encode_request(1, &READ_ONE),
            [0x01, 0x03, 0x00, 0x00, 0x00, 0x01, 0x84, 0x0A]
        );
        // length 00 05 | unit 01 | 03 02 12 34: no CRC, TCP carries none.
        let reply = [0x00, 0x05, 0x01, 0x03, 0x02, 0x12, 0x34];
        assert_eq!(Framing::Mbap.reply_needed(&READ_ONE, &[]), Needed::More(2));
        assert_eq!(
            Framing::Mbap.reply_needed(&READ_ONE, &reply[..3]),
            Needed::More(4)
        );
        assert_eq!(
            Framing::Mbap.reply_needed(&READ_ONE, &reply),
            Needed::Complete(7)
        );
        assert_eq!(
            Framing::Mbap.decode_reply(1, &READ_ONE, &reply),
            Ok(Reply::Normal(Response::Registers(vec![0x1234])))
        );
        // unit | PDU is read as in RTU, where it ends in a CRC that is not there.
        assert_eq!(
            Framing::Rtu.reply_needed(&READ_ONE, &reply[2..]),
            Needed::More(2)
        );
        assert!(matches!(
            Framing::Rtu.decode_reply(1, &READ_ONE, &reply[2..]),
            Err(FrameError::Crc { .. })
        ));
    }

    #[test]
    fn over_modbus_tcp_an_exception_is_three_bytes_and_the_longest_pdu_holds() {
        let exception = [0x00, 0x03, 0x01, 0x83, 0x02];
        assert_eq!(
            Framing::Mbap.reply_needed(&READ_ONE, &exception[..2]),
            Needed::More(3)
        );
        assert_eq!(
            Framing::Mbap.reply_needed(&READ_ONE, &exception),
            Needed::Complete(5)
        );
        assert_eq!(
            Framing::Mbap.decode_reply(1, &READ_ONE, &exception),
            Ok(Reply::Exception {
                function: 0x03,
                code: 0x02
            })
        );
        assert_eq!(
            Framing::Mbap.decode_reply(1, &READ_ONE, &[0x00, 0x02, 0x01, 0x83]),
            Err(FrameError::TooShort(2))
        );
        // 125 registers: unit, function, count, 250 bytes = 253, within an MBAP length.
        let most = Request::ReadHoldingRegisters {
            address: 0,
            count: 125,
        };
        assert_eq!(
            Framing::Mbap.reply_needed(&most, &[0x00, 253, 0x01, 0x03, 250]),
            Needed::More(250)
        );
        assert_eq!(
            Framing::Rtu.reply_needed(&most, &[0x01, 0x03, 250]),
            Needed::More(252)
        );
        assert_eq!(
            Framing::Mbap.reply_needed(&most, &[0x00, 254]),
            Needed::More(254)
        );
    }
}
