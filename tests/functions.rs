//! The Bus's functions beyond holding registers (coils, discrete inputs, input registers,
//! 0x16, 0x17, 0x07, 0x08, 0x11, raw requests, coil broadcasts) against a scripted
//! transport: the frames sent are the specification's examples, replies decode to their
//! values, echoes are checked, and bad input sends nothing.

mod common;

use benchbus::bus::TxOptions;
use benchbus::codec::{FrameError, Request};
use benchbus::Error;
use common::{hex, sent, with_crc, Act};
use std::time::{Duration, Instant};

fn reply(body: &str) -> Act {
    Act::Reply(with_crc(&hex(body)))
}

fn frame(body: &str) -> Vec<u8> {
    with_crc(&hex(body))
}

const OPTS: TxOptions = TxOptions {
    echo: benchbus::codec::Echo::Strict,
    write_interval: Duration::ZERO,
    timeout: None,
    retries: None,
    urgent: false,
    meaning: benchbus::codec::exception_meaning,
    window_from_start: false,
    write_ack: true,
};

#[test]
fn reads_of_coils_inputs_and_input_registers_are_the_specifications_examples() {
    let (bus, t) = common::bus(
        vec![
            reply("01 01 03 CD 6B 05"),
            reply("01 02 03 AC DB 35"),
            reply("01 04 02 00 0A"),
        ],
        0,
    );
    let coils = bus.read_coils(1, 19, 19, &OPTS).unwrap();
    // 0xCD: coils 20..27 = 1 0 1 1 0 0 1 1 (lowest bit first).
    assert_eq!(coils.len(), 19);
    assert_eq!(
        &coils[..8],
        &[true, false, true, true, false, false, true, true]
    );
    // The third byte 0x05: coils 36..38 = 1 0 1.
    assert_eq!(&coils[16..], &[true, false, true]);
    let inputs = bus.read_discrete_inputs(1, 196, 22, &OPTS).unwrap();
    assert_eq!(inputs.len(), 22);
    assert_eq!(&inputs[16..], &[true, false, true, false, true, true]);
    assert_eq!(bus.read_input_registers(1, 8, 1, &OPTS).unwrap(), [10]);
    assert_eq!(
        sent(&t),
        [
            frame("01 01 00 13 00 13"),
            frame("01 02 00 C4 00 16"),
            frame("01 04 00 08 00 01"),
        ]
    );
}

#[test]
fn writes_are_the_specifications_examples_and_their_echoes_are_checked() {
    let (bus, t) = common::bus(
        vec![
            reply("01 05 00 AC FF 00"),
            reply("01 0F 00 13 00 0A"),
            reply("01 16 00 04 00 F2 00 25"),
            reply("01 17 0C 00 FE 0A CD 00 01 00 03 00 0D 00 FF"),
        ],
        0,
    );
    bus.write_coil(1, 172, true, &OPTS).unwrap();
    let ten = [
        true, false, true, true, false, false, true, true, true, false,
    ];
    bus.write_coils(1, 19, &ten, &OPTS).unwrap();
    bus.mask_write_register(1, 4, 0xF2, 0x25, &OPTS).unwrap();
    let read = bus
        .read_write_registers(1, 3, 6, 14, &[0xFF, 0xFF, 0xFF], &OPTS)
        .unwrap();
    assert_eq!(read, [0xFE, 0xACD, 1, 3, 0xD, 0xFF]);
    assert_eq!(
        sent(&t),
        [
            frame("01 05 00 AC FF 00"),
            frame("01 0F 00 13 00 0A 02 CD 01"),
            frame("01 16 00 04 00 F2 00 25"),
            frame("01 17 00 03 00 06 00 0E 00 03 06 00 FF 00 FF 00 FF"),
        ]
    );
}

#[test]
fn a_coil_write_not_echoed_is_a_frame_error_and_retried() {
    // ON asked, OFF answered: then the echo right.
    let (bus, t) = common::bus(
        vec![reply("01 05 00 AC 00 00"), reply("01 05 00 AC FF 00")],
        1,
    );
    bus.write_coil(1, 172, true, &OPTS).unwrap();
    assert_eq!(sent(&t).len(), 2);
    assert_eq!((bus.stats().frame_errors, bus.stats().retries), (1, 1));
    let (bus, _) = common::bus(vec![reply("01 05 00 AC 00 00")], 0);
    let e = bus.write_coil(1, 172, true, &OPTS).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Frame {
                unit: 1,
                function: 5,
                kind: FrameError::Echo { .. },
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("value 0xff00"), "{e}");
    // A mask write whose reply carries another mask, and a 0x0F of another count.
    let (bus, _) = common::bus(
        vec![reply("01 16 00 04 00 F2 00 24"), reply("01 0F 00 13 00 09")],
        0,
    );
    let e = bus
        .mask_write_register(1, 4, 0xF2, 0x25, &OPTS)
        .unwrap_err();
    assert!(
        matches!(
            e,
            Error::Frame {
                kind: FrameError::Echo { .. },
                ..
            }
        ),
        "{e}"
    );
    let e = bus.write_coils(1, 19, &[true; 10], &OPTS).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Frame {
                kind: FrameError::Echo { .. },
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn a_read_reply_of_another_byte_count_is_refused() {
    // 19 coils take 3 bytes: a reply of 2 is not theirs.
    let (bus, _) = common::bus(vec![reply("01 01 02 CD 6B")], 0);
    let e = bus.read_coils(1, 19, 19, &OPTS).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Frame {
                kind: FrameError::ByteCount {
                    expected: 3,
                    received: 2
                },
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn serial_line_functions_exception_status_diagnostics_and_server_id() {
    let (bus, t) = common::bus(
        vec![
            reply("01 07 6D"),
            reply("01 08 00 00 A5 37"),
            reply("01 08 00 0B 00 2A"),
            reply("01 11 04 42 FF 01 02"),
        ],
        0,
    );
    assert_eq!(bus.read_exception_status(1, &OPTS).unwrap(), 0x6D);
    assert_eq!(
        bus.diagnostics(1, 0, &[0xA5, 0x37], &OPTS).unwrap(),
        [0xA5, 0x37]
    );
    // 0x0B: return bus message count, the count in the data.
    assert_eq!(bus.diagnostics(1, 0x0B, &[0, 0], &OPTS).unwrap(), [0, 0x2A]);
    assert_eq!(bus.report_server_id(1, &OPTS).unwrap(), [0x42, 0xFF, 1, 2]);
    assert_eq!(
        sent(&t),
        [
            frame("01 07"),
            frame("01 08 00 00 A5 37"),
            frame("01 08 00 0B 00 00"),
            frame("01 11"),
        ]
    );
}

#[test]
fn return_query_data_must_echo_its_data_and_every_sub_function_its_code() {
    let (bus, _) = common::bus(
        vec![reply("01 08 00 00 A5 36"), reply("01 08 00 0C 00 00")],
        0,
    );
    let e = bus.diagnostics(1, 0, &[0xA5, 0x37], &OPTS).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Frame {
                function: 8,
                kind: FrameError::Echo { .. },
                ..
            }
        ),
        "{e}"
    );
    let e = bus.diagnostics(1, 0x0B, &[0, 0], &OPTS).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Frame {
                kind: FrameError::Echo { .. },
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn force_listen_only_is_sent_once_and_not_awaited() {
    let (bus, t) = common::bus(vec![Act::Silent, Act::Silent, Act::Silent], 2);
    let start = Instant::now();
    assert_eq!(
        bus.diagnostics(1, 4, &[0, 0], &OPTS).unwrap(),
        Vec::<u8>::new()
    );
    // Not awaited: far less than one 5 ms timeout, let alone three attempts.
    assert!(
        start.elapsed() < Duration::from_millis(5),
        "{:?}",
        start.elapsed()
    );
    assert_eq!(sent(&t), [frame("01 08 00 04 00 00")]);
    let s = bus.stats();
    assert_eq!((s.transactions, s.timeouts, s.retries), (1, 0, 0));
}

#[test]
fn raw_requests_by_length_by_silence_and_their_exceptions() {
    let (bus, t) = common::bus(
        vec![
            reply("01 41 09 08 07"),
            reply("01 42 01 02 03 04 05"),
            reply("01 C1 01"),
        ],
        0,
    );
    assert_eq!(
        bus.request(1, 0x41, &[1, 2], Some(3), &OPTS).unwrap(),
        [9, 8, 7]
    );
    assert_eq!(
        bus.request(1, 0x42, &[], None, &OPTS).unwrap(),
        [1, 2, 3, 4, 5]
    );
    let e = bus.request(1, 0x41, &[1], None, &OPTS).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Exception {
                unit: 1,
                function: 0x41,
                code: 1,
                ..
            }
        ),
        "{e}"
    );
    assert_eq!(
        sent(&t),
        [frame("01 41 01 02"), frame("01 42"), frame("01 41 01")]
    );
    // A reply of another length than reply_length, and a bad CRC read by silence.
    let mut bad = frame("01 42 01 02 03");
    bad[4] ^= 1;
    let (bus, _) = common::bus(vec![reply("01 41 09 08"), Act::Reply(bad)], 0);
    assert!(matches!(
        bus.request(1, 0x41, &[], Some(3), &OPTS).unwrap_err(),
        Error::Timeout { .. }
    ));
    assert!(matches!(
        bus.request(1, 0x42, &[], None, &OPTS).unwrap_err(),
        Error::Frame {
            kind: FrameError::Crc { .. },
            ..
        }
    ));
}

#[test]
fn coil_broadcasts_go_to_unit_zero_and_await_nothing() {
    let (bus, t) = common::bus(vec![], 0);
    bus.broadcast(&Request::WriteSingleCoil {
        address: 172,
        value: true,
    })
    .unwrap();
    bus.broadcast(&Request::WriteMultipleCoils {
        address: 19,
        values: vec![true, false, true],
    })
    .unwrap();
    assert_eq!(
        sent(&t),
        [frame("00 05 00 AC FF 00"), frame("00 0F 00 13 00 03 01 05")]
    );
    assert_eq!(bus.stats().broadcasts, 2);
    let read = Request::ReadCoils {
        address: 0,
        count: 1,
    };
    assert!(matches!(
        bus.broadcast(&read),
        Err(Error::InvalidArgument(_))
    ));
}

#[test]
fn bad_input_is_refused_before_anything_is_sent() {
    let (bus, t) = common::bus(vec![], 0);
    let refused: Vec<(&str, benchbus::Result<()>)> = vec![
        ("coils 0", bus.read_coils(1, 0, 0, &OPTS).map(drop)),
        ("coils 2001", bus.read_coils(1, 0, 2001, &OPTS).map(drop)),
        (
            "inputs 2001",
            bus.read_discrete_inputs(1, 0, 2001, &OPTS).map(drop),
        ),
        (
            "inputs past 0xFFFF",
            bus.read_discrete_inputs(1, 0xFFFF, 2, &OPTS).map(drop),
        ),
        (
            "input registers 126",
            bus.read_input_registers(1, 0, 126, &OPTS).map(drop),
        ),
        (
            "input registers 0",
            bus.read_input_registers(1, 0, 0, &OPTS).map(drop),
        ),
        ("coils 1969", bus.write_coils(1, 0, &[true; 1969], &OPTS)),
        ("no coils", bus.write_coils(1, 0, &[], &OPTS)),
        (
            "coils past 0xFFFF",
            bus.write_coils(1, 0xFFFE, &[true; 3], &OPTS),
        ),
        (
            "0x17 read 126",
            bus.read_write_registers(1, 0, 126, 0, &[1], &OPTS)
                .map(drop),
        ),
        (
            "0x17 read 0",
            bus.read_write_registers(1, 0, 0, 0, &[1], &OPTS).map(drop),
        ),
        (
            "0x17 write 122",
            bus.read_write_registers(1, 0, 1, 0, &[1; 122], &OPTS)
                .map(drop),
        ),
        (
            "0x17 write past",
            bus.read_write_registers(1, 0, 1, 0xFFFF, &[1, 2], &OPTS)
                .map(drop),
        ),
        ("function 0", bus.request(1, 0, &[], None, &OPTS).map(drop)),
        (
            "function 0x80",
            bus.request(1, 0x80, &[], None, &OPTS).map(drop),
        ),
        (
            "function 0xFF",
            bus.request(1, 0xFF, &[], None, &OPTS).map(drop),
        ),
        (
            "data 253",
            bus.request(1, 0x41, &[0; 253], None, &OPTS).map(drop),
        ),
        (
            "reply 253",
            bus.request(1, 0x41, &[], Some(253), &OPTS).map(drop),
        ),
        (
            "diagnostics 251",
            bus.diagnostics(1, 0, &[0; 251], &OPTS).map(drop),
        ),
        ("unit 0", bus.read_coils(0, 0, 1, &OPTS).map(drop)),
        (
            "broadcast coils 1969",
            bus.broadcast(&Request::WriteMultipleCoils {
                address: 0,
                values: vec![true; 1969],
            }),
        ),
    ];
    for (what, result) in refused {
        assert!(
            matches!(result, Err(Error::InvalidArgument(_))),
            "{what}: {result:?}"
        );
    }
    assert!(sent(&t).is_empty());
    // The limits themselves are allowed.
    let (bus, t) = common::bus(vec![], 0);
    assert!(bus.request(1, 0x7F, &[0; 252], Some(252), &OPTS).is_err());
    assert!(bus.read_coils(1, 0xFFFF - 1999, 2000, &OPTS).is_err());
    assert_eq!(sent(&t).len(), 2, "both went out (and timed out)");
}

#[test]
fn a_local_echo_is_read_back_and_a_garbled_one_retried_for_every_function() {
    let (bus, t) = common::echo_bus(
        vec![
            reply("01 01 01 05"),
            reply("01 01 01 05"),
            reply("01 42 07 08"),
        ],
        1,
    );
    // The echo of the first attempt comes back garbled: sent again, as a corrupt reply is.
    t.0.lock().unwrap().garble_echo = 1;
    assert_eq!(bus.read_coils(1, 0, 3, &OPTS).unwrap(), [true, false, true]);
    assert_eq!((bus.stats().frame_errors, bus.stats().retries), (1, 1));
    // A raw reply read by silence after the echo: the echo is not part of it.
    assert_eq!(bus.request(1, 0x42, &[], None, &OPTS).unwrap(), [7, 8]);
    assert_eq!(sent(&t).len(), 3);
}

#[test]
fn reconnect_reopens_a_lost_port_for_every_function() {
    let (bus, t) = common::reopenable_bus(vec![reply("01 04 02 00 0A")], 0, true);
    t.0.lock().unwrap().lost = true;
    assert_eq!(bus.read_input_registers(1, 8, 1, &OPTS).unwrap(), [10]);
    assert_eq!(bus.stats().reopens, 1);
    assert_eq!(sent(&t), [frame("01 04 00 08 00 01")]);
}

#[test]
fn writes_of_coils_and_masks_are_paced_as_writes_and_unanswered_when_the_device_says_so() {
    let paced = TxOptions {
        write_interval: Duration::from_millis(30),
        ..OPTS
    };
    let (bus, t) = common::bus(
        vec![reply("01 05 00 AC FF 00"), reply("01 16 00 04 00 F2 00 25")],
        0,
    );
    bus.write_coil(1, 172, true, &paced).unwrap();
    bus.mask_write_register(1, 4, 0xF2, 0x25, &paced).unwrap();
    let at = common::sent_at(&t);
    assert!(
        at[1] - at[0] >= Duration::from_millis(30),
        "{:?}",
        at[1] - at[0]
    );
    // A device set to answer no write: a coil write is sent once and not awaited.
    let silent = TxOptions {
        write_ack: false,
        ..OPTS
    };
    let (bus, t) = common::bus(vec![Act::Silent], 2);
    bus.write_coils(1, 19, &[true; 10], &silent).unwrap();
    assert_eq!(sent(&t).len(), 1);
    assert_eq!(bus.stats().timeouts, 0);
    // Reads are never paced: no wait after a write.
    let (bus, t) = common::bus(vec![reply("01 05 00 AC FF 00"), reply("01 01 01 01")], 0);
    bus.write_coil(1, 172, true, &paced).unwrap();
    bus.read_coils(1, 172, 1, &paced).unwrap();
    let at = common::sent_at(&t);
    assert!(
        at[1] - at[0] < Duration::from_millis(30),
        "{:?}",
        at[1] - at[0]
    );
}
