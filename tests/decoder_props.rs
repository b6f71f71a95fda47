//! Property tests: no bytes, however wrong, make the decoder panic or read out of bounds,
//! and the incremental decoder always agrees with the one-shot decoder.

use benchbus::codec::{decode_reply, encode_request, reply_needed, Needed, Request};
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
                Needed::Unknown => break,
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
                Needed::Unknown => break,
            }
            buf.push(b);
        }
        if let (Needed::Complete(n), true) = (reply_needed(req, &frame), whole.is_ok()) {
            // What the decoder accepts is exactly what the incremental reader would take.
            assert_eq!(n, frame.len(), "case {case}: {frame:02x?}");
        }
    }
}
