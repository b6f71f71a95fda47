//! Byte pipes under the [`Bus`](crate::bus::Bus). A transport moves bytes and knows nothing
//! of Modbus; the bus does the framing, timing and checking.

mod serial;

pub use serial::SerialTransport;

use std::io;
use std::time::Duration;

/// A byte pipe to the devices.
pub trait Transport: Send {
    /// Writes the whole frame.
    ///
    /// # Errors
    /// The I/O error if the port failed.
    fn write_all(&mut self, frame: &[u8]) -> io::Result<()>;

    /// Reads at most `buf.len()` bytes, waiting at most `timeout` for the first one to
    /// arrive. Returns `Ok(0)` when nothing arrived in time.
    ///
    /// # Errors
    /// The I/O error if the port failed or vanished.
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;

    /// Drops every byte waiting in the input buffer and returns them (stale bytes before a
    /// request: a late reply, line noise).
    ///
    /// # Errors
    /// The I/O error if the port failed.
    fn discard_input(&mut self) -> io::Result<Vec<u8>>;

    /// Whether the bytes cross a serial line, where frames are separated by t3.5 of silence.
    fn is_serial_line(&self) -> bool {
        true
    }
}
