//! A scripted transport for tests of the Bus and the device layers without a port.
#![allow(dead_code)]

use benchbus::bus::{Bus, BusConfig};
use benchbus::codec::crc16;
use benchbus::timing::{LineFormat, Parity};
use benchbus::transport::{port_lost, Transport};
use benchbus::Error;
use std::collections::VecDeque;
use std::io;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// What the scripted device does with the next request.
pub enum Act {
    Reply(Vec<u8>),
    Silent,
    /// Silent within the timeout, but these bytes arrive after it (a late reply): the next
    /// request finds them waiting.
    Late(Vec<u8>),
}

#[derive(Default)]
pub struct Script {
    pub acts: VecDeque<Act>,
    pub pending: VecDeque<u8>,
    pub sent: Vec<Vec<u8>>,
    /// A serial line whose reply bytes arrive one per `byte_time` after the request.
    pub byte_time: Option<Duration>,
    /// When the current reply began to arrive.
    pub since: Option<std::time::Instant>,
    /// Reply bytes already handed out since `since`.
    pub taken: usize,
    /// When each frame was written.
    pub sent_at: Vec<std::time::Instant>,
    /// Bytes that arrive once the current read has given up.
    pub late: Vec<u8>,
    /// The port is gone: every call fails at once with a lost-port error.
    pub lost: bool,
    /// The port goes (as `lost`) right after the next frame is written.
    pub lose_after_write: bool,
    /// The next call fails with this (not lost) error kind, once.
    pub fail_once: Option<io::ErrorKind>,
    /// Whether the path is there to be opened (see [`reopenable_bus`]).
    pub absent: bool,
    /// The path opens, but to a port as lost as the old one.
    pub stay_lost: bool,
    /// Times the opener was called, and how many of them opened the port.
    pub open_attempts: u32,
    pub opens: u32,
    /// The adapter echoes every frame written, ahead of any reply.
    pub echo: bool,
    /// How many of the next echoes come back with a byte changed (a collision).
    pub garble_echo: usize,
    /// The next read panics (a bug below the Bus, while it holds its lock).
    pub panic_once: bool,
}

impl Script {
    /// The error of a call on the port now, if it fails.
    fn failure(&mut self) -> Option<io::Error> {
        if self.lost {
            return Some(port_lost("hung up (scripted)"));
        }
        self.fail_once
            .take()
            .map(|kind| io::Error::new(kind, "scripted failure"))
    }
}

#[derive(Clone, Default)]
pub struct Scripted(pub Arc<Mutex<Script>>);

impl Transport for Scripted {
    fn write_all(&mut self, frame: &[u8]) -> io::Result<()> {
        let mut s = self.0.lock().unwrap();
        if let Some(e) = s.failure() {
            return Err(e);
        }
        if s.lose_after_write {
            s.lose_after_write = false;
            s.lost = true;
        }
        s.sent.push(frame.to_vec());
        s.sent_at.push(std::time::Instant::now());
        if s.echo {
            let mut echo = frame.to_vec();
            if s.garble_echo > 0 {
                s.garble_echo -= 1;
                echo[2] ^= 0x10;
            }
            s.pending.extend(echo);
        }
        match s.acts.pop_front() {
            Some(Act::Reply(bytes)) => s.pending.extend(bytes),
            Some(Act::Late(bytes)) => s.late = bytes,
            _ => {}
        }
        s.since = Some(std::time::Instant::now());
        s.taken = 0;
        Ok(())
    }
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let mut s = self.0.lock().unwrap();
        if let Some(e) = s.failure() {
            return Err(e);
        }
        if s.panic_once {
            s.panic_once = false;
            drop(s);
            panic!("scripted panic in read");
        }
        if s.pending.is_empty() {
            // A silent device: nothing comes for the whole timeout (late bytes come after).
            let late = std::mem::take(&mut s.late);
            drop(s);
            std::thread::sleep(timeout);
            self.0.lock().unwrap().pending.extend(late);
            return Ok(0);
        }
        let mut ready = s.pending.len();
        if let (Some(byte_time), Some(since)) = (s.byte_time, s.since) {
            // Wait, within the timeout, for the next byte's wire time.
            let due = since + byte_time * (s.taken as u32 + 1);
            let now = std::time::Instant::now();
            if due > now {
                if due - now > timeout {
                    drop(s);
                    std::thread::sleep(timeout);
                    return Ok(0);
                }
                std::thread::sleep(due - now);
            }
            let arrived = (since.elapsed().as_nanos() / byte_time.as_nanos().max(1)) as usize;
            ready = ready.min(arrived.saturating_sub(s.taken));
        }
        let n = buf.len().min(ready);
        s.taken += n;
        for b in buf.iter_mut().take(n) {
            *b = s.pending.pop_front().unwrap();
        }
        Ok(n)
    }
    fn discard_input(&mut self) -> io::Result<Vec<u8>> {
        let mut s = self.0.lock().unwrap();
        if let Some(e) = s.failure() {
            return Err(e);
        }
        Ok(s.pending.drain(..).collect())
    }
    fn is_serial_line(&self) -> bool {
        self.0.lock().unwrap().byte_time.is_some()
    }
}

pub fn with_crc(body: &[u8]) -> Vec<u8> {
    let mut f = body.to_vec();
    f.extend_from_slice(&crc16(body).to_le_bytes());
    f
}

/// A script of `acts`, and the config of a quick 19200 8N1 mock line (5 ms timeout).
pub fn mock(acts: Vec<Act>, retries: u32) -> (Scripted, BusConfig) {
    let t = Scripted::default();
    t.0.lock().unwrap().acts = acts.into();
    let mut cfg = BusConfig::new("mock", LineFormat::new(19_200, Parity::None, 1)).unwrap();
    cfg.retries = retries;
    cfg.timeout = Duration::from_millis(5);
    cfg.turnaround = Duration::ZERO;
    (t, cfg)
}

pub fn bus(acts: Vec<Act>, retries: u32) -> (Bus, Scripted) {
    let (t, cfg) = mock(acts, retries);
    (Bus::with_transport(cfg, Box::new(t.clone())), t)
}

/// A Bus opened with `echo` on a scripted adapter that echoes what it sends.
pub fn echo_bus(acts: Vec<Act>, retries: u32) -> (Bus, Scripted) {
    let (t, mut cfg) = mock(acts, retries);
    cfg.echo = true;
    t.0.lock().unwrap().echo = true;
    (Bus::with_transport(cfg, Box::new(t.clone())), t)
}

/// A Bus on a scripted transport that can be reopened: its opener fails while the script's
/// `absent` is set, and otherwise brings the port back (clears `lost`).
pub fn reopenable_bus(acts: Vec<Act>, retries: u32, reconnect: bool) -> (Bus, Scripted) {
    let (t, mut cfg) = mock(acts, retries);
    cfg.reconnect = reconnect;
    let port = t.clone();
    let opener = Box::new(
        move |cfg: &BusConfig| -> benchbus::Result<Box<dyn Transport>> {
            let mut s = port.0.lock().unwrap();
            s.open_attempts += 1;
            if s.absent {
                return Err(Error::Port {
                    port: cfg.port().to_string(),
                    message: "cannot open: No such file or directory".into(),
                    source: None,
                });
            }
            s.opens += 1;
            s.lost = s.stay_lost;
            Ok(Box::new(port.clone()))
        },
    );
    let bus = Bus::with_opener(cfg, opener).unwrap();
    (bus, t)
}

/// A Bus on a scripted serial line at `baudrate` 8N1 whose reply bytes arrive one per
/// `byte_time` (zero: all at once, as on a pseudo-terminal).
pub fn serial_bus(acts: Vec<Act>, baudrate: u32, byte_time: Duration) -> (Bus, Scripted) {
    let t = Scripted::default();
    {
        let mut s = t.0.lock().unwrap();
        s.acts = acts.into();
        s.byte_time = Some(byte_time);
    }
    let mut cfg = BusConfig::new("mock", LineFormat::new(baudrate, Parity::None, 1)).unwrap();
    cfg.retries = 0;
    cfg.timeout = Duration::from_millis(20);
    (Bus::with_transport(cfg, Box::new(t.clone())), t)
}

/// When each frame was written to the scripted transport.
pub fn sent_at(t: &Scripted) -> Vec<std::time::Instant> {
    t.0.lock().map(|s| s.sent_at.clone()).unwrap_or_default()
}

/// Bytes from the manuals' hex notation ("01 03 00 06").
pub fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .filter_map(|b| u8::from_str_radix(b, 16).ok())
        .collect()
}

/// Every frame the scripted transport was sent.
pub fn sent(t: &Scripted) -> Vec<Vec<u8>> {
    t.0.lock().map(|s| s.sent.clone()).unwrap_or_default()
}

/// A 0x03 reply from `unit` carrying `values`.
pub fn words(unit: u8, values: &[u16]) -> Act {
    let mut body = vec![unit, 3, (values.len() * 2) as u8];
    for v in values {
        body.extend(v.to_be_bytes());
    }
    Act::Reply(with_crc(&body))
}
