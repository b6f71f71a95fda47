//! The J2 layer against a scripted transport: the manual's frames, chunking, the manual's
//! rules (MV in manual mode only, RAPNF before ramp parameters, limits) and write pacing.

mod common;

use benchbus::bus::TxOptions;
use benchbus::codec::Request;
use benchbus::device::j2::{index, profile, J2};
use benchbus::device::{Device, Tabled};
use benchbus::Error;
use common::{bus, hex, sent, with_crc, words, Act, Scripted};
use std::sync::{mpsc, Arc};
use std::time::{Duration, Instant};

/// The family file's pacing, 150 ms.
fn write_interval() -> std::time::Duration {
    profile().unwrap().write_interval()
}

fn j2(acts: Vec<Act>, retries: u32) -> (J2, Scripted) {
    let (bus, t) = bus(acts, retries);
    (J2::new(Arc::new(bus), 1), t)
}

/// The echo a 0x06 write gets.
fn echo(address: u16, value: u16) -> Act {
    let mut body = vec![1, 6];
    body.extend(address.to_be_bytes());
    body.extend(value.to_be_bytes());
    Act::Reply(with_crc(&body))
}

/// (function, address, count or value) of each frame sent.
fn summary(t: &Scripted) -> Vec<(u8, u16, u16)> {
    sent(t)
        .iter()
        .map(|f| {
            (
                f[1],
                u16::from_be_bytes([f[2], f[3]]),
                u16::from_be_bytes([f[4], f[5]]),
            )
        })
        .collect()
}

#[test]
fn the_manuals_three_frames() {
    let acts = vec![
        Act::Reply(hex("01 03 02 03 E8 B8 FA")),
        words(1, &[0, 0, 4000]), // LSP 0, USP 400.0: SV = 100.0 is within them
        Act::Reply(hex("01 06 00 06 03 E8 69 75")),
        words(1, &[0, 0, 4000]),
        Act::Reply(hex("01 10 00 06 00 01 E1 C8")),
    ];
    let (c, t) = j2(acts, 0);
    assert_eq!(c.get("SV").ok(), Some(100.0));
    c.set("SV", 100.0).expect("06");
    c.set_as("SV", 100.0, true).expect("10");
    let frames = sent(&t);
    assert_eq!(frames[0], hex("01 03 00 06 00 01 64 0B"));
    assert_eq!(frames[1], with_crc(&hex("01 03 00 14 00 03"))); // the limits, LSP..USP
    assert_eq!(frames[2], hex("01 06 00 06 03 E8 69 75"));
    assert_eq!(frames[4], hex("01 10 00 06 00 01 02 03 E8 A6 88"));
}

#[test]
fn parameters_come_in_blocks_of_sixteen() {
    let acts = vec![
        words(1, &[0; 15]),
        words(1, &[0; 15]),
        words(1, &[0; 15]),
        words(1, &[0; 15]),
        words(1, &[0; 15]),
        words(1, &[0; 13]),
    ];
    let (c, t) = j2(acts, 0);
    let all = c.parameters().expect("six reads");
    assert_eq!(all.len(), 43);
    let reads: Vec<(u16, u16)> = summary(&t).iter().map(|&(_, a, n)| (a, n)).collect();
    assert_eq!(
        reads,
        vec![(0, 15), (16, 15), (32, 15), (48, 15), (128, 15), (144, 13)]
    );
}

#[test]
fn blocks_cover_the_wanted_addresses_in_the_fewest_reads() {
    let blocks = |names: &[&str]| -> Vec<(u16, u16)> {
        let indices: Vec<usize> = names.iter().map(|n| index(n).unwrap()).collect();
        let plan = profile().unwrap().plan(&indices);
        plan.iter().map(|b| (b.start, b.count)).collect()
    };
    assert_eq!(blocks(&["AM", "MV"]), vec![(0, 1), (0x80, 1)]);
    // P, D, I at 14, 18, 16 (and P again): one read across the empty addresses.
    assert_eq!(blocks(&["P", "D", "I", "P"]), vec![(14, 5)]);
    // MV, P and I at 0, 14 and 16: 17 registers is past the 16 a request takes.
    assert_eq!(blocks(&["MV", "P", "I"]), vec![(0, 15), (16, 1)]);
    assert_eq!(blocks(&[]), vec![]);
    // MV and AM: two reads of one register, not the 0..0x80 span.
    let (c, t) = j2(vec![words(1, &[250]), words(1, &[0])], 0);
    assert_eq!(c.get_many(&["MV", "AM"]).ok(), Some(vec![25.0, 0.0]));
    assert_eq!(summary(&t), vec![(3, 0, 1), (3, 0x80, 1)]);
}

#[test]
fn values_decode_signed_tenths_and_unsigned_ints() {
    let mut pid = [0u16; 5];
    pid[0] = 305; // P = 30.5
    pid[2] = 0xFFFF; // I: two's complement -0.1 (not a valid I, but decoded as sent)
    pid[4] = 3; // D = 0.3 exactly
    let (c, _) = j2(vec![words(1, &pid), words(1, &[6])], 0);
    assert_eq!(
        c.get_many(&["P", "I", "D"]).ok(),
        Some(vec![30.5, -0.1, 0.3])
    );
    assert_eq!(c.get("INP").ok(), Some(6.0));
}

#[test]
fn mv_in_automatic_mode_is_refused_without_writing() {
    let (c, t) = j2(vec![words(1, &[1])], 0);
    let err = c.set("MV", 40.0).err();
    assert!(
        matches!(&err, Some(Error::State { unit: 1, .. })),
        "{err:?}"
    );
    assert!(err.is_some_and(|e| e.to_string().contains("switch_to_manual")));
    assert_eq!(summary(&t), vec![(3, 0x80, 1)]); // AM read, nothing written
}

#[test]
fn set_output_switches_to_manual_when_asked() {
    let acts = vec![words(1, &[1]), echo(0x80, 0), echo(0, 425)];
    let (c, t) = j2(acts, 0);
    c.set_output(42.5, true).expect("switched, then written");
    assert_eq!(summary(&t), vec![(3, 0x80, 1), (6, 0x80, 0), (6, 0, 425)]);
    // In manual mode MV is written at once.
    let (c, t) = j2(vec![words(1, &[0]), echo(0, 0)], 0);
    c.set_output(0.0, false).expect("manual already");
    assert_eq!(summary(&t), vec![(3, 0x80, 1), (6, 0, 0)]);
}

#[test]
fn ramp_parameters_are_written_after_rapnf_0() {
    let acts = vec![echo(0x82, 0), echo(0x28, 600)];
    let (c, t) = j2(acts, 0);
    c.set("RTM", 60.0).expect("RAPNF, then RTM");
    assert_eq!(summary(&t), vec![(6, 0x82, 0), (6, 0x28, 600)]);
}

#[test]
fn values_within_lsp_usp_are_checked_against_the_controllers_limits() {
    let (c, t) = j2(vec![words(1, &[0, 0, 2000])], 0);
    let err = c.set("SV", 250.0).err().map(|e| e.to_string());
    assert_eq!(
        err.as_deref(),
        Some("SV must be within the setpoint limits LSP to USP, 0 to 200, got 250 (set both with j2.limits = (low, high))")
    );
    assert_eq!(summary(&t), vec![(3, 0x14, 3)]); // the limits read, nothing written
                                                 // Out of the widest range: refused before anything is sent.
    let (c, t) = j2(vec![], 0);
    assert!(matches!(
        c.set("SV", 5000.0),
        Err(Error::InvalidArgument(_))
    ));
    assert!(matches!(c.set("PV", 1.0), Err(Error::InvalidArgument(_))));
    assert!(matches!(c.set("FST", 19.0), Err(Error::InvalidArgument(_))));
    assert!(matches!(c.set("nope", 1.0), Err(Error::InvalidArgument(_))));
    assert!(matches!(
        c.set("SV", f64::NAN),
        Err(Error::InvalidArgument(_))
    ));
    assert!(sent(&t).is_empty());
}

#[test]
fn limits_are_written_in_the_order_that_keeps_lsp_below_usp() {
    // Raising both above the current USP: USP first.
    let acts = vec![words(1, &[0, 0, 1000]), echo(0x16, 6000), echo(0x14, 2000)];
    let (c, t) = j2(acts, 0);
    c.set_limits(200.0, 600.0).expect("USP then LSP");
    assert_eq!(summary(&t)[1..], [(6, 0x16, 6000), (6, 0x14, 2000)]);
    // Lowering: LSP first.
    let acts = vec![words(1, &[0, 0, 1000]), echo(0x14, 0xFF38), echo(0x16, 500)];
    let (c, t) = j2(acts, 0);
    c.set_limits(-20.0, 50.0).expect("LSP then USP");
    assert_eq!(summary(&t)[1..], [(6, 0x14, 0xFF38), (6, 0x16, 500)]);
    let (c, t) = j2(vec![], 0);
    assert!(matches!(
        c.set_limits(10.0, 5.0),
        Err(Error::InvalidArgument(_))
    ));
    assert!(sent(&t).is_empty());
}

#[test]
fn negative_values_go_as_twos_complement() {
    let (c, t) = j2(vec![echo(8, 0xFE0C), echo(0x34, 0xFFCE)], 0);
    c.set("AL1", -50.0).expect("AL1");
    c.set("PVOS", -5.0).expect("PVOS");
    assert_eq!(summary(&t), vec![(6, 8, 0xFE0C), (6, 0x34, 0xFFCE)]);
}

#[test]
fn writes_to_one_controller_are_paced() {
    let acts = vec![echo(8, 1), echo(8, 2), echo(8, 3)];
    let (c, _) = j2(acts, 0);
    let start = Instant::now();
    for v in 1..=3 {
        c.set("AL1", f64::from(v) / 10.0).expect("write");
    }
    assert!(start.elapsed() >= write_interval() * 2);
}

#[test]
fn a_retried_write_keeps_the_interval() {
    // The first attempt gets no reply (5 ms timeout); the retry still waits 150 ms.
    let acts = vec![Act::Silent, echo(8, 1)];
    let (c, _) = j2(acts, 1);
    let start = Instant::now();
    c.set("AL1", 0.1).expect("second attempt");
    assert!(start.elapsed() >= write_interval());
    assert_eq!(c.bus().stats().retries, 1);
}

#[test]
fn pacing_does_not_hold_up_other_units() {
    // A long interval, so the read surely comes while the second write waits.
    let acts = vec![echo(8, 1), words(2, &[7]), echo(8, 2)];
    let (bus, t) = bus(acts, 0);
    let bus = Arc::new(bus);
    let paced = TxOptions {
        write_interval: Duration::from_secs(2),
        ..TxOptions::default()
    };
    let (tx, rx) = mpsc::channel();
    let writer = {
        let bus = Arc::clone(&bus);
        std::thread::spawn(move || {
            let first = bus.write_register(1, 8, 1, &paced);
            let _ = tx.send(());
            (first, bus.write_register(1, 8, 2, &paced))
        })
    };
    rx.recv_timeout(Duration::from_secs(5))
        .expect("first write done");
    std::thread::sleep(Duration::from_millis(50)); // the writer is now waiting its turn
    let start = Instant::now();
    let other = bus.read_holding_registers(2, 0, 1, &TxOptions::default());
    let read_took = start.elapsed();
    let (first, second) = writer.join().expect("writer thread");
    assert!(first.is_ok() && second.is_ok() && other.is_ok());
    let units: Vec<u8> = sent(&t).iter().map(|f| f[0]).collect();
    assert_eq!(units, vec![1, 2, 1]);
    assert!(read_took < Duration::from_secs(1), "{read_took:?}");
}

#[test]
fn a_broadcast_counts_as_a_write_to_every_unit() {
    let (c, t) = j2(vec![echo(8, 1), Act::Silent, echo(8, 2)], 0);
    c.set("AL1", 0.1).expect("write");
    let start = Instant::now();
    c.bus()
        .broadcast(&Request::WriteSingleRegister {
            address: 10,
            value: 7,
        })
        .expect("broadcast");
    // The broadcast waited out unit 1's interval, and the next write waits after it.
    assert!(start.elapsed() >= write_interval());
    let after = Instant::now();
    c.set("AL1", 0.2).expect("write");
    assert!(after.elapsed() >= write_interval());
    assert_eq!(
        sent(&t).iter().map(|f| f[0]).collect::<Vec<_>>(),
        vec![1, 0, 1]
    );
}

#[test]
fn sequences_for_one_unit_exclude_each_other_whatever_the_object() {
    let (bus, _) = bus(vec![], 0);
    let bus = Arc::new(bus);
    let (entered, go_on) = (mpsc::channel(), mpsc::channel::<()>());
    let holder = {
        let bus = Arc::clone(&bus);
        let (entered, go_on) = (entered.0, go_on.1);
        std::thread::spawn(move || {
            bus.exclusive(1, || {
                let _ = entered.send(());
                let _ = go_on.recv_timeout(Duration::from_secs(5));
            })
        })
    };
    entered
        .1
        .recv_timeout(Duration::from_secs(5))
        .expect("held");
    // Another unit is not held up.
    assert_eq!(bus.exclusive(2, || 2), 2);
    // The same unit waits until the holder lets go.
    let waiter = {
        let bus = Arc::clone(&bus);
        std::thread::spawn(move || bus.exclusive(1, Instant::now))
    };
    std::thread::sleep(Duration::from_millis(100));
    let released = Instant::now();
    let _ = go_on.0.send(());
    let got_in = waiter.join().expect("waiter");
    holder.join().expect("holder");
    assert!(got_in >= released);
}

#[test]
fn a_sequence_nested_in_its_own_threads_sequence_runs_at_once() {
    // What a Python signal handler does while the sequence's request waits: it reads the
    // same unit on the same thread. Waiting for the lock would be waiting for itself.
    let (bus, _) = bus(vec![], 0);
    let bus = Arc::new(bus);
    let (done, got) = mpsc::channel();
    let nested = {
        let bus = Arc::clone(&bus);
        std::thread::spawn(move || {
            let _ = done.send(bus.exclusive(1, || bus.exclusive(1, || 7) + 1));
        })
    };
    assert_eq!(
        got.recv_timeout(Duration::from_secs(5)),
        Ok(8),
        "deadlocked"
    );
    nested.join().expect("nested");
    // Once out, another thread takes the unit as before.
    let other = {
        let bus = Arc::clone(&bus);
        std::thread::spawn(move || bus.exclusive(1, || 3))
    };
    assert_eq!(other.join().expect("other"), 3);
}
