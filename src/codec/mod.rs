//! Sans-IO Modbus codec: requests to bytes, bytes to replies. No clock, no port, no Python.
//!
//! [`pdu`] holds the protocol data units (function codes and their data), [`rtu`] the serial
//! framing (unit address and CRC) and the incremental reply decoder, [`mbap`] the Modbus TCP
//! framing (MBAP header, transaction ids) and the session that carries RTU frames over it.
//! Which framing an endpoint speaks is [`Framing`].

pub mod mbap;
pub mod pdu;
pub mod rtu;

pub use pdu::{
    exception_meaning, is_gateway_exception, DeviceIdentification, Request, RequestError, Response,
};
pub use rtu::{
    check_echo, check_header, crc16, decode_reply, encode_request, reply_needed, Echo, FrameError,
    Needed, Reply, BROADCAST,
};

/// What frames cross a connection.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Framing {
    /// RTU frames (unit, PDU, CRC), byte for byte: a serial line, or RTU over TCP.
    Rtu,
    /// Modbus TCP: MBAP header + PDU ([`mbap`]).
    Mbap,
}
