//! Property tests of the Modbus ASCII framing: every `unit | PDU` round-trips, through the
//! receiver however the characters are split and whatever noise comes first; no characters,
//! however wrong, make any of its functions panic; the reply reader agrees with the decoder.

use benchbus::codec::ascii::{self, AsciiError, Receiver, Seen, MAX_FRAME, MAX_UNIT_PDU};
use benchbus::codec::{FrameError, Needed, Request};
use proptest::prelude::*;

/// Either error of a reply, for [`ascii::decode_reply`].
#[derive(Debug)]
enum Bad {
    Ascii,
    Frame,
}

impl From<AsciiError> for Bad {
    fn from(_: AsciiError) -> Bad {
        Bad::Ascii
    }
}

impl From<FrameError> for Bad {
    fn from(_: FrameError) -> Bad {
        Bad::Frame
    }
}

/// The `unit | PDU` of a valid frame.
fn frame_pdu(frame: &[u8]) -> Vec<u8> {
    ascii::decode(frame).unwrap_or_default()
}

fn any_request() -> impl Strategy<Value = Request> {
    prop_oneof![
        (any::<u16>(), 1u16..=125)
            .prop_map(|(address, count)| Request::ReadHoldingRegisters { address, count }),
        (any::<u16>(), any::<u16>())
            .prop_map(|(address, value)| Request::WriteSingleRegister { address, value }),
        (any::<u16>(), prop::collection::vec(any::<u16>(), 1..=123))
            .prop_map(|(address, values)| Request::WriteMultipleRegisters { address, values }),
    ]
}

/// Characters mostly from a frame's alphabet, so that the receiver goes deep into frames.
fn line_chars(max: usize) -> impl Strategy<Value = Vec<u8>> {
    let alphabet = b":0123456789ABCDEFabcdef\r\n";
    prop::collection::vec(
        prop_oneof![
            8 => prop::sample::select(&alphabet[..]),
            1 => any::<u8>(),
        ],
        0..max,
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(5_000))]

    #[test]
    fn every_unit_pdu_round_trips(unit_pdu in prop::collection::vec(any::<u8>(), 2..=MAX_UNIT_PDU),
                                  noise in prop::collection::vec(any::<u8>(), 0..40),
                                  split in any::<prop::sample::Index>()) {
        let frame = ascii::encode(&unit_pdu);
        prop_assert!(frame.len() <= MAX_FRAME);
        prop_assert_eq!(ascii::decode(&frame), Ok(unit_pdu.clone()));
        prop_assert_eq!(ascii::decode(&frame.to_ascii_lowercase()), Ok(unit_pdu.clone()));
        prop_assert_eq!(ascii::unit_of(&frame), unit_pdu.first().copied());
        // Noise without a `:` first, the frame split anywhere.
        let noise: Vec<u8> = noise.into_iter().filter(|&c| c != ascii::START).collect();
        let line = [&noise[..], &frame[..]].concat();
        let at = split.index(line.len() + 1);
        let mut rx = Receiver::new();
        let mut got = rx.feed(&line[..at]);
        got.extend(rx.feed(&line[at..]));
        prop_assert_eq!(got, vec![Ok(unit_pdu.clone())]);
        prop_assert_eq!(rx.dropped(), noise.len() as u64);
        prop_assert!(!rx.in_frame());
        prop_assert_eq!(ascii::seen(&line), Seen::Ended { start: noise.len(), end: line.len() });
    }

    #[test]
    fn requests_round_trip_and_their_replies_are_read_to_the_end(req in any_request(),
                                                                 unit in 1u8..=247) {
        let frame = ascii::encode_request(unit, &req);
        let unit_pdu = benchbus::codec::Framing::Mbap.encode_request(unit, &req);
        prop_assert_eq!(ascii::decode(&frame), Ok(unit_pdu));
        // Its reply is read by its length up to its CR LF, never past it, and decodes.
        let mut reply = vec![unit, req.function()];
        match &req {
            Request::ReadHoldingRegisters { count, .. } => {
                reply.push((2 * count) as u8);
                reply.extend((0..2 * count).map(|i| i as u8));
            }
            Request::WriteSingleRegister { .. } => reply = frame_pdu(&frame),
            Request::WriteMultipleRegisters { address, values } => {
                reply.extend(address.to_be_bytes());
                reply.extend((values.len() as u16).to_be_bytes());
            }
            _ => {}
        }
        let reply = ascii::encode(&reply);
        for i in 0..reply.len() {
            match ascii::reply_needed(&req, &reply[..i]) {
                Needed::More(n) => prop_assert!(n > 0 && i + n <= reply.len()),
                other => prop_assert!(false, "{:?} at {}", other, i),
            }
        }
        prop_assert_eq!(ascii::reply_needed(&req, &reply), Needed::Complete(reply.len()));
        prop_assert!(ascii::decode_reply::<Bad>(unit, &req, &reply).is_ok());
    }

}

proptest! {
    // Each case reads up to 700 characters one at a time: fewer cases.
    #![proptest_config(ProptestConfig::with_cases(1_500))]

    #[test]
    fn arbitrary_characters_never_panic(req in any_request(), unit in any::<u8>(),
                                        chars in line_chars(700),
                                        cuts in prop::collection::vec(any::<prop::sample::Index>(), 0..6)) {
        let _ = ascii::decode(&chars);
        let _ = ascii::unit_of(&chars);
        let _ = ascii::decode_reply::<Bad>(unit, &req, &chars);
        match ascii::seen(&chars) {
            Seen::Nothing => prop_assert!(!chars.contains(&ascii::START)),
            Seen::Begun { start } | Seen::TooLong { start } => {
                prop_assert_eq!(chars[start], ascii::START);
            }
            Seen::Ended { start, end } => {
                prop_assert!(end - start <= MAX_FRAME);
                prop_assert_eq!(&chars[start..start + 1], b":");
                prop_assert_eq!(&chars[end - 2..end], b"\r\n");
            }
        }
        // Fed in pieces, the receiver hands out at most one result per `:` and keeps no
        // more than a frame.
        let mut at: Vec<usize> = cuts.iter().map(|i| i.index(chars.len() + 1)).collect();
        at.push(0);
        at.push(chars.len());
        at.sort_unstable();
        let mut rx = Receiver::new();
        let mut results = 0;
        for w in at.windows(2) {
            results += rx.feed(&chars[w[0]..w[1]]).len();
        }
        let colons = chars.iter().filter(|&&c| c == ascii::START).count();
        prop_assert!(results <= colons);
        prop_assert!(rx.dropped() <= chars.len() as u64);
        // Read as the Bus reads a reply, the buffer grows until the reader says it is done.
        let mut buf = Vec::new();
        for &c in &chars {
            match ascii::reply_needed(&req, &buf) {
                Needed::Complete(n) => {
                    prop_assert!(n <= buf.len());
                    let ended = matches!(ascii::seen(&buf), Seen::Ended { end, .. } if end == n);
                    prop_assert!(ended);
                    break;
                }
                Needed::More(n) => prop_assert!(n > 0),
                // Only a frame too long has no length.
                other => {
                    prop_assert_eq!(other, Needed::Unknown);
                    let too_long = matches!(ascii::seen(&buf), Seen::TooLong { .. });
                    prop_assert!(too_long);
                    break;
                }
            }
            buf.push(c);
        }
    }
}

#[test]
fn a_valid_frame_split_in_every_place_comes_out_once() {
    let unit_pdu = [0x11, 0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64];
    let frame = ascii::encode(&unit_pdu);
    for a in 0..=frame.len() {
        for b in a..=frame.len() {
            let mut rx = Receiver::new();
            let mut got = rx.feed(&frame[..a]);
            got.extend(rx.feed(&frame[a..b]));
            got.extend(rx.feed(&frame[b..]));
            assert_eq!(got, [Ok(unit_pdu.to_vec())], "{a} {b}");
        }
    }
}
