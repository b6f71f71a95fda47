//! The Bus: one Modbus transaction at a time on one line, with retries, wire timing, per-unit
//! write pacing, statistics and a hex trace of every frame (log target `benchbus::wire`).
//!
//! One transaction, as it runs on the wire:
//!
//! ```text
//!  master  ...quiet >= t3.5 | request (n chars) |                         | quiet >= t3.5 | next
//!  slave                                        | turnaround | reply     |
//!          ^ timeout counts from the start of the request (at least timeout / 2 after its end)
//! ```
//!
//! The line is shared fairly: a call waits for its turn in arrival order and runs one attempt
//! per turn; a retry takes a new turn at the back of the queue, so an absent unit's retries
//! never hold the line while others wait; a write waits until the writes made before it to
//! its unit are over, and one made before an urgent write or a broadcast is not sent again
//! after it (`src/bus/writes.rs`). A [`CancelToken`] stops a call between attempts, or takes it
//! out of the queue.
//!
//! Stale bytes in the input buffer are dropped (and counted) before each request; the reply
//! is read by its expected length ([`Framing::reply_needed`]), never by waiting for a timeout; only a
//! timeout or a corrupt frame is retried, never an exception reply.
//!
//! A port that is lost (unplugged, hung up: [`crate::transport::is_lost`]) fails the call at
//! once and is dropped, which releases it (a USB adapter plugged in again can then get its
//! old name back). [`Bus::reopen`] opens the same path again; with [`BusConfig::reconnect`]
//! the Bus does that itself, once per call, before the call's request goes out.

use crate::codec::{
    ascii, check_echo, exception_meaning, hex, is_gateway_exception, DeviceIdentification, Echo,
    FrameError, Framing, Needed, Reply, Request, Response, BROADCAST,
};
use crate::error::{Error, Result};
use crate::timing::{sleep_until, LineFormat, SilenceGuard, Turnarounds, WritePacing};
use crate::transport::tuning::{check_rs485_platform, Rs485};
use crate::transport::{
    check_line_options, is_lost, open, parse_endpoint, Endpoint, Framed, Transport,
};
use owed::{Ledger, Owed};
use queue::{Cancel, Queue, Turn};
pub use queue::{CancelToken, Entered};
use std::collections::HashMap;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};
use writes::Writes;

mod owed;
mod owner;
mod queue;
mod writes;

/// How many timeouts an owed answer may take after the frame before it (see [`owed`]): the
/// documented limit of a unit's reply time.
const OWED_WINDOW: u32 = 3;

/// How many bytes of the request a failed reply must repeat to be taken for its echo (a
/// whole request if shorter): unit, function, address, and a byte of count or value. Five
/// is the shortest reply, so a read's echo read as a reply of byte count 0 still shows.
const ECHO_EVIDENCE: usize = 5;

/// The response taker for [`Bus::ask`]: what `pattern` binds in a response of its kind, as
/// `value`; a response of another kind is handed back.
macro_rules! pick {
    ($pattern:pat => $value:expr) => {
        |response: Response| match response {
            $pattern => Ok($value),
            other => Err(other),
        }
    };
}

/// The reads of `count` items from `address` (0x01 to 0x04), a row each: `fn name -> output
/// = request variant, response variant`; the response's values are the output. Each method
/// takes the unit, the address, the count and the [`TxOptions`].
macro_rules! reads {
    ($($(#[$doc:meta])* fn $name:ident -> $out:ty = $request:ident, $response:ident;)*) => {$(
        $(#[$doc])*
        pub fn $name(&self, unit: u8, address: u16, count: u16, opts: &TxOptions) -> Result<$out> {
            let request = Request::$request { address, count };
            self.ask(unit, &request, opts, pick!(Response::$response(values) => values))
        }
    )*};
}

/// The writes from `address` whose reply echoes them (0x05, 0x06, 0x0F, 0x10), a row each:
/// `fn name(field: type) = request variant`. Each method takes the unit, the address, the
/// value or values and the [`TxOptions`]; [`Bus::transact`] checks the echo.
macro_rules! writes {
    ($($(#[$doc:meta])* fn $name:ident($field:ident: $arg:ty) = $request:ident;)*) => {$(
        $(#[$doc])*
        pub fn $name(&self, unit: u8, address: u16, $field: $arg, opts: &TxOptions) -> Result<()> {
            let request = Request::$request { address, $field: $field.into() };
            self.transact(unit, &request, opts).map(|_| ())
        }
    )*};
}

/// The longest reply timeout a Bus takes ([`Bus::set_timeout`]): an hour.
pub const MAX_TIMEOUT: Duration = Duration::from_secs(3600);

/// The most retries a Bus takes ([`Bus::set_retries`]).
pub const MAX_RETRIES: u32 = 100;

/// Unit addresses a request may go to: 1..=255 (0 is broadcast). The serial line spec (2.2)
/// reserves 248..=255, but some devices use them (J2 controllers take stations 1..=255).
pub const UNITS: std::ops::RangeInclusive<u8> = 1..=255;

/// The unit addresses the serial line spec assigns to devices (2.2): what a scan tries.
pub const STANDARD_UNITS: std::ops::RangeInclusive<u8> = 1..=247;

/// How a Bus is opened.
#[derive(Debug, Clone)]
pub struct BusConfig {
    /// The port as given ([`BusConfig::port`]).
    port: String,
    /// What it names, parsed from it once ([`BusConfig::endpoint`]).
    endpoint: Endpoint,
    /// Line format (baud, parity, stop bits).
    pub line: LineFormat,
    /// How long to wait for a reply, per attempt.
    pub timeout: Duration,
    /// Further attempts after a timeout or a corrupt frame.
    pub retries: u32,
    /// Quiet time after a broadcast, for every device to act on it.
    pub turnaround: Duration,
    /// Whether a call that finds the port lost reopens it first (once per call; see
    /// [`Bus::reopen`]). Off: every call fails until [`Bus::reopen`] is called.
    pub reconnect: bool,
    /// Whether the adapter echoes what it sends (an RS485 adapter whose receiver stays on
    /// while it transmits): each request's echo is read back and checked before the reply
    /// is awaited (`Bus::send`). For serial lines and `rtu+tcp://`; refused on `tcp://`.
    pub echo: bool,
    /// Asked before each further attempt of a call (a retry, the next page of a device
    /// identification): whether the caller wants the call to stop there. The Python
    /// bindings run Python's signal handlers in it, so that Ctrl-C ends a call between
    /// attempts ([`Error::Interrupted`]); the attempt in flight always completes.
    pub interrupted: Option<fn() -> bool>,
    /// The kernel RS485 mode to set on a board UART when the port opens (Linux; see
    /// [`crate::transport::tuning`]); None leaves the port's mode as it is.
    pub rs485: Option<Rs485>,
    /// The quiet gap that ends a reply whose length is not known in advance (a raw
    /// [`Bus::request`] without a reply length): the longer of this and t3.5. Raise it for
    /// an adapter that delivers a reply in bursts (an FTDI chip's latency timer splits
    /// replies into chunks 16 ms apart unless set lower).
    pub silence: Duration,
    /// Whether the line speaks Modbus ASCII (`:`, hex, LRC, CR LF; [`crate::codec::ascii`])
    /// rather than RTU: serial lines and `rtu+tcp://` only (refused on `tcp://`). A reply
    /// ends at its CR LF, with up to [`crate::codec::ascii::INTER_CHAR_TIMEOUT`] between two
    /// of its characters; the line format is checked by [`LineFormat::check_ascii`].
    pub ascii: bool,
}

impl BusConfig {
    /// A config for the port `port` with the usual defaults: 100 ms timeout, 2 retries,
    /// 100 ms turnaround. The port is a serial port path (`/dev/ttyUSB0`, `/dev/pts/3`,
    /// `COM3`), `tcp://HOST[:PORT]` or `rtu+tcp://HOST:PORT` (see [`Bus::open`]), parsed
    /// here, once ([`crate::transport::parse_endpoint`]).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a malformed `scheme://` port, before anything is
    /// opened.
    pub fn new(port: &str, line: LineFormat) -> Result<BusConfig> {
        let endpoint = parse_endpoint(port).map_err(Error::InvalidArgument)?;
        Ok(BusConfig {
            port: port.to_string(),
            endpoint,
            line,
            timeout: Duration::from_millis(100),
            retries: 2,
            turnaround: Duration::from_millis(100),
            reconnect: false,
            echo: false,
            ascii: false,
            interrupted: None,
            rs485: None,
            silence: Duration::ZERO,
        })
    }

    /// The port as it was given, for messages.
    pub fn port(&self) -> &str {
        &self.port
    }

    /// What the port names: the transport a Bus opens and the framing it speaks there.
    pub fn endpoint(&self) -> &Endpoint {
        &self.endpoint
    }
}

/// Per-request options a device layer sets for its family.
#[derive(Debug, Clone, Copy)]
pub struct TxOptions {
    /// How strictly a write reply must echo the request.
    pub echo: Echo,
    /// Least time between two write requests to the same unit (J2: 150 ms).
    pub write_interval: Duration,
    /// Overrides the Bus timeout for this request.
    pub timeout: Option<Duration>,
    /// Overrides the Bus retries for this request.
    pub retries: Option<u32>,
    /// Whether the request is sent once, at once: no retry, and no wait for the answers
    /// its unit still owes to other calls (they stay owed, for the next call). For a stop
    /// on the way out of an error, when getting out matters more than the reply. A write's
    /// reply must echo its request, so an owed read answer that comes instead fails the
    /// echo check ([`Error::Frame`]): never taken for the write's. Reads are never sent so.
    pub urgent: bool,
    /// The device family's meaning of an exception code.
    pub meaning: fn(u8) -> &'static str,
    /// Whether the timeout is the whole window from the start of the request however long
    /// the request (a scan's probe: n silent units take n x timeout), rather than leaving the
    /// device at least half the timeout after a long request's end.
    pub window_from_start: bool,
    /// Whether a write is answered. False for devices set to answer no write (a BLD drive
    /// with F08.06 = 1): the write is sent once and nothing is awaited. Reads are always
    /// answered.
    pub write_ack: bool,
}

impl Default for TxOptions {
    fn default() -> Self {
        TxOptions {
            echo: Echo::Strict,
            write_interval: Duration::ZERO,
            timeout: None,
            retries: None,
            urgent: false,
            meaning: exception_meaning,
            window_from_start: false,
            write_ack: true,
        }
    }
}

/// Counters of what happened on the bus since it was opened.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stats {
    /// Requests completed with a reply (normal or exception) or sent as a broadcast.
    pub transactions: u64,
    /// Attempts repeated after a timeout or a corrupt frame.
    pub retries: u64,
    /// Attempts that got no complete reply in time.
    pub timeouts: u64,
    /// Replies with a bad CRC (in Modbus ASCII, a bad LRC).
    pub crc_errors: u64,
    /// Other malformed replies (wrong unit, function, length or echo).
    pub frame_errors: u64,
    /// Exception replies.
    pub exceptions: u64,
    /// Stale bytes dropped from the input before a request.
    pub stale_bytes: u64,
    /// Broadcast requests sent.
    pub broadcasts: u64,
    /// Times the port was opened again ([`Bus::reopen`], or a reconnect).
    pub reopens: u64,
    /// Times the line was found out of step and brought back: a frame that came too soon to
    /// answer its request (a copy, an earlier request's answer) was dropped, or bytes were
    /// waiting before a request.
    pub resyncs: u64,
}

/// Opens a Bus's transport from its config: at [`Bus::with_opener`], and again at each
/// [`Bus::reopen`] or reconnect. Its error is the one the caller sees (an [`Error::Port`]).
pub type Opener = Box<dyn FnMut(&BusConfig) -> Result<Box<dyn Transport>> + Send>;

/// The port, as the Bus holds it.
enum Link {
    Open(Framed),
    /// Lost (for this reason); the transport was dropped, so the port is released.
    Lost(String),
    /// Closed by [`Bus::close`].
    Closed,
}

struct State {
    link: Link,
    /// How the port is opened again; None for a Bus given its transport.
    opener: Option<Opener>,
    /// Frames handed to the transport (counted before each write): whether a call has put
    /// anything on the wire yet.
    frames_out: u64,
    silence: SilenceGuard,
    pacing: WritePacing,
    /// The answers units still owe for attempts that timed out (see [`owed`]).
    owed: Ledger,
    /// How soon each unit has answered lately (see [`Turnarounds`]).
    turnarounds: Turnarounds,
    /// Whether a local echo has come back right on this Bus (see [`Bus::read_echo`]).
    echo_seen: bool,
    stats: Stats,
    /// The call whose attempt has the line (see [`Bus::line`]).
    serving: u64,
}

/// A Modbus RTU master on one line. Thread-safe: callers take turns, one attempt each, in
/// the order they asked (a write after the earlier writes to its unit are over).
pub struct Bus {
    config: BusConfig,
    /// The reply timeout per attempt, in nanoseconds: the config's, then as set
    /// ([`Bus::set_timeout`]). A call reads it once, when it starts.
    timeout: AtomicU64,
    /// The retries after a timeout or a corrupt frame: the config's, then as set.
    retries: AtomicU32,
    /// The framing of the port's transport: what the Bus builds requests and reads replies
    /// in.
    framing: Framing,
    state: Mutex<State>,
    /// The turns on the line: whoever holds one may lock `state` for one attempt.
    queue: Arc<Queue>,
    /// The number of the next call (see [`owed::Owed::call`]).
    calls: AtomicU64,
    /// The writes in progress, so that each waits for the earlier ones to its unit (see
    /// [`writes`]).
    writes: Writes,
    /// One lock per unit for device layers' sequences (see [`Bus::exclusive`]), and the
    /// thread that holds it.
    sequences: Mutex<HashMap<u8, Arc<Sequence>>>,
    /// The process that opened the Bus, the only one that may use it (see [`Bus::owned`]).
    owner: u32,
}

impl std::fmt::Debug for Bus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bus").field("config", &self.config).finish()
    }
}

impl Bus {
    /// Opens the port of `config`: a serial port path, `tcp://HOST[:PORT]` (Modbus TCP to a
    /// gateway, port 502 by default) or `rtu+tcp://HOST:PORT` (RTU frames over TCP to a
    /// serial device server); see [`crate::transport::open`].
    ///
    /// # Errors
    /// [`Error::Port`] if the port cannot be opened or the connection made;
    /// [`Error::InvalidArgument`] for a bad line format.
    pub fn open(config: BusConfig) -> Result<Bus> {
        Bus::with_opener(config, Box::new(open))
    }

    /// A Bus over the transport `opener` makes from the config, now and at each reopen.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a bad line format, else the opener's error.
    pub fn with_opener(config: BusConfig, mut opener: Opener) -> Result<Bus> {
        check_config(&config)?;
        let transport = opener(&config)?;
        Ok(Bus::build(config, transport, Some(opener)))
    }

    /// A Bus over any transport (used by tests and other transports). It cannot be reopened:
    /// [`Bus::reopen`] fails with [`Error::Port`] (use [`Bus::with_opener`] for that).
    pub fn with_transport(config: BusConfig, transport: Box<dyn Transport>) -> Bus {
        Bus::build(config, transport, None)
    }

    fn build(config: BusConfig, transport: Box<dyn Transport>, opener: Option<Opener>) -> Bus {
        let framed = Framed::new(transport, &config.endpoint);
        let framing = if config.ascii {
            Framing::Ascii
        } else {
            framed.framing()
        };
        Bus {
            timeout: AtomicU64::new(nanos(config.timeout)),
            retries: AtomicU32::new(config.retries),
            config,
            framing,
            state: Mutex::new(State {
                link: Link::Open(framed),
                opener,
                frames_out: 0,
                silence: SilenceGuard::new(),
                pacing: WritePacing::new(),
                owed: Ledger::default(),
                turnarounds: Turnarounds::new(),
                echo_seen: false,
                stats: Stats::default(),
                serving: 0,
            }),
            queue: Arc::new(Queue::default()),
            calls: AtomicU64::new(0),
            writes: Writes::default(),
            sequences: Mutex::new(HashMap::new()),
            owner: std::process::id(),
        }
    }

    /// The configuration the bus was opened with. Its `timeout` and `retries` stay those it
    /// was opened with: [`Bus::timeout`] and [`Bus::retries`] are the ones calls use.
    pub fn config(&self) -> &BusConfig {
        &self.config
    }

    /// The reply timeout per attempt that a call starting now uses (unless its
    /// [`TxOptions`] give their own): the config's, or the last [`Bus::set_timeout`].
    pub fn timeout(&self) -> Duration {
        Duration::from_nanos(self.timeout.load(Ordering::Relaxed))
    }

    /// The retries that a call starting now makes (unless its [`TxOptions`] give their
    /// own): the config's, or the last [`Bus::set_retries`].
    pub fn retries(&self) -> u32 {
        self.retries.load(Ordering::Relaxed)
    }

    /// Sets the reply timeout per attempt for the calls that start from now on (a slow
    /// command, a long flash write); a call in flight keeps the one it started with.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a timeout of zero or over [`MAX_TIMEOUT`]; the
    /// timeout is then left as it was.
    pub fn set_timeout(&self, timeout: Duration) -> Result<()> {
        if timeout.is_zero() || timeout > MAX_TIMEOUT {
            return Err(Error::InvalidArgument(format!(
                "timeout must be 0 < seconds <= {}, got {}",
                MAX_TIMEOUT.as_secs(),
                timeout.as_secs_f64()
            )));
        }
        self.timeout.store(nanos(timeout), Ordering::Relaxed);
        Ok(())
    }

    /// Sets the retries for the calls that start from now on; a call in flight keeps the
    /// ones it started with.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for more than [`MAX_RETRIES`]; the retries are then left
    /// as they were.
    pub fn set_retries(&self, retries: u32) -> Result<()> {
        if retries > MAX_RETRIES {
            return Err(Error::InvalidArgument(format!(
                "retries must be 0 to {MAX_RETRIES}, got {retries}"
            )));
        }
        self.retries.store(retries, Ordering::Relaxed);
        Ok(())
    }

    /// A snapshot of the counters (all zero in a process other than the one that opened
    /// the Bus: see [`Bus::owned`]).
    pub fn stats(&self) -> Stats {
        if self.owned().is_err() {
            return Stats::default();
        }
        self.lock().stats
    }

    /// Whether [`Bus::close`] was called (and no [`Bus::reopen`] since); always, in a
    /// process other than the one that opened the Bus (see [`Bus::owned`]).
    pub fn is_closed(&self) -> bool {
        self.owned().is_err() || matches!(self.lock().link, Link::Closed)
    }

    /// Whether the port was lost (or a reopen failed) and has not been opened again since.
    pub fn is_lost(&self) -> bool {
        self.owned().is_ok() && matches!(self.lock().link, Link::Lost(_))
    }

    /// Closes the port; later calls fail with [`Error::Closed`] (a reconnecting Bus does not
    /// reopen it; [`Bus::reopen`] does). Closing twice is harmless. In a process other than
    /// the one that opened the Bus, it sends nothing and leaves the port to that process
    /// (see [`Bus::owned`]).
    pub fn close(&self) {
        if self.owned().is_err() {
            return self.let_go();
        }
        self.lock().link = Link::Closed;
    }

    /// Closes the port and opens the same path again with the same line format: after the
    /// port was lost and has come back (the adapter plugged in again), or to start afresh.
    /// The statistics, pacing and device objects on this Bus carry on; a transaction in
    /// progress on another thread finishes first.
    ///
    /// Works in any state, a closed Bus included (that opens it again). If the path cannot
    /// be opened, the Bus is left without a port: lost (closed, if it was closed), so calls
    /// fail at once until a reopen succeeds.
    ///
    /// # Errors
    /// [`Error::Port`] if the path cannot be opened (absent, in use) or the Bus was given its
    /// transport rather than a way to open it.
    pub fn reopen(&self) -> Result<()> {
        self.owned()?;
        let Some(mut st) = self.line(&Cancel::default(), |_| None) else {
            return Err(Error::Internal(
                "no turn on the line without a token".into(),
            ));
        };
        if st.opener.is_none() {
            return Err(self.cannot_reopen());
        }
        // The old handle goes first: it holds the port's exclusive lock.
        let old = std::mem::replace(&mut st.link, Link::Closed);
        let was_closed = matches!(old, Link::Closed);
        drop(old);
        self.open_link(&mut st).inspect_err(|e| {
            if !was_closed {
                st.link = Link::Lost(port_message(e));
            }
        })
    }

    /// Opens the port into `st` (counted in the stats), whose link holds no port; on failure
    /// the link is left as it was.
    fn open_link(&self, st: &mut State) -> Result<()> {
        let opened = match st.opener.as_mut() {
            Some(opener) => opener(&self.config),
            None => Err(self.cannot_reopen()),
        };
        let transport = opened?;
        st.link = Link::Open(Framed::new(transport, &self.config.endpoint));
        st.stats.reopens += 1;
        log::debug!(target: "benchbus::wire", "port {} reopened", self.config.port);
        Ok(())
    }

    /// Runs `body` (one attempt of a call, in its turn) on the open port; `call` is what
    /// the call did on the port in its earlier attempts.
    ///
    /// A lost port fails the call at once, or with [`BusConfig::reconnect`] is reopened
    /// first. A port lost during `body` is dropped; if nothing of this call had been written
    /// yet, a reconnecting Bus reopens it and runs `body` again. Either way at most one
    /// reopen per call.
    fn on_port<T>(
        &self,
        st: &mut State,
        call: &mut CallPort,
        mut body: impl FnMut(&mut State) -> Result<T>,
    ) -> Result<T> {
        match &st.link {
            Link::Open(_) => {}
            Link::Closed => return Err(self.closed()),
            Link::Lost(reason) if self.config.reconnect && !call.reopened => {
                let reason = reason.clone();
                self.reconnect(st, &reason)?;
                call.reopened = true;
            }
            Link::Lost(reason) => {
                return Err(Error::Port {
                    port: self.config.port.clone(),
                    message: format!(
                        "lost earlier ({reason}); call reopen() once it is back, or open the \
                         Bus with reconnect=True"
                    ),
                    source: None,
                })
            }
        }
        loop {
            let before = st.frames_out;
            let result = body(st);
            let untouched = !call.wrote && st.frames_out == before;
            call.wrote |= st.frames_out != before;
            let reason = match &result {
                Err(Error::Port {
                    source: Some(io), ..
                }) if is_lost(io) => io.to_string(),
                _ => return result,
            };
            // Dropping the transport closes the port (and releases its lock).
            st.link = Link::Lost(reason.clone());
            log::debug!(target: "benchbus::wire", "port {} lost: {reason}", self.config.port);
            if !self.config.reconnect || call.reopened || !untouched {
                return result;
            }
            self.reconnect(st, &reason)?;
            call.reopened = true;
        }
    }

    fn cannot_reopen(&self) -> Error {
        Error::Port {
            port: self.config.port.clone(),
            message: "cannot reopen: this Bus was given its transport, not a way to open it".into(),
            source: None,
        }
    }

    /// A reconnecting Bus's one attempt to reopen the port it lost for `reason`.
    fn reconnect(&self, st: &mut State, reason: &str) -> Result<()> {
        self.open_link(st).map_err(|e| Error::Port {
            port: self.config.port.clone(),
            message: format!("lost ({reason}); tried to reopen it: {}", port_message(&e)),
            source: None,
        })
    }

    reads! {
        /// Reads `count` holding registers (0x03).
        ///
        /// # Errors
        /// Any [`Error`]: bad arguments, port, timeout, frame or exception.
        fn read_holding_registers -> Vec<u16> = ReadHoldingRegisters, Registers;

        /// Reads `count` (1..=2000) coils from `address` (0x01).
        ///
        /// # Errors
        /// Any [`Error`]: bad arguments, port, timeout, frame or exception.
        fn read_coils -> Vec<bool> = ReadCoils, Bits;

        /// Reads `count` (1..=2000) discrete inputs from `address` (0x02).
        ///
        /// # Errors
        /// Any [`Error`].
        fn read_discrete_inputs -> Vec<bool> = ReadDiscreteInputs, Bits;

        /// Reads `count` (1..=125) input registers from `address` (0x04).
        ///
        /// # Errors
        /// Any [`Error`].
        fn read_input_registers -> Vec<u16> = ReadInputRegisters, Registers;
    }

    writes! {
        /// Writes one register (0x06).
        ///
        /// # Errors
        /// Any [`Error`].
        fn write_register(value: u16) = WriteSingleRegister;

        /// Writes consecutive registers (0x10).
        ///
        /// # Errors
        /// Any [`Error`].
        fn write_registers(values: &[u16]) = WriteMultipleRegisters;

        /// Sets one coil on or off (0x05); the reply must echo it (0xFF00 / 0x0000).
        ///
        /// # Errors
        /// Any [`Error`].
        fn write_coil(value: bool) = WriteSingleCoil;

        /// Sets 1..=1968 consecutive coils from `address` (0x0F).
        ///
        /// # Errors
        /// Any [`Error`].
        fn write_coils(values: &[bool]) = WriteMultipleCoils;
    }

    /// One request by [`Bus::transact`], its response taken apart by `pick` (which hands
    /// back a response of another kind, one the codec never gives for the request).
    fn ask<T>(
        &self,
        unit: u8,
        request: &Request,
        opts: &TxOptions,
        pick: impl FnOnce(Response) -> std::result::Result<T, Response>,
    ) -> Result<T> {
        pick(self.transact(unit, request, opts)?).map_err(|other| {
            let kind = FrameError::Length(format!("unexpected response {other:?}"));
            frame_error(unit, request.function(), kind, Vec::new())
        })
    }

    /// Changes bits of one register (0x16): the register becomes (its value AND `and_mask`)
    /// OR (`or_mask` AND NOT `and_mask`); the reply must echo the request.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn mask_write_register(
        &self,
        unit: u8,
        address: u16,
        and_mask: u16,
        or_mask: u16,
        opts: &TxOptions,
    ) -> Result<()> {
        let request = Request::MaskWriteRegister {
            address,
            and_mask,
            or_mask,
        };
        self.transact(unit, &request, opts).map(|_| ())
    }

    /// Writes `values` (1..=121) from `write_address`, then reads `read_count` (1..=125)
    /// registers from `read_address`, in one transaction (0x17; the device writes first).
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn read_write_registers(
        &self,
        unit: u8,
        read_address: u16,
        read_count: u16,
        write_address: u16,
        values: &[u16],
        opts: &TxOptions,
    ) -> Result<Vec<u16>> {
        let request = Request::ReadWriteRegisters {
            read_address,
            read_count,
            write_address,
            values: values.to_vec(),
        };
        self.ask(
            unit,
            &request,
            opts,
            pick!(Response::Registers(values) => values),
        )
    }

    /// Reads the eight exception status outputs (0x07, a serial line function: over Modbus
    /// TCP it goes to the unit behind the gateway like any other).
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn read_exception_status(&self, unit: u8, opts: &TxOptions) -> Result<u8> {
        self.ask(
            unit,
            &Request::ReadExceptionStatus,
            opts,
            pick!(Response::ExceptionStatus(status) => status),
        )
    }

    /// Runs diagnostics sub-function `sub_function` with `data` (0x08) and returns the
    /// data of the reply after its sub-function. The reply must carry the same
    /// sub-function, and for 0x00 (return query data, a line test) the same data.
    /// Sub-function 0x04 (force listen only) is sent once and not awaited (no device
    /// answers it): the result is then empty.
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn diagnostics(
        &self,
        unit: u8,
        sub_function: u16,
        data: &[u8],
        opts: &TxOptions,
    ) -> Result<Vec<u8>> {
        let request = Request::Diagnostics {
            sub_function,
            data: data.to_vec(),
        };
        self.ask(
            unit,
            &request,
            opts,
            pick!(Response::Diagnostics { data, .. } => data),
        )
    }

    /// The data field of a Report Server ID reply (0x11), after its byte count, as the
    /// device sent it (its layout is the device's).
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn report_server_id(&self, unit: u8, opts: &TxOptions) -> Result<Vec<u8>> {
        self.ask(
            unit,
            &Request::ReportServerId,
            opts,
            pick!(Response::ServerId(data) => data),
        )
    }

    /// Sends function `function` (1..=127) with `data` (the PDU after the function code)
    /// and returns the reply's bytes after its function code. With `reply_length` the
    /// reply is read by that length; without, it ends when the line has been quiet for
    /// the longer of t3.5 and [`BusConfig::silence`] (the one reply read by silence). An
    /// exception reply is known at 5 bytes, as for every function.
    ///
    /// # Errors
    /// Any [`Error`]; [`Error::InvalidArgument`] for a reserved function code or data
    /// longer than a PDU holds, before anything is sent.
    pub fn request(
        &self,
        unit: u8,
        function: u8,
        data: &[u8],
        reply_length: Option<usize>,
        opts: &TxOptions,
    ) -> Result<Vec<u8>> {
        let request = Request::Raw {
            function,
            data: data.to_vec(),
            reply_length,
        };
        self.ask(unit, &request, opts, pick!(Response::Raw(data) => data))
    }

    /// Reads device identification objects (0x2B / 0x0E) from `object_id` on, following
    /// "more follows" until the device has sent them all.
    ///
    /// # Errors
    /// Any [`Error`]; a device without the function answers exception 1.
    pub fn read_device_identification(
        &self,
        unit: u8,
        read_code: u8,
        object_id: u8,
        opts: &TxOptions,
    ) -> Result<DeviceIdentification> {
        let mut all = DeviceIdentification::default();
        let mut next = object_id;
        // A device may split its objects over several replies; 256 bounds a device that
        // keeps saying "more follows".
        for page in 0..256 {
            let request = Request::ReadDeviceIdentification {
                read_code,
                object_id: next,
            };
            if page > 0 && self.interrupted() {
                return Err(interrupted(unit, &request, page));
            }
            let page = self.ask(
                unit,
                &request,
                opts,
                pick!(Response::DeviceIdentification(page) => page),
            )?;
            let advanced = page.next_object > next || page.objects.keys().any(|&k| k >= next);
            all.read_code = page.read_code;
            all.conformity = page.conformity;
            all.objects.extend(page.objects);
            if !page.more_follows || !advanced {
                break;
            }
            next = page.next_object;
        }
        Ok(all)
    }

    /// Sends a write `request` to every unit (unit 0). Waits for no reply, then keeps the
    /// line quiet for the turnaround delay; any answer a device sends anyway is dropped. A
    /// broadcast is a write to every unit: it waits out each unit's write interval, and the
    /// next paced write to any unit waits its interval after it.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a request that is not a write or is malformed (before
    /// anything is sent); [`Error::Port`] or [`Error::Closed`]; on a Bus opened with `echo`,
    /// [`Error::Frame`] if the local echo was garbled (not repeated: whether the units got
    /// the write is not known; the turnaround is kept all the same).
    pub fn broadcast(&self, request: &Request) -> Result<()> {
        self.broadcast_paced(request, Duration::ZERO)
    }

    /// [`Bus::broadcast`] as a write to units whose devices want `write_interval` between
    /// two writes: it also waits that long after the last broadcast, for units that no
    /// paced write has told the Bus of yet (a gateway's, which knows every unit's interval).
    ///
    /// # Errors
    /// As [`Bus::broadcast`].
    pub fn broadcast_paced(&self, request: &Request, write_interval: Duration) -> Result<()> {
        self.owned()?;
        if !request.is_echoed_write() {
            return Err(Error::InvalidArgument(format!(
                "only a write (0x05, 0x06, 0x0F, 0x10, 0x16) can be broadcast, not function \
                 {:#04x}",
                request.function()
            )));
        }
        request.validate()?;
        let frame = self.framing.encode_request(BROADCAST, request);
        // Once gone out, the writes made before it do not go out (see `writes`).
        let call = self.writes.number(&self.calls);
        let ready = |st: &State| {
            let late = st.late_until(BROADCAST, call);
            st.pacing.broadcast_ready(write_interval).max(late)
        };
        let Some(mut st) = self.line(&Cancel::current(), ready) else {
            return Err(cancelled(BROADCAST, request, 0));
        };
        st.serving = call;
        let frames_before = st.frames_out;
        let done = self.on_port(&mut st, &mut CallPort::default(), |st| {
            let sent = self.send(st, &frame, request, self.timeout(), false);
            let sent_end = match &sent {
                Ok(end) => *end,
                Err(Error::Frame { .. }) => Instant::now(),
                Err(_) => return sent.map(|_| ()),
            };
            st.stats.broadcasts += 1;
            st.stats.transactions += 1;
            // The turnaround is quiet line: it counts from the end of the frame on the wire.
            sleep_until(sent_end + self.config.turnaround);
            let transport = self.port(&mut st.link)?;
            let answers = transport.discard_input().map_err(|e| self.io_error(e))?;
            if !answers.is_empty() {
                log::debug!(target: "benchbus::wire", "broadcast answered, dropped: {}", self.wire_text(&answers));
            }
            let now = Instant::now();
            st.silence.busy_until(now);
            st.pacing.broadcast(now);
            if let Err(e) = sent {
                st.stats.frame_errors += 1;
                return Err(e);
            }
            Ok(())
        });
        if st.frames_out != frames_before {
            self.writes.overrule(None, call);
        }
        done
    }

    /// Whether `unit` answers a read of one register at `address` within `timeout` (an
    /// exception reply counts as an answer, except a gateway's 0x0A / 0x0B for it). One
    /// attempt, no retries.
    ///
    /// `timeout` is the whole window a unit gets, counted from the start of the request (its
    /// own time on the wire included), so a scan of n absent units takes n x `timeout`. Unlike
    /// a read, which leaves the device at least half its timeout after a long request, a
    /// probe leaves it only t3.5 after the request to start its answer.
    ///
    /// # Errors
    /// [`Error::Port`] or [`Error::Closed`]; timeouts and corrupt frames mean "absent".
    pub fn probe(&self, unit: u8, address: u16, timeout: Duration) -> Result<bool> {
        let opts = TxOptions {
            timeout: Some(timeout),
            window_from_start: true,
            retries: Some(0),
            ..TxOptions::default()
        };
        match self.read_holding_registers(unit, address, 1, &opts) {
            // A gateway's answer for a unit it could not reach is not the unit's.
            Err(Error::Exception { code, .. }) if is_gateway_exception(code) => Ok(false),
            Ok(_) | Err(Error::Exception { .. }) => Ok(true),
            Err(Error::Timeout { .. } | Error::Frame { .. }) => Ok(false),
            Err(e) => Err(e),
        }
    }

    /// One request, retried after a timeout or a corrupt frame, and its checked response.
    ///
    /// Each attempt has its own turn on the line: a retry waits at the back of the queue,
    /// behind the callers that asked meanwhile, but a write waits until the writes made
    /// before it to its unit are over, and is not sent again after an urgent write, a write
    /// nested in it or a broadcast made after it (`src/bus/writes.rs`). A paced write waits
    /// for its interval, and a request to a unit that still owes answers to another call's
    /// timed-out attempts waits for them (up to three timeouts each), without a turn while
    /// it can. A frame that comes too soon to answer an attempt is dropped
    /// ([`Turnarounds`]). Under a cancelled [`CancelToken`] the call starts no further
    /// attempt and fails with [`Error::Cancelled`].
    ///
    /// # Errors
    /// Any [`Error`]: bad arguments before anything is sent, then port, timeout (after the
    /// last attempt), frame or exception; [`Error::Cancelled`], [`Error::Interrupted`].
    pub fn transact(&self, unit: u8, request: &Request, opts: &TxOptions) -> Result<Response> {
        self.owned()?;
        if !UNITS.contains(&unit) {
            return Err(Error::InvalidArgument(format!(
                "unit must be 1 to 255, got {unit} (unit 0 is broadcast: use Bus::broadcast)"
            )));
        }
        request.validate()?;
        let frame = self.framing.encode_request(unit, request);
        let cancel = Cancel::current();
        // An urgent request is sent once, and does not wait for what its unit owes.
        let urgent = opts.urgent && is_write(request);
        // Another write keeps its place among the writes to its unit; once gone out, an
        // urgent one keeps those made before it from going out (see `writes`).
        let mut writing = (writes::changes_device(request) && !urgent)
            .then(|| self.writes.enter(unit, &self.calls));
        let call = match &writing {
            Some(writing) => writing.call(),
            None if urgent => self.writes.number(&self.calls),
            None => self.calls.fetch_add(1, Ordering::Relaxed),
        };
        let paced = is_write(request) && !opts.write_interval.is_zero();
        let timeout = opts.timeout.unwrap_or_else(|| self.timeout());
        let attempts = if request.is_answered() && !urgent {
            opts.retries
                .unwrap_or_else(|| self.retries())
                .saturating_add(1)
        } else {
            1
        };
        let mut port = CallPort::default();
        let mut last_error = None;
        // The first of this call's attempts that got no answer: a frame that comes in a later
        // attempt may be its answer (the same request), so it is timed from there.
        let mut first_unanswered: Option<Sent> = None;
        let mut made = 0;
        if let Some(writing) = &writing {
            self.after_earlier_writes(unit, writing, request, &cancel)?;
        }
        for attempt in 0..attempts {
            if attempt > 0 && self.interrupted() {
                return Err(interrupted(unit, request, attempt));
            }
            // A repeated write is a write command too: it keeps the interval.
            let ready = |st: &State| {
                let pacing = paced
                    .then(|| st.pacing.write_ready(unit, opts.write_interval))
                    .flatten();
                let late = if urgent {
                    None
                } else {
                    st.late_until(unit, call)
                };
                pacing.max(late)
            };
            let Some(mut st) = self.line(&cancel, ready) else {
                return Err(cancelled(unit, request, attempt));
            };
            // An urgent write, a write nested in this one (a signal handler's) or a broadcast
            // made after this write has gone out: sent now, this one would undo it. Told
            // while holding the line, as they are sent.
            if writing.as_ref().is_some_and(|w| self.writes.overruled(w)) {
                log::debug!(
                    target: "benchbus::wire",
                    "not sent: an urgent or nested write or a broadcast to unit {unit} made after it went out"
                );
                if last_error.is_none() {
                    return Err(cancelled(unit, request, 0));
                }
                break;
            }
            st.serving = call;
            made = attempt + 1;
            let frames_before = st.frames_out;
            if attempt > 0 {
                st.stats.retries += 1;
            }
            let outcome = self.on_port(&mut st, &mut port, |st| {
                self.exchange(
                    st,
                    unit,
                    request,
                    &frame,
                    opts,
                    (timeout, urgent),
                    &mut first_unanswered,
                )
            });
            let overrules = urgent || writing.as_ref().is_some_and(writes::Writing::nested);
            if overrules && st.frames_out != frames_before {
                self.writes.overrule(Some(unit), call);
            }
            // The attempt timed out, so its answer is owed: it may still come, and a device
            // that queues requests answers every attempt, one after the other. RTU replies
            // carry no transaction id, but they name their unit: the next request of another
            // call to the same unit waits until the owed answers have come or their windows
            // have passed (see `State::late_until` and `Bus::send`), and a request to another
            // unit goes out at once and drops them if they come (see `attempt`): so the debt
            // is recorded at once, for the other callers' attempts between this call's.
            // Within a call an owed answer answers the same request, so retries do not wait.
            // A probe's unit is not asked again, and a late answer from it would name the
            // wrong unit.
            if matches!(outcome, Err(Error::Timeout { .. })) && !opts.window_from_start {
                st.owed
                    .owe(unit, request, call, timeout * OWED_WINDOW, Instant::now());
            }
            let error = match outcome {
                Err(e) if e.is_retryable() => e,
                ended => {
                    // Over while it holds the line: the next write to the unit goes on.
                    drop(writing.take());
                    return ended;
                }
            };
            if unanswered(request, opts) && attempt + 1 < attempts {
                log::debug!(target: "benchbus::wire", "unanswered write, sent again: {error}");
            }
            last_error = Some(error);
        }
        if let Some(Error::Timeout { attempts: n, .. }) = &mut last_error {
            *n = made;
        }
        Err(last_error.unwrap_or_else(|| Error::InvalidArgument("no attempt made".into())))
    }

    /// One attempt of a request on the open port, and its checked response, counted in the
    /// stats. A request that is not answered ([`unanswered`]) is sent, and only a garbled
    /// local echo fails it (to be sent again, as a corrupt reply would be).
    #[allow(clippy::too_many_arguments)]
    fn exchange(
        &self,
        st: &mut State,
        unit: u8,
        request: &Request,
        frame: &[u8],
        opts: &TxOptions,
        (timeout, urgent): (Duration, bool),
        earlier: &mut Option<Sent>,
    ) -> Result<Response> {
        let unanswered = unanswered(request, opts);
        let outcome = if unanswered {
            self.send(st, frame, request, timeout, urgent)
                .map(|_| (Reply::Normal(request.assumed_reply()), Vec::new()))
        } else {
            self.attempt(
                st,
                unit,
                request,
                frame,
                (timeout, urgent),
                opts.window_from_start,
                earlier,
            )
        };
        // Late frames the framing told apart and dropped itself (Modbus TCP).
        if let Link::Open(transport) = &mut st.link {
            st.stats.stale_bytes += transport.take_dropped();
        }
        if is_write(request) {
            st.pacing.wrote(unit, opts.write_interval, Instant::now());
        }
        let error = match outcome {
            Ok((Reply::Normal(response), _)) if unanswered => {
                st.stats.transactions += 1;
                return Ok(response);
            }
            Ok((Reply::Normal(response), reply)) => match check_echo(request, &response, opts.echo)
            {
                Ok(()) => {
                    st.stats.transactions += 1;
                    return Ok(response);
                }
                Err(kind) => frame_error(unit, request.function(), kind, reply),
            },
            Ok((Reply::Exception { function, code }, reply)) => {
                st.stats.transactions += 1;
                st.stats.exceptions += 1;
                return Err(Error::Exception {
                    unit,
                    function,
                    code,
                    meaning: (opts.meaning)(code).to_string(),
                    frame: reply,
                });
            }
            Err(e) => e,
        };
        match &error {
            Error::Timeout { .. } => st.stats.timeouts += 1,
            Error::Frame {
                kind: FrameError::Crc { .. } | FrameError::Ascii(ascii::AsciiError::Lrc { .. }),
                ..
            } => st.stats.crc_errors += 1,
            Error::Frame { .. } => st.stats.frame_errors += 1,
            _ => {}
        }
        Err(error)
    }

    /// One attempt: drop stale input, wait for silence, send, read the reply by its length.
    ///
    /// On a serial line a complete frame of the unit that came too soon after the request to
    /// answer it ([`Turnarounds::too_soon`]: a copy of an earlier reply, an earlier request's
    /// answer come late) is dropped and counted as a resync, and the wait for the answer goes
    /// on; if none follows, the attempt fails with [`FrameError::TooSoon`] (retried) and the
    /// unit's turnarounds are forgotten (it may have become faster). `earlier` is this
    /// call's first attempt that got no answer, if any: a frame
    /// may be its answer (the same request), so it is timed from there; this attempt is
    /// recorded there if it times out.
    #[allow(clippy::too_many_arguments)]
    fn attempt(
        &self,
        st: &mut State,
        unit: u8,
        request: &Request,
        frame: &[u8],
        (timeout, urgent): (Duration, bool),
        window_from_start: bool,
        earlier: &mut Option<Sent>,
    ) -> Result<(Reply, Vec<u8>)> {
        let sent_end = self.send(st, frame, request, timeout, urgent)?;
        let function = request.function();
        let mut buf = Vec::with_capacity(64);
        let mut chunk = [0u8; ascii::MAX_FRAME];
        let line = self.config.line;
        let State {
            link,
            silence,
            owed,
            turnarounds,
            stats,
            serving,
            ..
        } = st;
        let transport = self.port(link)?;
        let serial = transport.is_serial_line();
        let sent_start = if serial {
            sent_end
                .checked_sub(line.frame_time(frame.len()))
                .unwrap_or(sent_end)
        } else {
            sent_end
        };
        let this = Sent {
            start: sent_start,
            end: sent_end,
        };
        let since = earlier.unwrap_or(this);
        // The timeout counts from the start of the request, as in other Modbus masters, so a
        // silent unit costs one timeout per attempt: the device's first character must have
        // arrived by `answer_by` + one character time. The rest of the reply's time on the
        // wire (known as its length becomes known) comes on top, so a long reply at a low baud
        // rate is not cut off. A request that takes over half the timeout on the wire still
        // leaves the device half the timeout after its end (a probe: only t3.5, the least a
        // compliant device needs before it may start).
        let mut answer_by = if serial {
            let least = if window_from_start {
                line.t3_5()
            } else {
                (timeout / 2).max(line.t3_5())
            };
            (sent_start + timeout)
                .checked_sub(line.char_time())
                .unwrap_or(sent_start)
                .max(sent_end + least)
        } else {
            // A Modbus TCP gateway that serves one request at a time answers this one only
            // after the owed ones it is still busy with: that time is not this unit's.
            // (Not this call's own: its retries keep their timeout, as when a call held the
            // line throughout.)
            let queued = owed.until_any(*serving).map_or(Duration::ZERO, |end| {
                end.saturating_duration_since(sent_end)
            });
            sent_end + timeout + queued
        };
        // Whatever the line does (noise, a `:` after every pause in ASCII, frames that are
        // dropped), the attempt ends by then: its window and the longest frame's wire time.
        let mut hard_end = answer_by + line.frame_time(self.max_frame());
        // When the last byte of the reply so far arrived: the line is quiet since then.
        let mut last_byte = None;
        // When the first byte of the frame being read crossed the wire, at the latest.
        let mut first_byte = None;
        // When the first of `n` bytes that came together at `at` crossed the wire: on a
        // serial line they crossed one after another, the first that much before `at`.
        let began = |n: usize, at: Instant| if serial { line.first_of(n, at) } else { at };
        // Whether a frame was dropped as too soon in this attempt.
        let mut dropped_too_soon = false;
        let mut too_soon_after = None;
        loop {
            // An owed answer from another unit may come first: taken whole and valid, it is
            // dropped, and the wait for this reply goes on.
            let other = owed.of_other_unit(unit, self.unit_of(&buf));
            let needed = match other {
                Some(o) => self.framing.reply_needed(&o.request, &buf),
                None => self.framing.reply_needed(request, &buf),
            };
            let (want, wait) = match needed {
                Needed::Complete(n) => {
                    let at = last_byte.unwrap_or_else(Instant::now);
                    if let Some(o) = other {
                        if self
                            .framing
                            .decode_reply(o.unit, &o.request, &buf[..n])
                            .is_err()
                        {
                            break;
                        }
                        let other_unit = o.unit;
                        log::debug!(target: "benchbus::wire", "owed reply of unit {other_unit} dropped: {}", self.wire_text(&buf[..n]));
                        owed.frame_from(other_unit, at, true);
                    } else {
                        let too_soon = serial
                            && first_byte.is_some_and(|first| {
                                turnarounds.too_soon(unit, function, since.start, since.end, first)
                            })
                            && self.framing.decode_reply(unit, request, &buf[..n]).is_ok();
                        if !too_soon {
                            break;
                        }
                        log::debug!(target: "benchbus::wire", "<- unit {unit} too soon for the request (a copy, or an earlier answer), dropped: {}", self.wire_text(&buf[..n]));
                        stats.resyncs += 1;
                        dropped_too_soon = true;
                        too_soon_after =
                            first_byte.map(|first| first.saturating_duration_since(since.start));
                    }
                    stats.stale_bytes += n as u64;
                    buf.drain(..n);
                    first_byte = (!buf.is_empty()).then(|| began(buf.len(), at));
                    silence.busy_until(at);
                    // The line was taken until then; this unit's answer may follow it.
                    if serial {
                        answer_by = answer_by.max(at + line.t3_5());
                        hard_end = hard_end.max(answer_by + line.frame_time(self.max_frame()));
                    }
                    continue;
                }
                // The rest of another unit's frame follows within a frame's gaps.
                Needed::More(n) if other.is_some() => (n, self.within_frame()),
                Needed::More(n) => {
                    let on_wire = match (serial, buf.is_empty()) {
                        (false, _) => Duration::ZERO,
                        (true, true) => line.char_time(),
                        (true, false) => line.frame_time(buf.len() + n),
                    };
                    let mut deadline = answer_by + on_wire;
                    // In ASCII a frame begun (its `:` came) may pause up to 1 s between two
                    // characters; noise before a `:` does not hold the wait.
                    if let (Framing::Ascii, Some(at), false) =
                        (self.framing, last_byte, buf.is_empty())
                    {
                        deadline = deadline.max(at + ascii::INTER_CHAR_TIMEOUT);
                    }
                    (n, deadline.saturating_duration_since(Instant::now()))
                }
                // Not a reply to this request: take what follows until the line is quiet, so
                // the whole bad frame is reported and nothing of it is left for the next call.
                Needed::Unknown => (chunk.len(), self.end_of_frame_silence()),
                // A reply of no known length: it is over once the line has been quiet for
                // the silence gap.
                Needed::Silence => (chunk.len(), self.reply_silence()),
            };
            let want = want
                .min(chunk.len())
                .min(self.max_frame().saturating_sub(buf.len()));
            let wait = wait.min(hard_end.saturating_duration_since(Instant::now()));
            let n = self.read_within(transport, &mut chunk[..want], wait)?;
            if n == 0 {
                if matches!(needed, Needed::Unknown | Needed::Silence)
                    || other.is_some()
                    || want == 0
                {
                    break;
                }
                // Nothing came since `last_byte` (or since the request ended): the line has
                // been quiet that long already, and the next request need not wait t3.5 more.
                if let Some(at) = last_byte {
                    silence.busy_until(at);
                }
                if !buf.is_empty() {
                    log::debug!(target: "benchbus::wire", "<- unit {unit} incomplete: {}", self.wire_text(&buf));
                }
                if dropped_too_soon && buf.is_empty() {
                    // Nothing but the frame thought too soon: it may have been the answer, from
                    // a device that has become faster, or a copy that hid the request from the
                    // device. Not a number: a corrupt reply, retried; what is known of the
                    // unit's pace goes.
                    let usual = turnarounds.least(unit, function).unwrap_or_default();
                    turnarounds.forget(unit, function);
                    let after = too_soon_after.unwrap_or_default();
                    return Err(frame_error(
                        unit,
                        function,
                        FrameError::TooSoon { after, usual },
                        Vec::new(),
                    ));
                }
                if earlier.is_none() {
                    *earlier = Some(this);
                }
                // The whole request and more: no reply, however cut short, looks like that.
                if !self.config.echo && buf.len() > frame.len() && buf.starts_with(frame) {
                    return Err(frame_error(unit, function, FrameError::UnexpectedEcho, buf));
                }
                return Err(Error::Timeout {
                    unit,
                    function,
                    timeout,
                    attempts: 1,
                    received: buf,
                });
            }
            let now = Instant::now();
            buf.extend_from_slice(&chunk[..n]);
            last_byte = Some(now);
            if self.framing == Framing::Ascii {
                // Characters before the frame's `:` are noise: dropped, so that they do not
                // take the room of the frame.
                let noise = match ascii::seen(&buf) {
                    ascii::Seen::Nothing => buf.len(),
                    ascii::Seen::Begun { start }
                    | ascii::Seen::Ended { start, .. }
                    | ascii::Seen::TooLong { start } => start,
                };
                buf.drain(..noise);
                stats.stale_bytes += noise as u64;
                if noise > 0 {
                    first_byte = None;
                }
            }
            // When the frame began: on a serial line, the bytes of this read (the first of the
            // frame: at most 5 bytes of RTU, 11 characters of ASCII, as `reply_needed` asks)
            // crossed the wire one after another, the first of them that much before it (a
            // copy of a short reply read late, all at once, still shows as begun while the
            // request was going out). Only the first read counts: a simulator on a
            // pseudo-terminal hands over whole frames at once, and back-dating by a whole
            // long reply would make its answers look too soon.
            if first_byte.is_none() && !buf.is_empty() {
                first_byte = Some(began(buf.len(), now));
            }
        }
        // What crossed the wire (over Modbus TCP the MBAP frame), for the log and errors.
        let shown = transport.on_the_wire(&buf, false);
        log::debug!(target: "benchbus::wire", "<- {}", self.wire_text(shown.as_deref().unwrap_or(&buf)));
        let at = last_byte.unwrap_or_else(Instant::now);
        match self.framing.decode_reply(unit, request, &buf) {
            Ok(reply) => {
                // The addressed unit answered this request in full: it has stopped talking.
                silence.reply_ended(at);
                owed.frame_from(unit, at, false);
                // Its pace, from an answer that can only be this attempt's.
                if let (true, None, Some(first)) = (serial, *earlier, first_byte) {
                    turnarounds.answered(unit, function, this.start, this.end, first);
                }
                Ok((reply, shown.unwrap_or(buf)))
            }
            Err(kind) => {
                // Whatever this was (noise, another unit's late reply, a garbled length), it
                // may not be over, and it never moves the quiet time earlier.
                silence.busy_until(at);
                let kind = if self.is_unexpected_echo(frame, &buf) {
                    FrameError::UnexpectedEcho
                } else {
                    kind
                };
                Err(frame_error(unit, function, kind, shown.unwrap_or(buf)))
            }
        }
    }

    /// Drops stale input, waits out the silence, writes `frame` (of `request`), reads back
    /// its echo on a Bus opened with `echo`; returns when its last character will have left
    /// the wire. An `urgent` request does not listen for the answers its unit owes first
    /// (see [`TxOptions::urgent`]): they stay in the ledger.
    fn send(
        &self,
        st: &mut State,
        frame: &[u8],
        request: &Request,
        timeout: Duration,
        urgent: bool,
    ) -> Result<Instant> {
        let line = self.config.line;
        let transport = self.port(&mut st.link)?;
        let serial = transport.is_serial_line();
        // Answers another call's attempts to this unit left owed (see [`owed`]): listen for
        // each, up to its window after the frame before it, before sending anything: dropped
        // here, none can be taken for this request's answer. A broadcast waits for every
        // unit's. (The caller waited out most of that without a turn, see
        // `State::late_until`.) Over Modbus TCP the transaction id tells an owed answer from
        // the reply (see `attempt`).
        let target = self.unit_of(frame).unwrap_or(BROADCAST);
        if serial && !urgent {
            for owed in st.owed.take(target, st.serving) {
                let dropped = self.drain_owed(transport, &owed)?;
                st.stats.stale_bytes += dropped as u64;
                if dropped > 0 {
                    st.silence.busy_until(Instant::now());
                }
            }
        }
        // Stale bytes are traffic: the line is quiet only t3.5 after the last of them, and
        // bytes that arrive during that wait restart it, for up to the longest frame's time
        // (a device that never stops talking does not hold the bus for ever). Bytes nobody
        // expected mean the line was out of step: a resync.
        let stale_by = Instant::now() + line.frame_time(self.max_frame()) + line.t3_5();
        let mut resynced = false;
        for round in 0.. {
            let stale = transport.discard_input().map_err(|e| self.io_error(e))?;
            if !stale.is_empty() {
                st.stats.stale_bytes += stale.len() as u64;
                st.stats.resyncs += u64::from(!resynced);
                resynced = true;
                st.silence.busy_until(Instant::now());
                log::debug!(target: "benchbus::wire", "stale input dropped: {}", self.wire_text(&stale));
            } else if round > 0 {
                break;
            }
            // No t3.5 in ASCII: a frame is told by its `:` and CR LF, not by silence.
            if !serial || self.framing == Framing::Ascii || Instant::now() >= stale_by {
                break;
            }
            st.silence.wait(line.t3_5());
        }
        let shown = transport.on_the_wire(frame, true);
        log::debug!(target: "benchbus::wire", "-> {}", self.wire_text(shown.as_deref().unwrap_or(frame)));
        st.frames_out += 1;
        let start = Instant::now();
        transport.write_all(frame).map_err(|e| self.io_error(e))?;
        let end = if serial {
            start + line.frame_time(frame.len())
        } else {
            start
        };
        if self.config.echo {
            let echoed = self.read_echo(transport, frame, request, end + timeout, st.echo_seen);
            // The line was busy until the echo's last byte (or whatever came in its place).
            // The reply's window still counts from the reckoned request: the echo's wait is
            // charged to the attempt, which keeps the call within its bound.
            st.silence.busy_until(Instant::now().max(end));
            st.echo_seen |= echoed.is_ok();
            echoed?;
        }
        st.silence.busy_until(end);
        Ok(end)
    }

    /// Listens for the answers `owed` still owes, one frame at a time (by the length of an
    /// answer to its request, or until the line is quiet), each up to its window after the
    /// one before; returns how many bytes were dropped. Once a window passes with nothing,
    /// the rest are written off: a unit that answers within three timeouts has answered by
    /// then.
    fn drain_owed(&self, transport: &mut Framed, owed: &Owed) -> Result<usize> {
        let mut scratch = [0u8; ascii::MAX_FRAME];
        let mut buf = Vec::new();
        let mut dropped = 0;
        let mut count = owed.count;
        let mut until = owed.until;
        while count > 0 {
            let wait = match self.framing.reply_needed(&owed.request, &buf) {
                Needed::Complete(n) => {
                    log::debug!(target: "benchbus::wire", "owed reply of unit {} dropped: {}", owed.unit, self.wire_text(&buf[..n]));
                    buf.drain(..n);
                    dropped += n;
                    count -= 1;
                    until = Instant::now() + owed.window;
                    continue;
                }
                Needed::More(_) if !buf.is_empty() => self.within_frame(),
                Needed::More(_) => until
                    .saturating_duration_since(Instant::now())
                    .max(self.end_of_frame_silence()),
                Needed::Unknown | Needed::Silence => self.end_of_frame_silence(),
            };
            let room = (2 * self.max_frame())
                .saturating_sub(buf.len())
                .min(scratch.len());
            let n = self.read_within(transport, &mut scratch[..room], wait)?;
            if n > 0 {
                buf.extend_from_slice(&scratch[..n]);
                continue;
            }
            if buf.is_empty() {
                log::debug!(target: "benchbus::wire", "unit {} owed {count} more replies; none came in time", owed.unit);
                break;
            }
            // Quiet after a frame that is not an answer by its length: taken as one.
            log::debug!(target: "benchbus::wire", "owed reply of unit {} dropped: {}", owed.unit, self.wire_text(&buf));
            dropped += buf.len();
            buf.clear();
            count -= 1;
            until = Instant::now() + owed.window;
        }
        Ok(dropped + buf.len())
    }

    /// Reads back the adapter's local echo of `frame` (of `request`) by `deadline` (the
    /// attempt's timeout after the frame's reckoned end: an adapter's latency, such as a
    /// USB latency timer, comes on top of the wire time). It must be the frame, byte for
    /// byte. Once it differs, what follows is taken until the line is quiet, so that none
    /// of it is left for the reply.
    ///
    /// # Errors
    /// [`Error::Frame`] ([`FrameError::LocalEcho`], retried as a corrupt reply is) if the
    /// echo differs or breaks off: another talker on the line, noise, or a late reply that
    /// was still in the adapter. Until a first echo has been seen on this Bus
    /// (`echo_seen`): [`Error::Port`] if nothing came, or the device's reply came in the
    /// echo's place (the adapter does not echo, and `echo` is wrong for it).
    fn read_echo(
        &self,
        transport: &mut Framed,
        frame: &[u8],
        request: &Request,
        deadline: Instant,
        echo_seen: bool,
    ) -> Result<()> {
        let quiet = self.end_of_frame_silence();
        let mut got = Vec::with_capacity(frame.len());
        let mut chunk = [0u8; ascii::MAX_FRAME];
        loop {
            let echoing = frame.starts_with(&got);
            if echoing && got.len() == frame.len() {
                return Ok(());
            }
            let (want, wait) = if echoing {
                let left = deadline.saturating_duration_since(Instant::now());
                (frame.len() - got.len(), left)
            } else {
                (chunk.len().saturating_sub(got.len()), quiet)
            };
            let n = self.read_within(transport, &mut chunk[..want], wait)?;
            if n == 0 {
                break;
            }
            got.extend_from_slice(&chunk[..n]);
        }
        log::debug!(target: "benchbus::wire", "<- not the local echo: {}", self.wire_text(&got));
        let unit = self.unit_of(frame).unwrap_or_default();
        let reply_instead = match self.framing.reply_needed(request, &got) {
            Needed::Complete(n) => self.framing.decode_reply(unit, request, &got[..n]).is_ok(),
            _ => false,
        };
        if !echo_seen && (got.is_empty() || reply_instead) {
            let what = if got.is_empty() {
                "no local echo of the request came".to_string()
            } else {
                "the device's reply came where the local echo of the request should be".into()
            };
            return Err(Error::Port {
                port: self.config.port.clone(),
                message: format!(
                    "{what}: this adapter does not echo what it sends; open the Bus without \
                     echo=True"
                ),
                source: None,
            });
        }
        let at = got
            .iter()
            .zip(frame)
            .position(|(a, b)| a != b)
            .unwrap_or(got.len().min(frame.len()));
        Err(frame_error(
            unit,
            request.function(),
            FrameError::LocalEcho {
                at,
                len: frame.len(),
            },
            got,
        ))
    }

    /// `bytes` from the line as the wire log shows them: in Modbus ASCII the characters
    /// (CR LF and any other control or non-ASCII byte escaped: `:010300000002FA\r\n`), else
    /// in hex.
    fn wire_text(&self, bytes: &[u8]) -> String {
        match self.framing {
            Framing::Ascii => bytes.escape_ascii().to_string(),
            Framing::Rtu | Framing::Mbap => hex(bytes),
        }
    }

    /// The unit a frame in this Bus's framing goes to or comes from, once its first bytes
    /// have come.
    fn unit_of(&self, frame: &[u8]) -> Option<u8> {
        match self.framing {
            Framing::Ascii => ascii::unit_of(frame),
            Framing::Rtu | Framing::Mbap => frame.first().copied(),
        }
    }

    /// The longest frame in this Bus's framing, in bytes on the wire.
    fn max_frame(&self) -> usize {
        match self.framing {
            Framing::Ascii => ascii::MAX_FRAME,
            Framing::Rtu | Framing::Mbap => crate::codec::rtu::MAX_ADU,
        }
    }

    /// Whether the caller asks the call in progress to stop ([`BusConfig::interrupted`]:
    /// in Python, a signal handler that raised, Ctrl-C's).
    pub fn interrupted(&self) -> bool {
        self.config.interrupted.is_some_and(|asked| asked())
    }

    /// Reads into `buf` what arrives within `wait`: 0 if nothing did, or if there was no
    /// room or no time to wait.
    fn read_within(&self, transport: &mut Framed, buf: &mut [u8], wait: Duration) -> Result<usize> {
        if buf.is_empty() || wait.is_zero() {
            return Ok(0);
        }
        transport.read(buf, wait).map_err(|e| self.io_error(e))
    }

    /// The end-of-frame silence: how long the line must stay quiet for a frame that
    /// started to be over: t3.5, and at least 2 ms for the scheduler's sake. (The
    /// simulators' `end_of_frame_silence` is the same idea, with their own t3.5 and floor.)
    fn end_of_frame_silence(&self) -> Duration {
        self.config.line.t3_5().max(Duration::from_millis(2))
    }

    /// The longest gap between two characters of a frame begun: in RTU the end-of-frame
    /// silence, in ASCII the inter-character timeout (a frame ends at its CR LF).
    fn within_frame(&self) -> Duration {
        match self.framing {
            Framing::Ascii => ascii::INTER_CHAR_TIMEOUT,
            Framing::Rtu | Framing::Mbap => self.end_of_frame_silence(),
        }
    }

    /// The quiet gap that ends a reply of no known length: the end-of-frame silence, or
    /// [`BusConfig::silence`] if longer.
    fn reply_silence(&self) -> Duration {
        self.end_of_frame_silence().max(self.config.silence)
    }

    /// Whether `received`, a complete reply to `frame` by its length that failed to decode,
    /// is the request's own echo (in full, or as far as a reply's length took it): an
    /// adapter that echoes on a Bus not opened with `echo`. Never for a Bus that reads the
    /// echo itself.
    fn is_unexpected_echo(&self, frame: &[u8], received: &[u8]) -> bool {
        !self.config.echo
            && received.len() >= frame.len().min(ECHO_EVIDENCE)
            && (received.starts_with(frame) || frame.starts_with(received))
    }

    /// The open port's transport (an error if there is none: closed, or lost).
    fn port<'a>(&self, link: &'a mut Link) -> Result<&'a mut Framed> {
        match link {
            Link::Open(transport) => Ok(transport),
            Link::Closed => Err(self.closed()),
            Link::Lost(reason) => Err(Error::Port {
                port: self.config.port.clone(),
                message: format!("lost ({reason})"),
                source: None,
            }),
        }
    }

    /// The error every call on a closed bus fails with (in a process other than the one
    /// that opened it, [`Error::Forked`]).
    pub(crate) fn closed(&self) -> Error {
        match self.owned() {
            Err(forked) => forked,
            Ok(()) => Error::Closed {
                port: self.config.port.clone(),
            },
        }
    }

    fn io_error(&self, e: std::io::Error) -> Error {
        let message = if !is_lost(&e) {
            format!("I/O failed: {e}")
        } else if self.config.reconnect {
            format!("lost: {e} (the next call tries to reopen it)")
        } else {
            format!("lost: {e} (call reopen() once it is back)")
        };
        Error::Port {
            port: self.config.port.clone(),
            message,
            source: Some(e),
        }
    }

    /// The line for one attempt: this caller's turn in the queue (callers are served in the
    /// order they asked), once `ready(state)` (the instant it may go on, if later than now)
    /// has passed. A caller not ready yet gives its turn up and waits without one, so the
    /// others go on meanwhile, then asks again at the back. None if `cancel` fires first:
    /// the caller leaves the queue without touching the line.
    fn line(&self, cancel: &Cancel, ready: impl Fn(&State) -> Option<Instant>) -> Option<Line<'_>> {
        loop {
            let turn = self.queue.turn(cancel)?;
            let st = self.lock();
            match ready(&st) {
                Some(at) if at > Instant::now() => {
                    drop(st);
                    drop(turn);
                    if !self.queue.wait_until(at, cancel) {
                        return None;
                    }
                }
                _ => return Some(Line { st, _turn: turn }),
            }
        }
    }

    /// Runs `f` while holding this bus's lock for `unit`: a device layer's sequence of
    /// requests that must not interleave with another sequence for the same unit (read AM,
    /// then write MV), whichever device object runs it. Other units and single requests
    /// are not held up. In a process other than the one that opened the Bus, `f` runs
    /// without the lock (a thread of the parent may have held it at the fork), and its
    /// requests fail with [`Error::Forked`]. The thread that holds a unit's lock runs a
    /// sequence nested in its own at once (a Python signal handler run while the
    /// sequence's request waits, which reads the same unit): a lock it waited for would
    /// be its own.
    pub fn exclusive<R>(&self, unit: u8, f: impl FnOnce() -> R) -> R {
        if self.owned().is_err() {
            return f();
        }
        let sequence = {
            let mut all = self
                .sequences
                .lock()
                .unwrap_or_else(|poisoned| poisoned.into_inner());
            Arc::clone(all.entry(unit).or_default())
        };
        let me = std::thread::current().id();
        if sequence.holder() == Some(me) {
            return f();
        }
        let _held = sequence
            .lock
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        let _mine = sequence.hold(me);
        f()
    }

    /// Waits, without a turn, until the writes to `unit` made before `writing` are over
    /// (see [`writes`]). Meanwhile the write fails unsent, and at once, if it is cancelled,
    /// interrupted (asked every [`writes::ASK`]) or overruled: the earlier writes' retries
    /// do not hold a Ctrl-C up.
    fn after_earlier_writes(
        &self,
        unit: u8,
        writing: &writes::Writing<'_>,
        request: &Request,
        cancel: &Cancel,
    ) -> Result<()> {
        let call = writing.call();
        if !self.writes.behind(unit, call) {
            return Ok(());
        }
        // Its place among the unit's writes is taken: the calls made after it may go.
        cancel.queued();
        let mut asked: Option<Instant> = None;
        while self.writes.behind(unit, call) {
            if asked.is_none_or(|at| at.elapsed() >= writes::ASK) {
                if self.interrupted() {
                    return Err(interrupted(unit, request, 0));
                }
                asked = Some(Instant::now());
            }
            if self.writes.overruled(writing)
                || !self.queue.wait_until(Instant::now() + writes::POLL, cancel)
            {
                return Err(cancelled(unit, request, 0));
            }
        }
        Ok(())
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        // A panic while holding the lock leaves consistent state (counters, a port): go on.
        self.state
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

/// The line for one attempt: the state, and the turn that lets its holder use it (the
/// state goes first, so that the next turn finds it free).
struct Line<'a> {
    st: MutexGuard<'a, State>,
    _turn: Turn<'a>,
}

impl std::ops::Deref for Line<'_> {
    type Target = State;
    fn deref(&self) -> &State {
        &self.st
    }
}

impl std::ops::DerefMut for Line<'_> {
    fn deref_mut(&mut self) -> &mut State {
        &mut self.st
    }
}

/// What one call did on the port over its attempts (see [`Bus::on_port`]).
#[derive(Default)]
struct CallPort {
    /// Whether the call reopened the port (once per call at most).
    reopened: bool,
    /// Whether any of its attempts wrote to the port.
    wrote: bool,
}

/// When a request was on the wire (its end reckoned from its length and the baud rate).
#[derive(Debug, Clone, Copy)]
struct Sent {
    start: Instant,
    end: Instant,
}

impl State {
    /// Until when, on a serial line, an answer `target` (a broadcast: any unit) owes to
    /// another call than `call` may still come. A request of `call` to `target` waits that
    /// long, without a turn, so that an owed answer cannot pass for its own; meanwhile other
    /// callers use the line, and their attempts drop the owed answers if they come (see
    /// [`Bus::attempt`]); whatever is still owed is listened for before the request (see
    /// [`Bus::send`]).
    fn late_until(&self, target: u8, call: u64) -> Option<Instant> {
        let Link::Open(transport) = &self.link else {
            return None;
        };
        if !transport.is_serial_line() {
            return None;
        }
        self.owed.until(target, call, Instant::now())
    }
}

/// What a port error says, without the port's name (the Error's display adds it).
fn port_message(e: &Error) -> String {
    match e {
        Error::Port { message, .. } => message.clone(),
        other => other.to_string(),
    }
}

/// Whether nothing comes back for `request` but, on a Bus opened with `echo`, its local echo:
/// a request no device answers (force listen only), or a write the device does not
/// acknowledge.
fn unanswered(request: &Request, opts: &TxOptions) -> bool {
    !request.is_answered() || (request.is_echoed_write() && !opts.write_ack)
}

/// Whether `request` may write (reads are always answered; writes are paced).
fn is_write(request: &Request) -> bool {
    !request.is_read()
}

/// A duration in whole nanoseconds, as an atomic holds it (saturating, past 584 years).
fn nanos(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

fn check_config(config: &BusConfig) -> Result<()> {
    check_line_options(&config.endpoint, config.echo, config.rs485.is_some())
        .map_err(Error::InvalidArgument)?;
    check_rs485_platform(config.rs485.as_ref()).map_err(Error::InvalidArgument)?;
    let line = &config.line;
    if config.ascii {
        if config.endpoint.framing() == Framing::Mbap {
            return Err(Error::InvalidArgument(
                "Modbus ASCII is a serial line framing: not over tcp:// (Modbus TCP)".into(),
            ));
        }
        line.check_ascii().map_err(Error::InvalidArgument)?;
    } else if line.data_bits != 8 {
        return Err(Error::InvalidArgument(format!(
            "Modbus RTU takes 8 data bits, not {}",
            line.data_bits
        )));
    }
    if line.baudrate == 0 {
        return Err(Error::InvalidArgument("baudrate must be positive".into()));
    }
    if !(1..=2).contains(&line.stop_bits) {
        return Err(Error::InvalidArgument(format!(
            "stopbits must be 1 or 2, got {}",
            line.stop_bits
        )));
    }
    Ok(())
}

fn cancelled(unit: u8, request: &Request, attempts: u32) -> Error {
    Error::Cancelled {
        unit,
        function: request.function(),
        attempts,
    }
}

fn interrupted(unit: u8, request: &Request, attempts: u32) -> Error {
    Error::Interrupted {
        unit,
        function: request.function(),
        attempts,
    }
}

fn frame_error(unit: u8, function: u8, kind: FrameError, frame: Vec<u8>) -> Error {
    Error::Frame {
        unit,
        function,
        kind,
        frame,
    }
}

/// The functions of the specification's sections 6.9, 6.10, 6.14, 6.15 and 6.18: the comm
/// event counter and log, file records and the FIFO queue.
impl Bus {
    /// The status word (0xFFFF: a program command is still being processed, 0x0000: not)
    /// and the event counter (0x0B, a serial line function: over Modbus TCP it goes to the
    /// unit behind the gateway like any other).
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn get_comm_event_counter(&self, unit: u8, opts: &TxOptions) -> Result<(u16, u16)> {
        self.ask(
            unit,
            &Request::GetCommEventCounter,
            opts,
            pick!(Response::CommEventCounter { status, event_count } => (status, event_count)),
        )
    }

    /// The status word, the event counter, the message counter and the events (0 to 64
    /// bytes, the newest first) (0x0C, a serial line function, sent over Modbus TCP as
    /// [`Bus::get_comm_event_counter`] is).
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn get_comm_event_log(
        &self,
        unit: u8,
        opts: &TxOptions,
    ) -> Result<(u16, u16, u16, Vec<u8>)> {
        let log = pick!(Response::CommEventLog { status, event_count, message_count, events } =>
            (status, event_count, message_count, events));
        self.ask(unit, &Request::GetCommEventLog, opts, log)
    }

    /// Reads file records (0x14): for each group `(file, record, length)`, `length`
    /// registers from record `record` (0..=0x270F) of file `file` (1..=0xFFFF); one list of
    /// registers per group. At least one group; the request and its reply must fit a PDU.
    ///
    /// # Errors
    /// Any [`Error`]; [`Error::InvalidArgument`] for a group out of range, before anything
    /// is sent.
    pub fn read_file_record(
        &self,
        unit: u8,
        groups: &[(u16, u16, u16)],
        opts: &TxOptions,
    ) -> Result<Vec<Vec<u16>>> {
        let request = Request::ReadFileRecord {
            groups: groups.to_vec(),
        };
        self.ask(
            unit,
            &request,
            opts,
            pick!(Response::FileRecords(records) => records),
        )
    }

    /// Writes file records (0x15): for each group `(file, record, values)`, `values` from
    /// record `record` (0..=0x270F) of file `file` (1..=0xFFFF); the reply must echo the
    /// request. At least one group, each with a value or more; the request must fit a PDU.
    ///
    /// # Errors
    /// Any [`Error`]; [`Error::InvalidArgument`] for a group out of range, before anything
    /// is sent.
    pub fn write_file_record(
        &self,
        unit: u8,
        groups: &[(u16, u16, Vec<u16>)],
        opts: &TxOptions,
    ) -> Result<()> {
        let request = Request::WriteFileRecord {
            groups: groups.to_vec(),
        };
        self.transact(unit, &request, opts).map(|_| ())
    }

    /// The values queued in the FIFO whose count register is at `address` (0x18), oldest
    /// first: at most 31 (a reply with more is a frame error).
    ///
    /// # Errors
    /// Any [`Error`].
    pub fn read_fifo_queue(&self, unit: u8, address: u16, opts: &TxOptions) -> Result<Vec<u16>> {
        self.ask(
            unit,
            &Request::ReadFifoQueue { address },
            opts,
            pick!(Response::FifoQueue(values) => values),
        )
    }
}

/// A unit's lock for device layers' sequences ([`Bus::exclusive`]) and the thread that
/// holds it.
#[derive(Debug, Default)]
struct Sequence {
    lock: Mutex<()>,
    holder: Mutex<Option<std::thread::ThreadId>>,
}

impl Sequence {
    /// The thread that holds the lock now, if one does.
    fn holder(&self) -> Option<std::thread::ThreadId> {
        *self
            .holder
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Marks `me` (holding the lock) as its holder until the guard is dropped.
    fn hold(&self, me: std::thread::ThreadId) -> Holding<'_> {
        *self
            .holder
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner()) = Some(me);
        Holding(self)
    }
}

/// While alive, its thread is the [`Sequence`]'s holder.
struct Holding<'a>(&'a Sequence);

impl Drop for Holding<'_> {
    fn drop(&mut self) {
        *self
            .0
            .holder
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner()) = None;
    }
}
