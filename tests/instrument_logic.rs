//! The generic instrument against a scripted transport: the Taisong and ATV31 frames of
//! manual 004, splitting at the per-device limits, 32-bit values, text and identification.

mod common;

use benchbus::bus::{Bus, BusConfig};
use benchbus::device::instrument::Instrument;
use benchbus::device::value::Layout;
use benchbus::device::Table;

/// The table the instrument tests read: holding registers.
const H: Table = Table::Holding;
use benchbus::timing::{LineFormat, Parity};
use benchbus::Error;
use common::{bus, hex, sent, with_crc, words, Act, Scripted};
use std::sync::Arc;
use std::time::{Duration, Instant};

fn inst(acts: Vec<Act>, unit: u8, max_read: u16, max_write: u16) -> (Instrument, Scripted) {
    let (bus, t) = bus(acts, 0);
    let i = Instrument::new(Arc::new(bus), unit, max_read, max_write, Duration::ZERO);
    (i.expect("valid limits"), t)
}

fn taisong(acts: Vec<Act>, unit: u8) -> (Instrument, Scripted) {
    inst(acts, unit, 37, 20)
}

fn written(unit: u8, address: u16, count: u16) -> Act {
    let mut body = vec![unit, 0x10];
    body.extend(address.to_be_bytes());
    body.extend(count.to_be_bytes());
    Act::Reply(with_crc(&body))
}

#[test]
fn the_taisong_frames() {
    let acts = vec![
        Act::Reply(hex("01 03 02 03 E8 B8 FA")),
        Act::Reply(hex("01 06 00 05 00 64 98 20")),
        Act::Reply(hex("01 10 00 08 00 02 C0 0A")),
        words(1, &[1000, 7]),
    ];
    let (i, t) = taisong(acts, 1);
    assert_eq!(i.read_value(H, 0, 0, false).ok(), Some(1000.0));
    i.write_value(5, 100.0, 0, false, false).expect("SV");
    i.write_registers(8, &[100, 200]).expect("0x10");
    assert_eq!(i.read_registers(H, 0, 2).ok(), Some(vec![1000, 7]));
    let frames = sent(&t);
    assert_eq!(frames[0], hex("01 03 00 00 00 01 84 0A"));
    assert_eq!(frames[1], hex("01 06 00 05 00 64 98 20"));
    assert_eq!(frames[2], hex("01 10 00 08 00 02 04 00 64 00 C8 B2 40"));
    assert_eq!(frames[3], hex("01 03 00 00 00 02 C4 0B"));
    let (i, t) = taisong(vec![Act::Reply(hex("09 03 02 01 00 58 15"))], 9);
    assert_eq!(i.read_word(H, 0).ok(), Some(256));
    assert_eq!(sent(&t)[0], hex("09 03 00 00 00 01 85 42"));
}

#[test]
fn the_atv31_frames() {
    let acts = vec![
        Act::Reply(hex("02 03 08 00 28 02 58 01 F4 00 00 52 B0")),
        Act::Reply(hex("02 06 23 29 00 0D 92 70")),
        Act::Reply(hex("02 10 0F CB 00 02 33 11")),
    ];
    let (i, t) = inst(acts, 2, 29, 29);
    assert_eq!(
        i.read_registers(H, 0x0C1E, 4).ok(),
        Some(vec![0x28, 0x258, 0x1F4, 0])
    );
    i.write_word(0x2329, 13, false).expect("W9001");
    i.write_registers(0x0FCB, &[20, 30]).expect("W4043..4044");
    let frames = sent(&t);
    assert_eq!(frames[0], hex("02 03 0C 1E 00 04 27 6C"));
    assert_eq!(frames[1], hex("02 06 23 29 00 0D 92 70"));
    assert_eq!(frames[2], hex("02 10 0F CB 00 02 04 00 14 00 1E 30 F4"));
}

#[test]
fn long_reads_and_writes_are_split_at_the_limits() {
    let acts = vec![
        words(1, &[1; 37]),
        words(1, &[2; 37]),
        words(1, &[3; 26]),
        written(1, 0, 20),
        written(1, 20, 20),
        written(1, 40, 5),
    ];
    let (i, t) = taisong(acts, 1);
    let got = i.read_registers(H, 0, 100).expect("three reads");
    assert_eq!(got.len(), 100);
    assert_eq!((got[0], got[37], got[99]), (1, 2, 3));
    let values: Vec<u16> = (0..45).collect();
    i.write_registers(0, &values).expect("three writes");
    let spans: Vec<(u8, u16, u16)> = sent(&t)
        .iter()
        .map(|f| {
            (
                f[1],
                u16::from_be_bytes([f[2], f[3]]),
                u16::from_be_bytes([f[4], f[5]]),
            )
        })
        .collect();
    assert_eq!(
        spans,
        vec![
            (3, 0, 37),
            (3, 37, 37),
            (3, 74, 26),
            (0x10, 0, 20),
            (0x10, 20, 20),
            (0x10, 40, 5)
        ]
    );
    // The last write carries values 40..44.
    assert_eq!(sent(&t)[5][7..17], [0, 40, 0, 41, 0, 42, 0, 43, 0, 44]);
}

#[test]
fn bad_spans_and_limits_send_nothing() {
    let (i, t) = taisong(vec![], 1);
    assert!(matches!(
        i.read_registers(H, 0, 0),
        Err(Error::InvalidArgument(_))
    ));
    assert!(matches!(
        i.read_registers(H, 0xFFFF, 2),
        Err(Error::InvalidArgument(_))
    ));
    assert!(matches!(
        i.write_registers(0xFFFF, &[1, 2]),
        Err(Error::InvalidArgument(_))
    ));
    assert!(matches!(
        i.write_string(0, "abcde", 2),
        Err(Error::InvalidArgument(_))
    ));
    assert!(matches!(
        i.write_string(0, "Ω", 2),
        Err(Error::InvalidArgument(_))
    ));
    assert!(matches!(i.identify(4), Err(Error::InvalidArgument(_))));
    assert!(sent(&t).is_empty());
}

/// The core's refusals name the argument, as the Python error does: the binding passes
/// them on and checks nothing twice.
#[test]
fn refused_values_name_the_argument_and_send_nothing() {
    let (i, t) = taisong(vec![], 1);
    let message = |r: Result<(), Error>| match r {
        Err(Error::InvalidArgument(m)) => m,
        other => panic!("not refused: {other:?}"),
    };
    for value in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e39] {
        for bits in [32, 64] {
            if bits == 64 && value.is_finite() {
                continue; // a double holds it
            }
            let m = message(i.write_float(0, value, bits, Layout::Abcd));
            assert!(m.starts_with("value must be a finite number"), "{m}");
        }
    }
    let m = message(i.write_uint(0, 1 << 32, 32, Layout::Abcd));
    assert_eq!(m, "value must fit 32 bits, got 4294967296");
    let m = message(i.write_uint(0, 1, 16, Layout::Abcd));
    assert_eq!(m, "bits must be 32 or 64, got 16");
    let m = message(i.write_uint(0xFFFE, 1, 64, Layout::Abcd));
    assert!(m.contains("0xFFFF"), "{m}");
    let m = message(i.write_value(0, 65536.0, 0, false, false));
    assert!(
        m.starts_with("value 65536 with 0 decimals does not fit"),
        "{m}"
    );
    let m = message(i.write_value(0, 1.25, 1, false, true));
    assert_eq!(m, "value 1.25 has more than 1 decimals");
    for text in ["abcde", "Ω"] {
        let m = message(i.write_string(0, text, 2));
        assert_eq!(
            m,
            format!("text must be Latin-1 and at most 4 characters for 2 registers, got {text:?}")
        );
    }
    assert!(sent(&t).is_empty());
    let (bus, _) = bus(vec![], 0);
    let bus = Arc::new(bus);
    for (r, w) in [(0, 20), (126, 20), (37, 0), (37, 124)] {
        let made = Instrument::new(Arc::clone(&bus), 1, r, w, Duration::ZERO);
        assert!(matches!(made, Err(Error::InvalidArgument(_))), "{r} {w}");
    }
}

#[test]
fn thirty_two_bit_values_in_both_word_orders() {
    let acts = vec![
        written(1, 0x10, 2),
        words(1, &[0x1234, 0x5678]),
        written(1, 0x10, 2),
        written(1, 0x20, 2),
        words(1, &[0x0000, 0x41AC]),
    ];
    let (i, t) = taisong(acts, 1);
    i.write_uint(0x10, 0x1234_5678, 32, Layout::Abcd)
        .expect("write");
    assert_eq!(
        i.read_uint(H, 0x10, 32, Layout::Cdab).ok(),
        Some(0x5678_1234)
    );
    i.write_uint(0x10, 0x1234_5678, 32, Layout::Cdab)
        .expect("write");
    i.write_float(0x20, 21.5, 32, Layout::Cdab).expect("float");
    assert_eq!(i.read_float(H, 0x20, 32, Layout::Cdab).ok(), Some(21.5));
    let frames = sent(&t);
    assert_eq!(frames[0][7..11], [0x12, 0x34, 0x56, 0x78]);
    assert_eq!(frames[2][7..11], [0x56, 0x78, 0x12, 0x34]);
    assert_eq!(frames[3][7..11], [0x00, 0x00, 0x41, 0xAC]); // 21.5 = 0x41AC0000
}

#[test]
fn text_two_characters_a_register() {
    let acts = vec![written(1, 0x40, 3), words(1, &[0x4142, 0x4300, 0x0000])];
    let (i, t) = taisong(acts, 1);
    i.write_string(0x40, "ABC", 3).expect("write");
    assert_eq!(sent(&t)[0][7..13], *b"ABC\0\0\0");
    assert_eq!(i.read_string(H, 0x40, 3).ok().as_deref(), Some("ABC"));
}

fn id_page(more: bool, next: u8, objects: &[(u8, &str)]) -> Act {
    let mut body = vec![2, 0x2B, 0x0E, 1, 0x01, if more { 0xFF } else { 0 }, next];
    body.push(objects.len() as u8);
    for (id, text) in objects {
        body.push(*id);
        body.push(text.len() as u8);
        body.extend(text.as_bytes());
    }
    Act::Reply(with_crc(&body))
}

#[test]
fn identification_follows_more_follows() {
    let acts = vec![
        id_page(true, 1, &[(0, "TELEMECANIQUE")]),
        id_page(true, 2, &[(1, "ATV31HU09M3S232")]),
        id_page(false, 0, &[(2, "0201")]),
    ];
    let (i, t) = inst(acts, 2, 29, 29);
    let id = i.identify(1).expect("three pages");
    assert_eq!(
        id.objects.get(&0).map(Vec::as_slice),
        Some(&b"TELEMECANIQUE"[..])
    );
    assert_eq!(
        id.objects.get(&1).map(Vec::as_slice),
        Some(&b"ATV31HU09M3S232"[..])
    );
    assert_eq!(id.objects.get(&2).map(Vec::as_slice), Some(&b"0201"[..]));
    let frames = sent(&t);
    assert_eq!(frames[0], hex("02 2B 0E 01 00 34 77"));
    assert_eq!(frames[1][..5], hex("02 2B 0E 01 01")[..]);
    assert_eq!(frames[2][..5], hex("02 2B 0E 01 02")[..]);
}

#[test]
fn a_device_without_identification_says_so() {
    let standard = Act::Reply(with_crc(&hex("02 AB 01")));
    let atv31 = Act::Reply(with_crc(&hex("02 AB 0E 01")));
    for act in [standard, atv31] {
        let (i, _) = inst(vec![act], 2, 29, 29);
        match i.identify(1) {
            Err(Error::Exception {
                code: 1, meaning, ..
            }) => {
                assert!(meaning.contains("does not support Read Device Identification"));
            }
            other => panic!("{other:?}"),
        }
    }
}

#[test]
fn writes_keep_the_instruments_interval() {
    let (bus, _) = bus(vec![written(1, 0, 1), written(1, 0, 1)], 0);
    let i = Instrument::new(Arc::new(bus), 1, 37, 20, Duration::from_millis(80));
    let i = i.expect("valid");
    let start = Instant::now();
    i.write_registers(0, &[1]).expect("first");
    i.write_registers(0, &[2]).expect("second");
    assert!(start.elapsed() >= Duration::from_millis(80));
}

#[test]
fn a_long_reply_at_a_low_baud_rate_gets_its_wire_time() {
    // 37 registers at 2400 baud: 79 bytes, 330 ms on the wire, against a 100 ms timeout
    // (the device's allowance to answer); the reply's own time comes on top.
    let t = Scripted::default();
    {
        let mut s = t.0.lock().unwrap();
        s.acts.push_back(words(1, &[7; 37]));
        s.byte_time = Some(Duration::from_micros(4167));
    }
    let mut cfg = BusConfig::new("mock", LineFormat::new(2400, Parity::None, 1)).unwrap();
    cfg.timeout = Duration::from_millis(100);
    cfg.retries = 0;
    let bus = Bus::with_transport(cfg, Box::new(t.clone()));
    let i = Instrument::new(Arc::new(bus), 1, 37, 20, Duration::ZERO).expect("valid");
    let start = Instant::now();
    assert_eq!(i.read_registers(H, 0, 37).ok(), Some(vec![7; 37]));
    assert!(start.elapsed() >= Duration::from_millis(300));
}
