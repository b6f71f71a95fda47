//! A byte pipe and the framing its endpoint speaks: what the Bus writes its requests to and
//! reads its replies from. RTU framing passes the bytes through; Modbus TCP puts the codec's
//! MBAP [`Session`] between them and the pipe (requests `unit | PDU`, replies from their
//! MBAP length field on: `length | unit | PDU`).

use super::{port_lost, Endpoint, Transport};
use crate::codec::mbap::{Dropped, Session};
use crate::codec::{hex, Framing};
use std::io;
use std::time::{Duration, Instant};

/// The longest wait a deadline is computed for (a timeout beyond it waits this long).
const LONGEST_WAIT: Duration = Duration::from_secs(86_400);

/// A transport and its framing (see the module docs).
pub(crate) struct Framed {
    pipe: Box<dyn Transport>,
    /// The Modbus TCP session, and the peer's HOST:PORT for messages; None for RTU frames.
    mbap: Option<(Session, String)>,
}

impl Framed {
    /// `pipe`, opened for `endpoint`, speaking its framing ([`Endpoint::framing`]). A new
    /// session: the transaction ids start again.
    pub(crate) fn new(pipe: Box<dyn Transport>, endpoint: &Endpoint) -> Framed {
        let mbap =
            (endpoint.framing() == Framing::Mbap).then(|| (Session::new(), endpoint.address()));
        Framed { pipe, mbap }
    }

    /// Writes `frame`, the Bus's request in this framing ([`Framed::framing`]): an RTU frame
    /// as it is, or `unit | PDU` as an MBAP frame (the next transaction).
    pub(crate) fn write_all(&mut self, frame: &[u8]) -> io::Result<()> {
        let Some((session, _)) = &mut self.mbap else {
            return self.pipe.write_all(frame);
        };
        let out = session.request(frame).ok_or_else(|| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "cannot send {} over Modbus TCP: unit + PDU must be 2 to 254 bytes",
                    hex(frame)
                ),
            )
        })?;
        self.pipe.write_all(&out)
    }

    /// Lets go of the transport in a process that did not open it ([`Transport::abandon`]).
    pub(crate) fn abandon(self) {
        self.pipe.abandon();
    }

    /// The framing the Bus's frames take on this transport.
    pub(crate) fn framing(&self) -> Framing {
        if self.mbap.is_some() {
            Framing::Mbap
        } else {
            Framing::Rtu
        }
    }

    /// Reads at most `buf.len()` bytes of the reply (in this framing), waiting at most `timeout`
    /// for the first; Ok(0) when nothing came. Over Modbus TCP whole MBAP frames are taken
    /// and only the awaited reply's bytes are handed out, from its length field on (so the
    /// Bus reads the frame by its length, whole: see [`crate::codec::mbap::reply_needed`]);
    /// frames that keep coming but are all dropped do not hold the read past its deadline.
    pub(crate) fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let Some((session, peer)) = &mut self.mbap else {
            return self.pipe.read(buf, timeout);
        };
        if buf.is_empty() {
            return Ok(0);
        }
        let deadline = Instant::now() + timeout.min(LONGEST_WAIT);
        let mut chunk = [0u8; 512];
        let mut expired = false;
        loop {
            let dropped = session.take_frames().map_err(|e| out_of_step(peer, e))?;
            log_dropped(&dropped);
            let n = session.read(buf);
            if n > 0 {
                return Ok(n);
            }
            // One non-blocking try once the deadline has passed, then give up.
            if expired {
                return Ok(0);
            }
            let left = deadline.saturating_duration_since(Instant::now());
            expired = left.is_zero();
            let n = self.pipe.read(&mut chunk, left)?;
            if n == 0 {
                return Ok(0);
            }
            session.receive(chunk.get(..n).unwrap_or_default());
        }
    }

    /// Drops every byte waiting and returns it (over Modbus TCP: whole frames and the
    /// unread rest of the last reply; see [`Session::discard`]).
    pub(crate) fn discard_input(&mut self) -> io::Result<Vec<u8>> {
        let waiting = self.pipe.discard_input()?;
        match &mut self.mbap {
            None => Ok(waiting),
            Some((session, peer)) => session.discard(&waiting).map_err(|e| out_of_step(peer, e)),
        }
    }

    /// Whether frames cross a serial line (t3.5 between them): not over Modbus TCP, where
    /// the gateway keeps the line.
    pub(crate) fn is_serial_line(&self) -> bool {
        self.mbap.is_none() && self.pipe.is_serial_line()
    }

    /// How many bytes of frames the framing dropped by itself since it was last asked (a
    /// late Modbus TCP reply, told by its transaction id): the Bus counts them as stale.
    pub(crate) fn take_dropped(&mut self) -> u64 {
        self.mbap
            .as_mut()
            .map_or(0, |(session, _)| session.take_dropped())
    }

    /// The bytes that cross the wire for the frame `frame` the Bus writes (`sent`: the
    /// request about to go) or read (the reply to the last request), where they differ from
    /// it: over Modbus TCP the MBAP frame. The wire log and the errors' frames show these,
    /// so they match a capture. None: the frame itself.
    pub(crate) fn on_the_wire(&self, frame: &[u8], sent: bool) -> Option<Vec<u8>> {
        self.mbap.as_ref()?.0.shown(frame, sent)
    }
}

/// The error of a Modbus TCP stream out of step (a header's length out of range): there is
/// no telling where the next frame starts, so the connection is reported lost.
fn out_of_step(peer: &str, (length, seen): (usize, Vec<u8>)) -> io::Error {
    port_lost(format!(
        "Modbus TCP stream from {peer} out of step (MBAP length {length}, bytes {}): is it a \
         Modbus TCP gateway? (a serial device server passing raw RTU frames is rtu+tcp://); \
         connection dropped",
        hex(&seen)
    ))
}

/// Logs the frames a Modbus TCP session dropped (`benchbus::wire`, DEBUG).
fn log_dropped(dropped: &[Dropped]) {
    for d in dropped {
        match d {
            Dropped::Protocol { protocol, frame } => log::debug!(
                target: "benchbus::wire",
                "<- MBAP frame of protocol {protocol} (not Modbus), dropped: {}",
                hex(frame)
            ),
            Dropped::Late {
                tid,
                awaited,
                frame,
            } => {
                let awaited = match awaited {
                    Some(t) => format!("transaction {t} is awaited"),
                    None => "no reply is awaited".into(),
                };
                log::debug!(
                    target: "benchbus::wire",
                    "<- MBAP reply to transaction {tid} ({awaited}): a late reply, dropped: {}",
                    hex(frame)
                );
            }
        }
    }
}
