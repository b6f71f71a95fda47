//! A TCP connection on `std::net::TcpStream`, as a byte pipe: to a Modbus TCP gateway
//! (`tcp://`, whose MBAP framing is the codec's: [`crate::codec::mbap`]) or to a serial
//! device server passing raw RTU frames (`rtu+tcp://`).
//!
//! The socket is non-blocking; every wait is a `poll` (`WSAPoll` on Windows) bounded by the
//! caller's deadline, so a read waits at most its timeout and a signal (EINTR) only makes it
//! wait on to the same deadline. A connection that ends (the peer closed it: end of file; or it was reset or
//! aborted, or any other socket error) fails the call at once with
//! [`port_lost`]: the Bus drops it, and [`Bus::reopen`](crate::Bus::reopen)
//! or a reconnecting Bus connects again.

use super::{host_port, port_lost, Transport};
use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
#[cfg(unix)]
use std::os::unix::io::AsRawFd;
use std::time::{Duration, Instant};

/// How long a connection attempt may take, per address the host name resolves to (a host
/// that is down, or a firewall that drops the attempt, is given up on after this). A refused
/// connection fails at once. Resolving the name itself is the system resolver's business.
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(3);

/// How long a write may wait for room in the socket's send buffer. Writes of a few bytes
/// never wait in practice; a peer that takes nothing for this long has stopped reading, and
/// the connection is dropped as lost (a half-written frame would leave the stream out of
/// step anyway).
pub const WRITE_TIMEOUT: Duration = Duration::from_secs(1);

/// The most a drain takes in one go: a peer that never stops sending does not hold it.
const DRAIN_LIMIT: usize = 64 * 1024;

/// The longest wait a deadline is computed for (a timeout beyond it waits this long).
const LONGEST_WAIT: Duration = Duration::from_secs(86_400);

/// A TCP connection: bytes written go out as they are, bytes read are what came.
///
/// Behind a serial device server (`rtu+tcp://`) sits a serial line, so
/// [`Transport::is_serial_line`] is true: the Bus keeps t3.5 between frames and reckons
/// wire time from its line format, which is the serial side's (give the Bus the baudrate the
/// device server runs its serial port at). The network's own delay comes out of the reply
/// timeout. Over Modbus TCP (`tcp://`) the Bus frames its requests with the codec's MBAP
/// session, and the gateway keeps the line.
pub struct TcpTransport {
    conn: Conn,
}

impl std::fmt::Debug for TcpTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TcpTransport")
            .field("peer", &self.conn.peer)
            .finish()
    }
}

impl TcpTransport {
    /// Connects to `host` (a DNS name or an IP address, IPv6 without brackets) on `port`:
    /// every address the name resolves to is tried in turn, each for at most
    /// [`CONNECT_TIMEOUT`]. The socket is set `TCP_NODELAY` (a request goes out at once).
    ///
    /// # Errors
    /// The I/O error of the last address tried (see [`describe_connect_error`]), or of the
    /// name lookup.
    pub fn connect(host: &str, port: u16) -> io::Result<TcpTransport> {
        let peer = host_port(host, port);
        let addrs: Vec<SocketAddr> = (host, port)
            .to_socket_addrs()
            .map_err(|e| io::Error::new(e.kind(), format!("cannot resolve {host:?}: {e}")))?
            .collect();
        let mut last = None;
        for addr in &addrs {
            match TcpStream::connect_timeout(addr, CONNECT_TIMEOUT) {
                Ok(stream) => return TcpTransport::over(stream, peer),
                Err(e) => {
                    log::debug!(target: "benchbus::transport", "connect to {addr} failed: {e}");
                    last = Some(e);
                }
            }
        }
        Err(last.unwrap_or_else(|| {
            io::Error::new(
                io::ErrorKind::NotFound,
                format!("{host:?} resolves to no address"),
            )
        }))
    }

    /// A transport over a connected `stream` (whose peer is called `peer` in messages).
    ///
    /// # Errors
    /// The I/O error if the socket cannot be set up.
    pub fn over(stream: TcpStream, peer: String) -> io::Result<TcpTransport> {
        stream.set_nodelay(true)?;
        stream.set_nonblocking(true)?;
        Ok(TcpTransport {
            conn: Conn { stream, peer },
        })
    }
}

/// What a connect error means, for the message of a PortError ("cannot connect to
/// HOST:PORT: ...").
pub fn describe_connect_error(e: &io::Error) -> String {
    match e.kind() {
        io::ErrorKind::ConnectionRefused => {
            "connection refused (nothing listens on that port, or the host turned it away)".into()
        }
        io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock => format!(
            "no answer within {} s (host down or unreachable, or a firewall drops the \
             connection)",
            CONNECT_TIMEOUT.as_secs()
        ),
        _ => e.to_string(),
    }
}

/// The non-blocking socket, and waits on it bounded by deadlines.
struct Conn {
    stream: TcpStream,
    /// HOST:PORT, for messages.
    peer: String,
}

impl Conn {
    /// Reads at most `buf.len()` bytes, waiting at most `timeout` for the first; Ok(0) if
    /// nothing came (one non-blocking try when `timeout` is zero).
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        let deadline = Instant::now() + timeout.min(LONGEST_WAIT);
        loop {
            match self.stream.read(buf) {
                Ok(0) => return Err(self.closed()),
                Ok(n) => return Ok(n),
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {}
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(self.failed(e)),
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(0);
            }
            self.wait(false, left)?;
        }
    }

    /// Writes all of `data` within [`WRITE_TIMEOUT`].
    fn send(&mut self, mut data: &[u8]) -> io::Result<()> {
        let deadline = Instant::now() + WRITE_TIMEOUT;
        while !data.is_empty() {
            match self.stream.write(data) {
                Ok(0) => return Err(self.closed()),
                Ok(n) => data = data.get(n..).unwrap_or_default(),
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    let left = deadline.saturating_duration_since(Instant::now());
                    if left.is_zero() {
                        return Err(port_lost(format!(
                            "{} took nothing for {WRITE_TIMEOUT:?} (it stopped reading): \
                             connection dropped",
                            self.peer
                        )));
                    }
                    self.wait(true, left)?;
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(self.failed(e)),
            }
        }
        Ok(())
    }

    /// Waits up to `timeout` (rounded up to whole milliseconds) for the socket to be
    /// readable (or writable, if `write`), or to fail; returns early on a signal, for the
    /// caller to try again and wait on to its deadline.
    #[cfg(windows)]
    fn wait(&self, write: bool, timeout: Duration) -> io::Result<()> {
        super::windows::wait_socket(&self.stream, write, timeout)
    }

    /// Waits up to `timeout` (rounded up to whole milliseconds) for the socket to be
    /// readable (or writable, if `write`), or to fail; returns early on a signal, for the
    /// caller to try again and wait on to its deadline.
    #[cfg(unix)]
    fn wait(&self, write: bool, timeout: Duration) -> io::Result<()> {
        let ms = timeout.as_micros().div_ceil(1000).min(i32::MAX as u128) as libc::c_int;
        let mut fd = libc::pollfd {
            fd: self.stream.as_raw_fd(),
            events: if write { libc::POLLOUT } else { libc::POLLIN },
            revents: 0,
        };
        // SAFETY: one valid pollfd, owned by this stack frame, on a socket this owns.
        let n = unsafe { libc::poll(&mut fd, 1, ms) };
        if n < 0 {
            let e = io::Error::last_os_error();
            if e.kind() != io::ErrorKind::Interrupted {
                return Err(e);
            }
        }
        Ok(())
    }

    /// The error of a connection the peer closed (end of file).
    fn closed(&self) -> io::Error {
        port_lost(format!("connection closed by {}", self.peer))
    }

    /// A socket error: the connection is done for, whatever the error.
    fn failed(&self, e: io::Error) -> io::Error {
        port_lost(format!("connection to {} failed: {e}", self.peer))
    }

    /// Takes what is waiting, without waiting, up to [`DRAIN_LIMIT`], into `into`.
    fn drain(&mut self, into: &mut Vec<u8>) -> io::Result<()> {
        let mut chunk = [0u8; 1024];
        let mut taken = 0;
        while taken < DRAIN_LIMIT {
            let n = self.recv(&mut chunk, Duration::ZERO)?;
            if n == 0 {
                break;
            }
            into.extend_from_slice(chunk.get(..n).unwrap_or_default());
            taken += n;
        }
        Ok(())
    }
}

impl Transport for TcpTransport {
    fn write_all(&mut self, frame: &[u8]) -> io::Result<()> {
        self.conn.send(frame)
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        self.conn.recv(buf, timeout)
    }

    fn discard_input(&mut self) -> io::Result<Vec<u8>> {
        let mut stale = Vec::new();
        self.conn.drain(&mut stale)?;
        Ok(stale)
    }

    /// Closes this process's copy of the socket: a plain close (no `shutdown`), so the
    /// connection stays up for the process that opened it.
    fn abandon(self: Box<Self>) {
        drop(self);
    }
}
