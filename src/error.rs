//! The crate's one error type. Each variant keeps its evidence: the unit, the function and
//! the raw frame, so the caller (and the Python exception built from it) can show them.

use crate::codec::{hex, FrameError, RequestError};
use std::time::Duration;

/// Result with the crate's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

/// Everything that can go wrong talking to a device.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A bad argument, refused before anything was sent.
    #[error("{0}")]
    InvalidArgument(String),
    /// The port cannot be opened, vanished, or an I/O call failed.
    #[error("port {port}: {message}")]
    Port {
        /// The port's path.
        port: String,
        /// What failed.
        message: String,
        /// The underlying I/O error, if any.
        #[source]
        source: Option<std::io::Error>,
    },
    /// The bus was closed.
    #[error("bus on {port} is closed")]
    Closed {
        /// The port's path.
        port: String,
    },
    /// The Bus was opened by another process: this one got a copy of it by `fork()`
    /// (Python's `multiprocessing` with its fork start method, a forking server), and with
    /// it the port's descriptor. Nothing was sent or read, and nothing of the Bus was locked
    /// (see [`crate::bus::Bus::owned`]).
    #[error(
        "port {port}: this Bus was opened by process {owner}; process {here} got it by fork() \
         and cannot use it (the two would share the port and read each other's replies). \
         Here, close it and open a new Bus once the parent has closed its own; or start child \
         processes with multiprocessing's 'spawn' or 'forkserver' method; or serve the line \
         from the parent through a gateway (benchbus.Gateway) and open Bus(gateway.url) here"
    )]
    Forked {
        /// The port's path.
        port: String,
        /// The process that opened the Bus.
        owner: u32,
        /// The process that tried to use it.
        here: u32,
    },
    /// No (complete) reply in time.
    #[error("unit {unit}, function {function:#04x}: no complete reply within {timeout:?}{}{}", tries(*.attempts), partial(.received))]
    Timeout {
        /// Unit asked.
        unit: u8,
        /// Function asked.
        function: u8,
        /// The per-attempt timeout.
        timeout: Duration,
        /// How many times the request was sent.
        attempts: u32,
        /// Bytes of an incomplete reply, if any arrived.
        received: Vec<u8>,
    },
    /// A reply arrived but is malformed.
    #[error("unit {unit}, function {function:#04x}: {kind} (frame {})", hex(.frame))]
    Frame {
        /// Unit asked.
        unit: u8,
        /// Function asked.
        function: u8,
        /// What is wrong with it.
        kind: FrameError,
        /// The bytes received.
        frame: Vec<u8>,
    },
    /// The device is in a state that forbids the request (a J2 controller in automatic
    /// mode refuses MV); nothing was written.
    #[error("unit {unit}: {message}")]
    State {
        /// Unit asked.
        unit: u8,
        /// What forbids it, and how to get past it.
        message: String,
    },
    /// The device answered with an exception response.
    #[error("unit {unit}, function {function:#04x}: exception {code:#04x}: {meaning}")]
    Exception {
        /// Unit that answered.
        unit: u8,
        /// Function of the request.
        function: u8,
        /// The exception code.
        code: u8,
        /// Its meaning (device-specific where the device's manual gives one).
        meaning: String,
        /// The exception reply frame.
        frame: Vec<u8>,
    },
    /// The caller asked the call to stop between two attempts, or, on the way out of a
    /// motor's block, before a stop a silent drive would not have answered (`attempts` 0)
    /// (see [`crate::bus::BusConfig::interrupted`]: a signal handler raised, in Python a
    /// Ctrl-C). The attempts made were whole, and a late reply to them
    /// is listened for as after any timeout, so the line stays in step.
    #[error("unit {unit}, function {function:#04x}: interrupted {}", cancelled_after(*.attempts))]
    Interrupted {
        /// Unit asked.
        unit: u8,
        /// Function asked.
        function: u8,
        /// How many times the request had been sent.
        attempts: u32,
    },
    /// The call was cancelled ([`crate::bus::CancelToken`]): it left the queue for the line
    /// without sending anything (`attempts` 0), or after an attempt that failed it started
    /// no further one. The attempts made were whole, and a late reply to them is listened
    /// for as after any timeout, so the line stays in step.
    #[error("unit {unit}, function {function:#04x}: cancelled {}", cancelled_after(*.attempts))]
    Cancelled {
        /// Unit asked (0 for a broadcast).
        unit: u8,
        /// Function asked.
        function: u8,
        /// How many times the request had been sent.
        attempts: u32,
    },
    /// The device's unit was not vouched for (see [`crate::device::Vouch`]): its check
    /// found it to be another kind of device, or could not be made; nothing of the call
    /// was sent.
    #[error("unit {unit}: {reason}")]
    Unvouched {
        /// Unit asked.
        unit: u8,
        /// What the check said.
        reason: String,
    },
    /// A bug in benchbus: a panic, caught before it reached the caller (see [`guarded`]).
    #[error("internal error in benchbus (a bug; please report it): {0}")]
    Internal(String),
}

impl Error {
    /// Whether another attempt may succeed: after a timeout or a corrupt frame, never after
    /// an exception response.
    pub fn is_retryable(&self) -> bool {
        matches!(self, Error::Timeout { .. } | Error::Frame { .. })
    }

    /// The raw frame the error carries, if any.
    pub fn frame(&self) -> Option<&[u8]> {
        match self {
            Error::Timeout { received, .. } if !received.is_empty() => Some(received),
            Error::Frame { frame, .. } | Error::Exception { frame, .. } => Some(frame),
            _ => None,
        }
    }
}

impl From<RequestError> for Error {
    fn from(e: RequestError) -> Error {
        Error::InvalidArgument(e.to_string())
    }
}

/// Runs `f`, turning a panic inside it into [`Error::Internal`] so that it ends the call
/// with an error rather than unwinding into the caller (the Python bindings run every call
/// through this). A Bus whose lock a panic poisoned goes on: its state is kept consistent
/// between statements.
///
/// # Errors
/// `f`'s own error, or [`Error::Internal`] with the panic's message.
pub fn guarded<T>(f: impl FnOnce() -> Result<T>) -> Result<T> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).unwrap_or_else(|payload| {
        let message = payload
            .downcast_ref::<&str>()
            .map(|s| (*s).to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "a panic without a message".into());
        log::error!(target: "benchbus", "internal error (panic) caught: {message}");
        Err(Error::Internal(message))
    })
}

fn tries(attempts: u32) -> String {
    if attempts > 1 {
        format!(" in each of {attempts} attempts")
    } else {
        String::new()
    }
}

fn cancelled_after(attempts: u32) -> String {
    match attempts {
        0 => "before it was sent".into(),
        1 => "after 1 attempt".into(),
        n => format!("after {n} attempts"),
    }
}

fn partial(received: &[u8]) -> String {
    if received.is_empty() {
        String::new()
    } else {
        format!(" (partial reply {})", hex(received))
    }
}
