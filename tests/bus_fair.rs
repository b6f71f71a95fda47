//! A fair line: callers take turns one attempt at a time, in the order they asked, so an
//! absent unit's retries never hold the line while others wait; and cancellation.
//!
//! The line here is a small simulated RS485 bus of several units: each present unit answers
//! a read of one register `address` with `unit * 100 + address` after its own delay; an
//! absent unit never answers. A reply slower than the timeout arrives late, while another
//! caller's attempt may be on the line.

use benchbus::bus::{Bus, BusConfig, CancelToken, TxOptions};
use benchbus::codec::{crc16, Request};
use benchbus::timing::{LineFormat, Parity};
use benchbus::transport::Transport;
use benchbus::Error;
use std::collections::{HashMap, VecDeque};
use std::io;
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

#[derive(Default)]
struct Units {
    /// Each present unit's reply delay.
    delay: HashMap<u8, Duration>,
    /// Bytes on their way, each with the instant it arrives.
    coming: VecDeque<(Instant, u8)>,
    /// Every request written, with its instant.
    sent: Vec<(Instant, Vec<u8>)>,
}

#[derive(Clone, Default)]
struct Line(Arc<Mutex<Units>>);

impl Line {
    fn new(delays: &[(u8, Duration)]) -> Line {
        let line = Line::default();
        line.0.lock().unwrap().delay = delays.iter().copied().collect();
        line
    }

    fn bus(&self, timeout: Duration, retries: u32) -> Bus {
        let mut cfg = BusConfig::new("sim", LineFormat::new(115_200, Parity::None, 1)).unwrap();
        cfg.timeout = timeout;
        cfg.retries = retries;
        Bus::with_transport(cfg, Box::new(self.clone()))
    }

    /// The requests sent to `unit`.
    fn sent_to(&self, unit: u8) -> usize {
        let units = self.0.lock().unwrap();
        units.sent.iter().filter(|(_, f)| f[0] == unit).count()
    }
}

impl Transport for Line {
    fn write_all(&mut self, frame: &[u8]) -> io::Result<()> {
        let mut units = self.0.lock().unwrap();
        let now = Instant::now();
        units.sent.push((now, frame.to_vec()));
        let unit = frame[0];
        if let (Some(&delay), 3) = (units.delay.get(&unit), frame[1]) {
            let address = u16::from_be_bytes([frame[2], frame[3]]);
            let value = u16::from(unit) * 100 + address;
            let mut reply = vec![unit, 3, 2];
            reply.extend(value.to_be_bytes());
            reply.extend(crc16(&reply).to_le_bytes());
            units
                .coming
                .extend(reply.into_iter().map(|b| (now + delay, b)));
        }
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let deadline = Instant::now() + timeout;
        loop {
            let mut units = self.0.lock().unwrap();
            let now = Instant::now();
            let mut n = 0;
            while n < buf.len() && units.coming.front().is_some_and(|&(at, _)| at <= now) {
                buf[n] = units.coming.pop_front().unwrap().1;
                n += 1;
            }
            if n > 0 || now >= deadline {
                return Ok(n);
            }
            let next = units
                .coming
                .front()
                .map_or(deadline, |&(at, _)| at.min(deadline));
            drop(units);
            thread::sleep(next - now);
        }
    }

    fn discard_input(&mut self) -> io::Result<Vec<u8>> {
        let mut units = self.0.lock().unwrap();
        let now = Instant::now();
        let mut stale = Vec::new();
        while units.coming.front().is_some_and(|&(at, _)| at <= now) {
            stale.push(units.coming.pop_front().unwrap().1);
        }
        Ok(stale)
    }

    fn is_serial_line(&self) -> bool {
        true
    }
}

fn read(bus: &Bus, unit: u8, address: u16) -> benchbus::Result<Vec<u16>> {
    bus.read_holding_registers(unit, address, 1, &TxOptions::default())
}

const PRESENT: [u8; 4] = [1, 2, 3, 4];
const ABSENT: u8 = 9;

#[test]
fn an_absent_unit_does_not_hold_the_line_and_present_units_share_it_evenly() {
    let timeout = Duration::from_millis(50);
    let line = Line::new(&PRESENT.map(|u| (u, Duration::from_millis(1))));
    let bus = Arc::new(line.bus(timeout, 2));
    let stop_at = Instant::now() + Duration::from_millis(2500);
    let pollers: Vec<_> = PRESENT
        .iter()
        .map(|&unit| {
            let bus = Arc::clone(&bus);
            thread::spawn(move || {
                let mut worst = Duration::ZERO;
                let mut calls = 0u32;
                while Instant::now() < stop_at {
                    let start = Instant::now();
                    let got = read(&bus, unit, u16::from(unit)).unwrap();
                    assert_eq!(got, vec![u16::from(unit) * 101]);
                    worst = worst.max(start.elapsed());
                    calls += 1;
                }
                (calls, worst)
            })
        })
        .collect();
    let absent = {
        let bus = Arc::clone(&bus);
        thread::spawn(move || {
            let mut calls = 0u32;
            while Instant::now() < stop_at {
                let e = read(&bus, ABSENT, 0).unwrap_err();
                assert!(matches!(e, Error::Timeout { attempts: 3, .. }), "{e:?}");
                calls += 1;
            }
            calls
        })
    };
    let results: Vec<(u32, Duration)> = pollers.into_iter().map(|t| t.join().unwrap()).collect();
    let absent_calls = absent.join().unwrap();
    let counts: Vec<u32> = results.iter().map(|r| r.0).collect();
    let mean = f64::from(counts.iter().sum::<u32>()) / counts.len() as f64;
    let worst = results.iter().map(|r| r.1).max().unwrap();
    println!(
        "present units' calls {counts:?} (mean {mean:.0}), worst latency {worst:?} with \
         timeout {timeout:?}; the absent unit: {absent_calls} calls of 3 attempts"
    );
    assert!(absent_calls >= 5, "{absent_calls}");
    for &n in &counts {
        assert!(
            (f64::from(n) - mean).abs() <= 0.1 * mean,
            "{counts:?} not within 10 % of {mean}"
        );
    }
    // Behind one attempt of the absent unit (one timeout) and one of each other caller at
    // most; a line held through all the retries would make it 3 timeouts.
    assert!(worst < timeout * 2, "{worst:?}");
    assert_eq!(line.sent_to(ABSENT) as u32, absent_calls * 3);
    let stats = bus.stats();
    assert_eq!(stats.timeouts, u64::from(absent_calls) * 3);
    assert_eq!((stats.frame_errors, stats.crc_errors), (0, 0));
}

#[test]
fn a_late_reply_arriving_in_another_callers_attempt_is_dropped_there() {
    // Unit 5 answers 80 ms late with a 50 ms timeout: its replies come while unit 1's
    // attempts, queued between unit 5's, are on the line. Unit 1 gets its own answers.
    let timeout = Duration::from_millis(50);
    let line = Line::new(&[
        (1, Duration::from_millis(1)),
        (5, Duration::from_millis(80)),
    ]);
    let bus = Arc::new(line.bus(timeout, 1));
    let stop_at = Instant::now() + Duration::from_millis(1500);
    let slow = {
        let bus = Arc::clone(&bus);
        thread::spawn(move || {
            let mut answered = 0;
            while Instant::now() < stop_at {
                // The retry may take the first attempt's late reply (the same request).
                match read(&bus, 5, 7) {
                    Ok(v) => {
                        assert_eq!(v, vec![507]);
                        answered += 1;
                    }
                    Err(Error::Timeout { .. }) => {}
                    Err(e) => panic!("{e:?}"),
                }
            }
            answered
        })
    };
    let mut calls = 0;
    while Instant::now() < stop_at {
        assert_eq!(read(&bus, 1, 3).unwrap(), vec![103]);
        calls += 1;
    }
    slow.join().unwrap();
    let stats = bus.stats();
    // The line is fair: unit 1 is served between any two of unit 5's attempts, each of
    // which waits a timeout.
    let slow_attempts = line.sent_to(5);
    assert!(
        calls + 1 >= slow_attempts && calls >= 10,
        "{calls} calls of unit 1 for {slow_attempts} attempts of unit 5"
    );
    // Unit 5's late replies were dropped whole, never taken for unit 1's.
    assert_eq!((stats.frame_errors, stats.crc_errors), (0, 0));
    assert!(stats.stale_bytes >= 7, "{stats:?}");
}

#[test]
fn a_call_cancelled_in_the_queue_leaves_without_touching_the_line() {
    let timeout = Duration::from_millis(100);
    let line = Line::new(&[(1, Duration::from_millis(1))]);
    let bus = Arc::new(line.bus(timeout, 0));
    // The absent unit holds the line for one timeout; the queued call is cancelled then.
    let holder = {
        let bus = Arc::clone(&bus);
        thread::spawn(move || read(&bus, ABSENT, 0))
    };
    while line.sent_to(ABSENT) == 0 {
        thread::sleep(Duration::from_millis(1));
    }
    let token = CancelToken::new();
    let queued = {
        let (bus, token) = (Arc::clone(&bus), token.clone());
        thread::spawn(move || {
            let _in = token.enter();
            let start = Instant::now();
            (read(&bus, 1, 0), start.elapsed())
        })
    };
    thread::sleep(Duration::from_millis(20));
    token.cancel();
    let (result, took) = queued.join().unwrap();
    assert!(
        matches!(
            result,
            Err(Error::Cancelled {
                unit: 1,
                function: 3,
                attempts: 0
            })
        ),
        "{result:?}"
    );
    assert!(took < timeout, "left the queue only after {took:?}");
    assert!(holder.join().unwrap().is_err());
    assert_eq!(line.sent_to(1), 0);
    assert_eq!(
        result.unwrap_err().to_string(),
        "unit 1, function 0x03: cancelled before it was sent"
    );
    // The line goes on for the next caller.
    assert_eq!(read(&bus, 1, 2).unwrap(), vec![102]);
}

#[test]
fn a_cancel_during_an_attempt_lets_it_finish_and_starts_no_retry() {
    let timeout = Duration::from_millis(60);
    // Unit 5 answers after 100 ms: later than the timeout.
    let line = Line::new(&[
        (5, Duration::from_millis(100)),
        (1, Duration::from_millis(1)),
    ]);
    let bus = Arc::new(line.bus(timeout, 3));
    let token = CancelToken::new();
    let call = {
        let (bus, token) = (Arc::clone(&bus), token.clone());
        thread::spawn(move || {
            let _in = token.enter();
            let start = Instant::now();
            (read(&bus, 5, 1), start.elapsed())
        })
    };
    while line.sent_to(5) == 0 {
        thread::sleep(Duration::from_millis(1));
    }
    token.cancel();
    let (result, took) = call.join().unwrap();
    assert!(
        matches!(result, Err(Error::Cancelled { attempts: 1, .. })),
        "{result:?}"
    );
    // The attempt ran its timeout out; no further request went.
    assert!(took >= timeout, "{took:?}");
    assert_eq!(line.sent_to(5), 1);
    assert_eq!((bus.stats().timeouts, bus.stats().retries), (1, 0));
    // Its late reply (501) is listened for and dropped: the next call to unit 5 gets its
    // own answer, not that one.
    assert_eq!(read(&bus, 1, 4).unwrap(), vec![104]);
    let patient = TxOptions {
        timeout: Some(Duration::from_millis(200)),
        ..TxOptions::default()
    };
    assert_eq!(
        bus.read_holding_registers(5, 2, 1, &patient).unwrap(),
        vec![502],
        "the cancelled call's reply (501) answered the next call"
    );
    assert_eq!(bus.stats().stale_bytes, 7, "{:?}", bus.stats());
}

#[test]
fn a_cancelled_token_fails_every_call_under_it_at_once() {
    let line = Line::new(&[(1, Duration::from_millis(1))]);
    let bus = line.bus(Duration::from_millis(50), 2);
    let token = CancelToken::new();
    token.cancel();
    {
        let _in = token.enter();
        for _ in 0..2 {
            let start = Instant::now();
            assert!(matches!(
                read(&bus, 1, 0),
                Err(Error::Cancelled { attempts: 0, .. })
            ));
            assert!(start.elapsed() < Duration::from_millis(20));
        }
        assert!(matches!(
            bus.broadcast(&Request::WriteSingleRegister {
                address: 0,
                value: 1
            }),
            Err(Error::Cancelled {
                unit: 0,
                attempts: 0,
                ..
            })
        ));
    }
    assert_eq!(line.0.lock().unwrap().sent.len(), 0);
    // Out of its scope, calls go on.
    assert_eq!(read(&bus, 1, 0).unwrap(), vec![100]);
}

#[test]
fn a_paced_write_not_due_waits_without_holding_the_line() {
    // Unit 1 takes writes 300 ms apart; its second write waits for that, while unit 2's
    // reads go on meanwhile. A cancel ends that wait at once, with nothing sent.
    let line = Line::new(&[(2, Duration::from_millis(1))]);
    let bus = Arc::new(line.bus(Duration::from_millis(50), 0));
    let opts = TxOptions {
        write_interval: Duration::from_millis(300),
        write_ack: false,
        ..TxOptions::default()
    };
    bus.write_register(1, 0, 1, &opts).unwrap();
    let token = CancelToken::new();
    let writer = {
        let (bus, token) = (Arc::clone(&bus), token.clone());
        thread::spawn(move || {
            let _in = token.enter();
            let start = Instant::now();
            (bus.write_register(1, 0, 2, &opts), start.elapsed())
        })
    };
    thread::sleep(Duration::from_millis(20));
    let start = Instant::now();
    for _ in 0..5 {
        assert_eq!(read(&bus, 2, 1).unwrap(), vec![201]);
    }
    assert!(
        start.elapsed() < Duration::from_millis(150),
        "{:?}",
        start.elapsed()
    );
    token.cancel();
    let (result, took) = writer.join().unwrap();
    assert!(
        matches!(result, Err(Error::Cancelled { attempts: 0, .. })),
        "{result:?}"
    );
    assert!(took < Duration::from_millis(250), "{took:?}");
    assert_eq!(line.sent_to(1), 1);
}
