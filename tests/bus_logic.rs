//! Bus logic against a scripted transport: retries, exception replies, echo rules, stale input.

mod common;

use benchbus::bus::TxOptions;
use benchbus::codec::{Echo, FrameError, Request};
use benchbus::Error;
use common::{bus, with_crc, Act};
use std::time::{Duration, Instant};

#[test]
fn corrupt_reply_is_retried_and_recovers() {
    let good = with_crc(&[1, 3, 2, 0x13, 0x88]);
    let mut bad = good.clone();
    bad[3] ^= 0x40;
    let (bus, t) = bus(vec![Act::Reply(bad), Act::Reply(good)], 2);
    let v = bus
        .read_holding_registers(1, 0x000A, 1, &TxOptions::default())
        .unwrap();
    assert_eq!(v, vec![0x1388]);
    let s = bus.stats();
    assert_eq!((s.crc_errors, s.retries, s.transactions), (1, 1, 1));
    assert_eq!(t.0.lock().unwrap().sent.len(), 2);
}

#[test]
fn silent_unit_times_out_after_every_attempt() {
    let (bus, t) = bus(vec![Act::Silent, Act::Silent, Act::Silent], 2);
    let e = bus
        .read_holding_registers(1, 0, 1, &TxOptions::default())
        .unwrap_err();
    assert!(
        matches!(
            e,
            Error::Timeout {
                unit: 1,
                function: 3,
                attempts: 3,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("in each of 3 attempts"), "{e}");
    assert_eq!(t.0.lock().unwrap().sent.len(), 3);
    assert_eq!(bus.stats().timeouts, 3);
}

#[test]
fn exception_reply_is_not_retried() {
    // 000 B.4 读失败: reading F00.50 answers exception 0x02.
    let (bus, t) = bus(vec![Act::Reply(vec![0x01, 0x83, 0x02, 0xC0, 0xF1])], 2);
    let e = bus
        .read_holding_registers(1, 0x0032, 1, &TxOptions::default())
        .unwrap_err();
    match e {
        Error::Exception {
            unit,
            function,
            code,
            ref frame,
            ..
        } => {
            assert_eq!((unit, function, code), (1, 3, 2));
            assert_eq!(frame, &vec![0x01, 0x83, 0x02, 0xC0, 0xF1]);
        }
        other => panic!("{other}"),
    }
    assert_eq!(t.0.lock().unwrap().sent.len(), 1);
    assert_eq!(bus.stats().exceptions, 1);
}

#[test]
fn device_meaning_replaces_standard_text() {
    fn drive_meaning(code: u8) -> &'static str {
        if code == 8 {
            "not changeable while running"
        } else {
            "other"
        }
    }
    let (bus, _) = bus(vec![Act::Reply(with_crc(&[1, 0x86, 0x08]))], 0);
    let opts = TxOptions {
        meaning: drive_meaning,
        ..TxOptions::default()
    };
    let e = bus.write_register(1, 0x2002, 4, &opts).unwrap_err();
    assert!(
        e.to_string().contains("not changeable while running"),
        "{e}"
    );
}

#[test]
fn non_echo_is_refused_unless_the_device_allows_it() {
    // 002 §2.2: answer to a write of 3 carries a register count of 1.
    let reply = vec![0x11, 0x06, 0x00, 0x01, 0x00, 0x01, 0x1B, 0x5A];
    let (strict, _) = bus(vec![Act::Reply(reply.clone())], 0);
    let e = strict
        .write_register(0x11, 1, 3, &TxOptions::default())
        .unwrap_err();
    assert!(matches!(e, Error::Frame { .. }), "{e}");
    let (lenient, t) = bus(vec![Act::Reply(reply)], 0);
    let opts = TxOptions {
        echo: Echo::CountForSingleWrite,
        ..TxOptions::default()
    };
    lenient.write_register(0x11, 1, 3, &opts).unwrap();
    assert_eq!(
        t.0.lock().unwrap().sent[0],
        vec![0x11, 0x06, 0x00, 0x01, 0x00, 0x03, 0x9A, 0x9B]
    );
}

#[test]
fn stale_input_is_dropped_and_counted() {
    let (bus, t) = bus(vec![Act::Reply(with_crc(&[1, 3, 2, 0, 7]))], 0);
    t.0.lock().unwrap().pending.extend([0xAA, 0xBB, 0xCC]);
    let v = bus
        .read_holding_registers(1, 0, 1, &TxOptions::default())
        .unwrap();
    assert_eq!(v, vec![7]);
    assert_eq!(bus.stats().stale_bytes, 3);
}

#[test]
fn reply_from_wrong_unit_is_a_frame_error() {
    let (bus, _) = bus(vec![Act::Reply(with_crc(&[2, 3, 2, 0, 7]))], 0);
    let e = bus
        .read_holding_registers(1, 0, 1, &TxOptions::default())
        .unwrap_err();
    assert!(matches!(e, Error::Frame { .. }), "{e}");
    assert_eq!(bus.stats().frame_errors, 1);
}

#[test]
fn bad_arguments_send_nothing() {
    let (bus, t) = bus(vec![], 0);
    let opts = TxOptions::default();
    assert!(matches!(
        bus.read_holding_registers(0, 0, 1, &opts),
        Err(Error::InvalidArgument(_))
    ));
    assert!(matches!(
        bus.read_holding_registers(1, 0, 126, &opts),
        Err(Error::InvalidArgument(_))
    ));
    assert!(matches!(
        bus.read_holding_registers(1, 0xFFFF, 2, &opts),
        Err(Error::InvalidArgument(_))
    ));
    assert!(matches!(
        bus.write_registers(1, 0, &[0; 124], &opts),
        Err(Error::InvalidArgument(_))
    ));
    assert!(t.0.lock().unwrap().sent.is_empty());
}

#[test]
fn closed_bus_refuses_calls() {
    let (bus, _) = bus(vec![], 0);
    bus.close();
    bus.close();
    assert!(matches!(
        bus.read_holding_registers(1, 0, 1, &TxOptions::default()),
        Err(Error::Closed { .. })
    ));
}

#[test]
fn write_interval_spaces_writes_to_one_unit() {
    let echo = with_crc(&[1, 6, 0, 6, 3, 0xE8]);
    let (bus, _) = bus(vec![Act::Reply(echo.clone()), Act::Reply(echo)], 0);
    let opts = TxOptions {
        write_interval: Duration::from_millis(150),
        ..TxOptions::default()
    };
    let start = std::time::Instant::now();
    bus.write_register(1, 6, 1000, &opts).unwrap();
    bus.write_register(1, 6, 1000, &opts).unwrap();
    assert!(start.elapsed() >= Duration::from_millis(150));
}

#[test]
fn device_identification_follows_more_follows() {
    // Page 1: objects 0 and 1, more follows, next object 2. Page 2: object 2.
    let p1 = with_crc(&[
        2, 0x2B, 0x0E, 1, 1, 0xFF, 2, 2, 0, 2, b'A', b'B', 1, 1, b'C',
    ]);
    let p2 = with_crc(&[2, 0x2B, 0x0E, 1, 1, 0, 0, 1, 2, 4, b'0', b'2', b'0', b'1']);
    let (bus, t) = bus(vec![Act::Reply(p1), Act::Reply(p2)], 0);
    let id = bus
        .read_device_identification(2, 1, 0, &TxOptions::default())
        .unwrap();
    assert_eq!(id.objects[&0], b"AB");
    assert_eq!(id.objects[&1], b"C");
    assert_eq!(id.objects[&2], b"0201");
    assert_eq!(
        t.0.lock().unwrap().sent[1],
        with_crc(&[2, 0x2B, 0x0E, 1, 2])
    );
}

// Wire timing at 1200 baud 8N1, where a character takes 8.33 ms: an 8-byte request 66.7 ms,
// t3.5 29.2 ms, so each rule below moves the send times by tens of milliseconds.

#[test]
fn silence_counts_from_the_reply_even_when_it_beats_the_reckoned_request_end() {
    // A pseudo-terminal delivers the reply at once, before the request's 66.7 ms on the wire
    // would have passed: the next request waits t3.5 after the reply, not after that.
    let reply = || common::words(1, &[7]);
    let (bus, t) = common::serial_bus(vec![reply(), reply()], 1200, Duration::ZERO);
    let line = bus.config().line;
    for _ in 0..2 {
        bus.read_holding_registers(1, 0, 1, &TxOptions::default())
            .unwrap();
    }
    let at = common::sent_at(&t);
    let gap = at[1] - at[0];
    assert!(gap >= line.t3_5(), "{gap:?}");
    assert!(gap < line.t3_5() + line.frame_time(8) / 2, "{gap:?}");
}

/// A read at 1200 baud (40 ms timeout, one retry) whose first attempt meets `first` and
/// whose retry is answered: the time between the two requests, the line, and the Bus.
fn retry_gap(first: Act) -> (Duration, benchbus::LineFormat, benchbus::Bus) {
    let (bus, t) = common::serial_bus(vec![first, common::words(1, &[7])], 1200, Duration::ZERO);
    let opts = TxOptions {
        retries: Some(1),
        timeout: Some(Duration::from_millis(40)),
        ..TxOptions::default()
    };
    bus.read_holding_registers(1, 0, 1, &opts).unwrap();
    let at = common::sent_at(&t);
    (at[1] - at[0], bus.config().line, bus)
}

#[test]
fn a_timeout_with_nothing_received_leaves_the_line_quiet_since_the_request() {
    // Nothing came back: the line has been quiet since the request ended, far longer than
    // t3.5, so the retry goes out as soon as the timeout has passed.
    let (gap, line, _) = retry_gap(Act::Silent);
    // The 66.7 ms request is longer than half the 40 ms timeout: the device is left half the
    // timeout after its end, then the first reply character's time.
    let expected = line.frame_time(8) + Duration::from_millis(20) + line.char_time();
    assert!(gap >= expected, "{gap:?}");
    assert!(
        gap < expected + line.t3_5() * 4 / 5,
        "{gap:?} (a t3.5 wait would add 29 ms)"
    );
}

#[test]
fn late_bytes_found_before_a_request_are_traffic_and_restart_the_silence() {
    // The reply came after the timeout: it is dropped as stale, and the retry waits t3.5
    // after finding it rather than going out into the rest of it.
    let (gap, line, bus) = retry_gap(Act::Late(vec![1, 3, 2]));
    let timed_out = line.frame_time(8) + Duration::from_millis(20) + line.char_time();
    assert!(gap >= timed_out + line.t3_5(), "{gap:?}");
    assert_eq!(bus.stats().stale_bytes, 3);
}

/// The time between the requests of two reads of silent units at 1200 baud (8-byte requests
/// of 66.7 ms), one attempt each with `timeout`.
fn silent_read_gap(timeout: Duration) -> Duration {
    let (bus, t) = common::serial_bus(vec![Act::Silent, Act::Silent], 1200, Duration::ZERO);
    let opts = TxOptions {
        retries: Some(0),
        timeout: Some(timeout),
        ..TxOptions::default()
    };
    for unit in [5, 6] {
        assert!(matches!(
            bus.read_holding_registers(unit, 0, 1, &opts),
            Err(benchbus::Error::Timeout { .. })
        ));
    }
    let at = common::sent_at(&t);
    at[1] - at[0]
}

#[test]
fn a_read_timeout_counts_from_the_start_of_the_request() {
    // As in other Modbus masters, a silent unit costs one timeout per attempt, the request's
    // own time on the wire included: 200 ms, not 66.7 + 200 ms.
    let gap = silent_read_gap(Duration::from_millis(200));
    assert!(gap >= Duration::from_millis(199), "{gap:?}");
    assert!(gap < Duration::from_millis(230), "{gap:?}");
}

#[test]
fn a_read_leaves_the_device_half_its_timeout_after_a_long_request() {
    // The 66.7 ms request is longer than the 100 ms timeout less half of it: the device still
    // gets 50 ms after the request's end to start answering (then a character's time).
    let line = benchbus::LineFormat::new(1200, benchbus::Parity::None, 1);
    let gap = silent_read_gap(Duration::from_millis(100));
    let expected = line.frame_time(8) + Duration::from_millis(50) + line.char_time();
    assert!(gap >= expected, "{gap:?}");
    assert!(gap < expected + Duration::from_millis(25), "{gap:?}");
}

#[test]
fn a_foreign_frame_never_moves_the_quiet_time_earlier() {
    // A complete frame from another unit, delivered before the request's reckoned end (as a
    // late reply to someone else would be): the retry still waits t3.5 after that end.
    let (bus, t) = common::serial_bus(
        vec![
            Act::Reply(common::with_crc(&[2, 3, 2, 0, 7])),
            common::words(1, &[7]),
        ],
        1200,
        Duration::ZERO,
    );
    let line = bus.config().line;
    let opts = TxOptions {
        retries: Some(1),
        ..TxOptions::default()
    };
    assert_eq!(bus.read_holding_registers(1, 0, 1, &opts).unwrap(), vec![7]);
    let at = common::sent_at(&t);
    assert!(
        at[1] - at[0] >= line.frame_time(8) + line.t3_5(),
        "{:?}",
        at[1] - at[0]
    );
    assert_eq!(bus.stats().frame_errors, 1);
}

#[test]
fn a_timeout_shorter_than_t35_still_gives_the_device_t35() {
    // A compliant device cannot answer before t3.5 of quiet after the request.
    let (bus, t) = common::serial_bus(vec![Act::Silent, Act::Silent], 1200, Duration::ZERO);
    let line = bus.config().line;
    let opts = TxOptions {
        retries: Some(1),
        timeout: Some(Duration::from_millis(1)),
        ..TxOptions::default()
    };
    assert!(bus.read_holding_registers(1, 0, 1, &opts).is_err());
    let at = common::sent_at(&t);
    assert!(at[1] - at[0] >= line.frame_time(8) + line.t3_5() + line.char_time());
}

#[test]
fn a_probe_window_counts_from_the_start_of_the_request() {
    // scan(timeout=0.1): each absent unit costs 100 ms in all, its request's 66.7 ms on the
    // wire included, so a scan of n absent units takes n x timeout.
    let (bus, t) = common::serial_bus(vec![Act::Silent, Act::Silent], 1200, Duration::ZERO);
    assert!(!bus.probe(5, 0, Duration::from_millis(100)).unwrap());
    assert!(!bus.probe(6, 0, Duration::from_millis(100)).unwrap());
    let at = common::sent_at(&t);
    let window = at[1] - at[0];
    assert!(window >= Duration::from_millis(99), "{window:?}");
    // Without the window rule it would be 100 ms + the request's 66.7 ms.
    assert!(window < Duration::from_millis(130), "{window:?}");
}

#[test]
fn a_probe_leaves_the_device_at_least_t35_to_answer() {
    // A window shorter than the request itself still gives the device t3.5 after it.
    let (bus, t) = common::serial_bus(vec![Act::Silent, Act::Silent], 1200, Duration::ZERO);
    let line = bus.config().line;
    assert!(!bus.probe(5, 0, Duration::from_millis(10)).unwrap());
    assert!(!bus.probe(6, 0, Duration::from_millis(10)).unwrap());
    let at = common::sent_at(&t);
    assert!(
        at[1] - at[0] >= line.frame_time(8) + line.t3_5(),
        "{:?}",
        at[1] - at[0]
    );
}

// ---- a lost port: at once, reopen, reconnect ---------------------------------------------

fn port_message(e: &Error) -> String {
    match e {
        Error::Port { message, .. } => message.clone(),
        other => panic!("not a port error: {other}"),
    }
}

fn read(bus: &benchbus::Bus) -> benchbus::Result<Vec<u16>> {
    bus.read_holding_registers(1, 0, 1, &TxOptions::default())
}

#[test]
fn a_lost_port_fails_at_once_and_stays_lost_without_reconnect() {
    let (bus, t) = common::reopenable_bus(vec![Act::Silent, Act::Silent, Act::Silent], 2, false);
    t.0.lock().unwrap().lost = true;
    let start = std::time::Instant::now();
    let e = read(&bus).unwrap_err();
    assert!(port_message(&e).starts_with("lost: hung up"), "{e}");
    assert!(e.to_string().contains("call reopen()"), "{e}");
    assert!(bus.is_lost() && !bus.is_closed());
    // The port is back, but a Bus without reconnect waits for reopen().
    t.0.lock().unwrap().lost = false;
    let e = read(&bus).unwrap_err();
    assert!(port_message(&e).starts_with("lost earlier (hung up"), "{e}");
    let write = Request::WriteSingleRegister {
        address: 0,
        value: 1,
    };
    assert!(bus.broadcast(&write).is_err() && bus.probe(1, 0, Duration::ZERO).is_err());
    // No timeout waited out (5 ms x 3 attempts per call), nothing sent, no reopen tried.
    assert!(
        start.elapsed() < Duration::from_millis(5),
        "{:?}",
        start.elapsed()
    );
    let s = t.0.lock().unwrap();
    assert!(s.sent.is_empty());
    assert_eq!((s.open_attempts, s.opens), (1, 1));
    assert_eq!(bus.stats().timeouts, 0);
}

#[test]
fn reopen_brings_a_lost_port_back_and_the_stats_survive() {
    let (bus, t) = common::reopenable_bus(
        vec![common::words(1, &[7]), common::words(1, &[8])],
        0,
        false,
    );
    assert_eq!(read(&bus).unwrap(), vec![7]);
    {
        let mut s = t.0.lock().unwrap();
        s.lost = true;
        s.absent = true;
    }
    assert!(read(&bus).is_err());
    // The path is not there yet: reopen fails, the bus stays without a port.
    let e = bus.reopen().unwrap_err();
    assert_eq!(port_message(&e), "cannot open: No such file or directory");
    assert!(bus.is_lost());
    assert!(port_message(&read(&bus).unwrap_err()).contains("No such file"));
    t.0.lock().unwrap().absent = false;
    bus.reopen().unwrap();
    assert!(!bus.is_lost());
    assert_eq!(read(&bus).unwrap(), vec![8]);
    let stats = bus.stats();
    assert_eq!((stats.transactions, stats.reopens), (2, 1));
}

#[test]
fn reopen_replaces_an_open_port_and_opens_a_closed_bus() {
    let (bus, t) = common::reopenable_bus(
        vec![common::words(1, &[1]), common::words(1, &[2])],
        0,
        false,
    );
    bus.reopen().unwrap();
    assert_eq!(read(&bus).unwrap(), vec![1]);
    bus.close();
    assert!(matches!(read(&bus), Err(Error::Closed { .. })));
    bus.reopen().unwrap();
    assert!(!bus.is_closed());
    assert_eq!(read(&bus).unwrap(), vec![2]);
    // A failed reopen of a closed bus leaves it closed.
    bus.close();
    t.0.lock().unwrap().absent = true;
    assert!(bus.reopen().is_err());
    assert!(bus.is_closed());
    assert_eq!(bus.stats().reopens, 2);
}

#[test]
fn a_bus_given_its_transport_cannot_reopen_and_keeps_its_port() {
    let (bus, _) = bus(vec![common::words(1, &[3])], 0);
    let e = bus.reopen().unwrap_err();
    assert!(port_message(&e).contains("cannot reopen"), "{e}");
    assert_eq!(read(&bus).unwrap(), vec![3]);
}

#[test]
fn reconnect_reopens_a_port_found_lost_before_anything_is_sent() {
    let (bus, t) = common::reopenable_bus(vec![common::words(1, &[5])], 0, true);
    // Unplugged and plugged in again between two calls: the next call finds the old handle
    // hung up before it writes, reopens, and goes on.
    t.0.lock().unwrap().lost = true;
    assert_eq!(read(&bus).unwrap(), vec![5]);
    let s = t.0.lock().unwrap();
    assert_eq!((s.open_attempts, s.opens, s.sent.len()), (2, 2, 1));
    assert_eq!(bus.stats().reopens, 1);
}

#[test]
fn reconnect_fails_the_call_that_lost_its_request_and_reopens_on_the_next() {
    let echo = with_crc(&[1, 6, 0, 6, 3, 0xE8]);
    let (bus, t) = common::reopenable_bus(vec![Act::Silent, Act::Reply(echo)], 2, true);
    t.0.lock().unwrap().lose_after_write = true;
    let opts = TxOptions::default();
    // The write went out, then the port went: whether it arrived is unknown, so the call
    // fails rather than repeat it on another handle.
    let e = bus.write_register(1, 6, 1000, &opts).unwrap_err();
    assert!(
        port_message(&e).contains("the next call tries to reopen it"),
        "{e}"
    );
    assert!(bus.is_lost());
    bus.write_register(1, 6, 1000, &opts).unwrap();
    let s = t.0.lock().unwrap();
    assert_eq!((s.opens, s.sent.len()), (2, 2));
}

#[test]
fn reconnect_tries_once_per_call_while_the_path_is_gone() {
    let (bus, t) = common::reopenable_bus(vec![common::words(1, &[9])], 3, true);
    {
        let mut s = t.0.lock().unwrap();
        s.lost = true;
        s.absent = true;
    }
    let start = std::time::Instant::now();
    for _ in 0..3 {
        let e = read(&bus).unwrap_err();
        assert!(
            port_message(&e).contains("tried to reopen it: cannot open: No such file"),
            "{e}"
        );
    }
    assert!(
        start.elapsed() < Duration::from_millis(5),
        "{:?}",
        start.elapsed()
    );
    assert_eq!(t.0.lock().unwrap().open_attempts, 1 + 3);
    t.0.lock().unwrap().absent = false;
    assert_eq!(read(&bus).unwrap(), vec![9]);
    assert_eq!(bus.stats().reopens, 1);
}

#[test]
fn reconnect_gives_up_when_the_reopened_port_is_lost_too() {
    let (bus, t) = common::reopenable_bus(vec![], 0, true);
    {
        let mut s = t.0.lock().unwrap();
        s.lost = true;
        s.stay_lost = true;
    }
    // The path opens, but the new handle is hung up too: one reopen per call, then the error.
    for call in 1..=2 {
        let e = read(&bus).unwrap_err();
        assert!(port_message(&e).starts_with("lost: hung up"), "{e}");
        assert_eq!(t.0.lock().unwrap().open_attempts, 1 + call);
    }
    assert!(t.0.lock().unwrap().sent.is_empty());
}

#[test]
fn reconnect_does_not_reopen_a_closed_bus() {
    let (bus, t) = common::reopenable_bus(vec![], 0, true);
    bus.close();
    assert!(matches!(read(&bus), Err(Error::Closed { .. })));
    assert_eq!(t.0.lock().unwrap().open_attempts, 1);
}

#[test]
fn an_interrupted_call_is_not_a_lost_port() {
    let (bus, t) = common::reopenable_bus(vec![common::words(1, &[4])], 0, true);
    t.0.lock().unwrap().fail_once = Some(std::io::ErrorKind::Interrupted);
    let e = read(&bus).unwrap_err();
    assert!(port_message(&e).starts_with("I/O failed"), "{e}");
    assert!(!bus.is_lost());
    assert_eq!(read(&bus).unwrap(), vec![4]);
    assert_eq!(t.0.lock().unwrap().open_attempts, 1);
}

#[test]
fn a_late_reply_to_a_timed_out_call_never_answers_the_next_call() {
    // RTU replies carry no transaction id: the first call's reply (value 7) comes after it
    // gave up; the second call, same shape, must get its own value (9), not that one.
    let (bus, _) = common::serial_bus(
        vec![
            Act::Late(common::with_crc(&[1, 3, 2, 0, 7])),
            common::words(1, &[9]),
        ],
        19_200,
        Duration::ZERO,
    );
    assert!(matches!(
        bus.read_holding_registers(1, 0, 1, &TxOptions::default()),
        Err(Error::Timeout { .. })
    ));
    assert_eq!(
        bus.read_holding_registers(1, 1, 1, &TxOptions::default())
            .unwrap(),
        vec![9]
    );
    assert_eq!(bus.stats().stale_bytes, 7);
}

#[test]
fn local_echo_is_read_back_before_the_reply() {
    let (bus, t) = common::echo_bus(vec![common::words(1, &[0x1388])], 0);
    let v = bus
        .read_holding_registers(1, 0x3006, 1, &TxOptions::default())
        .unwrap();
    assert_eq!(v, vec![0x1388]);
    t.0.lock()
        .unwrap()
        .acts
        .push_back(Act::Reply(with_crc(&[1, 6, 0x20, 0, 0, 5])));
    bus.write_register(1, 0x2000, 5, &TxOptions::default())
        .unwrap_or_else(|e| panic!("{e}"));
    let s = bus.stats();
    assert_eq!((s.transactions, s.frame_errors, s.stale_bytes), (2, 0, 0));
    assert!(t.0.lock().unwrap().pending.is_empty());
}

#[test]
fn a_garbled_echo_is_a_collision_and_is_retried() {
    let (bus, t) = common::echo_bus(vec![common::words(1, &[1]), common::words(1, &[2])], 1);
    t.0.lock().unwrap().garble_echo = 1;
    let v = bus
        .read_holding_registers(1, 0, 1, &TxOptions::default())
        .unwrap();
    // The first attempt's reply is stale by the retry and dropped; the retry's is taken.
    assert_eq!(v, vec![2]);
    let s = bus.stats();
    assert_eq!((s.frame_errors, s.retries, s.transactions), (1, 1, 1));

    let (bus, t2) = common::echo_bus(vec![common::words(1, &[1])], 0);
    t2.0.lock().unwrap().garble_echo = 1;
    let e = bus
        .read_holding_registers(1, 0, 1, &TxOptions::default())
        .unwrap_err();
    match &e {
        Error::Frame {
            kind: FrameError::LocalEcho { at: 2, len: 8 },
            frame,
            ..
        } => assert_eq!(frame[..3], [1, 3, 0x10], "the garbled echo is reported"),
        other => panic!("{other:?}"),
    }
    assert!(e.to_string().contains("collision"), "{e}");
}

#[test]
fn an_adapter_that_does_not_echo_is_a_port_error_at_once() {
    let (bus, t) = common::echo_bus(vec![common::words(1, &[1])], 2);
    t.0.lock().unwrap().echo = false;
    let e = bus
        .read_holding_registers(1, 0, 1, &TxOptions::default())
        .unwrap_err();
    assert!(matches!(e, Error::Port { source: None, .. }), "{e:?}");
    assert!(e.to_string().contains("reply came where"), "{e}");
    assert!(e.to_string().contains("without echo=True"), "{e}");
    assert_eq!(common::sent(&t).len(), 1, "not retried");
    // A silent device: nothing at all comes back.
    let (bus, t) = common::echo_bus(vec![Act::Silent], 2);
    t.0.lock().unwrap().echo = false;
    let e = bus
        .read_holding_registers(1, 0, 1, &TxOptions::default())
        .unwrap_err();
    assert!(e.to_string().contains("no local echo"), "{e}");
    assert!(!bus.is_lost());
}

#[test]
fn an_echo_on_a_bus_not_told_of_it_says_so() {
    // A read: the echo (8 bytes, function 3) is taken for a reply of the wrong length.
    let (bus, t) = bus(vec![common::words(1, &[1])], 0);
    t.0.lock().unwrap().echo = true;
    let e = bus
        .read_holding_registers(1, 0x0102, 1, &TxOptions::default())
        .unwrap_err();
    assert!(
        matches!(
            e,
            Error::Frame {
                kind: FrameError::UnexpectedEcho,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(e.to_string().contains("echo=True"), "{e}");
    // A write of several registers: its echo's first 8 bytes fail the CRC.
    let (bus2, t) = common::bus(vec![Act::Reply(with_crc(&[1, 0x10, 0, 0, 0, 2]))], 0);
    t.0.lock().unwrap().echo = true;
    let e = bus2
        .write_registers(1, 0, &[1, 2], &TxOptions::default())
        .unwrap_err();
    assert!(e.to_string().contains("echo=True"), "{e}");
}

#[test]
fn a_panic_under_the_bus_is_an_internal_error_and_the_bus_goes_on() {
    let (bus, t) = bus(vec![common::words(1, &[1]), common::words(1, &[2])], 0);
    t.0.lock().unwrap().panic_once = true;
    let e = benchbus::error::guarded(|| bus.read_holding_registers(1, 0, 1, &TxOptions::default()))
        .unwrap_err();
    assert!(
        matches!(&e, Error::Internal(m) if m == "scripted panic in read"),
        "{e:?}"
    );
    assert!(e.to_string().contains("internal error"), "{e}");
    // The panic poisoned the Bus's lock while it held it: the next call goes on regardless.
    let v = benchbus::error::guarded(|| bus.read_holding_registers(1, 0, 1, &TxOptions::default()));
    assert_eq!(v.unwrap(), vec![2]);
    assert_eq!(bus.stats().transactions, 1);
}

#[test]
fn a_collision_is_retried_without_waiting_out_the_timeout() {
    let (bus, t) = common::echo_bus(vec![common::words(1, &[1]), common::words(1, &[2])], 1);
    t.0.lock().unwrap().garble_echo = 1;
    let opts = TxOptions {
        timeout: Some(Duration::from_millis(300)),
        ..TxOptions::default()
    };
    assert_eq!(bus.read_holding_registers(1, 0, 1, &opts).unwrap(), vec![2]);
    let at = common::sent_at(&t);
    // The garbled echo and what follows it are taken until the line is quiet (t3.5 here),
    // then the retry goes: far sooner than the 300 ms a reply is allowed.
    assert!(
        at[1] - at[0] < Duration::from_millis(150),
        "{:?}",
        at[1] - at[0]
    );
    // Nothing of the first attempt was left for the retry to find.
    assert_eq!(bus.stats().stale_bytes, 0);
}

#[test]
fn once_an_echo_was_seen_a_reply_in_its_place_is_retried() {
    // A late reply still in the adapter comes ahead of the echo: not "does not echo".
    let (bus, t) = common::echo_bus(vec![common::words(1, &[1]), common::words(1, &[2])], 1);
    assert_eq!(
        bus.read_holding_registers(1, 0, 1, &TxOptions::default())
            .unwrap(),
        vec![1]
    );
    t.0.lock().unwrap().echo = false;
    let e = bus
        .read_holding_registers(1, 0, 1, &TxOptions::default())
        .unwrap_err();
    assert!(is_local_echo(&e), "{e:?}");
    assert_eq!(bus.stats().retries, 1);
}

#[test]
fn a_truncated_write_reply_is_a_timeout_not_an_echo() {
    // A 0x06 reply repeats the request: cut short, it is still just a late or lost reply.
    let (bus, _) = bus(
        vec![Act::Reply(with_crc(&[1, 6, 0, 1, 0, 5])[..6].to_vec())],
        0,
    );
    let e = bus
        .write_register(1, 1, 5, &TxOptions::default())
        .unwrap_err();
    assert!(matches!(e, Error::Timeout { .. }), "{e:?}");
}

/// Whether `e` is a garbled (or missing) local echo.
fn is_local_echo(e: &Error) -> bool {
    matches!(
        e,
        Error::Frame {
            kind: FrameError::LocalEcho { .. },
            ..
        }
    )
}

#[test]
fn a_broadcast_with_a_garbled_echo_keeps_its_turnaround() {
    let (bus, t) = common::echo_bus(vec![], 0);
    t.0.lock().unwrap().garble_echo = 1;
    let write = Request::WriteSingleRegister {
        address: 1,
        value: 5,
    };
    let e = bus.broadcast(&write).unwrap_err();
    assert!(is_local_echo(&e), "{e:?}");
    let s = bus.stats();
    assert_eq!((s.broadcasts, s.frame_errors), (1, 1));
    assert_eq!(common::sent(&t).len(), 1, "a broadcast is not repeated");
    bus.broadcast(&write).unwrap();
    assert_eq!(bus.stats().broadcasts, 2);
}

#[test]
fn an_unanswered_write_with_a_garbled_echo_is_sent_again() {
    let (bus, t) = common::echo_bus(vec![], 2);
    t.0.lock().unwrap().garble_echo = 1;
    let opts = TxOptions {
        write_ack: false,
        ..TxOptions::default()
    };
    bus.write_register(1, 1, 5, &opts).unwrap();
    let s = bus.stats();
    assert_eq!((s.transactions, s.frame_errors, s.retries), (1, 1, 1));
    assert_eq!(common::sent(&t).len(), 2);
}

#[test]
fn an_unanswered_write_whose_echo_stays_garbled_fails_after_its_attempts() {
    let (bus, t) = common::echo_bus(vec![], 2);
    t.0.lock().unwrap().garble_echo = 5;
    let opts = TxOptions {
        write_ack: false,
        ..TxOptions::default()
    };
    let e = bus.write_register(1, 1, 5, &opts).unwrap_err();
    assert!(is_local_echo(&e), "{e:?}");
    let s = bus.stats();
    assert_eq!(
        (s.transactions, s.frame_errors, s.retries, s.timeouts),
        (0, 3, 2, 0)
    );
    assert_eq!(common::sent(&t).len(), 3);
}

#[test]
fn a_multiple_register_broadcast_goes_to_unit_0_once_and_waits_no_reply() {
    let (bus, t) = bus(vec![], 2);
    bus.broadcast(&Request::WriteMultipleRegisters {
        address: 0x2000,
        values: vec![1, 0x0203],
    })
    .unwrap();
    assert_eq!(
        common::sent(&t),
        vec![with_crc(&common::hex("00 10 20 00 00 02 04 00 01 02 03"))]
    );
    let s = bus.stats();
    assert_eq!((s.broadcasts, s.transactions, s.timeouts), (1, 1, 0));
    // Malformed writes and reads are refused before anything is sent.
    for e in [
        bus.broadcast(&Request::WriteMultipleRegisters {
            address: 0,
            values: vec![],
        })
        .unwrap_err(),
        bus.broadcast(&Request::WriteMultipleRegisters {
            address: 0,
            values: vec![0; 124],
        })
        .unwrap_err(),
        bus.broadcast(&Request::WriteMultipleRegisters {
            address: 0xFFFF,
            values: vec![1, 2],
        })
        .unwrap_err(),
        bus.broadcast(&Request::ReadHoldingRegisters {
            address: 0,
            count: 1,
        })
        .unwrap_err(),
    ] {
        assert!(matches!(e, Error::InvalidArgument(_)), "{e:?}");
    }
    assert_eq!(common::sent(&t).len(), 1);
}

#[test]
fn a_paced_broadcast_waits_its_interval_after_the_last_broadcast() {
    let (bus, t) = bus(vec![], 0);
    let interval = Duration::from_millis(150);
    let write = benchbus::codec::Request::WriteSingleRegister {
        address: 8,
        value: 1,
    };
    bus.broadcast_paced(&write, interval).unwrap();
    let first = Instant::now();
    // No unit was written with its interval yet: only the broadcast's own holds the next.
    bus.broadcast_paced(&write, interval).unwrap();
    assert!(first.elapsed() >= interval, "{:?}", first.elapsed());
    let second = Instant::now();
    bus.broadcast(&write).unwrap();
    assert!(second.elapsed() < interval, "{:?}", second.elapsed());
    assert_eq!(common::sent(&t).len(), 3);
}

#[test]
fn a_request_to_another_unit_does_not_wait_for_a_late_reply() {
    // A script looping over units: unit 2 is silent, unit 1 answers. A late reply names its
    // unit, so unit 1's request goes out at once rather than after two more timeouts.
    let (bus, t) = common::serial_bus(
        vec![Act::Silent, common::words(1, &[9])],
        19_200,
        Duration::ZERO,
    );
    let timeout = bus.config().timeout;
    assert!(matches!(
        bus.read_holding_registers(2, 0, 1, &TxOptions::default()),
        Err(Error::Timeout { .. })
    ));
    let gave_up = std::time::Instant::now();
    assert_eq!(
        bus.read_holding_registers(1, 0, 1, &TxOptions::default())
            .unwrap(),
        vec![9]
    );
    let gap = common::sent_at(&t)[1].saturating_duration_since(gave_up);
    assert!(gap < timeout / 2, "waited {gap:?} before the next unit");
}

#[test]
fn a_late_reply_from_another_unit_is_dropped_and_the_answer_taken() {
    // Unit 2's late reply (value 7) comes in right after the request to unit 1 went out, and
    // unit 1's answer (9) after it: the late frame is dropped whole, the answer taken.
    let late = common::with_crc(&[2, 3, 2, 0, 7]);
    let mut both = late.clone();
    both.extend(common::with_crc(&[1, 3, 2, 0, 9]));
    let (bus, _) = common::serial_bus(vec![Act::Silent, Act::Reply(both)], 19_200, Duration::ZERO);
    assert!(bus
        .read_holding_registers(2, 0, 1, &TxOptions::default())
        .is_err());
    assert_eq!(
        bus.read_holding_registers(1, 0, 1, &TxOptions::default())
            .unwrap(),
        vec![9]
    );
    let stats = bus.stats();
    assert_eq!(stats.stale_bytes, late.len() as u64);
    assert_eq!((stats.frame_errors, stats.crc_errors), (0, 0));
}

#[test]
fn a_frame_from_another_unit_not_awaited_is_still_a_frame_error() {
    // Unit 2 never timed out: a frame naming it is not a late reply, but a wrong one.
    let (bus, _) = common::serial_bus(
        vec![Act::Reply(common::with_crc(&[2, 3, 2, 0, 7]))],
        19_200,
        Duration::ZERO,
    );
    assert!(matches!(
        bus.read_holding_registers(1, 0, 1, &TxOptions::default()),
        Err(Error::Frame {
            kind: benchbus::codec::FrameError::WrongUnit { .. },
            ..
        })
    ));
}

#[test]
fn a_late_reply_from_the_same_unit_is_still_awaited_before_its_next_request() {
    // Unit 1 timed out, then unit 2 answered at once; unit 1's next request (another
    // register, a reply of the same shape) still listens out what is left of the window.
    let (bus, t) = common::serial_bus(
        vec![Act::Silent, common::words(2, &[5]), common::words(1, &[9])],
        19_200,
        Duration::ZERO,
    );
    let timeout = bus.config().timeout;
    assert!(bus
        .read_holding_registers(1, 0, 1, &TxOptions::default())
        .is_err());
    let gave_up = std::time::Instant::now();
    assert_eq!(
        bus.read_holding_registers(2, 0, 1, &TxOptions::default())
            .unwrap(),
        vec![5]
    );
    assert_eq!(
        bus.read_holding_registers(1, 1, 1, &TxOptions::default())
            .unwrap(),
        vec![9]
    );
    let at = common::sent_at(&t);
    assert!(at[1].saturating_duration_since(gave_up) < timeout / 2);
    assert!(at[2].saturating_duration_since(gave_up) >= timeout * 2);
}

#[test]
fn a_byte_count_that_disagrees_with_the_request_is_a_frame_error_naming_both() {
    // 01 03 01 00 07 + CRC is a valid frame whose byte count (1) answers no one-register
    // read: not a CRC error (as reading 6 bytes by its count would make it), but the counts.
    let (bus, t) = common::serial_bus(
        vec![Act::Reply(common::hex("01 03 01 00 07 09 86"))],
        19_200,
        Duration::ZERO,
    );
    let err = bus
        .read_holding_registers(1, 0, 1, &TxOptions::default())
        .unwrap_err();
    assert!(
        matches!(
            &err,
            Error::Frame {
                kind: benchbus::codec::FrameError::ByteCount {
                    expected: 2,
                    received: 1
                },
                frame,
                ..
            } if frame.len() == 7
        ),
        "{err:?}"
    );
    assert_eq!(bus.stats().frame_errors, 1);
    assert_eq!(bus.stats().crc_errors, 0);
    // Nothing of it was left for the next call.
    assert!(t.0.lock().unwrap().pending.is_empty());
}

/// Set by the test below; read by its Bus's `interrupted` hook.
static INTERRUPT: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

#[test]
fn an_interrupt_between_attempts_ends_the_call_and_keeps_the_line_in_step() {
    use std::sync::atomic::Ordering;
    fn asked() -> bool {
        INTERRUPT.load(Ordering::SeqCst)
    }
    // Unit 1 is silent; its reply (7) comes late. The call has 4 attempts, but is asked to
    // stop after the first: one request only. The next call still drops the late reply.
    let (t, mut cfg) = common::mock(
        vec![
            Act::Late(with_crc(&[1, 3, 2, 0, 7])),
            common::words(1, &[9]),
        ],
        3,
    );
    cfg.interrupted = Some(asked);
    let bus = benchbus::Bus::with_transport(cfg, Box::new(t.clone()));
    INTERRUPT.store(true, Ordering::SeqCst);
    let err = bus
        .read_holding_registers(1, 0, 1, &TxOptions::default())
        .unwrap_err();
    INTERRUPT.store(false, Ordering::SeqCst);
    assert!(
        matches!(
            err,
            Error::Interrupted {
                unit: 1,
                function: 3,
                attempts: 1
            }
        ),
        "{err:?}"
    );
    assert_eq!(
        err.to_string(),
        "unit 1, function 0x03: interrupted after 1 attempt"
    );
    assert_eq!(common::sent(&t).len(), 1);
    assert_eq!((bus.stats().timeouts, bus.stats().retries), (1, 0));
    assert_eq!(
        bus.read_holding_registers(1, 1, 1, &TxOptions::default())
            .unwrap(),
        vec![9]
    );
}

#[test]
fn an_urgent_write_goes_once_at_once_and_an_owed_answer_never_passes_for_its_echo() {
    // Unit 1 timed out on a read (its answer, 7, is owed); then the stop on leaving a block
    // on an error: an urgent write, on a Bus with 2 retries. It goes out at once (no wait
    // for the owed answer) and once; the owed read answer that comes in its reply's place
    // fails the echo check: a frame error, not a write taken as done.
    let (bus, t) = common::serial_bus(
        vec![
            Act::Silent,
            Act::Reply(with_crc(&[1, 3, 2, 0, 7])),
            common::words(1, &[9]),
        ],
        19_200,
        Duration::ZERO,
    );
    bus.set_retries(2).unwrap();
    let timeout = bus.timeout();
    let read = TxOptions {
        retries: Some(0),
        ..TxOptions::default()
    };
    assert!(matches!(
        bus.read_holding_registers(1, 0, 1, &read),
        Err(Error::Timeout { .. })
    ));
    let gave_up = std::time::Instant::now();
    let urgent = TxOptions {
        urgent: true,
        ..TxOptions::default()
    };
    let err = bus.write_register(1, 0x2000, 5, &urgent).unwrap_err();
    assert!(matches!(err, Error::Frame { .. }), "{err:?}");
    let at = common::sent_at(&t);
    assert_eq!(at.len(), 2, "the urgent write is sent once");
    assert!(at[1].saturating_duration_since(gave_up) < timeout / 2);
    // Reads are never urgent: a read with the flag still waits for what the unit owes.
    let value = bus.read_holding_registers(1, 1, 1, &urgent).unwrap();
    assert_eq!(value, vec![9]);
    assert!(common::sent_at(&t)[2].saturating_duration_since(gave_up) >= timeout * 2);
}

#[test]
fn timeout_and_retries_set_on_a_live_bus_apply_to_the_next_call_and_bad_ones_change_nothing() {
    let (bus, t) = bus(vec![Act::Silent, Act::Silent, Act::Silent], 2);
    assert_eq!(bus.retries(), 2);
    bus.set_retries(1).unwrap();
    bus.set_timeout(Duration::from_millis(7)).unwrap();
    match bus.read_holding_registers(1, 0, 1, &TxOptions::default()) {
        Err(Error::Timeout {
            timeout, attempts, ..
        }) => assert_eq!((timeout, attempts), (Duration::from_millis(7), 2)),
        other => panic!("{other:?}"),
    }
    assert_eq!(common::sent(&t).len(), 2);
    for bad in [
        Duration::ZERO,
        benchbus::bus::MAX_TIMEOUT + Duration::from_nanos(1),
    ] {
        assert!(matches!(
            bus.set_timeout(bad),
            Err(Error::InvalidArgument(_))
        ));
    }
    assert!(matches!(
        bus.set_retries(benchbus::bus::MAX_RETRIES + 1),
        Err(Error::InvalidArgument(_))
    ));
    assert_eq!(
        (bus.timeout(), bus.retries()),
        (Duration::from_millis(7), 1)
    );
    // The config keeps what the Bus was opened with.
    assert_eq!(bus.config().timeout, Duration::from_millis(5));
}
