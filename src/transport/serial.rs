//! The serial transport on the serialport crate: a USB RS485 adapter, a board's UART or a
//! pseudo-terminal on Linux and macOS, a COM port on Windows.

use super::tuning::{self, Rs485, Tuned};
use super::{port_lost, Transport};
use crate::timing::{LineFormat, Parity};
use serialport::SerialPort;
use std::io::{self, Read, Write};
#[cfg(unix)]
use std::os::unix::io::AsRawFd;
use std::sync::Once;
use std::time::Duration;

/// The serialport crate's port on this system.
#[cfg(unix)]
type Port = serialport::TTYPort;
#[cfg(windows)]
type Port = serialport::COMPort;

/// A serial port opened for Modbus RTU (raw mode, exclusive).
///
/// Exclusive: on Linux and macOS the serialport crate sets `TIOCEXCL` (a later open by
/// another non-root program fails with `EBUSY`) and takes an exclusive `flock` (a later open
/// by anything that locks, such as another Bus in this or another process, fails); on
/// Windows it opens the port without sharing, and Windows refuses any later open. See
/// [`describe_open_error`].
///
/// A port that is gone fails every call at once with [`port_lost`]. On Linux and macOS it
/// hangs up (a USB adapter unplugged, a pseudo-terminal whose master closed): the kernel
/// marks the file hung up, so a read returns nothing or `EIO`, an ioctl `EIO`, and `poll`
/// reports `POLLHUP`. On Windows the handle of an unplugged adapter stays, and every call on
/// it fails with one of the errors its driver gives then (`ERROR_BAD_COMMAND`,
/// `ERROR_ACCESS_DENIED`, `ERROR_DEVICE_REMOVED`, `ERROR_OPERATION_ABORTED`...), or the port
/// no longer answers `ClearCommError`.
///
/// On Windows a name `COM1`..`COM256` is opened as `\\.\COMn` (the form `COM10` and up
/// need); the Bus keeps the name it was given.
pub struct SerialTransport {
    port: Port,
    line: LineFormat,
    /// What the open asked of the driver, and got (see [`super::tuning`]).
    tuned: Tuned,
}

/// What a write may take beyond the frame's own time on the wire: the driver's and the
/// adapter's buffers, never a hang.
const WRITE_SLACK: Duration = Duration::from_millis(100);

fn to_serialport_parity(p: Parity) -> serialport::Parity {
    match p {
        Parity::None => serialport::Parity::None,
        Parity::Even => serialport::Parity::Even,
        Parity::Odd => serialport::Parity::Odd,
    }
}

/// The crate's data bits for `bits` (7 for Modbus ASCII's usual format; 8 otherwise).
fn to_serialport_data_bits(bits: u8) -> serialport::DataBits {
    match bits {
        5 => serialport::DataBits::Five,
        6 => serialport::DataBits::Six,
        7 => serialport::DataBits::Seven,
        _ => serialport::DataBits::Eight,
    }
}

static FORMAT_DROPPED: Once = Once::new();

impl SerialTransport {
    /// Opens `path` with the line format `line`.
    ///
    /// A pseudo-terminal has no parity bit and carries 8 data bits: the kernel either clears
    /// `PARENB` (and reads back 8 data bits for 7) silently or refuses the setting with
    /// `EINVAL`. Either way the port is opened at 8 data bits without parity and this is
    /// logged once at DEBUG; the bus still times the line with the format it was given.
    ///
    /// # Errors
    /// The serialport error if the port cannot be opened.
    pub fn open(path: &str, line: &LineFormat) -> serialport::Result<SerialTransport> {
        SerialTransport::open_with(path, line, None)
    }

    /// Opens `path` as [`SerialTransport::open`] does, asks its driver for low latency, and
    /// sets the kernel's RS485 mode if `rs485` is given (see [`super::tuning`]).
    ///
    /// # Errors
    /// The serialport error if the port cannot be opened, or (the port closed again) if it
    /// has no RS485 mode to set.
    pub fn open_with(
        path: &str,
        line: &LineFormat,
        rs485: Option<&Rs485>,
    ) -> serialport::Result<SerialTransport> {
        let stop_bits = if line.stop_bits == 2 {
            serialport::StopBits::Two
        } else {
            serialport::StopBits::One
        };
        #[cfg(windows)]
        let device = super::windows::device_path(path);
        #[cfg(not(windows))]
        let device = path.to_string();
        let builder = serialport::new(device.as_str(), line.baudrate)
            .stop_bits(stop_bits)
            .flow_control(serialport::FlowControl::None)
            .timeout(Duration::from_millis(100));
        let wanted = to_serialport_parity(line.parity);
        let bits = to_serialport_data_bits(line.data_bits);
        let plain = wanted == serialport::Parity::None && bits == serialport::DataBits::Eight;
        let port = match Port::open(&builder.clone().parity(wanted).data_bits(bits)) {
            Ok(port) => port,
            Err(e) if !plain && is_invalid_input(&e) => {
                let eight_none = builder
                    .parity(serialport::Parity::None)
                    .data_bits(serialport::DataBits::Eight);
                let port = Port::open(&eight_none).map_err(|e| open_error(&device, e))?;
                note_format_dropped(path, line);
                port
            }
            Err(e) => return Err(open_error(&device, e)),
        };
        if !plain && (port.parity().ok() != Some(wanted) || port.data_bits().ok() != Some(bits)) {
            note_format_dropped(path, line);
        }
        let tuned = tuning::on_open(&port, rs485).map_err(|message| {
            serialport::Error::new(
                serialport::ErrorKind::Io(io::ErrorKind::Unsupported),
                message,
            )
        })?;
        Ok(SerialTransport {
            port,
            line: *line,
            tuned,
        })
    }

    /// What the open asked of the driver (low latency, RS485 mode), and got.
    pub fn tuned(&self) -> &Tuned {
        &self.tuned
    }
}

/// The error of a failed open of `device`, as [`describe_open_error`] reads it.
#[cfg(windows)]
fn open_error(device: &str, e: serialport::Error) -> serialport::Error {
    super::windows::open_error(device, e)
}

/// The error of a failed open, as [`describe_open_error`] reads it (the crate's own).
#[cfg(not(windows))]
fn open_error(_device: &str, e: serialport::Error) -> serialport::Error {
    e
}

/// What an open error means, for the message of a PortError: "in use" for a port another
/// Bus or program holds (the crate reports both `EBUSY` and a refused `flock` as
/// `NoDevice`; on Windows `ERROR_ACCESS_DENIED`, which [`SerialTransport::open`] reports so
/// too), how to get the permission for a port the user may not open, the ports that exist
/// for one that does not, the system's own words otherwise.
pub fn describe_open_error(e: &serialport::Error) -> String {
    match e.kind() {
        serialport::ErrorKind::NoDevice => format!(
            "in use by another Bus or program (benchbus opens a port exclusively): {}",
            e.description
        ),
        serialport::ErrorKind::Io(io::ErrorKind::PermissionDenied) => {
            format!("{} ({PERMISSION_HINT})", e.description)
        }
        serialport::ErrorKind::Io(io::ErrorKind::NotFound) => {
            format!("{} ({})", e.description, ports_here())
        }
        _ if not_a_terminal(e) => format!(
            "not a serial port (the system says {:?}; {})",
            e.description,
            ports_here()
        ),
        _ => e.description.clone(),
    }
}

/// Whether an open failed because the file is not a terminal (`ENOTTY`: a regular file,
/// `/dev/null`, a directory's device...), which the crate reports by the system's text alone.
fn not_a_terminal(e: &serialport::Error) -> bool {
    ["Not a typewriter", "Inappropriate ioctl for device"]
        .iter()
        .any(|text| e.description.contains(text))
}

/// The serial ports this system has, for the message of a port that does not exist.
fn ports_here() -> String {
    match super::ports::list_ports() {
        Ok(ports) if ports.is_empty() => "this system lists no serial ports".into(),
        Ok(ports) => {
            let paths: Vec<&str> = ports.iter().map(|p| p.path.as_str()).collect();
            format!("the serial ports here: {}", paths.join(", "))
        }
        Err(e) => format!("the serial ports cannot be listed: {e}"),
    }
}

/// How a user gets the permission to open a serial port.
#[cfg(target_os = "linux")]
pub(crate) const PERMISSION_HINT: &str = "serial ports belong to the dialout group: add \
    yourself with 'sudo usermod -aG dialout $USER', then log out and in again";
#[cfg(not(target_os = "linux"))]
pub(crate) const PERMISSION_HINT: &str = "your user may not open this port: ask for access \
    to it (on most systems, membership of the group that owns it)";

fn is_invalid_input(e: &serialport::Error) -> bool {
    matches!(e.kind(), serialport::ErrorKind::InvalidInput)
        || matches!(
            e.kind(),
            serialport::ErrorKind::Io(io::ErrorKind::InvalidInput)
        )
        || e.description.contains("Invalid argument")
}

fn note_format_dropped(path: &str, line: &LineFormat) {
    FORMAT_DROPPED.call_once(|| {
        log::debug!(
            target: "benchbus::transport",
            "{path} has no parity bit and 8 data bits only (a pseudo-terminal?): opened \
             at 8 data bits without parity; timing still uses {line}"
        );
    });
}

/// The port's descriptor, for the Linux probes of [`super::doctor`].
#[cfg(unix)]
impl AsRawFd for SerialTransport {
    fn as_raw_fd(&self) -> std::os::unix::io::RawFd {
        self.port.as_raw_fd()
    }
}

impl SerialTransport {
    /// Whether the port has hung up: `poll` on it reports `POLLHUP`, `POLLERR` or `POLLNVAL`.
    #[cfg(unix)]
    fn hung_up(&self) -> bool {
        let mut fd = libc::pollfd {
            fd: self.port.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        // SAFETY: one valid pollfd, owned by this stack frame, for a zero-timeout poll.
        let n = unsafe { libc::poll(&mut fd, 1, 0) };
        n > 0 && fd.revents & (libc::POLLHUP | libc::POLLERR | libc::POLLNVAL) != 0
    }

    /// `e` as [`port_lost`] if the port has hung up; as it is otherwise (an interrupted
    /// system call is never a lost port).
    #[cfg(unix)]
    fn checked(&self, e: io::Error) -> io::Error {
        if e.kind() != io::ErrorKind::Interrupted && self.hung_up() {
            port_lost(format!("hung up (unplugged, or its other end closed): {e}"))
        } else {
            e
        }
    }

    /// `e` as [`port_lost`] if the port is gone (unplugged); as it is otherwise.
    #[cfg(windows)]
    fn checked(&self, e: io::Error) -> io::Error {
        match super::windows::gone(&self.port, &e) {
            Some(why) => port_lost(format!("gone (unplugged?): {why}")),
            None => e,
        }
    }

    /// Sets the port's timeout for the next read or write.
    fn set_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        #[cfg(windows)]
        let timeout = super::windows::comm_timeout(timeout);
        self.port
            .set_timeout(timeout)
            .map_err(|e| self.checked(e.into()))
    }
}

impl Transport for SerialTransport {
    fn write_all(&mut self, frame: &[u8]) -> io::Result<()> {
        // The port's timeout is the last read's (zero after a stale-input drain): a write gets
        // its own, so a momentarily full output buffer is waited for, boundedly.
        self.set_timeout(WRITE_SLACK + self.line.frame_time(frame.len()) * 2)?;
        self.port.write_all(frame).map_err(|e| self.checked(e))
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let deadline = std::time::Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            self.set_timeout(left)?;
            return match self.port.read(buf) {
                Err(e) if e.kind() == io::ErrorKind::TimedOut => Ok(0),
                // A signal (Ctrl-C, a timer) interrupted the wait: the reply is still on its
                // way, so wait on until the same deadline. Abandoning it here would leave it
                // to answer the next request; Python raises the signal when the call returns.
                Err(e) if e.kind() == io::ErrorKind::Interrupted && !left.is_zero() => continue,
                // In raw mode (VMIN 1) a read returns nothing only at end of file: a hang-up.
                Ok(0) => Err(port_lost(
                    "hung up (unplugged, or its other end closed): read found end of file",
                )),
                Err(e) => Err(self.checked(e)),
                Ok(n) => Ok(n),
            };
        }
    }

    fn discard_input(&mut self) -> io::Result<Vec<u8>> {
        let mut stale = Vec::new();
        let mut chunk = [0u8; 256];
        loop {
            let waiting = self
                .port
                .bytes_to_read()
                .map_err(|e| self.checked(e.into()))?;
            if waiting == 0 {
                break;
            }
            let n = self.read(&mut chunk, Duration::ZERO)?;
            if n == 0 {
                break;
            }
            stale.extend_from_slice(&chunk[..n]);
        }
        Ok(stale)
    }

    /// Closes this process's copy of the descriptor and nothing else. The port's own drop
    /// would first clear the port's exclusive mode (`TIOCNXCL`), which the copies share: the
    /// parent's port would then be open to others. The `flock` stays with the parent's copy.
    #[cfg(unix)]
    fn abandon(self: Box<Self>) {
        use std::os::fd::{FromRawFd, IntoRawFd, OwnedFd};
        let fd = self.port.into_raw_fd();
        // SAFETY: `into_raw_fd` gave up the port's ownership of `fd`, so it is closed once,
        // here, and not used after.
        drop(unsafe { OwnedFd::from_raw_fd(fd) });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    #[cfg(unix)]
    use crate::transport::is_lost;
    #[cfg(unix)]
    use std::time::Instant;

    /// What the user is told of an I/O error of `kind` that says `message`, on opening.
    fn told(kind: io::ErrorKind, message: &str) -> String {
        describe_open_error(&serialport::Error::new(
            serialport::ErrorKind::Io(kind),
            message,
        ))
    }

    #[cfg(unix)]
    fn line() -> LineFormat {
        LineFormat::new(19_200, Parity::None, 1)
    }

    #[cfg(unix)]
    #[test]
    fn a_hung_up_port_fails_every_call_at_once_as_lost() {
        let (master, path) = crate::transport::test_pty();
        let mut t = SerialTransport::open(&path, &line()).unwrap();
        t.write_all(&[1, 2, 3]).unwrap();
        // SAFETY: our own fd, closed once: the far end goes away, as an unplugged adapter.
        unsafe { libc::close(master) };
        let start = Instant::now();
        let e = t.read(&mut [0u8; 8], Duration::from_secs(5)).unwrap_err();
        assert!(is_lost(&e), "{e:?}");
        assert!(e.to_string().contains("hung up"), "{e}");
        assert!(is_lost(&t.discard_input().unwrap_err()));
        assert!(is_lost(&t.write_all(&[1]).unwrap_err()));
        assert!(
            start.elapsed() < Duration::from_millis(500),
            "{:?}",
            start.elapsed()
        );
    }

    #[test]
    fn a_port_the_user_may_not_open_says_how_to_get_the_permission() {
        let text = told(io::ErrorKind::PermissionDenied, "Permission denied");
        assert!(text.starts_with("Permission denied ("), "{text}");
        #[cfg(target_os = "linux")]
        assert!(
            text.contains("dialout") && text.contains("sudo usermod -aG dialout $USER"),
            "{text}"
        );
        assert_eq!(told(io::ErrorKind::InvalidData, "Bad data"), "Bad data");
    }

    #[cfg(unix)]
    #[test]
    fn a_file_that_is_not_a_terminal_is_told_it_is_not_a_serial_port() {
        let Err(e) = SerialTransport::open("/dev/null", &line()) else {
            panic!("/dev/null opened as a serial port");
        };
        let text = describe_open_error(&e);
        assert!(
            text.starts_with("not a serial port (the system says "),
            "{text}"
        );
    }

    #[test]
    fn a_port_that_does_not_exist_is_told_with_the_ports_that_do() {
        let text = told(io::ErrorKind::NotFound, "No such file or directory");
        let ports: Vec<String> = crate::transport::ports::list_ports()
            .unwrap()
            .into_iter()
            .map(|p| p.path)
            .collect();
        let expected = if ports.is_empty() {
            "No such file or directory (this system lists no serial ports)".to_string()
        } else {
            format!(
                "No such file or directory (the serial ports here: {})",
                ports.join(", ")
            )
        };
        assert_eq!(text, expected);
    }

    #[cfg(unix)]
    #[test]
    fn a_port_held_by_another_opener_is_refused_as_in_use() {
        let (master, path) = crate::transport::test_pty();
        let held = SerialTransport::open(&path, &line()).unwrap();
        let e = SerialTransport::open(&path, &line())
            .err()
            .map(|e| describe_open_error(&e));
        assert!(
            e.as_deref()
                .is_some_and(|m| m.starts_with("in use by another Bus or program")),
            "{e:?}"
        );
        drop(held);
        assert!(SerialTransport::open(&path, &line()).is_ok());
        // SAFETY: our own fd, closed once.
        unsafe { libc::close(master) };
    }

    #[test]
    fn the_line_formats_data_bits_are_asked_of_the_driver() {
        assert_eq!(to_serialport_data_bits(7), serialport::DataBits::Seven);
        assert_eq!(to_serialport_data_bits(8), serialport::DataBits::Eight);
    }

    #[cfg(unix)]
    #[test]
    fn a_pty_asked_for_7e1_opens_and_carries_whole_bytes() {
        let (master, path) = crate::transport::test_pty();
        let mut t = SerialTransport::open(&path, &LineFormat::ascii(9600, Parity::Even)).unwrap();
        // The far end writes a byte with its top bit set: the pty, at 8 data bits whatever
        // it was asked, hands it over whole.
        // SAFETY: our own fd and a valid one-byte buffer.
        let wrote = unsafe { libc::write(master, [0xB1u8].as_ptr().cast(), 1) };
        assert_eq!(wrote, 1);
        let mut got = [0u8; 4];
        let n = t.read(&mut got, Duration::from_secs(1)).unwrap();
        assert_eq!(&got[..n], [0xB1]);
        assert_eq!(t.line.data_bits, 7, "the Bus still times 7 data bits");
        // SAFETY: our own fd, closed once.
        unsafe { libc::close(master) };
    }
}
