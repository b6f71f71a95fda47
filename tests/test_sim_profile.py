"""ProfileDevice: the example profiles served on a pseudo-terminal, judged by pymodbus's
serial client (a third-party master), the request frames as they crossed the line, and the
values decoded here by hand (struct) from the profiles' declarations."""

from __future__ import annotations

import logging
import struct
from collections.abc import Iterator
from pathlib import Path

import pytest
from pymodbus.client import ModbusSerialClient

from benchbus.sim import ProfileDevice, Simulator
from conftest import crc

logging.getLogger("pymodbus").setLevel(logging.CRITICAL)

PROFILES = Path(__file__).resolve().parent.parent / "examples" / "profiles"


def frame(*pdu: int, unit: int = 1) -> bytes:
    body = bytes([unit, *pdu])
    return body + crc(body)


Rig = tuple[Simulator[ProfileDevice], ModbusSerialClient, ProfileDevice]


def rig(dev: ProfileDevice) -> Iterator[Rig]:
    with Simulator({1: dev}) as sim:
        client = ModbusSerialClient(sim.port, baudrate=9600, parity="N", timeout=1, retries=0)
        assert client.connect()
        try:
            yield sim, client, dev
        finally:
            client.close()
        assert sim.errors == []


@pytest.fixture
def sensor() -> Iterator[Rig]:
    yield from rig(ProfileDevice(PROFILES / "xy_md02.toml", values={"temperature": -12.3}))


@pytest.fixture
def relays() -> Iterator[Rig]:
    yield from rig(ProfileDevice(PROFILES / "relay_board.toml"))


@pytest.fixture
def controller() -> Iterator[Rig]:
    yield from rig(ProfileDevice(str(PROFILES / "flow_controller.toml")))


# ---- the sensor: input registers, holding settings -----------------------------------------


def test_sensor_readings_on_the_wire(sensor: Rig) -> None:
    sim, client, dev = sensor
    reply = client.read_input_registers(0x0001, count=2, device_id=1)
    assert sim.requests[-1] == frame(0x04, 0x00, 0x01, 0x00, 0x02)
    temperature, humidity = struct.unpack(">hH", struct.pack(">HH", *reply.registers))
    assert temperature == -123  # values= wins over the profile's default 21.5
    assert humidity == 450  # the profile's default 45.0, x 0.1
    assert temperature * 0.1 == pytest.approx(dev.value("temperature"))
    dev.set_value("humidity", 61.7)
    assert client.read_input_registers(0x0002, count=1, device_id=1).registers == [617]


def test_sensor_settings_written_and_checked(sensor: Rig) -> None:
    sim, client, dev = sensor
    assert not client.write_register(0x0101, 17, device_id=1).isError()
    assert sim.requests[-1] == frame(0x06, 0x01, 0x01, 0x00, 0x11)
    assert dev.value("unit_address") == 17
    # Out of min/max (1..247): illegal data value, nothing written.
    assert client.write_register(0x0101, 248, device_id=1).exception_code == 3
    assert dev.value("unit_address") == 17
    # An enum takes its members' numbers only.
    assert not client.write_register(0x0102, 2, device_id=1).isError()
    assert dev.value("baud") == "b19200"
    assert client.write_register(0x0102, 3, device_id=1).exception_code == 3
    # i16 x 0.1: -1.5 degC is 0xFFF1; -10.1 is below min.
    assert not client.write_register(0x0103, 0xFFF1, device_id=1).isError()
    assert dev.value("temperature_correction") == pytest.approx(-1.5)
    assert client.write_register(0x0103, 0x10000 - 101, device_id=1).exception_code == 3
    assert dev.value("temperature_correction") == pytest.approx(-1.5)
    assert sim.peek(1, 0x0101, 4) == [17, 2, 0xFFF1, 0]


def test_sensor_limits_and_unknown_addresses(sensor: Rig) -> None:
    sim, client, dev = sensor
    # [limits] max_read = 10, max_write = 1: exception 3 before the addresses are looked at.
    assert client.read_holding_registers(0x0101, count=11, device_id=1).exception_code == 3
    assert sim.requests[-1] == frame(0x03, 0x01, 0x01, 0x00, 0x0B)
    assert client.read_holding_registers(0x0101, count=4, device_id=1).registers == [1, 0, 0, 0]
    assert client.write_registers(0x0101, [2, 0], device_id=1).exception_code == 3
    assert dev.value("unit_address") == 1
    # An address the profile does not declare: illegal data address.
    assert client.read_input_registers(0x0000, count=2, device_id=1).exception_code == 2
    assert client.read_holding_registers(0x0100, count=1, device_id=1).exception_code == 2
    assert client.write_register(0x0105, 1, device_id=1).exception_code == 2


# ---- the relay board: coils, discrete inputs, bits of a register -----------------------------


def test_relays_on_the_wire(relays: Rig) -> None:
    sim, client, dev = relays
    assert client.read_coils(0, count=7, device_id=1).bits[:7] == [True] + [False] * 6
    assert sim.requests[-1] == frame(0x01, 0x00, 0x00, 0x00, 0x07)
    assert not client.write_coil(2, True, device_id=1).isError()
    assert sim.requests[-1] == frame(0x05, 0x00, 0x02, 0xFF, 0x00)
    assert dev.value("relay3") is True
    states = [False, True, False, True, False, True, False, True]
    assert not client.write_coils(0, states, device_id=1).isError()
    assert sim.requests[-1] == frame(0x0F, 0x00, 0x00, 0x00, 0x08, 0x01, 0xAA)
    assert [dev.value(f"relay{i}") for i in range(1, 9)] == states
    dev.set_value("input3", True)
    dev.set_value("input8", True)
    assert client.read_discrete_inputs(0, count=8, device_id=1).bits[:8] == [
        False, False, True, False, False, False, False, True,
    ]  # fmt: skip


def test_relays_access_bits_and_limits(relays: Rig) -> None:
    sim, client, dev = relays
    # relay8 is write-only: a read that touches it is an illegal data address.
    assert client.read_coils(0, count=8, device_id=1).exception_code == 2
    # board_address is read-only: exception 2, the address is not writable.
    assert client.read_holding_registers(0x0020, count=1, device_id=1).registers == [1]
    assert client.write_register(0x0020, 5, device_id=1).exception_code == 2
    assert dev.value("board_address") == 1
    # all_on / all_off are bits 0 and 1 of one holding register.
    assert not client.write_register(0x0010, 0b10, device_id=1).isError()
    assert (dev.value("all_on"), dev.value("all_off")) == (False, True)
    dev.set_value("all_on", True)
    assert client.read_holding_registers(0x0010, count=1, device_id=1).registers == [0b11]
    # max_read = max_write = 8 bits.
    assert client.read_discrete_inputs(0, count=9, device_id=1).exception_code == 3
    assert client.write_coils(0, [True] * 9, device_id=1).exception_code == 3
    assert sim.requests[-1] == frame(0x0F, 0x00, 0x00, 0x00, 0x09, 0x02, 0xFF, 0x01)
    assert dev.value("relay1") is True and dev.value("relay2") is False


def test_relays_mask_write_and_read_write_keep_the_checks(relays: Rig) -> None:
    sim, client, dev = relays
    # 0x16 on the command word: (0b00 AND 0xFFFE) OR (0x0001 AND NOT 0xFFFE) sets bit 0.
    reply = client.mask_write_register(address=0x0010, and_mask=0xFFFE, or_mask=0x0001, device_id=1)
    assert not reply.isError()
    assert sim.requests[-1] == frame(0x16, 0x00, 0x10, 0xFF, 0xFE, 0x00, 0x01)
    assert (dev.value("all_on"), dev.value("all_off")) == (True, False)
    reply = client.mask_write_register(address=0x0020, and_mask=0, or_mask=9, device_id=1)
    assert reply.exception_code == 2 and dev.value("board_address") == 1
    # 0x17: the write first, then the read; a refused write writes and reads nothing.
    reply = client.readwrite_registers(
        read_address=0x0020, read_count=1, write_address=0x0010, values=[0b10], device_id=1
    )
    assert reply.registers == [1] and dev.value("all_off") is True
    reply = client.readwrite_registers(
        read_address=0x0010, read_count=1, write_address=0x0020, values=[7], device_id=1
    )
    assert reply.exception_code == 2 and dev.value("board_address") == 1


# ---- the controller: 32- and 64-bit values, orders, enum, string ----------------------------


def test_controller_floats_in_cdab(controller: Rig) -> None:
    sim, client, dev = controller
    words = client.read_holding_registers(0x0000, count=2, device_id=1).registers
    assert sim.requests[-1] == frame(0x03, 0x00, 0x00, 0x00, 0x02)
    # CDAB: the low word first.
    assert struct.unpack(">f", struct.pack(">HH", words[1], words[0]))[0] == 50.0
    low, high = struct.unpack(">HH", struct.pack(">f", 120.5))
    assert not client.write_registers(0x0000, [high, low], device_id=1).isError()
    assert sim.requests[-1] == frame(
        0x10, 0x00, 0x00, 0x00, 0x02, 0x04, *struct.pack(">HH", high, low)
    )
    assert dev.value("setpoint") == 120.5
    # Above max = 200: illegal data value; half a float: illegal data address.
    low, high = struct.unpack(">HH", struct.pack(">f", 250.0))
    assert client.write_registers(0x0000, [high, low], device_id=1).exception_code == 3
    assert client.write_register(0x0000, 0, device_id=1).exception_code == 2
    assert dev.value("setpoint") == 120.5
    pv = client.read_input_registers(0x0002, count=2, device_id=1).registers
    assert struct.unpack(">f", struct.pack(">HH", pv[1], pv[0]))[0] == 49.75


def test_controller_integers_orders_and_offsets(controller: Rig) -> None:
    sim, client, dev = controller
    total = client.read_input_registers(0x0004, count=2, device_id=1).registers
    assert struct.unpack(">I", struct.pack(">HH", *total))[0] == 123456  # 1234.56 / 0.01
    gas = client.read_input_registers(0x0011, count=2, device_id=1).registers
    raw = struct.unpack("<i", struct.pack(">HH", *gas))[0]
    assert raw * 0.01 - 273.15 == pytest.approx(22.5)  # DCBA: all four bytes reversed
    runtime = client.read_input_registers(0x0020, count=4, device_id=1).registers
    swapped = b"".join(struct.pack("<H", w) for w in runtime)  # BADC: bytes of each word
    assert struct.unpack(">Q", swapped)[0] == 86400
    dev.set_value("runtime", 2**40 + 5)
    runtime = client.read_input_registers(0x0020, count=4, device_id=1).registers
    swapped = b"".join(struct.pack("<H", w) for w in runtime)
    assert struct.unpack(">Q", swapped)[0] == 2**40 + 5
    offset = client.read_holding_registers(0x0024, count=4, device_id=1).registers
    assert struct.unpack(">q", struct.pack(">4H", *offset))[0] == -42
    too_big = struct.unpack(">4H", struct.pack(">q", 1_000_001))
    assert client.write_registers(0x0024, list(too_big), device_id=1).exception_code == 3
    fine = struct.unpack(">4H", struct.pack(">q", -999_999))
    assert not client.write_registers(0x0024, list(fine), device_id=1).isError()
    assert dev.value("zero_offset") == -999_999
    gain = struct.unpack(">4H", struct.pack(">d", 1.25))
    assert not client.write_registers(0x0028, list(gain), device_id=1).isError()
    assert dev.value("gain") == 1.25
    assert sim.requests[-1] == frame(0x10, 0x00, 0x28, 0x00, 0x04, 0x08, *struct.pack(">d", 1.25))


def test_controller_enum_string_and_write_only(controller: Rig) -> None:
    sim, client, dev = controller
    assert client.read_holding_registers(0x0010, count=1, device_id=1).registers == [1]
    assert not client.write_register(0x0010, 2, device_id=1).isError()
    assert dev.value("mode") == "purge"
    assert client.write_register(0x0010, 4, device_id=1).exception_code == 3
    name = client.read_holding_registers(0x0030, count=8, device_id=1).registers
    assert struct.pack(">8H", *name).rstrip(b"\0") == b"FC-200 #1"
    words = list(struct.unpack(">8H", b"line B".ljust(16, b"\0")))
    assert not client.write_registers(0x0030, words, device_id=1).isError()
    assert dev.value("device_name") == "line B"
    # reset_total is write-only: read refused, 1 accepted, 2 out of 0..1.
    assert client.read_holding_registers(0x0040, count=1, device_id=1).exception_code == 2
    assert not client.write_register(0x0040, 1, device_id=1).isError()
    assert client.write_register(0x0040, 2, device_id=1).exception_code == 3
    # max_read = 16.
    assert client.read_holding_registers(0x0030, count=17, device_id=1).exception_code == 3
    assert sim.requests[-1] == frame(0x03, 0x00, 0x30, 0x00, 0x11)


# ---- the profile itself ---------------------------------------------------------------------


def test_values_and_defaults_by_name() -> None:
    dev = ProfileDevice(PROFILES / "flow_controller.toml", values={"mode": 3, "setpoint": 7.5})
    assert dev.value("mode") == "close" and dev.value("setpoint") == 7.5
    assert dev.value("gain") == 1.0 and dev.value("device_name") == "FC-200 #1"
    assert (dev.name, dev.line["baudrate"], dev.limits["max_read"]) == ("FC-200", 19200, 16)
    assert dev.unit_of("flow") == "sccm" and "flow" in dev.names
    with pytest.raises(ValueError, match="setpoint"):
        dev.set_value("setpoint", 201.0)
    with pytest.raises(ValueError, match="mode"):
        dev.set_value("mode", "boost")
    with pytest.raises(KeyError, match="nope"):
        dev.value("nope")
    with pytest.raises(ValueError, match="unit_address"):
        ProfileDevice(PROFILES / "xy_md02.toml", values={"unit_address": 0})


GOOD = """
[device]
name = "t"
[[register]]
name = "a"
address = 1
"""


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ("[oops]\n", "unknown key"),
        ('[[register]]\nname = "a"\naddress = 5\n', "used twice"),
        ('[[register]]\nname = "b"\naddress = 1\n', "also 'a'"),
        ('[[register]]\nname = "b"\naddress = 0\ntype = "u32"\n', "also 'a'"),
        ('[[register]]\nname = "b"\naddress = 9\ntable = "coil"\ntype = "u16"\n', "bool"),
        ('[[register]]\nname = "b"\naddress = 9\ntable = "input"\naccess = "rw"\n', "read-only"),
        ('[[register]]\nname = "b"\naddress = 9\ncolour = 1\n', "colour"),
        ('[[register]]\nname = "b"\naddress = 9\nenum = { x = "on" }\n', "enum key"),
        ('[[register]]\nname = "b"\naddress = 9\nenum = { 0 = "on", 1 = "on" }\n', "twice"),
        ('[[register]]\nname = "b"\naddress = 9\nmin = 5\nmax = 1\n', "above max"),
        ('[[register]]\nname = "b"\naddress = 9\nmax = 10\ndefault = 11\n', "default"),
        ('[[register]]\nname = "b"\naddress = 9\ntype = "string"\n', "length"),
        ('[[register]]\nname = "b"\naddress = 9\ntype = "bool"\nbit = 16\n', "bit"),
        ('[[register]]\nname = "b"\naddress = 0xFFFF\ntype = "f32"\n', "past"),
        ('[[register]]\nname = "b c"\naddress = 9\n', "identifier"),
        ("[limits]\nmax_read = 0\n", "max_read"),
        ('[line]\nparity = "X"\n', "parity"),
        ("[line]\nstopbits = 3\n", "stopbits"),
        ("[line]\nbaudrate = -9600\n", "baudrate"),
        ("[line]\ntimeout = 0\n", "timeout"),
        ('[line]\nframing = "tcp"\n', "framing"),
        ("[[register\n", "not valid TOML"),
    ],
)
def test_a_broken_profile_is_a_value_error(tmp_path: Path, extra: str, message: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(GOOD + extra)
    with pytest.raises(ValueError, match=message) as raised:
        ProfileDevice(path)
    assert str(path) in str(raised.value)


def test_bits_of_one_register_may_share_it(tmp_path: Path) -> None:
    path = tmp_path / "bits.toml"
    rows = "".join(
        f'[[register]]\nname = "b{i}"\naddress = 3\ntype = "bool"\nbit = {i}\n' for i in range(16)
    )
    path.write_text(rows)
    dev = ProfileDevice(path, values={"b0": True, "b15": True})
    assert dev.registers[3] == 0x8001
