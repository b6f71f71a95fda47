//! The PBL layer against a scripted transport: the manual's frames, the control word's
//! read-modify-write, block reads of the parameter list and the checks before sending.

mod common;

use benchbus::device::pbl::{table, Pbl};
use benchbus::device::{Device, Tabled};
use benchbus::Error;
use common::{bus, hex, sent, with_crc, words, Act, Scripted};
use std::sync::Arc;

fn pbl(acts: Vec<Act>, unit: u8) -> (Pbl, Scripted) {
    let (bus, t) = bus(acts, 0);
    (Pbl::new(Arc::new(bus), unit), t)
}

#[test]
fn the_manuals_three_frames() {
    let acts = vec![
        Act::Reply(hex("11 03 06 00 6B 00 13 00 00 38 B9")),
        Act::Reply(hex("11 06 00 01 00 01 1B 5A")), // a count of 1, not the echo
        Act::Reply(hex("11 10 00 01 00 02 12 98")),
    ];
    let (p, t) = pbl(acts, 0x11);
    assert_eq!(
        p.read_parameters(0x6B, 3).ok(),
        Some(vec![0x006B, 0x0013, 0x0000])
    );
    p.write_parameter(1, 3)
        .expect("the non-echo reply is accepted");
    p.bus()
        .write_registers(0x11, 1, &[0x000A, 0x0102], &Default::default())
        .expect("0x10");
    let frames = sent(&t);
    assert_eq!(frames[0], hex("11 03 00 6B 00 03 76 87"));
    // INDEX.md: the manual prints 9A 9B, the CRC of this frame (value 3), after a value of 1.
    assert_eq!(frames[1], hex("11 06 00 01 00 03 9A 9B"));
    assert_eq!(frames[2], hex("11 10 00 01 00 02 04 00 0A 01 02 C6 F0"));
}

#[test]
fn start_stop_and_direction_keep_the_other_bits() {
    let acts = vec![
        words(1, &[0x0012]),
        Act::Reply(with_crc(&[1, 6, 0, 0, 0, 0x01])), // count-style reply
        words(1, &[0x0013]),
        Act::Reply(with_crc(&[1, 6, 0, 0, 0x00, 0x12])),
        words(1, &[0x0012]),
    ];
    let (p, t) = pbl(acts, 1);
    p.start().expect("start");
    p.stop().expect("stop");
    p.set_reverse(true)
        .expect("already reverse: nothing written");
    let frames = sent(&t);
    assert_eq!(frames[1], with_crc(&[1, 6, 0, 0, 0x00, 0x13]));
    assert_eq!(frames[3], with_crc(&[1, 6, 0, 0, 0x00, 0x12]));
    assert_eq!(frames.len(), 5);
}

#[test]
fn the_parameter_list_is_read_in_blocks_of_61() {
    let blocks: Vec<Act> = [0u16, 61, 122, 183]
        .iter()
        .map(|&start| {
            let values: Vec<u16> = (start..(start + 61).min(223)).collect();
            words(1, &values)
        })
        .collect();
    let (p, t) = pbl(blocks, 1);
    let all = p.parameters().expect("parameters");
    assert_eq!(sent(&t).len(), 4);
    assert_eq!(sent(&t)[1], with_crc(&[1, 3, 0, 61, 0, 61]));
    assert_eq!(sent(&t)[3], with_crc(&[1, 3, 0, 183, 0, 40]));
    assert!(all.iter().all(|(name, _)| !name.starts_with("reserved_")));
    assert!(all.contains(&("acceleration", 209)) && all.contains(&("speed", 50)));
    assert_eq!(all.len(), table().unwrap().len() - 28 - 3);
}

#[test]
fn alarms_join_two_words() {
    let (p, _) = pbl(vec![words(1, &[0x0001, 0x0002])], 1);
    assert_eq!(p.alarms().ok(), Some(0x0002_0001));
}

#[test]
fn bad_parameters_are_refused_before_sending() {
    let (p, t) = pbl(vec![], 1);
    for (n, v) in [(50, 1), (2, 0), (100, 3), (215, 0), (223, 0)] {
        assert!(
            matches!(p.write_parameter(n, v), Err(Error::InvalidArgument(_))),
            "{n} = {v}"
        );
    }
    assert!(p.read_parameters(200, 30).is_err());
    assert!(p.set("no_such_parameter", 1.0).is_err());
    assert!(sent(&t).is_empty());
}
