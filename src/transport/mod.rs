//! Byte pipes under the [`Bus`](crate::bus::Bus). A transport moves bytes and knows nothing
//! of Modbus; the bus does the framing, timing and checking.

mod serial;

pub use serial::{describe_open_error, SerialTransport};

use std::io;
use std::time::Duration;

/// A byte pipe to the devices.
///
/// A port that is gone for good (a USB adapter unplugged, a pseudo-terminal whose other end
/// closed) must fail every call at once with an error [`is_lost`] recognises (make it with
/// [`port_lost`]), never wait out a timeout: the Bus then drops the transport, which releases
/// the port, and only reopening the path can bring it back. Any other error (an interrupted
/// system call) leaves the transport in use.
pub trait Transport: Send {
    /// Writes the whole frame.
    ///
    /// # Errors
    /// The I/O error if the port failed ([`port_lost`] if it is gone).
    fn write_all(&mut self, frame: &[u8]) -> io::Result<()>;

    /// Reads at most `buf.len()` bytes, waiting at most `timeout` for the first one to
    /// arrive. Returns `Ok(0)` when nothing arrived in time.
    ///
    /// # Errors
    /// The I/O error if the port failed ([`port_lost`] if it is gone).
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;

    /// Drops every byte waiting in the input buffer and returns them (stale bytes before a
    /// request: a late reply, line noise).
    ///
    /// # Errors
    /// The I/O error if the port failed ([`port_lost`] if it is gone).
    fn discard_input(&mut self) -> io::Result<Vec<u8>>;

    /// Whether the bytes cross a serial line, where frames are separated by t3.5 of silence.
    fn is_serial_line(&self) -> bool {
        true
    }
}

/// The error of a transport whose port is gone for good (see [`Transport`]).
pub fn port_lost(message: impl Into<String>) -> io::Error {
    io::Error::new(io::ErrorKind::BrokenPipe, message.into())
}

/// Whether `error` says the port is gone for good: a hang-up, a connection that ended.
pub fn is_lost(error: &io::Error) -> bool {
    matches!(
        error.kind(),
        io::ErrorKind::BrokenPipe
            | io::ErrorKind::ConnectionReset
            | io::ErrorKind::ConnectionAborted
            | io::ErrorKind::NotConnected
            | io::ErrorKind::UnexpectedEof
    )
}
