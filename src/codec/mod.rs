//! Sans-IO Modbus codec: requests to bytes, bytes to replies. No clock, no port, no Python.
//!
//! [`pdu`] holds the protocol data units (function codes and their data), [`rtu`] the serial
//! framing (unit address and CRC) and the incremental reply decoder.

pub mod pdu;
pub mod rtu;

pub use pdu::{
    exception_meaning, is_gateway_exception, DeviceIdentification, Request, RequestError, Response,
};
pub use rtu::{
    check_echo, check_header, crc16, decode_reply, encode_request, reply_needed, Echo, FrameError,
    Needed, Reply, BROADCAST,
};
