//! What the transports do differently on Windows: COM port names, telling an open failure
//! "in use" from "no such port", the errors of a port that is gone, and waiting on a socket.
//!
//! The serialport crate opens a COM port with sharing mode 0 (Windows refuses a second open
//! of it with `ERROR_ACCESS_DENIED`), and sets `COMMTIMEOUTS` so that a read returns the bytes
//! that have arrived as soon as there are any, or nothing when its timeout has passed.

use serialport::{Error, ErrorKind};
use std::io;
use std::net::TcpStream;
use std::os::windows::fs::OpenOptionsExt;
use std::os::windows::io::{AsRawHandle, AsRawSocket};
use std::time::Duration;
use windows_sys::Win32::Devices::Communication::ClearCommError;
use windows_sys::Win32::Foundation::{
    GetLastError, ERROR_ACCESS_DENIED, ERROR_BAD_COMMAND, ERROR_DEVICE_NOT_CONNECTED,
    ERROR_DEVICE_REMOVED, ERROR_FILE_NOT_FOUND, ERROR_GEN_FAILURE, ERROR_INVALID_HANDLE,
    ERROR_NOT_READY, ERROR_NO_SUCH_DEVICE, ERROR_OPERATION_ABORTED, ERROR_PATH_NOT_FOUND,
    ERROR_SHARING_VIOLATION, HANDLE,
};
use windows_sys::Win32::Networking::WinSock::{
    WSAGetLastError, WSAPoll, POLLRDNORM, POLLWRNORM, SOCKET_ERROR, WSAEINTR, WSAPOLLFD,
};

/// The highest COM port number Windows hands out.
const LAST_COM: u32 = 256;

/// The device path to open for the port name `name`: `COM1`..`COM256` (any case) as
/// `\\.\COMn`, the form Windows needs from `COM10` on (and takes for any COM port); any other
/// name as it is.
pub(super) fn device_path(name: &str) -> String {
    let number = name
        .get(..3)
        .filter(|p| p.eq_ignore_ascii_case("COM"))
        .and_then(|_| name.get(3..))
        .filter(|n| !n.starts_with('0') && n.bytes().all(|b| b.is_ascii_digit()))
        .and_then(|n| n.parse::<u32>().ok())
        .filter(|n| (1..=LAST_COM).contains(n));
    match number {
        Some(n) => format!(r"\\.\COM{n}"),
        None => name.to_string(),
    }
}

/// The serialport error of a failed open of `device`, told apart: the crate reports "in
/// use" (`ERROR_ACCESS_DENIED`), "no such port" and any other failure alike, so the port is
/// opened once more the way the crate does (no sharing) to see which it is. In use: kind
/// `NoDevice` (as on Linux, where `EBUSY` is that kind); no such port: `Io(NotFound)`;
/// anything else as the crate reported it.
pub(super) fn open_error(device: &str, e: Error) -> Error {
    if !matches!(
        e.kind(),
        ErrorKind::NoDevice | ErrorKind::Io(io::ErrorKind::Other)
    ) {
        return e;
    }
    let probe = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .share_mode(0)
        .open(device);
    let code = match probe {
        // Free now (it was released meanwhile): the crate's own words.
        Ok(_) => return e,
        Err(p) => p.raw_os_error().and_then(|c| u32::try_from(c).ok()),
    };
    match code {
        Some(ERROR_ACCESS_DENIED | ERROR_SHARING_VIOLATION) => {
            Error::new(ErrorKind::NoDevice, e.description)
        }
        Some(ERROR_FILE_NOT_FOUND | ERROR_PATH_NOT_FOUND) => {
            Error::new(ErrorKind::Io(io::ErrorKind::NotFound), e.description)
        }
        _ => e,
    }
}

/// Whether a Windows error code on an open port says the port is gone: what the serial
/// drivers of USB adapters report once the adapter is unplugged (the handle stays, every
/// call on it fails), and what wine reports for a Unix device whose other end went away.
pub(super) fn is_gone_code(code: u32) -> bool {
    matches!(
        code,
        ERROR_FILE_NOT_FOUND
            | ERROR_ACCESS_DENIED
            | ERROR_INVALID_HANDLE
            | ERROR_NOT_READY
            | ERROR_BAD_COMMAND
            | ERROR_GEN_FAILURE
            | ERROR_NO_SUCH_DEVICE
            | ERROR_OPERATION_ABORTED
            | ERROR_DEVICE_NOT_CONNECTED
            | ERROR_DEVICE_REMOVED
    )
}

/// Why the port whose handle `port` holds is gone, given the error `e` a call on it failed
/// with; None if it is still there. Gone: `e` carries one of the codes of
/// [`is_gone_code`] (then `e` says why), or the port no longer answers `ClearCommError` (the
/// serialport crate's own errors carry no code, so the port is asked; its error says why).
pub(super) fn gone(port: &impl AsRawHandle, e: &io::Error) -> Option<String> {
    let code = e.raw_os_error().and_then(|c| u32::try_from(c).ok());
    if code.is_some_and(is_gone_code) {
        return Some(e.to_string());
    }
    let mut errors = 0u32;
    // SAFETY: the handle is the port's own, open for the borrow's length; ClearCommError
    // writes only `errors` (COMSTAT may be null). GetLastError is read right after it.
    let failed = unsafe {
        ClearCommError(
            port.as_raw_handle() as HANDLE,
            &mut errors,
            std::ptr::null_mut(),
        ) == 0
    };
    if !failed {
        return None;
    }
    // SAFETY: reads the calling thread's last error, nothing else.
    let probe = io::Error::from_raw_os_error(unsafe { GetLastError() } as i32);
    Some(probe.to_string())
}

/// A serial timeout as the serialport crate gives it to `COMMTIMEOUTS`: whole milliseconds,
/// rounded up, at least 1 (a constant of 0 with the crate's other settings is not "return at
/// once" but an unbounded wait).
pub(super) fn comm_timeout(timeout: Duration) -> Duration {
    let ms = timeout
        .as_micros()
        .div_ceil(1000)
        .clamp(1, u128::from(u32::MAX - 1));
    Duration::from_millis(ms as u64)
}

/// Waits up to `timeout` (rounded up to whole milliseconds) for `socket` to be readable (or
/// writable, if `write`), or to fail; returns early on an interruption, for the caller to
/// try again and wait on to its deadline.
pub(super) fn wait_socket(socket: &TcpStream, write: bool, timeout: Duration) -> io::Result<()> {
    let ms = timeout.as_micros().div_ceil(1000).min(i32::MAX as u128) as i32;
    let mut fd = WSAPOLLFD {
        fd: socket.as_raw_socket() as usize,
        events: if write { POLLWRNORM } else { POLLRDNORM },
        revents: 0,
    };
    // SAFETY: one valid WSAPOLLFD, owned by this stack frame, on a socket the caller owns.
    if unsafe { WSAPoll(&mut fd, 1, ms) } == SOCKET_ERROR {
        // SAFETY: reads the calling thread's last socket error, nothing else.
        let code = unsafe { WSAGetLastError() };
        if code != WSAEINTR {
            return Err(io::Error::from_raw_os_error(code));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn com_names_get_the_device_prefix_windows_needs_from_com10_on() {
        assert_eq!(device_path("COM1"), r"\\.\COM1");
        assert_eq!(device_path("COM10"), r"\\.\COM10");
        assert_eq!(device_path("com256"), r"\\.\COM256");
        assert_eq!(device_path("Com42"), r"\\.\COM42");
        for as_given in [
            r"\\.\COM12",
            "COM0",
            "COM257",
            "COM07",
            "COM",
            "COM1x",
            "COMX",
            "COM+1",
            "LPT1",
            "CNCA0",
            "",
            "\u{e9}\u{e9}",
        ] {
            assert_eq!(device_path(as_given), as_given);
        }
    }

    #[test]
    fn unplugged_adapter_codes_are_gone_others_are_not() {
        for code in [
            ERROR_BAD_COMMAND,
            ERROR_ACCESS_DENIED,
            ERROR_DEVICE_REMOVED,
            ERROR_OPERATION_ABORTED,
            ERROR_GEN_FAILURE,
            ERROR_FILE_NOT_FOUND,
        ] {
            assert!(is_gone_code(code), "{code}");
        }
        // ERROR_INVALID_PARAMETER, ERROR_SEM_TIMEOUT, ERROR_IO_PENDING
        for code in [87, 121, 997] {
            assert!(!is_gone_code(code), "{code}");
        }
    }

    /// A file of its own in the temporary directory, removed on drop.
    struct TempFile(std::path::PathBuf);

    impl TempFile {
        fn new(tag: &str) -> TempFile {
            let path = std::env::temp_dir().join(format!(
                "benchbus-{tag}-{}-{:?}",
                std::process::id(),
                std::thread::current().id()
            ));
            std::fs::write(&path, b"").unwrap();
            TempFile(path)
        }

        fn path(&self) -> &str {
            self.0.to_str().unwrap()
        }
    }

    impl Drop for TempFile {
        fn drop(&mut self) {
            let _ = std::fs::remove_file(&self.0);
        }
    }

    fn crate_error() -> Error {
        Error::new(ErrorKind::NoDevice, "Access denied.")
    }

    #[test]
    fn an_open_refused_because_another_holds_the_port_is_in_use() {
        // Held without sharing, as the serialport crate holds a COM port. (Wine does not
        // refuse a second open of a device; it does of a file, so a file stands in for it.)
        let file = TempFile::new("held");
        let held = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .share_mode(0)
            .open(file.path())
            .unwrap();
        let e = open_error(file.path(), crate_error());
        assert_eq!(
            (e.kind(), e.description.as_str()),
            (ErrorKind::NoDevice, "Access denied.")
        );
        drop(held);
        // Free again by the time it is asked: the crate's own error stands.
        let e = open_error(file.path(), crate_error());
        assert_eq!(e.kind(), ErrorKind::NoDevice);
    }

    #[test]
    fn an_open_of_a_port_that_does_not_exist_is_not_found() {
        for missing in [r"\\.\COM199", r"C:\no-such-dir\port"] {
            let e = open_error(
                missing,
                Error::new(
                    ErrorKind::NoDevice,
                    "The system cannot find the file specified.",
                ),
            );
            assert_eq!(
                e.kind(),
                ErrorKind::Io(io::ErrorKind::NotFound),
                "{missing}"
            );
            assert_eq!(e.description, "The system cannot find the file specified.");
        }
    }

    #[test]
    fn other_open_errors_are_left_as_the_crate_gave_them() {
        let e = open_error(
            r"\\.\COM199",
            Error::new(ErrorKind::InvalidInput, "bad name"),
        );
        assert_eq!(e.kind(), ErrorKind::InvalidInput);
        let file = TempFile::new("free");
        let e = open_error(
            file.path(),
            Error::new(
                ErrorKind::Io(io::ErrorKind::Other),
                "The parameter is incorrect.",
            ),
        );
        assert_eq!(e.kind(), ErrorKind::Io(io::ErrorKind::Other));
    }

    #[test]
    fn comm_timeouts_round_up_to_whole_milliseconds_never_zero() {
        assert_eq!(comm_timeout(Duration::ZERO), Duration::from_millis(1));
        assert_eq!(
            comm_timeout(Duration::from_micros(1)),
            Duration::from_millis(1)
        );
        assert_eq!(
            comm_timeout(Duration::from_micros(1750)),
            Duration::from_millis(2)
        );
        assert_eq!(
            comm_timeout(Duration::from_millis(100)),
            Duration::from_millis(100)
        );
        assert_eq!(
            comm_timeout(Duration::from_secs(u64::MAX)),
            Duration::from_millis(u64::from(u32::MAX - 1))
        );
    }
}
