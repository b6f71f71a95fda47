//! The TCP transports against a fake gateway on loopback: a `TcpListener` on 127.0.0.1 (port
//! 0) served by a thread. Modbus TCP (`tcp://`, MBAP frames) and raw RTU over TCP
//! (`rtu+tcp://`). Every socket wait in the fake gateway is bounded by `BOUND`.

use benchbus::bus::{Bus, BusConfig, TxOptions};
use benchbus::codec::{crc16, FrameError, Request};
use benchbus::timing::{LineFormat, Parity};
use benchbus::transport::is_lost;
use benchbus::Error;
use std::io::{ErrorKind, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::mpsc;
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

/// The longest any fake-gateway wait may take before the test fails.
const BOUND: Duration = Duration::from_secs(5);

/// The request every test reads: holding register 0x3006, one of it, from unit 1.
const REQUEST_PDU: [u8; 5] = [0x03, 0x30, 0x06, 0x00, 0x01];

fn listener() -> (TcpListener, u16) {
    let l = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = l.local_addr().unwrap().port();
    (l, port)
}

/// The next connection, within `BOUND`.
fn accept(l: &TcpListener) -> TcpStream {
    l.set_nonblocking(true).unwrap();
    let start = Instant::now();
    loop {
        match l.accept() {
            Ok((s, _)) => {
                s.set_nonblocking(false).unwrap();
                s.set_read_timeout(Some(BOUND)).unwrap();
                s.set_write_timeout(Some(BOUND)).unwrap();
                return s;
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock && start.elapsed() < BOUND => {
                thread::sleep(Duration::from_millis(5));
            }
            Err(e) => panic!("fake gateway: no connection: {e}"),
        }
    }
}

/// Exactly `n` bytes from the client, within `BOUND`.
fn recv(s: &mut TcpStream, n: usize) -> Vec<u8> {
    let mut buf = vec![0u8; n];
    s.read_exact(&mut buf).unwrap();
    buf
}

/// An MBAP frame: transaction `tid`, protocol 0, `adu` (unit + PDU).
fn mbap(tid: u16, adu: &[u8]) -> Vec<u8> {
    mbap_protocol(tid, 0, adu)
}

fn mbap_protocol(tid: u16, protocol: u16, adu: &[u8]) -> Vec<u8> {
    let mut out = tid.to_be_bytes().to_vec();
    out.extend_from_slice(&protocol.to_be_bytes());
    out.extend_from_slice(&(adu.len() as u16).to_be_bytes());
    out.extend_from_slice(adu);
    out
}

/// The MBAP request the Bus sends for `REQUEST_PDU` to unit 1 as transaction `tid`.
fn request(tid: u16) -> Vec<u8> {
    let mut adu = vec![1];
    adu.extend_from_slice(&REQUEST_PDU);
    mbap(tid, &adu)
}

/// A 0x03 reply of one register holding `value`, unit + PDU.
fn one_register(value: u16) -> Vec<u8> {
    let [hi, lo] = value.to_be_bytes();
    vec![1, 3, 2, hi, lo]
}

fn with_crc(adu: &[u8]) -> Vec<u8> {
    let mut out = adu.to_vec();
    out.extend_from_slice(&crc16(adu).to_le_bytes());
    out
}

fn config(url: &str, timeout_ms: u64, retries: u32) -> BusConfig {
    let mut c = BusConfig::new(url, LineFormat::new(19_200, Parity::None, 1)).unwrap();
    c.timeout = Duration::from_millis(timeout_ms);
    c.retries = retries;
    c
}

fn read(bus: &Bus) -> benchbus::Result<Vec<u16>> {
    bus.read_holding_registers(1, 0x3006, 1, &TxOptions::default())
}

fn join<T>(server: JoinHandle<T>) -> T {
    match server.join() {
        Ok(v) => v,
        Err(_) => panic!("the fake gateway failed (see its panic above)"),
    }
}

/// Whether `e` is a port error whose I/O source says the connection is lost.
fn is_lost_port(e: &Error) -> bool {
    matches!(e, Error::Port { source: Some(io), .. } if is_lost(io))
}

#[test]
fn mbap_request_is_golden_and_transaction_ids_count_up() {
    let (l, port) = listener();
    let server = thread::spawn(move || {
        let mut s = accept(&l);
        let first = recv(&mut s, 12);
        s.write_all(&mbap(1, &one_register(0x1234))).unwrap();
        let second = recv(&mut s, 12);
        // The reply in pieces: the transport puts the frame together.
        let reply = mbap(2, &one_register(0xABCD));
        for piece in [&reply[..3], &reply[3..8], &reply[8..]] {
            s.write_all(piece).unwrap();
            thread::sleep(Duration::from_millis(20));
        }
        (first, second)
    });
    let bus = Bus::open(config(&format!("tcp://127.0.0.1:{port}"), 1000, 0)).unwrap();
    assert_eq!(read(&bus).unwrap(), vec![0x1234]);
    assert_eq!(read(&bus).unwrap(), vec![0xABCD]);
    let (first, second) = join(server);
    // The first transaction id is 1 (benchbus::codec::mbap::FIRST_TRANSACTION_ID).
    assert_eq!(first, [0, 1, 0, 0, 0, 6, 1, 3, 0x30, 6, 0, 1]);
    assert_eq!(second, [0, 2, 0, 0, 0, 6, 1, 3, 0x30, 6, 0, 1]);
    assert_eq!(bus.stats().transactions, 2);
}

#[test]
fn mbap_broadcast_is_sent_and_awaits_no_reply() {
    let (l, port) = listener();
    let server = thread::spawn(move || {
        let mut s = accept(&l);
        let broadcast = recv(&mut s, 12);
        let next = recv(&mut s, 12);
        s.write_all(&mbap(2, &one_register(7))).unwrap();
        (broadcast, next)
    });
    let bus = Bus::open(config(&format!("tcp://127.0.0.1:{port}"), 1000, 0)).unwrap();
    bus.broadcast(&Request::WriteSingleRegister {
        address: 0x0001,
        value: 0x0002,
    })
    .unwrap();
    assert_eq!(read(&bus).unwrap(), vec![7]);
    let (broadcast, next) = join(server);
    assert_eq!(broadcast, [0, 1, 0, 0, 0, 6, 0, 6, 0, 1, 0, 2]);
    assert_eq!(next, request(2));
    assert_eq!(bus.stats().broadcasts, 1);
}

#[test]
fn mbap_stale_transaction_and_foreign_protocol_are_ignored() {
    let (l, port) = listener();
    let server = thread::spawn(move || {
        let mut s = accept(&l);
        let first = recv(&mut s, 12);
        let mut burst = mbap(7, &one_register(0xDEAD)); // an earlier request's reply
        burst.extend(mbap_protocol(1, 1, &one_register(0xBEEF))); // not Modbus
        burst.extend(mbap(1, &one_register(0x0001))); // the answer
        burst.extend(mbap(1, &one_register(0x0BAD))); // the same again: not awaited any more
        s.write_all(&burst).unwrap();
        let second = recv(&mut s, 12);
        s.write_all(&mbap(2, &one_register(0x0002))).unwrap();
        (first, second)
    });
    let bus = Bus::open(config(&format!("tcp://127.0.0.1:{port}"), 1000, 0)).unwrap();
    assert_eq!(read(&bus).unwrap(), vec![0x0001]);
    assert_eq!(read(&bus).unwrap(), vec![0x0002]);
    let (first, second) = join(server);
    assert_eq!((first, second), (request(1), request(2)));
    let s = bus.stats();
    assert_eq!((s.transactions, s.frame_errors, s.timeouts), (2, 0, 0));
}

#[test]
fn mbap_exception_reply_is_an_exception_with_its_code() {
    let (l, port) = listener();
    let server = thread::spawn(move || {
        let mut s = accept(&l);
        let got = recv(&mut s, 12);
        s.write_all(&mbap(1, &[1, 0x83, 0x0B])).unwrap();
        got
    });
    let bus = Bus::open(config(&format!("tcp://127.0.0.1:{port}"), 1000, 2)).unwrap();
    match read(&bus) {
        Err(Error::Exception {
            unit: 1,
            function: 3,
            code: 0x0B,
            frame,
            ..
        // The frame as it crossed the network (MBAP header, transaction 1), as a capture
        // shows it, not the RTU form the Bus decoded.
        }) => assert_eq!(frame, mbap(1, &[1, 0x83, 0x0B])),
        other => panic!("{other:?}"),
    }
    assert_eq!(join(server), request(1));
    let s = bus.stats();
    assert_eq!((s.exceptions, s.retries), (1, 0));
}

#[test]
fn rtu_over_tcp_passes_frames_byte_for_byte() {
    let (l, port) = listener();
    let server = thread::spawn(move || {
        let mut s = accept(&l);
        let got = recv(&mut s, 8);
        s.write_all(&[1, 3, 2, 0x12, 0x34, 0xB5, 0x33]).unwrap();
        got
    });
    let bus = Bus::open(config(&format!("rtu+tcp://127.0.0.1:{port}"), 1000, 0)).unwrap();
    assert_eq!(read(&bus).unwrap(), vec![0x1234]);
    assert_eq!(join(server), [1, 3, 0x30, 6, 0, 1, 0x6B, 0x0B]);
}

#[test]
fn host_names_and_ipv6_addresses_connect() {
    let (l, port) = listener();
    let server = thread::spawn(move || {
        let mut s = accept(&l);
        let got = recv(&mut s, 12);
        s.write_all(&mbap(1, &one_register(5))).unwrap();
        got
    });
    let bus = Bus::open(config(&format!("tcp://localhost:{port}"), 1000, 0)).unwrap();
    assert_eq!(read(&bus).unwrap(), vec![5]);
    assert_eq!(join(server), request(1));

    // IPv6 loopback, where the machine has it.
    let Ok(l6) = TcpListener::bind("[::1]:0") else {
        return;
    };
    let port6 = l6.local_addr().unwrap().port();
    let server = thread::spawn(move || {
        let mut s = accept(&l6);
        let got = recv(&mut s, 8);
        s.write_all(&with_crc(&one_register(6))).unwrap();
        got
    });
    let bus = Bus::open(config(&format!("rtu+tcp://[::1]:{port6}"), 1000, 0)).unwrap();
    assert_eq!(read(&bus).unwrap(), vec![6]);
    assert_eq!(join(server), with_crc(&[1, 3, 0x30, 6, 0, 1]));
}

#[test]
fn refused_connection_is_a_quick_port_error() {
    let port = listener().1; // bound, then dropped: nothing listens there now
    for url in [
        format!("tcp://127.0.0.1:{port}"),
        format!("rtu+tcp://127.0.0.1:{port}"),
    ] {
        let start = Instant::now();
        let e = Bus::open(config(&url, 100, 0)).unwrap_err();
        assert!(
            start.elapsed() < Duration::from_secs(2),
            "{:?}",
            start.elapsed()
        );
        match &e {
            Error::Port {
                port: p, message, ..
            } => {
                assert_eq!(p, &url);
                assert!(
                    message.starts_with(&format!("cannot connect to 127.0.0.1:{port}: ")),
                    "{message}"
                );
                assert!(message.contains("refused"), "{message}");
            }
            other => panic!("{other:?}"),
        }
    }
}

#[test]
fn malformed_urls_are_invalid_arguments_before_anything_opens() {
    for url in [
        "foo://x",
        "tcp://",
        "tcp://host:0",
        "rtu+tcp://host",
        "tcp://host:502/x",
    ] {
        match BusConfig::new(url, LineFormat::new(19_200, Parity::None, 1)).and_then(Bus::open) {
            Err(Error::InvalidArgument(m)) => assert!(m.contains("tcp://HOST[:PORT]"), "{m}"),
            other => panic!("{url}: {other:?}"),
        }
    }
}

#[test]
fn connection_closed_mid_reply_is_lost_and_reopen_brings_it_back() {
    let (l, port) = listener();
    let server = thread::spawn(move || {
        let mut s = accept(&l);
        let first = recv(&mut s, 12);
        s.write_all(&mbap(1, &one_register(1))[..5]).unwrap();
        drop(s);
        let mut s = accept(&l);
        let again = recv(&mut s, 12);
        s.write_all(&mbap(1, &one_register(0x0042))).unwrap();
        (first, again)
    });
    let bus = Bus::open(config(&format!("tcp://127.0.0.1:{port}"), 1000, 2)).unwrap();
    let start = Instant::now();
    let e = read(&bus).unwrap_err();
    assert!(is_lost_port(&e), "{e:?}");
    assert!(
        e.to_string().contains("connection closed by 127.0.0.1"),
        "{e}"
    );
    assert!(
        start.elapsed() < Duration::from_millis(900),
        "{:?}",
        start.elapsed()
    );
    assert!(bus.is_lost());
    // Not retried, and later calls fail at once until reopened.
    assert_eq!(bus.stats().retries, 0);
    assert!(matches!(read(&bus), Err(Error::Port { .. })));
    bus.reopen().unwrap();
    assert!(!bus.is_lost());
    // A new connection: its transaction ids start again at 1.
    assert_eq!(read(&bus).unwrap(), vec![0x0042]);
    assert_eq!(join(server), (request(1), request(1)));
    assert_eq!(bus.stats().reopens, 1);
}

#[test]
fn reconnect_finds_an_idle_close_before_writing_and_goes_on() {
    for scheme in ["tcp", "rtu+tcp"] {
        let mbap_framing = scheme == "tcp";
        let (l, port) = listener();
        let (closed_tx, closed_rx) = mpsc::channel();
        let server = thread::spawn(move || {
            let (len, reply) = if mbap_framing {
                (12, mbap(1, &one_register(1)))
            } else {
                (8, with_crc(&one_register(1)))
            };
            let mut s = accept(&l);
            let first = recv(&mut s, len);
            s.write_all(&reply).unwrap();
            drop(s); // the gateway's idle timeout
            closed_tx.send(()).unwrap();
            let mut s = accept(&l);
            let second = recv(&mut s, len);
            s.write_all(&reply).unwrap();
            (first, second)
        });
        let mut c = config(&format!("{scheme}://127.0.0.1:{port}"), 1000, 0);
        c.reconnect = true;
        let bus = Bus::open(c).unwrap();
        assert_eq!(read(&bus).unwrap(), vec![1]);
        closed_rx.recv_timeout(BOUND).unwrap();
        thread::sleep(Duration::from_millis(50)); // the FIN crosses loopback
        assert_eq!(read(&bus).unwrap(), vec![1], "{scheme}");
        let (first, second) = join(server);
        assert_eq!(
            first, second,
            "{scheme}: the same request, sent once on each connection"
        );
        let s = bus.stats();
        assert_eq!((s.reopens, s.transactions), (1, 2), "{scheme}");
    }
}

#[test]
fn late_reply_during_the_next_call_is_dropped() {
    let (l, port) = listener();
    let server = thread::spawn(move || {
        let mut s = accept(&l);
        let first = recv(&mut s, 12);
        // Past the 200 ms timeout, and within the next call's (sent at once after it).
        thread::sleep(Duration::from_millis(300));
        s.write_all(&mbap(1, &one_register(0x0BAD))).unwrap();
        let second = recv(&mut s, 12);
        s.write_all(&mbap(2, &one_register(0x0002))).unwrap();
        (first, second)
    });
    let bus = Bus::open(config(&format!("tcp://127.0.0.1:{port}"), 200, 0)).unwrap();
    assert!(matches!(read(&bus), Err(Error::Timeout { .. })));
    assert_eq!(read(&bus).unwrap(), vec![0x0002]);
    assert_eq!(join(server), (request(1), request(2)));
    assert_eq!(bus.stats().timeouts, 1);
}

#[test]
fn late_reply_after_the_next_request_is_told_apart_by_its_transaction_id() {
    let (l, port) = listener();
    let server = thread::spawn(move || {
        let mut s = accept(&l);
        let first = recv(&mut s, 12);
        let second = recv(&mut s, 12); // the first is answered only once this is in
        let mut burst = mbap(1, &one_register(0x0BAD));
        burst.extend(mbap(2, &one_register(0x0002)));
        s.write_all(&burst).unwrap();
        (first, second)
    });
    let bus = Bus::open(config(&format!("tcp://127.0.0.1:{port}"), 100, 0)).unwrap();
    assert!(matches!(read(&bus), Err(Error::Timeout { .. })));
    assert_eq!(read(&bus).unwrap(), vec![0x0002]);
    assert_eq!(join(server), (request(1), request(2)));
}

#[test]
fn out_of_step_stream_is_lost_not_misread() {
    let (l, port) = listener();
    let server = thread::spawn(move || {
        let mut s = accept(&l);
        let got = recv(&mut s, 12);
        s.write_all(b"SSH-2.0-OpenSSH\r\n").unwrap(); // not Modbus TCP
        got
    });
    let bus = Bus::open(config(&format!("tcp://127.0.0.1:{port}"), 1000, 2)).unwrap();
    let e = read(&bus).unwrap_err();
    assert!(is_lost_port(&e), "{e:?}");
    assert!(e.to_string().contains("out of step"), "{e}");
    assert!(bus.is_lost());
    assert_eq!(join(server), request(1));
}

#[test]
fn a_length_that_counts_extra_bytes_is_a_frame_error_and_the_next_call_is_in_step() {
    let (l, port) = listener();
    let server = thread::spawn(move || {
        let mut s = accept(&l);
        let first = recv(&mut s, 12);
        // tid 00 01 | protocol 00 00 | length 00 07 | unit 01 | 03 02 12 34 | 56 78: the
        // length counts two bytes more than a one-register reply has.
        let mut padded = one_register(0x1234);
        padded.extend_from_slice(&[0x56, 0x78]);
        s.write_all(&mbap(1, &padded)).unwrap();
        let second = recv(&mut s, 12);
        s.write_all(&mbap(2, &one_register(0x0042))).unwrap();
        (first, second)
    });
    let bus = Bus::open(config(&format!("tcp://127.0.0.1:{port}"), 1000, 0)).unwrap();
    match read(&bus) {
        Err(Error::Frame {
            unit: 1,
            function: 3,
            kind: FrameError::Length(message),
            frame,
        }) => {
            assert!(message.contains("2 bytes more"), "{message}");
            // The whole frame, extra bytes and all, as it crossed the network.
            let mut padded = one_register(0x1234);
            padded.extend_from_slice(&[0x56, 0x78]);
            assert_eq!(frame, mbap(1, &padded));
        }
        other => panic!("{other:?}"),
    }
    // The extra bytes went with their frame: the next call reads its own reply.
    assert_eq!(read(&bus).unwrap(), vec![0x0042]);
    assert_eq!(join(server), (request(1), request(2)));
    let s = bus.stats();
    assert_eq!((s.frame_errors, s.stale_bytes, s.transactions), (1, 0, 1));
}

#[test]
fn echo_is_refused_over_mbap_before_connecting() {
    let (l, port) = listener();
    drop(l); // nothing listens: a connection attempt would be a Port error
    let mut c = config(&format!("tcp://127.0.0.1:{port}"), 100, 0);
    c.echo = true;
    match Bus::open(c) {
        Err(Error::InvalidArgument(m)) => assert!(m.contains("echo"), "{m}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_gateway_still_busy_gets_the_next_request_at_once_and_its_late_reply_is_dropped() {
    // The gateway answers transaction 1 only after the Bus gave up on it (100 ms), then
    // answers transaction 2. The second request goes out at once (transaction ids tell the
    // late reply apart), and is given the gateway's remaining busy time on top of its own
    // timeout; the late reply is dropped and counted.
    let (l, port) = listener();
    let server = thread::spawn(move || {
        let mut s = accept(&l);
        let _first = recv(&mut s, 12);
        let second = recv(&mut s, 12);
        let second_at = Instant::now();
        thread::sleep(Duration::from_millis(120));
        s.write_all(&mbap(1, &one_register(0x1111))).unwrap();
        s.write_all(&mbap(2, &one_register(0x2222))).unwrap();
        (second, second_at)
    });
    let bus = Bus::open(config(&format!("tcp://127.0.0.1:{port}"), 100, 0)).unwrap();
    assert!(matches!(read(&bus), Err(Error::Timeout { .. })));
    let gave_up = Instant::now();
    assert_eq!(read(&bus).unwrap(), vec![0x2222]);
    let (second, second_at) = join(server);
    assert_eq!(second, request(2));
    assert!(second_at.saturating_duration_since(gave_up) < Duration::from_millis(50));
    assert_eq!(
        bus.stats().stale_bytes,
        mbap(1, &one_register(0x1111)).len() as u64
    );
}
