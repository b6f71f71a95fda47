//! Every example frame of the five manuals and of the Modbus application protocol
//! specification (tests/vectors/rtu.json) through the codec.

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

fn bits(v: &Value) -> Vec<bool> {
    v["values"]
        .as_array()
        .unwrap_or_else(|| panic!("values missing in {v}"))
        .iter()
        .map(|x| x.as_bool().expect("bool value"))
        .collect()
}

fn bytes_of(v: &Value, key: &str) -> Vec<u8> {
    hex(v[key]
        .as_str()
        .unwrap_or_else(|| panic!("{key} missing in {v}")))
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
        "read_coils" => Request::ReadCoils {
            address: num(r, "address") as u16,
            count: num(r, "count") as u16,
        },
        "read_discrete_inputs" => Request::ReadDiscreteInputs {
            address: num(r, "address") as u16,
            count: num(r, "count") as u16,
        },
        "read_input_registers" => Request::ReadInputRegisters {
            address: num(r, "address") as u16,
            count: num(r, "count") as u16,
        },
        "write_coil" => Request::WriteSingleCoil {
            address: num(r, "address") as u16,
            value: r["value"].as_bool().expect("coil value"),
        },
        "write_coils" => Request::WriteMultipleCoils {
            address: num(r, "address") as u16,
            values: bits(r),
        },
        "mask_write_register" => Request::MaskWriteRegister {
            address: num(r, "address") as u16,
            and_mask: num(r, "and_mask") as u16,
            or_mask: num(r, "or_mask") as u16,
        },
        "read_write_registers" => Request::ReadWriteRegisters {
            read_address: num(r, "read_address") as u16,
            read_count: num(r, "read_count") as u16,
            write_address: num(r, "write_address") as u16,
            values: registers(r),
        },
        "read_exception_status" => Request::ReadExceptionStatus,
        "diagnostics" => Request::Diagnostics {
            sub_function: num(r, "sub_function") as u16,
            data: bytes_of(r, "data"),
        },
        "get_comm_event_counter" => Request::GetCommEventCounter,
        "get_comm_event_log" => Request::GetCommEventLog,
        "read_file_record" => Request::ReadFileRecord {
            groups: groups(r)
                .iter()
                .map(|g| {
                    let n = |i: usize| g[i].as_u64().expect("group field") as u16;
                    (n(0), n(1), n(2))
                })
                .collect(),
        },
        "write_file_record" => Request::WriteFileRecord {
            groups: groups(r)
                .iter()
                .map(|g| {
                    let n = |i: usize| g[i].as_u64().expect("group field") as u16;
                    let values = g[2].as_array().expect("group values");
                    let values = values.iter().map(|x| x.as_u64().expect("value") as u16);
                    (n(0), n(1), values.collect())
                })
                .collect(),
        },
        "read_fifo_queue" => Request::ReadFifoQueue {
            address: num(r, "address") as u16,
        },
        other => panic!("unknown function {other}"),
    }
}

fn groups(r: &Value) -> &Vec<Value> {
    r["groups"]
        .as_array()
        .unwrap_or_else(|| panic!("groups missing in {r}"))
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
    // The specification's examples: one for each function it gives an example of.
    let spec: std::collections::BTreeSet<u8> = vectors
        .iter()
        .filter(|v| {
            v["source"]
                .as_str()
                .is_some_and(|s| s.starts_with("Modbus Application"))
        })
        .map(|v| request(&v["request"]).function())
        .collect();
    assert_eq!(
        spec.into_iter().collect::<Vec<_>>(),
        [0x01, 0x02, 0x04, 0x05, 0x07, 0x08, 0x0B, 0x0C, 0x0F, 0x14, 0x15, 0x16, 0x17, 0x18]
    );
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
                    "bits" => Response::Bits(bits(result)),
                    "write_coil" => Response::WriteSingleCoil {
                        address: num(result, "address") as u16,
                        value: num(result, "value") as u16,
                    },
                    "write_coils" => Response::WriteMultipleCoils {
                        address: num(result, "address") as u16,
                        count: num(result, "count") as u16,
                    },
                    "mask_write" => Response::MaskWriteRegister {
                        address: num(result, "address") as u16,
                        and_mask: num(result, "and_mask") as u16,
                        or_mask: num(result, "or_mask") as u16,
                    },
                    "exception_status" => Response::ExceptionStatus(num(result, "status") as u8),
                    "diagnostics" => Response::Diagnostics {
                        sub_function: num(result, "sub_function") as u16,
                        data: bytes_of(result, "data"),
                    },
                    "comm_event_counter" => Response::CommEventCounter {
                        status: num(result, "status") as u16,
                        event_count: num(result, "event_count") as u16,
                    },
                    "comm_event_log" => Response::CommEventLog {
                        status: num(result, "status") as u16,
                        event_count: num(result, "event_count") as u16,
                        message_count: num(result, "message_count") as u16,
                        events: bytes_of(result, "events"),
                    },
                    "file_records" => Response::FileRecords(
                        result["records"]
                            .as_array()
                            .expect("records")
                            .iter()
                            .map(|g| {
                                let g = g.as_array().expect("record group");
                                g.iter()
                                    .map(|x| x.as_u64().expect("value") as u16)
                                    .collect()
                            })
                            .collect(),
                    ),
                    // The echo: the request's PDU after its function code.
                    "file_record_echo" => Response::FileRecordEcho(
                        hex(r["frame"].as_str().expect("frame"))[2..]
                            .split_last_chunk::<2>()
                            .expect("crc")
                            .0
                            .to_vec(),
                    ),
                    "fifo" => Response::FifoQueue(registers(result)),
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
