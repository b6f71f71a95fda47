//! The drive layer against a scripted transport: the manuals' frames, the block-read
//! fallback, the parameter write enable, unanswered writes and family differences.

mod common;

use benchbus::device::drive::{Command, Drive, Family};
use benchbus::device::{Device, Tabled};
use benchbus::Error;
use common::{bus, hex, sent, with_crc, Act, Scripted};
use std::sync::Arc;

fn drive(acts: Vec<Act>, family: Family, write_ack: bool) -> (Drive, Scripted) {
    let (bus, t) = bus(acts, 0);
    (Drive::new(Arc::new(bus), 1, family, write_ack), t)
}

fn echo(frame: &str) -> Act {
    Act::Reply(hex(frame))
}

#[test]
fn commands_and_setpoint_are_the_manuals_frames() {
    // 000 B.4 / 001 section 3: forward, reverse, stop, fault reset, speed 3000 rpm.
    let frames = [
        "01 06 20 00 00 01 43 CA",
        "01 06 20 00 00 02 03 CB",
        "01 06 20 00 00 05 42 09",
        "01 06 20 00 00 07 C3 C8",
        "01 06 20 01 0B B8 D4 88",
    ];
    let (d, t) = drive(frames.iter().map(|f| echo(f)).collect(), Family::Bld, true);
    for c in [
        Command::Forward,
        Command::Reverse,
        Command::Stop,
        Command::ResetFault,
    ] {
        d.command(c).expect("command");
    }
    d.set("speed_setpoint", 3000.0).expect("setpoint");
    assert_eq!(sent(&t), frames.map(hex).to_vec());
}

#[test]
fn a_refused_block_read_falls_back_and_is_remembered() {
    let mut acts = vec![Act::Reply(with_crc(&[1, 0x83, 0x03]))];
    for i in 0..18u16 {
        let word = (0x100 + i).to_be_bytes();
        acts.push(Act::Reply(with_crc(&[1, 3, 2, word[0], word[1]])));
    }
    let (d, t) = drive(acts, Family::C20, true);
    let snap = d.telemetry().expect("telemetry");
    assert_eq!(d.block_reads(), Some(false));
    assert_eq!(snap.values.len(), 18);
    assert_eq!(snap.values[6], ("speed", 262.0, "rpm"));
    assert_eq!(snap.hall_count, None);
    let frames = sent(&t);
    assert_eq!(frames[0], with_crc(&[1, 3, 0x30, 0x00, 0x00, 18]));
    assert_eq!(frames[18], with_crc(&[1, 3, 0x30, 0x11, 0x00, 1]));
    // Remembered: the next status read goes register by register from the start.
    t.0.lock().map(|mut s| s.sent.clear()).ok();
    let status_acts = [5u8, 0x41, 0x0A].map(|w| Act::Reply(with_crc(&[1, 3, 2, 0, w])));
    t.0.lock().map(|mut s| s.acts.extend(status_acts)).ok();
    let status = d.status().expect("status");
    assert_eq!((status.state, status.fault_code), (5, 0x0A));
    assert_eq!(sent(&t).len(), 3);
}

#[test]
fn a_block_read_that_worked_does_not_fall_back() {
    let mut words = vec![1u8, 3, 6];
    words.extend([0, 1, 0, 0x41, 0, 0]);
    let acts = vec![
        Act::Reply(with_crc(&words)),
        Act::Reply(with_crc(&[1, 0x83, 0x02])),
    ];
    let (d, t) = drive(acts, Family::Bld, true);
    assert_eq!(d.status().expect("status").state, 1);
    assert_eq!(d.block_reads(), Some(true));
    assert!(matches!(d.status(), Err(Error::Exception { code: 2, .. })));
    assert_eq!(sent(&t).len(), 2);
}

#[test]
fn a_parameter_write_enables_and_restores_0x200e() {
    let acts = vec![
        Act::Reply(with_crc(&[1, 3, 2, 0, 0])),
        echo("01 06 20 0E 00 01 22 09"),
        echo("01 06 00 0A 09 C4 AE 0B"),
        echo("01 06 20 0E 00 00 E3 C9"),
    ];
    let (d, t) = drive(acts, Family::Bld, true);
    d.write_parameter("F00.10", 0x09C4).expect("write");
    let frames = sent(&t);
    assert_eq!(frames[0], hex("01 03 20 0E 00 01 EE 09"));
    // The manual's "write F00.10 = 25.00 Hz" frame, then the enable put back to 0, which is
    // byte for byte the frame the manual labels "enable" (its erratum).
    assert_eq!(frames[2], hex("01 06 00 0A 09 C4 AE 0B"));
    assert_eq!(frames[3], hex("01 06 20 0E 00 00 E3 C9"));
}

#[test]
fn a_refused_parameter_write_still_restores_and_names_the_parameter() {
    let acts = vec![
        Act::Reply(with_crc(&[1, 3, 2, 0, 0])),
        echo("01 06 20 0E 00 01 22 09"),
        Act::Reply(hex("01 86 03 02 61")), // 000 B.4 写失败: F00.00 = 5, data error 0x03
        echo("01 06 20 0E 00 00 E3 C9"),
    ];
    let (d, t) = drive(acts, Family::Bld, true);
    let e = d.write_parameter("F00.00", 5).expect_err("refused");
    let text = e.to_string();
    assert!(matches!(e, Error::Exception { code: 3, .. }), "{text}");
    assert!(
        text.contains("F00.00 = 5") && text.contains("out of range"),
        "{text}"
    );
    assert_eq!(sent(&t)[2], hex("01 06 00 00 00 05 49 C9"));
    assert_eq!(sent(&t).len(), 4);
}

#[test]
fn an_enabled_drive_is_left_enabled() {
    let acts = vec![
        Act::Reply(with_crc(&[1, 3, 2, 0, 1])),
        echo("01 06 00 0A 09 C4 AE 0B"),
    ];
    let (d, t) = drive(acts, Family::Bld, true);
    d.write_parameter("F00.10", 0x09C4).expect("write");
    assert_eq!(sent(&t).len(), 2);
}

#[test]
fn writes_without_reply_send_once_and_wait_for_nothing() {
    let (d, t) = drive(vec![], Family::Bld, false);
    d.command(Command::Forward).expect("unanswered write");
    d.set("speed_setpoint", 1500.0).expect("unanswered write");
    assert_eq!(sent(&t).len(), 2);
    let stats = d.bus().stats();
    assert_eq!((stats.transactions, stats.timeouts), (2, 0));
}

#[test]
fn family_differences_are_checked_before_sending() {
    let (c20, t) = drive(
        vec![Act::Reply(with_crc(&[1, 6, 0x20, 0x08, 0, 200]))],
        Family::C20,
        true,
    );
    assert!(matches!(
        c20.command(Command::Brake),
        Err(Error::InvalidArgument(_))
    ));
    assert!(c20.set("stop_mode", 1.0).is_err());
    assert!(c20.get("hall_count_high").is_err());
    c20.set("station_address", 200.0).expect("C20 takes 1..247");
    assert_eq!(sent(&t).len(), 1);

    let (bld, t) = drive(vec![], Family::Bld, true);
    let e = bld
        .set("station_address", 200.0)
        .expect_err("BLD takes 1..127");
    assert_eq!(e.to_string(), "station_address must be 1 to 127, got 200");
    assert!(bld.set("speed", 1.0).is_err());
    assert!(bld.set("pole_pairs", 2.5).is_err());
    assert!(bld.set("no_such_register", 1.0).is_err());
    assert!(sent(&t).is_empty());
}

fn registers_reply(words: &[u16]) -> Act {
    let mut body = vec![1u8, 3, (words.len() * 2) as u8];
    for w in words {
        body.extend(w.to_be_bytes());
    }
    Act::Reply(with_crc(&body))
}

#[test]
fn firmware_without_the_hall_registers_gives_no_hall_count() {
    let mut words = vec![0u16; 18];
    words[6] = 1450;
    // 0x3000..0x3014 refused; one by one, 0x3000..0x3011 answer and 0x3012 is refused;
    // then 0x3000..0x3011 as a block.
    let mut acts = vec![Act::Reply(with_crc(&[1, 0x83, 0x02]))];
    acts.extend(words.iter().map(|&w| registers_reply(&[w])));
    acts.push(Act::Reply(with_crc(&[1, 0x83, 0x02])));
    acts.push(registers_reply(&words));
    acts.push(registers_reply(&words));
    let (d, t) = drive(acts, Family::Bld, true);
    let snap = d.telemetry().expect("telemetry without hall registers");
    assert_eq!(snap.hall_count, None);
    assert_eq!(snap.values[6], ("speed", 1450.0, "rpm"));
    let frames = sent(&t);
    assert_eq!(frames[0], with_crc(&[1, 3, 0x30, 0x00, 0x00, 21]));
    assert_eq!(
        frames.last(),
        Some(&with_crc(&[1, 3, 0x30, 0x00, 0x00, 18]))
    );
    assert_eq!(d.block_reads(), Some(true));
    // Remembered: the next snapshot asks for 18 registers at once.
    let before = frames.len();
    d.telemetry().expect("second snapshot");
    let frames = sent(&t);
    assert_eq!(frames.len(), before + 1);
    assert_eq!(frames[before], with_crc(&[1, 3, 0x30, 0x00, 0x00, 18]));
}

#[test]
fn a_one_register_answer_to_a_block_read_falls_back() {
    // A drive that answers a count of 3 with one register: a wrong-length reply.
    let acts = vec![
        registers_reply(&[3]),
        registers_reply(&[3]),
        registers_reply(&[0x41]),
        registers_reply(&[0]),
    ];
    let (d, _) = drive(acts, Family::Bld, true);
    let status = d.status().expect("status one register at a time");
    assert_eq!((status.state, status.control_source), (3, 2));
    assert_eq!(d.block_reads(), Some(false));
}

#[test]
fn baud_rates_by_family() {
    let (bld, t) = drive(
        vec![Act::Reply(with_crc(&[1, 6, 0x20, 0x09, 0, 7]))],
        Family::Bld,
        true,
    );
    bld.set_baud_rate(115_200).expect("BLD has 115200");
    assert_eq!(sent(&t)[0], with_crc(&[1, 6, 0x20, 0x09, 0, 7]));
    assert!(bld.set_baud_rate(14_400).is_err());
    let (c20, t) = drive(vec![registers_reply(&[3])], Family::C20, true);
    assert!(c20.set_baud_rate(115_200).is_err());
    assert_eq!(c20.baud_rate().ok(), Some(Some(9600)));
    assert_eq!(sent(&t).len(), 1);
}

#[test]
fn leaving_ends_a_jog_this_object_started_then_stops() {
    // Jog forward, then the exit sequence: jog stop (8), stop (5).
    let frames = [
        "01 06 20 00 00 03 C2 0B",
        "01 06 20 00 00 08 83 CC",
        "01 06 20 00 00 05 42 09",
        "01 06 20 00 00 05 42 09",
    ];
    let (d, t) = drive(frames.iter().map(|f| echo(f)).collect(), Family::Bld, true);
    assert!(!d.jogging());
    d.command(Command::JogForward).expect("jog");
    assert!(d.jogging());
    d.stop_on_exit(false).expect("exit");
    assert!(!d.jogging());
    // Without a jog on, only the stop goes out.
    d.stop_on_exit(false).expect("exit");
    assert_eq!(sent(&t), frames.map(hex).to_vec());
}

/// Set by the test below; read by its Bus's `interrupted` hook.
static SECOND_CTRL_C: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

#[test]
fn a_second_ctrl_c_skips_the_stop_only_after_a_jog_stop_the_drive_did_not_answer() {
    use std::sync::atomic::Ordering;
    fn asked() -> bool {
        SECOND_CTRL_C.load(Ordering::SeqCst)
    }
    let jog_stop = "01 06 20 00 00 08 83 CC";
    let stop = "01 06 20 00 00 05 42 09";
    let jogging = |acts: Vec<Act>| {
        let (t, mut cfg) = common::mock(acts, 0);
        cfg.interrupted = Some(asked);
        let bus = Arc::new(benchbus::Bus::with_transport(cfg, Box::new(t.clone())));
        let d = Drive::new(bus, 1, Family::Bld, true);
        d.command(Command::JogForward).expect("jog");
        (d, t)
    };
    let jog = || echo("01 06 20 00 00 03 C2 0B");
    // A silent drive, asked to stop meanwhile: the jog stop only, and the interrupt.
    let (d, t) = jogging(vec![jog(), Act::Silent]);
    SECOND_CTRL_C.store(true, Ordering::SeqCst);
    let err = d.stop_on_exit(true).unwrap_err();
    SECOND_CTRL_C.store(false, Ordering::SeqCst);
    assert!(
        matches!(err, Error::Interrupted { attempts: 0, .. }),
        "{err:?}"
    );
    assert_eq!(sent(&t).last(), Some(&hex(jog_stop)));
    assert_eq!(sent(&t).len(), 2);
    // A drive that answered the jog stop is sent the stop, asked or not.
    let (d, t) = jogging(vec![jog(), echo(jog_stop), echo(stop)]);
    SECOND_CTRL_C.store(true, Ordering::SeqCst);
    let done = d.stop_on_exit(true);
    SECOND_CTRL_C.store(false, Ordering::SeqCst);
    done.expect("exit");
    assert_eq!(sent(&t)[1..], [hex(jog_stop), hex(stop)]);
    // Not asked: the stop follows the unanswered jog stop.
    let (d, t) = jogging(vec![jog(), Act::Silent, Act::Silent]);
    assert!(matches!(d.stop_on_exit(true), Err(Error::Timeout { .. })));
    assert_eq!(sent(&t)[1..], [hex(jog_stop), hex(stop)]);
}

#[test]
fn a_refused_jog_is_not_counted_as_started() {
    let refusal = Act::Reply(with_crc(&[1, 0x86, 0x01]));
    let (d, _t) = drive(vec![refusal], Family::Bld, true);
    assert!(d.command(Command::JogReverse).is_err());
    assert!(!d.jogging());
}

#[test]
fn get_many_reads_neighbours_in_one_request_and_the_rest_apart() {
    // speed_setpoint (0x2001, rpm), pole_pairs and accel_time (0x2003, tenths of s) are
    // one block, asked in any order; state (0x2100) is a block of its own.
    let acts = vec![registers_reply(&[1500, 2, 25]), registers_reply(&[3])];
    let (d, t) = drive(acts, Family::Bld, true);
    let names = ["accel_time", "speed_setpoint", "state", "pole_pairs"];
    let got = d.get_many(&names).expect("four registers");
    assert_eq!(got, vec![2.5, 1500.0, 3.0, 2.0]);
    assert_eq!(
        sent(&t),
        vec![
            with_crc(&[1, 3, 0x20, 0x01, 0x00, 3]),
            with_crc(&[1, 3, 0x21, 0x00, 0x00, 1]),
        ]
    );
}

#[test]
fn get_many_on_a_drive_that_refuses_block_reads_reads_one_register_a_request() {
    let acts = vec![
        Act::Reply(with_crc(&[1, 0x83, 0x03])),
        registers_reply(&[1500]),
        registers_reply(&[4]),
    ];
    let (d, t) = drive(acts, Family::C20, true);
    let got = d.get_many(&["speed_setpoint", "pole_pairs"]).expect("two");
    assert_eq!(got, vec![1500.0, 4.0]);
    assert_eq!(d.block_reads(), Some(false));
    assert_eq!(sent(&t)[2], with_crc(&[1, 3, 0x20, 0x02, 0x00, 1]));
    // Remembered: the next read of two neighbours goes register by register at once.
    t.0.lock().map(|mut s| s.sent.clear()).ok();
    let acts = [1400u16, 5].map(|w| registers_reply(&[w]));
    t.0.lock().map(|mut s| s.acts.extend(acts)).ok();
    assert_eq!(
        d.get_many(&["speed_setpoint", "pole_pairs"]).ok(),
        Some(vec![1400.0, 5.0])
    );
    assert_eq!(sent(&t).len(), 2);
}
