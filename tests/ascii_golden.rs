//! The Modbus ASCII frames of tests/vectors/ascii.json through the codec, both ways: each
//! `unit | PDU` frames to the text given and the text decodes to it (whole, fed to the
//! receiver a character at a time, and as a reply to its request).

use benchbus::codec::ascii::{self, AsciiError, Receiver};
use benchbus::codec::{FrameError, Needed, Reply, Request, Response};
use serde_json::Value;

/// Functions whose frames are checked at the framing level only: the codec builds no such
/// request yet.
const FRAMING_ONLY: [&str; 2] = ["read_coils", "read_input_registers"];

/// Either error of a reply, for [`ascii::decode_reply`].
#[derive(Debug, PartialEq)]
enum Bad {
    Ascii(AsciiError),
    Frame(FrameError),
}

impl From<AsciiError> for Bad {
    fn from(e: AsciiError) -> Bad {
        Bad::Ascii(e)
    }
}

impl From<FrameError> for Bad {
    fn from(e: FrameError) -> Bad {
        Bad::Frame(e)
    }
}

fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).expect("hex byte"))
        .collect()
}

fn num(v: &Value, key: &str) -> u64 {
    v[key]
        .as_u64()
        .unwrap_or_else(|| panic!("{key} missing in {v}"))
}

fn text<'a>(v: &'a Value, key: &str) -> &'a str {
    v[key]
        .as_str()
        .unwrap_or_else(|| panic!("{key} missing in {v}"))
}

fn registers(v: &Value) -> Vec<u16> {
    v["values"]
        .as_array()
        .unwrap_or_else(|| panic!("values missing in {v}"))
        .iter()
        .map(|x| x.as_u64().expect("value") as u16)
        .collect()
}

/// The request a vector's call makes, or None for a function checked at the framing level.
fn request(r: &Value) -> Option<Request> {
    Some(match text(r, "function") {
        "read_holding_registers" => Request::ReadHoldingRegisters {
            address: num(r, "address") as u16,
            count: num(r, "count") as u16,
        },
        "write_register" => Request::WriteSingleRegister {
            address: num(r, "address") as u16,
            value: num(r, "value") as u16,
        },
        "write_registers" => Request::WriteMultipleRegisters {
            address: num(r, "address") as u16,
            values: registers(r),
        },
        f if FRAMING_ONLY.contains(&f) => return None,
        other => panic!("unknown function {other}"),
    })
}

/// `frame` fed to a receiver one character at a time: what it hands out.
fn received(frame: &[u8]) -> Vec<Result<Vec<u8>, AsciiError>> {
    let mut rx = Receiver::new();
    let mut out = Vec::new();
    for &c in frame {
        out.extend(rx.feed(&[c]));
    }
    assert!(!rx.in_frame());
    assert_eq!(rx.dropped(), 0);
    out
}

/// `frame` (a whole, valid frame) against its `unit | PDU`, both ways.
fn framing_both_ways(id: &str, frame: &str, unit_pdu: &[u8], lower: bool) {
    let frame = frame.as_bytes();
    assert_eq!(ascii::decode(frame).as_deref(), Ok(unit_pdu), "{id}");
    assert_eq!(received(frame), [Ok(unit_pdu.to_vec())], "{id}");
    let sent = ascii::encode(unit_pdu);
    if lower {
        assert_ne!(sent, frame, "{id}: not in lower case");
    }
    assert_eq!(sent, frame.to_ascii_uppercase(), "{id}");
}

fn expected_response(id: &str, result: &Value) -> Response {
    match text(result, "kind") {
        "registers" => Response::Registers(registers(result)),
        "write_single" => Response::WriteSingleRegister {
            address: num(result, "address") as u16,
            value: num(result, "value") as u16,
        },
        "write_multiple" => Response::WriteMultipleRegisters {
            address: num(result, "address") as u16,
            count: num(result, "count") as u16,
        },
        other => panic!("{id}: unknown kind {other}"),
    }
}

#[test]
fn every_ascii_vector_frames_and_decodes_both_ways() {
    let text_of = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/vectors/ascii.json"
    ))
    .expect("vectors file");
    let doc: Value = serde_json::from_str(&text_of).expect("json");
    let vectors = doc["vectors"].as_array().expect("vectors");
    assert!(vectors.len() >= 9, "only {} vectors", vectors.len());
    let mut replies_decoded = 0;
    for v in vectors {
        let id = text(v, "id");
        let unit = num(v, "unit") as u8;
        let r = &v["request"];
        let req_pdu = hex(text(r, "unit_pdu"));
        assert_eq!(req_pdu.first(), Some(&unit), "{id}: unit");
        framing_both_ways(id, text(r, "frame"), &req_pdu, false);
        let req = request(r);
        if let Some(req) = &req {
            assert_eq!(
                ascii::encode_request(unit, req),
                text(r, "frame").as_bytes(),
                "{id}: request"
            );
            assert_eq!(ascii::unit_of(text(r, "frame").as_bytes()), Some(unit));
        }
        let Some(reply) = v.get("reply") else {
            continue;
        };
        let frame = text(reply, "frame").as_bytes();
        let unit_pdu = hex(text(reply, "unit_pdu"));
        let result = &reply["result"];
        let lower = reply.get("case").and_then(Value::as_str) == Some("lower");
        if text(result, "kind") == "lrc_error" {
            let lrc = AsciiError::Lrc {
                computed: num(result, "computed") as u8,
                received: num(result, "received") as u8,
            };
            assert_eq!(ascii::decode(frame), Err(lrc.clone()), "{id}");
            assert_eq!(received(frame), [Err(lrc.clone())], "{id}");
            // The bytes it carries, with the right LRC, are the unit | PDU given.
            assert_eq!(ascii::lrc(&unit_pdu), lrc_of(&lrc), "{id}");
            if let Some(req) = &req {
                assert_eq!(
                    ascii::decode_reply::<Bad>(unit, req, frame),
                    Err(Bad::Ascii(lrc)),
                    "{id}"
                );
            }
            continue;
        }
        framing_both_ways(id, text(reply, "frame"), &unit_pdu, lower);
        let Some(req) = req else {
            continue;
        };
        // Read character by character, the reply is complete exactly at its LF.
        let complete_at =
            (0..=frame.len()).find_map(|i| match ascii::reply_needed(&req, &frame[..i]) {
                Needed::Complete(n) => Some((i, n)),
                Needed::More(n) => {
                    assert!(
                        i + n <= frame.len(),
                        "{id}: {n} more at {i} reads past the end"
                    );
                    None
                }
                other => panic!("{id}: {other:?} at {i}"),
            });
        assert_eq!(
            complete_at,
            Some((frame.len(), frame.len())),
            "{id}: length"
        );
        let decoded = ascii::decode_reply::<Bad>(unit, &req, frame);
        let want = if text(result, "kind") == "exception" {
            Reply::Exception {
                function: req.function(),
                code: num(result, "code") as u8,
            }
        } else {
            Reply::Normal(expected_response(id, result))
        };
        assert_eq!(decoded, Ok(want), "{id}");
        replies_decoded += 1;
    }
    assert!(
        replies_decoded >= 5,
        "only {replies_decoded} replies decoded"
    );
}

fn lrc_of(e: &AsciiError) -> u8 {
    match e {
        AsciiError::Lrc { computed, .. } => *computed,
        other => panic!("{other:?}"),
    }
}
