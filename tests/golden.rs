//! Every example frame of the five manuals (tests/vectors/rtu.json) through the codec.

use benchbus::codec::{
    check_echo, decode_reply, encode_request, reply_needed, Echo, FrameError, Needed, Reply,
    Request, Response,
};
use serde_json::Value;

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

fn registers(v: &Value) -> Vec<u16> {
    v["values"]
        .as_array()
        .unwrap_or_else(|| panic!("values missing in {v}"))
        .iter()
        .map(|x| x.as_u64().expect("value") as u16)
        .collect()
}

fn request(r: &Value) -> Request {
    match r["function"].as_str().expect("function") {
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
        "read_device_identification" => Request::ReadDeviceIdentification {
            read_code: num(r, "read_code") as u8,
            object_id: num(r, "object_id") as u8,
        },
        other => panic!("unknown function {other}"),
    }
}

#[test]
fn every_vector_encodes_and_decodes_as_the_manual_says() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/vectors/rtu.json"
    ))
    .expect("vectors file");
    let doc: Value = serde_json::from_str(&text).expect("json");
    let vectors = doc["vectors"].as_array().expect("vectors");
    assert!(vectors.len() >= 40, "only {} vectors", vectors.len());
    for v in vectors {
        let id = v["id"].as_str().expect("id");
        let unit = num(v, "unit") as u8;
        let r = &v["request"];
        let req = request(r);
        assert_eq!(
            encode_request(unit, &req),
            hex(r["frame"].as_str().expect("frame")),
            "{id}: request"
        );
        let Some(reply) = v.get("reply") else {
            continue;
        };
        let bytes = hex(reply["frame"].as_str().expect("frame"));
        // The incremental decoder finds the end of the reply by its length.
        let mut needed_at = None;
        for i in 0..=bytes.len() {
            if let Needed::Complete(n) = reply_needed(&req, &bytes[..i]) {
                needed_at = Some((i, n));
                break;
            }
        }
        assert_eq!(needed_at, Some((bytes.len(), bytes.len())), "{id}: length");
        let result = &reply["result"];
        let decoded = decode_reply(unit, &req, &bytes);
        match result["kind"].as_str().expect("kind") {
            "crc_error" => assert!(
                matches!(decoded, Err(FrameError::Crc { .. })),
                "{id}: {decoded:?}"
            ),
            "exception" => assert_eq!(
                decoded,
                Ok(Reply::Exception {
                    function: req.function(),
                    code: num(result, "code") as u8
                }),
                "{id}"
            ),
            kind => {
                let Ok(Reply::Normal(resp)) = decoded else {
                    panic!("{id}: {decoded:?}");
                };
                let expected = match kind {
                    "registers" => Response::Registers(registers(result)),
                    "write_single" => Response::WriteSingleRegister {
                        address: num(result, "address") as u16,
                        value: num(result, "value") as u16,
                    },
                    "write_multiple" => Response::WriteMultipleRegisters {
                        address: num(result, "address") as u16,
                        count: num(result, "count") as u16,
                    },
                    "device_id" => {
                        let Response::DeviceIdentification(ref id) = resp else {
                            panic!("{id}: {resp:?}");
                        };
                        let objects = result["objects"].as_object().expect("objects");
                        assert_eq!(id.objects.len(), objects.len(), "{id:?}");
                        for (k, s) in objects {
                            let k: u8 = k.parse().expect("object id");
                            assert_eq!(id.objects[&k], s.as_str().expect("text").as_bytes());
                        }
                        resp.clone()
                    }
                    other => panic!("{id}: unknown kind {other}"),
                };
                assert_eq!(resp, expected, "{id}");
                let echo_ok = check_echo(&req, &resp, Echo::Strict).is_ok();
                let lenient_ok = check_echo(&req, &resp, Echo::CountForSingleWrite).is_ok();
                if reply.get("echo") == Some(&Value::Bool(false)) {
                    assert!(!echo_ok && lenient_ok, "{id}: non-echo rules");
                } else {
                    assert!(echo_ok, "{id}: echo");
                }
            }
        }
    }
}
