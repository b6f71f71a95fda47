//! TCP transports on `std::net::TcpStream`: Modbus TCP (MBAP frames) to a gateway
//! (`tcp://`), and raw RTU frames over TCP to a serial device server (`rtu+tcp://`).
//!
//! The socket is non-blocking; every wait is a `poll` (`WSAPoll` on Windows) bounded by the
//! caller's deadline, so a read waits at most its timeout and a signal (EINTR) only makes it
//! wait on to the same deadline. A connection that ends (the peer closed it: end of file; or it was reset or
//! aborted, or any other socket error) fails the call at once with
//! [`port_lost`]: the Bus drops it, and [`Bus::reopen`](crate::Bus::reopen)
//! or a reconnecting Bus connects again.

use super::{port_lost, Transport};
use crate::codec::crc16;
use crate::error::hex;
use std::collections::VecDeque;
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

/// The transaction id of the first request on a Modbus TCP connection; each request after
/// it takes the next (wrapping after 65535).
pub const FIRST_TRANSACTION_ID: u16 = 1;

/// MBAP header bytes before the length field's count starts: transaction id, protocol id,
/// length.
const MBAP_PREFIX: usize = 6;

/// The MBAP length field's sane range: unit id + function code at least, unit id + the
/// longest PDU (253 bytes) at most.
const MBAP_LENGTH: std::ops::RangeInclusive<usize> = 2..=254;

/// The most a drain takes in one go: a peer that never stops sending does not hold it.
const DRAIN_LIMIT: usize = 64 * 1024;

/// The longest wait a deadline is computed for (a timeout beyond it waits this long).
const LONGEST_WAIT: Duration = Duration::from_secs(86_400);

/// What crosses the TCP connection.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Framing {
    /// Modbus TCP: MBAP header + PDU, translated to and from the Bus's RTU frames.
    Mbap,
    /// The Bus's RTU frames (CRC included), byte for byte.
    Rtu,
}

/// A TCP connection to a Modbus TCP gateway or a serial device server.
///
/// **`rtu+tcp://` ([`Framing::Rtu`])**: a plain byte pipe. A serial line sits behind the
/// device server, so [`Transport::is_serial_line`] is true: the Bus keeps t3.5 between
/// frames and reckons wire time from its line format, which is the serial side's (give the
/// Bus the baudrate the device server runs its serial port at). The network's own delay
/// comes out of the reply timeout.
///
/// **`tcp://` ([`Framing::Mbap`])**: the Bus builds and reads RTU frames; this transport
/// translates, so the Bus's reply reading, checks, retries and late-reply handling serve it
/// unchanged. A frame written is checked for its CRC, which is stripped, and sent as an
/// MBAP frame: transaction id ([`FIRST_TRANSACTION_ID`] first, then one more per request),
/// protocol id 0, length (1 + PDU length), unit id (the RTU frame's first byte), PDU. A
/// broadcast (unit 0) is sent like any request. What is read is taken whole MBAP frames at
/// a time and handed to the Bus in RTU form (unit + PDU + CRC-16), in as many pieces as it
/// asks for. A frame whose transaction id is not the last request's (a late reply to an
/// earlier one), whose protocol id is not 0, or that comes after the last request was
/// already answered, is dropped (logged at DEBUG on `benchbus::wire`). A header whose
/// length is outside 2..=254 means the stream is out of step (or not Modbus TCP at all):
/// there is no telling where the next frame starts, so the connection is reported lost and
/// the Bus drops it; a reopen (or a reconnecting Bus) starts a fresh one. The gateway does
/// the serial timing, so [`Transport::is_serial_line`] is false: no t3.5, no wire time.
pub struct TcpTransport {
    conn: Conn,
    /// The MBAP translation state; None for raw RTU over TCP.
    mbap: Option<Mbap>,
}

impl std::fmt::Debug for TcpTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TcpTransport")
            .field("peer", &self.conn.peer)
            .field("mbap", &self.mbap.is_some())
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
    pub fn connect(host: &str, port: u16, framing: Framing) -> io::Result<TcpTransport> {
        let peer = if host.contains(':') {
            format!("[{host}]:{port}")
        } else {
            format!("{host}:{port}")
        };
        let addrs: Vec<SocketAddr> = (host, port)
            .to_socket_addrs()
            .map_err(|e| io::Error::new(e.kind(), format!("cannot resolve {host:?}: {e}")))?
            .collect();
        let mut last = None;
        for addr in &addrs {
            match TcpStream::connect_timeout(addr, CONNECT_TIMEOUT) {
                Ok(stream) => return TcpTransport::over(stream, peer, framing),
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
    pub fn over(stream: TcpStream, peer: String, framing: Framing) -> io::Result<TcpTransport> {
        stream.set_nodelay(true)?;
        stream.set_nonblocking(true)?;
        let mbap = match framing {
            Framing::Mbap => Some(Mbap {
                next_tid: FIRST_TRANSACTION_ID,
                awaited: None,
                raw: Vec::new(),
                ready: VecDeque::new(),
                dropped: 0,
            }),
            Framing::Rtu => None,
        };
        Ok(TcpTransport {
            conn: Conn { stream, peer },
            mbap,
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

/// The MBAP frame of transaction `tid` carrying `adu` (unit + PDU, of a length in
/// [`MBAP_LENGTH`]): transaction id, protocol id 0, length, then `adu`.
fn mbap_frame(tid: u16, adu: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(MBAP_PREFIX + adu.len());
    out.extend_from_slice(&tid.to_be_bytes());
    out.extend_from_slice(&[0, 0]);
    out.extend_from_slice(&(adu.len() as u16).to_be_bytes());
    out.extend_from_slice(adu);
    out
}

/// The Modbus TCP side of a [`TcpTransport`].
struct Mbap {
    /// The transaction id of the next request.
    next_tid: u16,
    /// The transaction id of the request whose reply is awaited: the last one written, until
    /// it is answered (or the input is discarded before the next request).
    awaited: Option<u16>,
    /// Bytes received that do not yet make a whole MBAP frame.
    raw: Vec<u8>,
    /// The awaited reply in RTU form, as much of it as the Bus has not read yet.
    ready: VecDeque<u8>,
    /// Bytes of frames dropped (late replies, other protocols) since last asked.
    dropped: u64,
}

impl Mbap {
    /// The MBAP frame for the RTU frame `frame` (CRC checked and stripped); the next
    /// transaction id is used up and awaited.
    fn wrap(&mut self, frame: &[u8]) -> io::Result<Vec<u8>> {
        let not_rtu = |why: &str| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("cannot send {} over Modbus TCP: {why}", hex(frame)),
            )
        };
        let Some((adu, crc)) = frame.split_last_chunk::<2>() else {
            return Err(not_rtu("not an RTU frame"));
        };
        if !MBAP_LENGTH.contains(&adu.len()) {
            return Err(not_rtu("not an RTU frame (length)"));
        }
        if crc16(adu).to_le_bytes() != *crc {
            return Err(not_rtu("its CRC is wrong"));
        }
        let tid = self.next_tid;
        self.next_tid = tid.wrapping_add(1);
        self.awaited = Some(tid);
        Ok(mbap_frame(tid, adu))
    }

    /// The MBAP frame that carries the RTU frame `frame` (its CRC dropped unchecked): as a
    /// request it takes the next transaction id, as a reply the last request's. None for
    /// bytes too short to be a frame.
    fn shown(&self, frame: &[u8], sent: bool) -> Option<Vec<u8>> {
        let (adu, _crc) = frame.split_last_chunk::<2>()?;
        if !MBAP_LENGTH.contains(&adu.len()) {
            return None;
        }
        let tid = if sent {
            self.next_tid
        } else {
            self.next_tid.wrapping_sub(1)
        };
        Some(mbap_frame(tid, adu))
    }

    /// The next whole MBAP frame in `raw`, taken out of it; None while it is incomplete.
    ///
    /// # Errors
    /// [`port_lost`] if the header's length is not sane (the stream is out of step); what
    /// was buffered is dropped.
    fn next_frame(&mut self, peer: &str) -> io::Result<Option<Vec<u8>>> {
        let length = match self.raw.as_slice() {
            [_, _, _, _, hi, lo, ..] => usize::from(u16::from_be_bytes([*hi, *lo])),
            _ => return Ok(None),
        };
        if !MBAP_LENGTH.contains(&length) {
            let seen = hex(&self.raw[..self.raw.len().min(16)]);
            self.raw.clear();
            self.ready.clear();
            return Err(port_lost(format!(
                "Modbus TCP stream from {peer} out of step (MBAP length {length}, bytes {seen}): \
                 is it a Modbus TCP gateway? (a serial device server passing raw RTU frames is \
                 rtu+tcp://); connection dropped"
            )));
        }
        let total = MBAP_PREFIX + length;
        if self.raw.len() < total {
            return Ok(None);
        }
        let rest = self.raw.split_off(total);
        Ok(Some(std::mem::replace(&mut self.raw, rest)))
    }

    /// Takes a whole MBAP frame: the awaited reply goes to `ready` in RTU form; anything
    /// else is dropped.
    fn take(&mut self, frame: &[u8]) {
        let [t0, t1, p0, p1, _, _, adu @ ..] = frame else {
            return;
        };
        let tid = u16::from_be_bytes([*t0, *t1]);
        let protocol = u16::from_be_bytes([*p0, *p1]);
        if protocol != 0 || self.awaited != Some(tid) {
            self.dropped += frame.len() as u64;
        }
        if protocol != 0 {
            log::debug!(
                target: "benchbus::wire",
                "<- MBAP frame of protocol {protocol} (not Modbus), dropped: {}",
                hex(frame)
            );
            return;
        }
        if self.awaited != Some(tid) {
            let awaited = match self.awaited {
                Some(t) => format!("transaction {t} is awaited"),
                None => "no reply is awaited".into(),
            };
            log::debug!(
                target: "benchbus::wire",
                "<- MBAP reply to transaction {tid} ({awaited}): a late reply, dropped: {}",
                hex(frame)
            );
            return;
        }
        self.awaited = None;
        self.ready.extend(adu);
        self.ready.extend(crc16(adu).to_le_bytes());
    }
}

impl Transport for TcpTransport {
    fn write_all(&mut self, frame: &[u8]) -> io::Result<()> {
        match &mut self.mbap {
            None => self.conn.send(frame),
            Some(mbap) => {
                let out = mbap.wrap(frame)?;
                self.conn.send(&out)
            }
        }
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let Some(mbap) = &mut self.mbap else {
            return self.conn.recv(buf, timeout);
        };
        if buf.is_empty() {
            return Ok(0);
        }
        let deadline = Instant::now() + timeout.min(LONGEST_WAIT);
        let mut chunk = [0u8; 512];
        let mut expired = false;
        loop {
            while let Some(frame) = mbap.next_frame(&self.conn.peer)? {
                mbap.take(&frame);
            }
            if !mbap.ready.is_empty() {
                let n = buf.len().min(mbap.ready.len());
                for (slot, byte) in buf.iter_mut().zip(mbap.ready.drain(..n)) {
                    *slot = byte;
                }
                return Ok(n);
            }
            // One non-blocking try once the deadline has passed, then give up: frames that
            // keep coming but are all dropped do not hold the read past its deadline.
            if expired {
                return Ok(0);
            }
            let left = deadline.saturating_duration_since(Instant::now());
            expired = left.is_zero();
            let n = self.conn.recv(&mut chunk, left)?;
            if n == 0 {
                return Ok(0);
            }
            mbap.raw
                .extend_from_slice(chunk.get(..n).unwrap_or_default());
        }
    }

    fn discard_input(&mut self) -> io::Result<Vec<u8>> {
        let Some(mbap) = &mut self.mbap else {
            let mut stale = Vec::new();
            self.conn.drain(&mut stale)?;
            return Ok(stale);
        };
        // The awaited reply's unread rest, then every whole frame waiting. A frame's
        // beginning stays: its rest is on its way, and without it the stream is out of step.
        let mut stale: Vec<u8> = mbap.ready.drain(..).collect();
        self.conn.drain(&mut mbap.raw)?;
        while let Some(frame) = mbap.next_frame(&self.conn.peer)? {
            stale.extend_from_slice(&frame);
        }
        // Whatever answers an earlier request from now on is late.
        mbap.awaited = None;
        Ok(stale)
    }

    fn is_serial_line(&self) -> bool {
        self.mbap.is_none()
    }

    fn on_the_wire(&self, frame: &[u8], sent: bool) -> Option<Vec<u8>> {
        self.mbap.as_ref()?.shown(frame, sent)
    }

    fn take_dropped(&mut self) -> u64 {
        self.mbap
            .as_mut()
            .map_or(0, |mbap| std::mem::take(&mut mbap.dropped))
    }
}
