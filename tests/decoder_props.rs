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
