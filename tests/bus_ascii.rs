//! The Bus in Modbus ASCII against a scripted line: what goes on the wire, how replies are
//! read (to their CR LF, with up to a second between two characters), retried and counted.
//! The frames are the Modbus Application Protocol specification's examples in the serial
//! line spec's ASCII framing (`tests/vectors/ascii.json`).

mod common;

use benchbus::bus::{Bus, BusConfig, TxOptions};
use benchbus::codec::{ascii, FrameError, Request};
use benchbus::timing::{LineFormat, Parity};
use benchbus::Error;
use common::{mock, sent, Act, Scripted};
use std::time::{Duration, Instant};

/// Read holding registers 0x006B..0x006D of unit 0x11, and its reply 0x022B, 0, 0x64.
const READ: &[u8] = b":1103006B00037E\r\n";
const REPLY: &[u8] = b":110306022B0000006455\r\n";

fn ascii_config(cfg: &mut BusConfig) {
    cfg.ascii = true;
    cfg.line = LineFormat::ascii(19_200, Parity::Even);
}

fn ascii_bus(acts: Vec<Act>, retries: u32) -> (Bus, Scripted) {
    let (t, mut cfg) = mock(acts, retries);
    ascii_config(&mut cfg);
    (Bus::with_transport(cfg, Box::new(t.clone())), t)
}

/// A Bus in ASCII on a scripted serial line whose reply characters arrive one per
/// `byte_time`, with a 20 ms timeout.
fn slow_bus(acts: Vec<Act>, byte_time: Duration) -> (Bus, Scripted) {
    let t = Scripted::default();
    {
        let mut s = t.0.lock().unwrap();
        s.acts = acts.into();
        s.byte_time = Some(byte_time);
    }
    let mut cfg = BusConfig::new("mock", LineFormat::ascii(19_200, Parity::Even)).unwrap();
    cfg.ascii = true;
    cfg.retries = 0;
    cfg.timeout = Duration::from_millis(20);
    (Bus::with_transport(cfg, Box::new(t.clone())), t)
}

fn read(bus: &Bus) -> benchbus::Result<Vec<u16>> {
    bus.read_holding_registers(0x11, 0x6B, 3, &TxOptions::default())
}

#[test]
fn a_read_goes_out_as_an_ascii_frame_and_its_reply_decodes() {
    let (bus, t) = ascii_bus(vec![Act::Reply(REPLY.to_vec())], 0);
    assert_eq!(read(&bus).unwrap(), [0x022B, 0, 0x64]);
    assert_eq!(sent(&t), [READ.to_vec()]);
    assert_eq!(bus.stats().transactions, 1);
}

#[test]
fn every_function_is_framed_in_ascii() {
    // The specification's examples (tests/vectors/ascii.json): write single register (6.6),
    // write multiple registers (6.12), read coils (6.1), read input registers (6.4).
    let (bus, t) = ascii_bus(
        vec![
            Act::Reply(b":110600010003E5\r\n".to_vec()),
            Act::Reply(b":111000010002DC\r\n".to_vec()),
            Act::Reply(b":110103CD6B05AE\r\n".to_vec()),
            Act::Reply(b":110402000ADF\r\n".to_vec()),
        ],
        0,
    );
    let opts = TxOptions::default();
    bus.write_register(0x11, 1, 3, &opts).unwrap();
    bus.write_registers(0x11, 1, &[0x000A, 0x0102], &opts)
        .unwrap();
    let coils = bus.read_coils(0x11, 0x13, 19, &opts).unwrap();
    let bits = |byte: u8, n: usize| (0..n).map(move |i| byte >> i & 1 == 1);
    let expected: Vec<bool> = bits(0xCD, 8)
        .chain(bits(0x6B, 8))
        .chain(bits(0x05, 3))
        .collect();
    assert_eq!(coils, expected);
    assert_eq!(bus.read_input_registers(0x11, 8, 1, &opts).unwrap(), [10]);
    assert_eq!(
        sent(&t),
        [
            b":110600010003E5\r\n".to_vec(),
            b":11100001000204000A0102CB\r\n".to_vec(),
            b":110100130013C8\r\n".to_vec(),
            b":110400080001E2\r\n".to_vec(),
        ]
    );
}

#[test]
fn an_exception_reply_is_the_devices_refusal() {
    let (bus, _) = ascii_bus(vec![Act::Reply(b":1183026A\r\n".to_vec())], 2);
    let e = read(&bus).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Exception {
                unit: 0x11,
                function: 3,
                code: 2,
                ..
            }
        ),
        "{e}"
    );
    let s = bus.stats();
    assert_eq!((s.exceptions, s.retries), (1, 0));
}

#[test]
fn a_bad_lrc_is_retried_and_counted_as_a_checksum_error() {
    let mut bad = REPLY.to_vec();
    bad[20] = b'6';
    let (bus, t) = ascii_bus(vec![Act::Reply(bad), Act::Reply(REPLY.to_vec())], 1);
    assert_eq!(read(&bus).unwrap(), [0x022B, 0, 0x64]);
    let s = bus.stats();
    assert_eq!((s.crc_errors, s.frame_errors, s.retries), (1, 0, 1));
    assert_eq!(sent(&t).len(), 2);
}

#[test]
fn a_bad_lrc_every_time_fails_as_a_frame_error_naming_the_lrc() {
    let mut bad = REPLY.to_vec();
    bad[20] = b'6';
    let (bus, _) = ascii_bus(vec![Act::Reply(bad.clone()), Act::Reply(bad.clone())], 1);
    let e = read(&bus).unwrap_err();
    match &e {
        Error::Frame { kind, frame, .. } => {
            assert!(
                matches!(kind, FrameError::Ascii(ascii::AsciiError::Lrc { .. })),
                "{e}"
            );
            assert_eq!(frame, &bad);
        }
        _ => panic!("{e}"),
    }
    assert!(e.to_string().contains("LRC"), "{e}");
    assert_eq!(bus.stats().crc_errors, 2);
}

#[test]
fn a_malformed_frame_is_retried_and_counted_as_a_frame_error() {
    let mut bad = REPLY.to_vec();
    bad[5] = b'G';
    let (bus, _) = ascii_bus(vec![Act::Reply(bad), Act::Reply(REPLY.to_vec())], 1);
    assert_eq!(read(&bus).unwrap(), [0x022B, 0, 0x64]);
    let s = bus.stats();
    assert_eq!((s.crc_errors, s.frame_errors, s.retries), (0, 1, 1));
}

#[test]
fn noise_before_the_colon_is_dropped_and_a_colon_restarts_the_frame() {
    // Two bytes of line noise, then a frame cut off by the reply's own `:`.
    let mut noisy = b"\x00\xFF:1103".to_vec();
    noisy.extend_from_slice(REPLY);
    let (bus, _) = ascii_bus(vec![Act::Reply(noisy)], 0);
    assert_eq!(read(&bus).unwrap(), [0x022B, 0, 0x64]);
    let s = bus.stats();
    assert_eq!((s.stale_bytes, s.frame_errors, s.retries), (7, 0, 0));
}

#[test]
fn a_reply_arriving_slowly_character_by_character_is_waited_for() {
    // 23 characters, one every 10 ms: the whole reply takes far over the 20 ms timeout, and
    // less than the attempt's end (the timeout and the longest frame's wire time, 513
    // characters at 19200 7E1: 267 ms).
    let (bus, _) = slow_bus(vec![Act::Reply(REPLY.to_vec())], Duration::from_millis(10));
    let start = Instant::now();
    assert_eq!(read(&bus).unwrap(), [0x022B, 0, 0x64]);
    assert!(
        start.elapsed() >= Duration::from_millis(220),
        "{:?}",
        start.elapsed()
    );
    assert_eq!(bus.stats().timeouts, 0);
}

/// The end of an attempt on the 19200 7E1 line of `slow_bus`: its 20 ms timeout and the
/// longest ASCII frame's wire time (513 characters of 10 bits).
fn attempt_end() -> Duration {
    Duration::from_millis(20) + Duration::from_micros(513 * 10 * 1_000_000 / 19_200)
}

#[test]
fn a_reply_slower_than_the_attempts_end_times_out_there() {
    // One character every 15 ms: 345 ms for the reply, past the attempt's end.
    let (bus, _) = slow_bus(vec![Act::Reply(REPLY.to_vec())], Duration::from_millis(15));
    let start = Instant::now();
    let e = read(&bus).unwrap_err();
    let took = start.elapsed();
    assert!(matches!(e, Error::Timeout { .. }), "{e}");
    assert!(
        took >= attempt_end() - Duration::from_millis(5) && took < Duration::from_millis(340),
        "{took:?}"
    );
}

#[test]
fn a_colon_after_every_pause_does_not_hold_the_call() {
    // Each `:` starts a frame again, and each character would extend a 1 s inter-character
    // wait: 200 of them, 15 ms apart (3 s), end at the attempt's end all the same.
    let (bus, _) = slow_bus(vec![Act::Reply(vec![b':'; 200])], Duration::from_millis(15));
    let start = Instant::now();
    let e = read(&bus).unwrap_err();
    let took = start.elapsed();
    assert!(matches!(e, Error::Timeout { .. }), "{e}");
    assert!(took < attempt_end() + Duration::from_millis(50), "{took:?}");
}

#[test]
fn a_reply_that_stops_mid_frame_times_out_at_the_attempts_end() {
    // A frame begun may pause up to 1 s between characters (serial line spec 2.5.2.1), but
    // the attempt ends at its timeout and the longest frame's wire time (267 ms at 19200
    // 7E1).
    let (bus, _) = ascii_bus(vec![Act::Reply(b":110306022B".to_vec())], 0);
    let start = Instant::now();
    let e = read(&bus).unwrap_err();
    let took = start.elapsed();
    match &e {
        Error::Timeout { received, .. } => assert_eq!(received, b":110306022B"),
        _ => panic!("{e}"),
    }
    let line = bus.config().line;
    let end = bus.config().timeout + line.frame_time(ascii::MAX_FRAME);
    assert!(
        took + Duration::from_millis(5) >= end && took < end + Duration::from_millis(100),
        "{took:?} for an attempt's end of {end:?}"
    );
    assert!(took < ascii::INTER_CHAR_TIMEOUT, "{took:?}");
}

#[test]
fn noise_alone_does_not_hold_the_wait_for_the_frame() {
    // Characters without a `:` are no frame begun: the timeout is the Bus's own.
    let (bus, _) = ascii_bus(vec![Act::Reply(b"\x00\x7F\x00".to_vec())], 0);
    let start = Instant::now();
    let e = read(&bus).unwrap_err();
    assert!(matches!(e, Error::Timeout { .. }), "{e}");
    assert!(
        start.elapsed() < Duration::from_millis(500),
        "{:?}",
        start.elapsed()
    );
    assert_eq!(bus.stats().stale_bytes, 3);
}

#[test]
fn a_raw_request_is_read_to_its_cr_lf_without_waiting_for_silence() {
    // Report server id (0x11) as a raw request with no reply length: in RTU it would end by
    // silence (here 800 ms), in ASCII it ends at its CR LF.
    let reply = ascii::encode(&[0x11, 0x11, 0x03, 0x42, 0xFF, 0x01]);
    let (t, mut cfg) = mock(vec![Act::Reply(reply)], 0);
    ascii_config(&mut cfg);
    cfg.silence = Duration::from_millis(800);
    cfg.timeout = Duration::from_millis(50);
    let bus = Bus::with_transport(cfg, Box::new(t.clone()));
    let start = Instant::now();
    let data = bus
        .request(0x11, 0x11, &[], None, &TxOptions::default())
        .unwrap();
    assert!(
        start.elapsed() < Duration::from_millis(300),
        "{:?}",
        start.elapsed()
    );
    assert_eq!(data, [0x03, 0x42, 0xFF, 0x01]);
    assert_eq!(sent(&t), [b":1111DE\r\n".to_vec()]);
}

#[test]
fn the_longest_write_goes_out_whole_and_its_echo_is_read_back() {
    // 123 registers: unit, function, address, count, byte count and 246 bytes, LRC: 254
    // bytes, 511 characters with `:` and CR LF (an RTU frame is at most 256 bytes).
    let (t, mut cfg) = mock(vec![], 0);
    ascii_config(&mut cfg);
    cfg.echo = true;
    t.0.lock().unwrap().echo = true;
    let values: Vec<u16> = (0..123).map(|v| v * 0x0101).collect();
    let reply = ascii::encode(&[0x11, 0x10, 0x00, 0x00, 0x00, 123]);
    t.0.lock().unwrap().acts.push_back(Act::Reply(reply));
    let bus = Bus::with_transport(cfg, Box::new(t.clone()));
    bus.write_registers(0x11, 0, &values, &TxOptions::default())
        .unwrap();
    let frame = &sent(&t)[0];
    assert_eq!(frame.len(), 511);
    assert_eq!(
        ascii::decode(frame).unwrap()[..7],
        [0x11, 0x10, 0, 0, 0, 123, 246]
    );
}

#[test]
fn the_longest_write_without_echo_and_its_reply() {
    let values = [0xABCDu16; 123];
    let reply = ascii::encode(&[0x11, 0x10, 0x00, 0x00, 0x00, 123]);
    let (bus, t) = ascii_bus(vec![Act::Reply(reply)], 0);
    bus.write_registers(0x11, 0, &values, &TxOptions::default())
        .unwrap();
    assert_eq!(sent(&t)[0].len(), 511);
}

#[test]
fn a_frame_that_never_ends_or_a_flood_of_noise_fails_without_a_panic() {
    // A `:` and 600 hex digits with no CR LF: past the 513 characters of the longest frame.
    let mut endless = b":".to_vec();
    endless.extend(std::iter::repeat_n(b'1', 600));
    // The longest reply the spec allows, in place of a three-register read's.
    let mut longest = vec![0x11, 0x03, 250];
    longest.extend([0u8; 250]);
    let noise = vec![0xFFu8; 3000];
    for (reply, note) in [
        (endless, "endless"),
        (ascii::encode(&longest), "longest"),
        (noise, "noise"),
    ] {
        let (bus, _) = ascii_bus(vec![Act::Reply(reply.clone()), Act::Reply(reply)], 1);
        let e = read(&bus).unwrap_err();
        assert!(
            matches!(e, Error::Frame { .. } | Error::Timeout { .. }),
            "{note}: {e}"
        );
    }
}

#[test]
fn a_broadcast_goes_out_to_unit_zero_in_ascii() {
    let (bus, t) = ascii_bus(vec![], 0);
    bus.broadcast(&Request::WriteSingleRegister {
        address: 1,
        value: 3,
    })
    .unwrap();
    assert_eq!(sent(&t), [b":000600010003F6\r\n".to_vec()]);
}

#[test]
fn a_late_reply_of_another_unit_is_dropped_and_the_answer_read() {
    // Unit 0x11 times out; its reply comes late, ahead of unit 0x12's.
    let late = REPLY.to_vec();
    let answer = ascii::encode(&[0x12, 0x03, 0x02, 0x00, 0x07]);
    let (bus, _) = ascii_bus(vec![Act::Late(late), Act::Reply(answer)], 0);
    assert!(matches!(read(&bus), Err(Error::Timeout { .. })));
    let v = bus
        .read_holding_registers(0x12, 0, 1, &TxOptions::default())
        .unwrap();
    assert_eq!(v, [7]);
    assert_eq!(bus.stats().stale_bytes, REPLY.len() as u64);
}

fn refused(cfg: BusConfig) -> String {
    let t = Scripted::default();
    match Bus::with_opener(cfg, Box::new(move |_| Ok(Box::new(t.clone())))) {
        Err(Error::InvalidArgument(m)) => m,
        Err(e) => panic!("not refused as an invalid argument: {e}"),
        Ok(_) => panic!("opened"),
    }
}

#[test]
fn line_formats_and_ports_that_cannot_carry_the_framing_are_refused() {
    let ascii_cfg = |port: &str, line: LineFormat| {
        let mut cfg = BusConfig::new(port, line).unwrap();
        cfg.ascii = true;
        cfg
    };
    let seven_n_one = LineFormat {
        stop_bits: 1,
        ..LineFormat::ascii(9600, Parity::None)
    };
    let m = refused(ascii_cfg("mock", seven_n_one));
    assert!(m.contains("7N2") && m.contains("7N1 is not allowed"), "{m}");
    let six = LineFormat {
        data_bits: 6,
        ..LineFormat::ascii(9600, Parity::Even)
    };
    assert!(refused(ascii_cfg("mock", six)).contains("7 or 8 data bits"));
    let m = refused(ascii_cfg(
        "tcp://127.0.0.1:1502",
        LineFormat::ascii(9600, Parity::Even),
    ));
    assert!(m.contains("tcp://") && m.contains("serial line"), "{m}");
    let upper = refused(ascii_cfg(
        "TCP://127.0.0.1:1502",
        LineFormat::ascii(9600, Parity::Even),
    ));
    assert!(upper.contains("tcp://"), "{upper}");
    // RTU takes 8 data bits.
    let m = refused(BusConfig::new("mock", LineFormat::ascii(9600, Parity::Even)).unwrap());
    assert!(m.contains("RTU") && m.contains("8 data bits"), "{m}");
    // What the spec allows opens: 7E1, 7N2, 8N1 in ASCII, and over rtu+tcp://.
    for (port, line) in [
        ("mock", LineFormat::ascii(9600, Parity::Even)),
        ("mock", LineFormat::ascii(9600, Parity::None)),
        ("mock", LineFormat::new(9600, Parity::None, 1)),
        (
            "rtu+tcp://127.0.0.1:1",
            LineFormat::ascii(9600, Parity::Odd),
        ),
    ] {
        let t = Scripted::default();
        let cfg = ascii_cfg(port, line);
        assert!(
            Bus::with_opener(cfg, Box::new(move |_| Ok(Box::new(t.clone())))).is_ok(),
            "{port} {line}"
        );
    }
}

#[test]
fn the_longest_raw_request_is_513_characters_and_its_echo_fits() {
    // 252 data bytes after the function code: unit | PDU is 254 bytes, the longest frame.
    let (t, mut cfg) = mock(vec![], 0);
    ascii_config(&mut cfg);
    cfg.echo = true;
    t.0.lock().unwrap().echo = true;
    let reply = ascii::encode(&[0x11, 0x41, 0x00]);
    t.0.lock().unwrap().acts.push_back(Act::Reply(reply));
    let bus = Bus::with_transport(cfg, Box::new(t.clone()));
    let data = bus
        .request(0x11, 0x41, &[0xAB; 252], Some(1), &TxOptions::default())
        .unwrap();
    assert_eq!(data, [0x00]);
    assert_eq!(sent(&t)[0].len(), ascii::MAX_FRAME);
}
