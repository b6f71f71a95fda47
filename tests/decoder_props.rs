//! Property tests: no bytes, however wrong, make the decoder panic or read out of bounds,
//! and the incremental decoder always agrees with the one-shot decoder.

use benchbus::codec::{decode_reply, encode_request, reply_needed, Framing, Needed, Request};
use proptest::prelude::*;

fn any_request() -> impl Strategy<Value = Request> {
    prop_oneof![
        (any::<u16>(), 1u16..=125)
            .prop_map(|(address, count)| Request::ReadHoldingRegisters { address, count }),
        (any::<u16>(), any::<u16>())
            .prop_map(|(address, value)| Request::WriteSingleRegister { address, value }),
        (any::<u16>(), prop::collection::vec(any::<u16>(), 1..=123))
            .prop_map(|(address, values)| Request::WriteMultipleRegisters { address, values }),
        (1u8..=4, any::<u8>()).prop_map(|(read_code, object_id)| {
            Request::ReadDeviceIdentification {
                read_code,
                object_id,
            }
        }),
        (any::<u16>(), 1u16..=2000, any::<bool>()).prop_map(|(address, count, coils)| {
            if coils {
                Request::ReadCoils { address, count }
            } else {
                Request::ReadDiscreteInputs { address, count }
            }
        }),
        (any::<u16>(), 1u16..=125)
            .prop_map(|(address, count)| Request::ReadInputRegisters { address, count }),
        (any::<u16>(), any::<bool>())
            .prop_map(|(address, value)| Request::WriteSingleCoil { address, value }),
        (any::<u16>(), prop::collection::vec(any::<bool>(), 1..=1968))
            .prop_map(|(address, values)| Request::WriteMultipleCoils { address, values }),
        (any::<u16>(), any::<u16>(), any::<u16>()).prop_map(|(address, and_mask, or_mask)| {
            Request::MaskWriteRegister {
                address,
                and_mask,
                or_mask,
            }
        }),
        (
            any::<u16>(),
            1u16..=125,
            any::<u16>(),
            prop::collection::vec(any::<u16>(), 1..=121)
        )
            .prop_map(|(read_address, read_count, write_address, values)| {
                Request::ReadWriteRegisters {
                    read_address,
                    read_count,
                    write_address,
                    values,
                }
            }),
        Just(Request::ReadExceptionStatus),
        Just(Request::ReportServerId),
        (any::<u16>(), prop::collection::vec(any::<u8>(), 0..=250))
            .prop_map(|(sub_function, data)| Request::Diagnostics { sub_function, data }),
        (
            1u8..=0x7F,
            prop::collection::vec(any::<u8>(), 0..=252),
            prop::option::of(0usize..=252)
        )
            .prop_map(|(function, data, reply_length)| Request::Raw {
                function,
                data,
                reply_length,
            }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(20_000))]

    #[test]
    fn arbitrary_bytes_never_panic(req in any_request(), unit in any::<u8>(),
                                   bytes in prop::collection::vec(any::<u8>(), 0..300)) {
        let _ = decode_reply(unit, &req, &bytes);
        // Feed the bytes one at a time as the bus does; Needed must stay consistent.
        let mut buf = Vec::new();
        for b in &bytes {
            match reply_needed(&req, &buf) {
                Needed::Complete(n) => { prop_assert!(n <= buf.len()); break; }
                Needed::More(n) => prop_assert!(n > 0),
                Needed::Unknown | Needed::Silence => break,
            }
            buf.push(*b);
        }
    }

    #[test]
    fn plausible_replies_never_panic(req in any_request(), unit in 1u8..=247,
                                     tail in prop::collection::vec(any::<u8>(), 0..260)) {
        // Start with a valid header so the decoder goes deep into the frame.
        let mut frame = vec![unit, req.function()];
        frame.extend(tail);
        let _ = decode_reply(unit, &req, &frame);
        if let Needed::Complete(n) = reply_needed(&req, &frame) {
            let _ = decode_reply(unit, &req, &frame[..n]);
        }
    }

    #[test]
    fn modbus_tcp_replies_never_panic_and_are_read_whole(req in any_request(),
                                                         unit in any::<u8>(),
                                                         bytes in prop::collection::vec(any::<u8>(), 0..300)) {
        // A reply as the Modbus TCP session hands it out: `length | unit | PDU`.
        let _ = Framing::Mbap.decode_reply(unit, &req, &bytes);
        let mut buf = Vec::new();
        for b in &bytes {
            match Framing::Mbap.reply_needed(&req, &buf) {
                Needed::Complete(n) => {
                    // By the length field alone: every byte it counts, no more.
                    prop_assert_eq!(n, 2 + usize::from(u16::from_be_bytes([buf[0], buf[1]])));
                    let _ = Framing::Mbap.decode_reply(unit, &req, &buf[..n]);
                    break;
                }
                Needed::More(n) => prop_assert!(n > 0 && buf.len() + n <= 256),
                Needed::Unknown | Needed::Silence => break,
            }
            buf.push(*b);
        }
    }

    #[test]
    fn encoded_requests_carry_a_valid_crc(req in any_request(), unit in any::<u8>()) {
        let f = encode_request(unit, &req);
        let n = f.len();
        prop_assert!(n <= 256);
        prop_assert_eq!(benchbus::codec::crc16(&f[..n - 2]).to_le_bytes(), [f[n - 2], f[n - 1]]);
    }
}

/// A small deterministic generator (xorshift64*), so millions of cases cost no more than the
/// decoding itself.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

#[test]
fn millions_of_mutated_replies_never_panic_and_agree_with_the_incremental_decoder() {
    let requests = [
        Request::ReadHoldingRegisters {
            address: 0x3000,
            count: 21,
        },
        Request::ReadHoldingRegisters {
            address: 0,
            count: 125,
        },
        Request::WriteSingleRegister {
            address: 0x2001,
            value: 1500,
        },
        Request::WriteMultipleRegisters {
            address: 0x0100,
            values: vec![1, 2, 3],
        },
        Request::ReadDeviceIdentification {
            read_code: 1,
            object_id: 0,
        },
        Request::ReadCoils {
            address: 19,
            count: 19,
        },
        Request::ReadDiscreteInputs {
            address: 0,
            count: 2000,
        },
        Request::ReadInputRegisters {
            address: 8,
            count: 1,
        },
        Request::WriteSingleCoil {
            address: 172,
            value: true,
        },
        Request::WriteMultipleCoils {
            address: 19,
            values: vec![true; 10],
        },
        Request::MaskWriteRegister {
            address: 4,
            and_mask: 0xF2,
            or_mask: 0x25,
        },
        Request::ReadWriteRegisters {
            read_address: 3,
            read_count: 6,
            write_address: 14,
            values: vec![0xFF; 3],
        },
        Request::ReadExceptionStatus,
        Request::Diagnostics {
            sub_function: 0,
            data: vec![0xA5, 0x37],
        },
        Request::ReportServerId,
        Request::Raw {
            function: 0x41,
            data: vec![1, 2],
            reply_length: Some(3),
        },
    ];
    // Plausible starting points: each request's well-formed reply shapes, and exceptions.
    let seeds: Vec<Vec<u8>> = vec![
        [&[1u8, 3, 42][..], &[0x55; 42][..]].concat(),
        [&[1u8, 3, 250][..], &[0xAA; 250][..]].concat(),
        vec![1, 6, 0x20, 0x01, 0x05, 0xDC],
        vec![1, 0x10, 0x01, 0x00, 0x00, 0x03],
        vec![
            1, 0x2B, 0x0E, 1, 1, 0, 0, 2, 0, 3, b'A', b'B', b'C', 1, 1, b'X',
        ],
        vec![1, 0x83, 2],
        vec![1, 0xAB, 0x0E, 1],
        vec![1, 0x01, 3, 0xCD, 0x6B, 0x05],
        [&[1u8, 2, 250][..], &[0x33; 250][..]].concat(),
        vec![1, 4, 2, 0, 0x0A],
        vec![1, 5, 0, 0xAC, 0xFF, 0],
        vec![1, 0x0F, 0, 0x13, 0, 0x0A],
        vec![1, 0x16, 0, 4, 0, 0xF2, 0, 0x25],
        vec![
            1, 0x17, 12, 0, 0xFE, 0x0A, 0xCD, 0, 1, 0, 3, 0, 0x0D, 0, 0xFF,
        ],
        vec![1, 7, 0x6D],
        vec![1, 8, 0, 0, 0xA5, 0x37],
        vec![1, 0x11, 3, 0x42, 0xFF, 0x01],
        vec![1, 0x41, 9, 8, 7],
        vec![1, 0x97, 2],
    ];
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    for case in 0..3_000_000u32 {
        let req = &requests[rng.below(requests.len())];
        let mut frame = seeds[rng.below(seeds.len())].clone();
        for _ in 0..=rng.below(4) {
            match rng.below(4) {
                0 if !frame.is_empty() => {
                    let i = rng.below(frame.len());
                    frame[i] = rng.next() as u8;
                }
                1 => frame.truncate(rng.below(frame.len() + 1)),
                2 => frame.extend((0..rng.below(8)).map(|_| rng.next() as u8)),
                _ => {}
            }
        }
        if rng.below(2) == 0 {
            // Half of them with a valid CRC, to get past the first check.
            let crc = benchbus::codec::crc16(&frame);
            frame.extend_from_slice(&crc.to_le_bytes());
        }
        let unit = if rng.below(8) == 0 { 2 } else { 1 };
        let whole = decode_reply(unit, req, &frame);
        let mut buf = Vec::new();
        for &b in &frame {
            match reply_needed(req, &buf) {
                Needed::Complete(n) => {
                    assert!(n <= buf.len(), "case {case}");
                    break;
                }
                Needed::More(n) => assert!(n > 0, "case {case}"),
                Needed::Unknown | Needed::Silence => break,
            }
            buf.push(b);
        }
        if let (Needed::Complete(n), true) = (reply_needed(req, &frame), whole.is_ok()) {
            // What the decoder accepts is exactly what the incremental reader would take.
            assert_eq!(n, frame.len(), "case {case}: {frame:02x?}");
        }
    }
}
