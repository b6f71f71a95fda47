"""Every example frame of the five manuals and of the Modbus application protocol
specification (tests/vectors/rtu.json), on the wire.

Each vector's request must leave the library byte for byte from the Python call it names,
and the manual's reply must decode to the values the manual states (or raise the error a
corrupt frame deserves).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

import benchbus as bb
from conftest import ScriptedSlave

VECTORS = json.loads((Path(__file__).parent / "vectors" / "rtu.json").read_text("utf-8"))["vectors"]


def frame(text: str) -> bytes:
    return bytes.fromhex(text)


def call(bus: bb.Bus, unit: int, req: dict[str, Any], lenient: bool) -> Any:
    fn = req["function"]
    if fn == "read_holding_registers":
        return bus.read_holding_registers(unit, req["address"], req["count"])
    if fn == "write_register":
        return bus.write_register(unit, req["address"], req["value"], accept_count_echo=lenient)
    if fn == "write_registers":
        return bus.write_registers(unit, req["address"], req["values"])
    if fn == "read_device_identification":
        return bus.read_device_identification(unit, req["read_code"], req["object_id"])
    if fn in ("read_coils", "read_discrete_inputs", "read_input_registers"):
        return getattr(bus, fn)(unit, req["address"], req["count"])
    if fn in ("write_coil", "write_coils"):
        return getattr(bus, fn)(unit, req["address"], req.get("value", req.get("values")))
    if fn == "mask_write_register":
        return bus.mask_write_register(unit, req["address"], req["and_mask"], req["or_mask"])
    if fn == "read_write_registers":
        return bus.read_write_registers(
            unit, req["read_address"], req["read_count"], req["write_address"], req["values"]
        )
    if fn == "read_exception_status":
        return bus.read_exception_status(unit)
    if fn == "diagnostics":
        return bus.diagnostics(unit, req["sub_function"], frame(req["data"]))
    if fn in ("get_comm_event_counter", "get_comm_event_log"):
        return getattr(bus, fn)(unit)
    if fn == "read_file_record":
        return bus.read_file_record(unit, [tuple(g) for g in req["groups"]])
    if fn == "write_file_record":
        return bus.write_file_record(unit, [tuple(g) for g in req["groups"]])
    if fn == "read_fifo_queue":
        return bus.read_fifo_queue(unit, req["address"])
    raise AssertionError(f"unknown function {fn}")


#: The vectors from the Modbus Application Protocol Specification, not from a manual.
SPEC = "Modbus Application Protocol Specification V1.1b3"


def test_every_manual_is_covered() -> None:
    sources = {v["source"].split()[0][:3] for v in VECTORS if not v["source"].startswith(SPEC)}
    assert sources == {"000", "001", "002", "003", "004"}
    assert len({v["id"] for v in VECTORS}) == len(VECTORS)


def test_every_function_the_specification_gives_an_example_of_is_covered() -> None:
    spec = [v for v in VECTORS if v["source"].startswith(SPEC)]
    functions = {bytes.fromhex(v["request"]["frame"])[1] for v in spec}
    assert functions == {
        0x01,
        0x02,
        0x04,
        0x05,
        0x07,
        0x08,
        0x0B,
        0x0C,
        0x0F,
        0x14,
        0x15,
        0x16,
        0x17,
        0x18,
    }
    # The specification's PDUs, sent to unit 1 with the serial line's CRC.
    assert all(v["unit"] == 1 and v["crc"] == "computed" for v in spec)


@pytest.mark.parametrize("v", VECTORS, ids=[v["id"] for v in VECTORS])
def test_vector_on_the_wire(slave: ScriptedSlave, v: dict[str, Any]) -> None:
    req = v["request"]
    reply = v.get("reply")
    sent = frame(req["frame"])
    result = reply["result"] if reply else None
    with bb.Bus(slave.port, timeout=0.2, retries=0) as bus:
        slave.expect(len(sent), frame(reply["frame"]) if reply else None)
        lenient = bool(reply and reply.get("echo") is False)
        kind = result["kind"] if result else None
        if kind is None:
            with pytest.raises(bb.ResponseTimeout):
                call(bus, v["unit"], req, lenient)
        elif kind == "exception":
            with pytest.raises(bb.ModbusException) as exc:
                call(bus, v["unit"], req, lenient)
            assert exc.value.code == result["code"]
            assert exc.value.unit == v["unit"]
            assert exc.value.frame == reply["frame"].upper()
        elif kind == "crc_error":
            with pytest.raises(bb.CrcError):
                call(bus, v["unit"], req, lenient)
        else:
            got = call(bus, v["unit"], req, lenient)
            if kind in ("registers", "bits"):
                assert got == result["values"]
            elif kind == "device_id":
                assert got == {int(k): s for k, s in result["objects"].items()}
            elif kind == "exception_status":
                assert got == result["status"]
            elif kind == "diagnostics":
                assert got == frame(result["data"])
            elif kind == "comm_event_counter":
                assert got == bb.CommEventCounter(result["status"], result["event_count"])
                assert (got.status, got.event_count) == (result["status"], result["event_count"])
            elif kind == "comm_event_log":
                assert isinstance(got, bb.CommEventLog)
                assert got == (
                    result["status"],
                    result["event_count"],
                    result["message_count"],
                    frame(result["events"]),
                )
            elif kind == "file_records":
                assert got == result["records"]
            elif kind == "fifo":
                assert got == result["values"]
            else:
                assert got is None
        slave.join()
    assert slave.received[0] == sent


def test_non_echo_refused_by_default(slave: ScriptedSlave) -> None:
    """PBL's 0x06 reply carries a register count, not the value: strict mode refuses it."""
    (v,) = [v for v in VECTORS if v.get("reply", {}).get("echo") is False]
    with bb.Bus(slave.port, timeout=0.2, retries=0) as bus:
        slave.expect(8, frame(v["reply"]["frame"]))
        with pytest.raises(bb.FrameError, match="not echoed"):
            call(bus, v["unit"], v["request"], lenient=False)
