//! The serial transport on the serialport crate: a USB RS485 adapter or a pseudo-terminal.

use super::Transport;
use crate::timing::{LineFormat, Parity};
use serialport::{SerialPort, TTYPort};
use std::io::{self, Read, Write};
use std::sync::Once;
use std::time::Duration;

/// A serial port opened for Modbus RTU (raw mode, exclusive).
pub struct SerialTransport {
    port: TTYPort,
}

fn to_serialport_parity(p: Parity) -> serialport::Parity {
    match p {
        Parity::None => serialport::Parity::None,
        Parity::Even => serialport::Parity::Even,
        Parity::Odd => serialport::Parity::Odd,
    }
}

static PARITY_DROPPED: Once = Once::new();

impl SerialTransport {
    /// Opens `path` with the line format `line`.
    ///
    /// A pseudo-terminal has no parity bit: the kernel either clears `PARENB` silently or
    /// refuses the setting with `EINVAL`. Either way the port is opened without parity and
    /// this is logged once at DEBUG; the bus still times the line with the format it was given.
    ///
    /// # Errors
    /// The serialport error if the port cannot be opened.
    pub fn open(path: &str, line: &LineFormat) -> serialport::Result<SerialTransport> {
        let stop_bits = if line.stop_bits == 2 {
            serialport::StopBits::Two
        } else {
            serialport::StopBits::One
        };
        let builder = serialport::new(path, line.baudrate)
            .data_bits(serialport::DataBits::Eight)
            .stop_bits(stop_bits)
            .flow_control(serialport::FlowControl::None)
            .timeout(Duration::from_millis(100));
        let wanted = to_serialport_parity(line.parity);
        let port = match TTYPort::open(&builder.clone().parity(wanted)) {
            Ok(port) => port,
            Err(e) if wanted != serialport::Parity::None && is_invalid_input(&e) => {
                let port = TTYPort::open(&builder.parity(serialport::Parity::None))?;
                note_parity_dropped(path, line);
                return Ok(SerialTransport { port });
            }
            Err(e) => return Err(e),
        };
        if wanted != serialport::Parity::None && port.parity().ok() != Some(wanted) {
            note_parity_dropped(path, line);
        }
        Ok(SerialTransport { port })
    }
}

fn is_invalid_input(e: &serialport::Error) -> bool {
    matches!(e.kind(), serialport::ErrorKind::InvalidInput)
        || matches!(
            e.kind(),
            serialport::ErrorKind::Io(io::ErrorKind::InvalidInput)
        )
        || e.description.contains("Invalid argument")
}

fn note_parity_dropped(path: &str, line: &LineFormat) {
    PARITY_DROPPED.call_once(|| {
        log::debug!(
            target: "benchbus::transport",
            "{path} has no parity bit (a pseudo-terminal?): opened without parity; \
             timing still uses {line}"
        );
    });
}

impl Transport for SerialTransport {
    fn write_all(&mut self, frame: &[u8]) -> io::Result<()> {
        self.port.write_all(frame)
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        self.port.set_timeout(timeout)?;
        match self.port.read(buf) {
            Err(e) if e.kind() == io::ErrorKind::TimedOut => Ok(0),
            // A read that returns nothing after poll said "readable" means the other end hung up.
            Ok(0) => Err(io::Error::new(
                io::ErrorKind::BrokenPipe,
                "port closed by the other end",
            )),
            other => other,
        }
    }

    fn discard_input(&mut self) -> io::Result<Vec<u8>> {
        let mut stale = Vec::new();
        let mut chunk = [0u8; 256];
        while self.port.bytes_to_read()? > 0 {
            let n = self.read(&mut chunk, Duration::ZERO)?;
            if n == 0 {
                break;
            }
            stale.extend_from_slice(&chunk[..n]);
        }
        Ok(stale)
    }
}
