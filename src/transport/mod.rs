//! Byte pipes under the [`Bus`](crate::bus::Bus). A transport moves bytes and knows nothing
//! of Modbus: a serial port ([`SerialTransport`]) or a TCP connection ([`TcpTransport`]).
//!
//! What goes where: the frames' bytes are the codec's ([`crate::codec::rtu`] for RTU,
//! [`crate::codec::mbap`] for Modbus TCP's MBAP header and transaction ids); which framing
//! an endpoint speaks is [`Endpoint::framing`]; the Bus writes and reads frames in that
//! framing through a transport and its framing together (`framed`, which passes RTU frames
//! through and runs a Modbus TCP session on `unit | PDU` for `tcp://`); timing, checks and
//! retries are the Bus's.
//!
//! Which transport a Bus opens is chosen by its [`Endpoint`], parsed from its port string
//! ([`parse_endpoint`]) once, when its config is made ([`BusConfig::new`]), and opened by
//! [`open`].

pub mod doctor;
mod framed;
#[cfg(target_os = "linux")]
mod linux;
pub mod ports;
mod serial;
mod tcp;
pub mod tuning;
#[cfg(windows)]
mod windows;

pub(crate) use framed::Framed;
pub use serial::{describe_open_error, SerialTransport};
pub use tcp::{describe_connect_error, TcpTransport, CONNECT_TIMEOUT, WRITE_TIMEOUT};

use crate::bus::BusConfig;
use crate::codec::Framing;
use crate::error::Error;

use std::io;
use std::net::{Ipv4Addr, Ipv6Addr};
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

    /// Lets go of the port in a process that did not open it: a child made by `fork()`,
    /// whose descriptors are copies of the parent's, sharing the port's settings, its locks
    /// and the connection with them. Nothing may be sent, and nothing shared changed: only
    /// this process's copy of the descriptor may be closed. The default leaks the transport
    /// (its drop never runs), which is always safe; a transport whose drop does more than
    /// close its descriptor must not run it here.
    fn abandon(self: Box<Self>) {
        std::mem::forget(self);
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

/// The port Modbus TCP uses when a `tcp://` address names none.
pub const MODBUS_TCP_PORT: u16 = 502;

/// What a Bus's port string names.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Endpoint {
    /// A serial port path (`/dev/ttyUSB0`): anything without `://`.
    Serial(String),
    /// `tcp://HOST[:PORT]`: Modbus TCP (MBAP frames) to a gateway; port 502 by default.
    ModbusTcp {
        /// DNS name, IPv4 address, or IPv6 address (without its brackets).
        host: String,
        /// TCP port.
        port: u16,
    },
    /// `rtu+tcp://HOST:PORT`: raw RTU frames over TCP to a serial device server (ser2net).
    RtuOverTcp {
        /// DNS name, IPv4 address, or IPv6 address (without its brackets).
        host: String,
        /// TCP port.
        port: u16,
    },
}

/// Refuses line options `endpoint` has no line for: a local echo (`echo`) over Modbus TCP,
/// where the gateway keeps the line; the kernel RS485 mode (`rs485`) anywhere but a local
/// serial port.
///
/// # Errors
/// The message saying why.
pub fn check_line_options(endpoint: &Endpoint, echo: bool, rs485: bool) -> Result<(), String> {
    if echo && matches!(endpoint, Endpoint::ModbusTcp { .. }) {
        return Err(
            "echo=True is for a serial line (or rtu+tcp://): over tcp:// the gateway \
                    keeps the line, and no echo reaches the Bus"
                .into(),
        );
    }
    if rs485 && !matches!(endpoint, Endpoint::Serial(_)) {
        return Err(
            "rs485=True is for a local serial port: over the network the gateway or \
                    device server drives the line"
                .into(),
        );
    }
    Ok(())
}

impl Endpoint {
    /// The frames that cross it: Modbus TCP's MBAP frames for `tcp://`, RTU frames for a
    /// serial port and `rtu+tcp://`.
    pub fn framing(&self) -> Framing {
        match self {
            Endpoint::ModbusTcp { .. } => Framing::Mbap,
            Endpoint::Serial(_) | Endpoint::RtuOverTcp { .. } => Framing::Rtu,
        }
    }

    /// `HOST:PORT` of a network endpoint (an IPv6 address in brackets), as `connect` takes
    /// it and messages show it; the path of a serial one.
    pub fn address(&self) -> String {
        match self {
            Endpoint::Serial(path) => path.clone(),
            Endpoint::ModbusTcp { host, port } | Endpoint::RtuOverTcp { host, port } => {
                host_port(host, *port)
            }
        }
    }
}

/// `HOST:PORT`, an IPv6 address in brackets: how `connect` takes a peer and messages show it.
pub(crate) fn host_port(host: &str, port: u16) -> String {
    if host.contains(':') {
        format!("[{host}]:{port}")
    } else {
        format!("{host}:{port}")
    }
}

/// Opens the transport of `config`'s endpoint ([`BusConfig::endpoint`]): a serial port at
/// its line format (and, on a board UART, its kernel RS485 mode), or a TCP connection
/// (Modbus TCP, or RTU frames over TCP). Opening again connects again. A [`Bus`]'s opener
/// unless it is given another ([`Bus::with_opener`]).
///
/// [`Bus`]: crate::Bus
/// [`Bus::with_opener`]: crate::Bus::with_opener
///
/// # Errors
/// [`Error::Port`] if the port cannot be opened or the connection made.
pub fn open(config: &BusConfig) -> crate::Result<Box<dyn Transport>> {
    let endpoint = config.endpoint();
    let (host, tcp_port) = match endpoint {
        Endpoint::Serial(path) => {
            return match SerialTransport::open_with(path, &config.line, config.rs485.as_ref()) {
                Ok(transport) => Ok(Box::new(transport)),
                Err(e) => Err(Error::Port {
                    port: config.port().to_string(),
                    message: format!("cannot open: {}", describe_open_error(&e)),
                    source: None,
                }),
            }
        }
        Endpoint::ModbusTcp { host, port } | Endpoint::RtuOverTcp { host, port } => (host, *port),
    };
    match TcpTransport::connect(host, tcp_port) {
        Ok(transport) => Ok(Box::new(transport)),
        Err(e) => Err(Error::Port {
            port: config.port().to_string(),
            message: format!(
                "cannot connect to {}: {}",
                endpoint.address(),
                describe_connect_error(&e)
            ),
            source: None,
        }),
    }
}

/// The port forms a Bus accepts, for messages.
const EXPECTED: &str = "expected a serial port path (/dev/ttyUSB0), tcp://HOST[:PORT] \
                        (Modbus TCP, port 502 by default) or rtu+tcp://HOST:PORT (RTU frames \
                        over TCP); HOST is a DNS name, an IPv4 address or a bracketed IPv6 \
                        address such as [::1]";

/// Parses a Bus's port string: a serial path, `tcp://HOST[:PORT]` or `rtu+tcp://HOST:PORT`.
/// A Bus's is parsed once, by [`BusConfig::new`]; what comes after takes the [`Endpoint`].
///
/// Pure (no name lookup, nothing opened). The scheme is matched without regard to case.
/// HOST is a DNS name (letters, digits, `-`, `_`, dot-separated labels), an IPv4 address,
/// or an IPv6 address in brackets (`[::1]`, no zone id); PORT is 1..=65535. Nothing may
/// follow the port: no path, query or user info.
///
/// # Errors
/// A message naming the port string, what is wrong with it and the forms expected: an
/// unknown scheme, an empty or malformed host, a missing (for `rtu+tcp`) or bad port,
/// anything after the port.
pub fn parse_endpoint(port: &str) -> Result<Endpoint, String> {
    let Some((scheme, rest)) = port.split_once("://") else {
        return Ok(Endpoint::Serial(port.to_string()));
    };
    let bad = |what: &str| format!("port {port:?}: {what}; {EXPECTED}");
    let scheme = scheme.to_ascii_lowercase();
    let default_port = match scheme.as_str() {
        "tcp" => Some(MODBUS_TCP_PORT),
        "rtu+tcp" => None,
        _ => return Err(bad(&format!("unknown transport {scheme:?}"))),
    };
    if let Some(c) = rest.chars().find(|c| matches!(c, '/' | '?' | '#' | '@')) {
        return Err(bad(&format!(
            "nothing but HOST[:PORT] may follow \"{scheme}://\" (found {c:?})"
        )));
    }
    let (host, port_part) = split_host_port(rest).map_err(|m| bad(&m))?;
    let tcp_port = match (port_part, default_port) {
        (Some(p), _) => parse_tcp_port(p).map_err(|m| bad(&m))?,
        (None, Some(p)) => p,
        (None, None) => return Err(bad(&format!("{scheme}:// needs a port (HOST:PORT)"))),
    };
    let host = host.to_string();
    Ok(if scheme == "tcp" {
        Endpoint::ModbusTcp {
            host,
            port: tcp_port,
        }
    } else {
        Endpoint::RtuOverTcp {
            host,
            port: tcp_port,
        }
    })
}

/// `HOST[:PORT]` split and the host checked: (host without brackets, port text if any).
fn split_host_port(rest: &str) -> Result<(&str, Option<&str>), String> {
    if rest.is_empty() {
        return Err("no host".into());
    }
    if let Some(bracketed) = rest.strip_prefix('[') {
        let Some((host, after)) = bracketed.split_once(']') else {
            return Err("an IPv6 address opened with '[' has no closing ']'".into());
        };
        if host.parse::<Ipv6Addr>().is_err() {
            return Err(format!("{host:?} in brackets is not an IPv6 address"));
        }
        return match after {
            "" => Ok((host, None)),
            _ => match after.strip_prefix(':') {
                Some(p) => Ok((host, Some(p))),
                None => Err(format!("unexpected {after:?} after the IPv6 address")),
            },
        };
    }
    let (host, port) = match rest.split_once(':') {
        Some((_, p)) if p.contains(':') => {
            return Err("an IPv6 address must be in brackets, as tcp://[::1]:502".into())
        }
        Some((h, p)) => (h, Some(p)),
        None => (rest, None),
    };
    check_host(host)?;
    Ok((host, port))
}

/// Whether `host` is an IPv4 address or a DNS name.
fn check_host(host: &str) -> Result<(), String> {
    if host.is_empty() {
        return Err("no host".into());
    }
    let labels: Vec<&str> = host.split('.').collect();
    if labels
        .iter()
        .all(|l| !l.is_empty() && l.bytes().all(|b| b.is_ascii_digit()))
    {
        // All digits: only an IPv4 address can look like that.
        return match host.parse::<Ipv4Addr>() {
            Ok(_) => Ok(()),
            Err(_) => Err(format!("{host:?} is not an IPv4 address")),
        };
    }
    // A fully qualified name may end in a dot ("gw.lab.").
    let name = host.strip_suffix('.').unwrap_or(host);
    let name_ok = name.len() <= 253
        && name.split('.').all(|l| {
            (1..=63).contains(&l.len())
                && !l.starts_with('-')
                && !l.ends_with('-')
                && l.bytes()
                    .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
        });
    if name_ok {
        Ok(())
    } else {
        Err(format!("{host:?} is not a host name or an IPv4 address"))
    }
}

fn parse_tcp_port(p: &str) -> Result<u16, String> {
    if p.is_empty() {
        return Err("no port after ':'".into());
    }
    match p.parse::<u16>() {
        Ok(n) if n > 0 && p.bytes().all(|b| b.is_ascii_digit()) => Ok(n),
        _ => Err(format!("bad TCP port {p:?} (1 to 65535)")),
    }
}

/// A pseudo-terminal pair for the transport's tests: (master fd, slave path). The slave
/// stays open only through what the test opens on the path.
#[cfg(all(test, unix))]
pub(crate) fn test_pty() -> (libc::c_int, String) {
    let (mut master, mut slave) = (-1, -1);
    let mut name = [0 as libc::c_char; 128];
    // SAFETY: valid out-pointers; a name buffer far longer than any /dev/pts/N.
    let rc = unsafe {
        libc::openpty(
            &mut master,
            &mut slave,
            name.as_mut_ptr(),
            // Null *mut: macOS declares these two *mut, Linux *const (a *mut coerces).
            std::ptr::null_mut(),
            std::ptr::null_mut(),
        )
    };
    assert_eq!(rc, 0, "openpty: {}", io::Error::last_os_error());
    // SAFETY: openpty wrote a NUL-terminated path into `name`.
    let path = unsafe { std::ffi::CStr::from_ptr(name.as_ptr()) }
        .to_string_lossy()
        .into_owned();
    // SAFETY: our own fd, closed once.
    unsafe { libc::close(slave) };
    (master, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tcp(host: &str, port: u16) -> Endpoint {
        Endpoint::ModbusTcp {
            host: host.into(),
            port,
        }
    }

    fn rtu(host: &str, port: u16) -> Endpoint {
        Endpoint::RtuOverTcp {
            host: host.into(),
            port,
        }
    }

    #[test]
    fn serial_paths_pass_through() {
        for p in ["/dev/ttyUSB0", "/dev/pts/3", "COM3", "relative:path", ""] {
            assert_eq!(parse_endpoint(p), Ok(Endpoint::Serial(p.into())));
        }
    }

    #[test]
    fn network_forms_parse() {
        assert_eq!(parse_endpoint("tcp://gw.lab"), Ok(tcp("gw.lab", 502)));
        assert_eq!(parse_endpoint("tcp://gw.lab:5020"), Ok(tcp("gw.lab", 5020)));
        assert_eq!(parse_endpoint("TCP://10.0.0.7"), Ok(tcp("10.0.0.7", 502)));
        assert_eq!(parse_endpoint("tcp://[::1]"), Ok(tcp("::1", 502)));
        assert_eq!(
            parse_endpoint("tcp://[fe80::2]:1502"),
            Ok(tcp("fe80::2", 1502))
        );
        assert_eq!(
            parse_endpoint("rtu+tcp://moxa-1:4001"),
            Ok(rtu("moxa-1", 4001))
        );
        assert_eq!(
            parse_endpoint("rtu+tcp://[::1]:65535"),
            Ok(rtu("::1", 65535))
        );
        assert_eq!(parse_endpoint("tcp://localhost:1"), Ok(tcp("localhost", 1)));
        assert_eq!(parse_endpoint("tcp://gw.lab.:7"), Ok(tcp("gw.lab.", 7)));
        assert_eq!(parse_endpoint("tcp://my_gw"), Ok(tcp("my_gw", 502)));
    }

    #[test]
    fn address_brackets_ipv6() {
        assert_eq!(tcp("::1", 502).address(), "[::1]:502");
        assert_eq!(rtu("gw", 4001).address(), "gw:4001");
    }

    #[test]
    fn bad_urls_are_refused_with_the_expected_forms() {
        let cases = [
            ("foo://x", "unknown transport \"foo\""),
            ("udp://host:502", "unknown transport"),
            ("://host", "unknown transport \"\""),
            ("tcp://", "no host"),
            ("tcp://:502", "no host"),
            ("rtu+tcp://host", "needs a port"),
            ("rtu+tcp://[::1]", "needs a port"),
            ("tcp://host:", "no port"),
            ("tcp://host:0", "bad TCP port"),
            ("tcp://host:65536", "bad TCP port"),
            ("tcp://host:+502", "bad TCP port"),
            ("tcp://host:50x", "bad TCP port"),
            ("tcp://host:502/path", "nothing but HOST[:PORT]"),
            ("tcp://host/", "nothing but HOST[:PORT]"),
            ("tcp://user@host:502", "nothing but HOST[:PORT]"),
            ("tcp://host:502?x=1", "nothing but HOST[:PORT]"),
            ("tcp://::1:502", "must be in brackets"),
            ("tcp://[::1", "no closing"),
            ("tcp://[::1]502", "after the IPv6 address"),
            ("tcp://[nothost]:502", "not an IPv6 address"),
            ("tcp://[fe80::1%eth0]:502", "not an IPv6 address"),
            ("tcp://192.168.1.300", "not an IPv4 address"),
            ("tcp://1.2.3", "not an IPv4 address"),
            ("tcp://bad host", "not a host name"),
            ("tcp://-gw", "not a host name"),
            ("tcp://a..b", "not a host name"),
            ("tcp://.", "not a host name"),
        ];
        for (url, why) in cases {
            let message = parse_endpoint(url).expect_err(url);
            assert!(message.contains(why), "{url}: {message}");
            assert!(message.contains(&format!("{url:?}")), "{url}: {message}");
            assert!(message.contains("rtu+tcp://HOST:PORT"), "{url}: {message}");
        }
    }
}
