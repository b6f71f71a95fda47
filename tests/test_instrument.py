"""benchbus.Instrument through the real serial path against the simulated Taisong meter and
the ATV31-style device of manual 004."""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Iterator

import pytest

import benchbus as bb
from benchbus.sim import Atv31Device, Simulator, TaisongDevice
from conftest import FakeClock

Rig = tuple[bb.Bus, Simulator[TaisongDevice | Atv31Device], TaisongDevice, Atv31Device]


def h(text: str) -> bytes:
    return bytes.fromhex(text)


def summary(frames: list[bytes]) -> list[tuple[int, int, int]]:
    """(function, address, count or value) of each request."""
    return [(f[1], int.from_bytes(f[2:4], "big"), int.from_bytes(f[4:6], "big")) for f in frames]


@contextlib.contextmanager
def open_rig() -> Iterator[Rig]:
    """A Taisong meter at unit 1 and an ATV31 at unit 2 on one line, clocks standing still."""
    meter, atv = TaisongDevice(clock=FakeClock()), Atv31Device()
    devices: dict[int, TaisongDevice | Atv31Device] = {1: meter, 2: atv}
    with Simulator(devices) as sim, bb.Bus(sim.port) as bus:
        yield bus, sim, meter, atv


@pytest.fixture
def rig() -> Iterator[Rig]:
    with open_rig() as opened:
        yield opened


def test_line_defaults() -> None:
    with Simulator({1: TaisongDevice()}) as sim:
        with bb.Instrument(sim.port) as meter:
            bus = meter.bus
            assert (bus.baudrate, bus.parity, bus.stopbits) == (9600, "N", 1)
            assert (meter.max_read, meter.max_write, meter.min_write_interval) == (37, 20, 0.0)
        with bb.Instrument(sim.port, baudrate=2400) as slow:
            assert slow.bus.baudrate == 2400 and slow.bus.char_time == pytest.approx(10 / 2400)
    with pytest.raises(ValueError, match="2400, 4800, 9600 or 19200"):
        bb.Instrument("/dev/null", baudrate=38400)


# ---- the manual's frames ------------------------------------------------------------------


def test_taisong_frames(rig: Rig) -> None:
    bus, sim, meter, _ = rig
    inst = bb.Instrument(bus, 1)
    meter.hold(1000)
    assert inst.read_register(0x0000) == 1000
    assert (sim.requests[-1], sim.replies[-1]) == (
        h("01 03 00 00 00 01 84 0A"),
        h("01 03 02 03 E8 B8 FA"),
    )
    assert len(inst.read_registers(0x0000, 2)) == 2
    assert sim.requests[-1] == h("01 03 00 00 00 02 C4 0B")
    inst.write_register(0x0005, 100)
    assert sim.requests[-1] == sim.replies[-1] == h("01 06 00 05 00 64 98 20")
    assert meter.sv == 100
    inst.write_registers(0x0008, [100, 200])
    assert sim.requests[-1] == h("01 10 00 08 00 02 04 00 64 00 C8 B2 40")
    assert sim.replies[-1] == h("01 10 00 08 00 02 C0 0A")
    assert meter.registers[8:10] == [100, 200]


def test_taisong_frame_at_unit_9() -> None:
    nine = TaisongDevice(clock=FakeClock())
    nine.hold(256)
    with Simulator({9: nine}) as sim, bb.Instrument(sim.port, unit=9) as inst:
        assert inst.read_register(0) == 256
        assert sim.requests[-1] == h("09 03 00 00 00 01 85 42")
        assert sim.replies[-1] == h("09 03 02 01 00 58 15")


def test_atv31_frames(rig: Rig) -> None:
    bus, sim, _, atv = rig
    inst = bb.Instrument(bus, 2, max_read=29, max_write=29)
    assert inst.read_registers(0x0C1E, 4) == [0x0028, 0x0258, 0x01F4, 0x0000]
    assert sim.requests[-1] == h("02 03 0C 1E 00 04 27 6C")
    assert sim.replies[-1] == h("02 03 08 00 28 02 58 01 F4 00 00 52 B0")
    inst.write_register(0x2329, 13)  # W9001: ACC = 13 s
    assert sim.requests[-1] == sim.replies[-1] == h("02 06 23 29 00 0D 92 70")
    inst.write_registers(0x0FCB, [20, 30])  # W4043..W4044: ACC = 20 s, DEC = 30 s
    assert sim.requests[-1] == h("02 10 0F CB 00 02 04 00 14 00 1E 30 F4")
    assert sim.replies[-1] == h("02 10 0F CB 00 02 33 11")
    assert (atv.registers[0x2329], atv.registers[0x0FCB], atv.registers[0x0FCC]) == (13, 20, 30)


def test_identification(rig: Rig) -> None:
    bus, sim, _, _ = rig
    ident = bb.Instrument(bus, 2, max_read=29, max_write=29).identify()
    assert sim.requests[-1] == h("02 2B 0E 01 00 34 77")
    assert ident.vendor == "TELEMECANIQUE" and ident["vendor"] == "TELEMECANIQUE"
    assert (ident.product_code, ident.revision) == ("ATV31HU09M3S232", "0201")
    assert ident.objects == {0: "TELEMECANIQUE", 1: "ATV31HU09M3S232", 2: "0201"}
    assert ident.conformity == 0x02 and ident["vendor_url"] is None


def test_identification_follows_more_follows() -> None:
    paged = Atv31Device(identity_page_size=1, extra_objects={3: "http://example.org", 0x80: "x"})
    with Simulator({2: paged}) as sim, bb.Instrument(sim.port, unit=2) as inst:
        basic = inst.identify()
        # (read code, object id) of each request: asked again from each next object.
        assert [(f[3], f[4]) for f in sim.requests] == [(1, 0), (1, 1), (1, 2)]
        assert basic.objects == {0: "TELEMECANIQUE", 1: "ATV31HU09M3S232", 2: "0201"}
        sim.clear_log()
        extended = inst.identify("extended")
        assert extended["vendor_url"] == "http://example.org" and extended.objects[0x80] == "x"
        assert len(sim.requests) == 5  # one object a reply: 0, 1, 2, 3, 0x80
    with pytest.raises(ValueError, match="level"):
        inst.identify("everything")  # type: ignore[arg-type]


def test_a_device_without_identification_raises_code_1(rig: Rig) -> None:
    bus, sim, _, _ = rig
    with pytest.raises(bb.ModbusException) as caught:
        bb.Instrument(bus, 1).identify()
    assert (caught.value.code, caught.value.function, caught.value.unit) == (1, 0x2B, 1)
    assert "does not support Read Device Identification" in caught.value.meaning
    assert sim.replies[-1][:3] == h("01 AB 01")


def test_the_atv31_form_of_an_identification_error() -> None:
    with Simulator({2: Atv31Device(mei_exceptions=True)}) as sim, bb.Bus(sim.port) as bus:
        with pytest.raises(bb.ModbusException) as caught:
            bus.read_device_identification(2, 4, 0x50)  # one object, an id it does not have
        assert caught.value.code == 2
        assert sim.replies[-1][:4] == h("02 AB 0E 02") and len(sim.replies[-1]) == 6
        assert bus.stats.crc_errors == bus.stats.frame_errors == bus.stats.retries == 0


# ---- limits ---------------------------------------------------------------------------------


def test_long_reads_and_writes_are_split_at_the_limits(rig: Rig) -> None:
    bus, sim, meter, _ = rig
    inst = bb.Instrument(bus, 1)
    meter.registers[0x100:0x164] = list(range(100))
    assert inst.read_registers(0x100, 100) == list(range(100))
    inst.write_registers(0x200, range(1000, 1045))
    assert summary(sim.requests) == [
        (3, 0x100, 37),
        (3, 0x125, 37),
        (3, 0x14A, 26),
        (0x10, 0x200, 20),
        (0x10, 0x214, 20),
        (0x10, 0x228, 5),
    ]
    assert meter.registers[0x200:0x22D] == list(range(1000, 1045))
    # The meter itself refuses more: the limits are real.
    too_far = bb.Instrument(bus, 1, max_read=38, max_write=21)
    with pytest.raises(bb.ModbusException) as caught:
        too_far.read_registers(0, 38)
    assert caught.value.code == 3
    with pytest.raises(bb.ModbusException):
        too_far.write_registers(0x300, [0] * 21)


def test_writes_keep_the_minimum_interval() -> None:
    strict = TaisongDevice(clock=FakeClock(), min_write_interval=0.1)
    with Simulator({1: strict}) as sim, bb.Bus(sim.port) as bus:
        paced = bb.Instrument(bus, 1, min_write_interval=0.12)
        paced.write_registers(0x10, list(range(50)))  # three requests
        paced.write_register(0x05, 7)
        times = [t for t, f in zip(sim.request_times, sim.requests) if f[1] in (6, 0x10)]
        assert len(times) == 4
        assert min(b - a for a, b in zip(times, times[1:])) >= 0.12
        assert strict.write_violations == []
        # Without the interval the meter refuses the second write (so the check can fail).
        time.sleep(0.15)
        unpaced = bb.Instrument(bus, 1)
        with pytest.raises(bb.ModbusException) as caught:
            unpaced.write_registers(0x10, list(range(25)))
        assert caught.value.code == 6 and len(strict.write_violations) == 1


# ---- round trips of every type --------------------------------------------------------------


@pytest.mark.parametrize(
    ("value", "decimals", "signed", "raw"),
    [
        (0, 0, False, 0),
        (65535, 0, False, 0xFFFF),
        (-1, 0, True, 0xFFFF),
        (-32768, 0, True, 0x8000),
        (12.5, 1, True, 125),
        (-12.5, 1, True, 0xFF83),
        (0.03, 2, False, 3),
        (655.35, 2, False, 0xFFFF),
    ],
)
def test_registers_with_decimals_and_sign(
    rig: Rig, value: float, decimals: int, signed: bool, raw: int
) -> None:
    bus, _, meter, _ = rig
    inst = bb.Instrument(bus, 1)
    inst.write_register(0x20, value, decimals, signed)
    assert meter.registers[0x20] == raw
    back = inst.read_register(0x20, decimals, signed)
    assert back == value and isinstance(back, int if decimals == 0 else float)
    inst.write_register(0x21, value, decimals, signed, function=16)
    assert meter.registers[0x21] == raw


@pytest.mark.parametrize("order", ["big", "little"])
def test_32_bit_values_and_floats(rig: Rig, order: str) -> None:
    bus, _, meter, _ = rig
    inst = bb.Instrument(bus, 1)
    inst.write_long(0x30, 0x12345678, word_order=order)  # type: ignore[arg-type]
    words = [0x1234, 0x5678] if order == "big" else [0x5678, 0x1234]
    assert meter.registers[0x30:0x32] == words
    assert inst.read_long(0x30, word_order=order) == 0x12345678  # type: ignore[arg-type]
    inst.write_long(0x32, -2, signed=True, word_order=order)  # type: ignore[arg-type]
    assert inst.read_long(0x32, signed=True, word_order=order) == -2  # type: ignore[arg-type]
    assert inst.read_long(0x32, word_order=order) == 0xFFFFFFFE  # type: ignore[arg-type]
    for value in (21.5, -0.15625, 3.4e38, 1e-40):
        inst.write_float(0x34, value, word_order=order)  # type: ignore[arg-type]
        back = inst.read_float(0x34, word_order=order)  # type: ignore[arg-type]
        assert back == pytest.approx(value, rel=1e-7, abs=1e-45)
    inst.write_float(0x36, 21.5, word_order=order)  # type: ignore[arg-type]
    high, low = 0x41AC, 0x0000
    assert meter.registers[0x36:0x38] == ([high, low] if order == "big" else [low, high])


#: 0x01020304 and 0x0102030405060708 in the four layouts, as (word order, byte order).
LAYOUTS = {
    ("big", "big"): ([0x0102, 0x0304], [0x0102, 0x0304, 0x0506, 0x0708]),
    ("little", "big"): ([0x0304, 0x0102], [0x0708, 0x0506, 0x0304, 0x0102]),
    ("big", "little"): ([0x0201, 0x0403], [0x0201, 0x0403, 0x0605, 0x0807]),
    ("little", "little"): ([0x0403, 0x0201], [0x0807, 0x0605, 0x0403, 0x0201]),
}


@pytest.mark.parametrize(("words", "order"), list(LAYOUTS))
def test_32_and_64_bit_values_in_all_four_layouts(rig: Rig, words: str, order: str) -> None:
    bus, _, meter, _ = rig
    inst = bb.Instrument(bus, 1)
    layout = {"word_order": words, "byte_order": order}
    two, four = LAYOUTS[(words, order)]
    inst.write_long(0x30, 0x01020304, **layout)  # type: ignore[arg-type]
    assert meter.registers[0x30:0x32] == two
    assert inst.read_long(0x30, **layout) == 0x01020304  # type: ignore[arg-type]
    inst.write_long(0x40, 0x0102030405060708, bits=64, **layout)  # type: ignore[arg-type]
    assert meter.registers[0x40:0x44] == four
    assert inst.read_long(0x40, bits=64, **layout) == 0x0102030405060708  # type: ignore[arg-type]
    inst.write_long(0x40, -2, True, bits=64, **layout)  # type: ignore[arg-type]
    assert inst.read_long(0x40, True, bits=64, **layout) == -2  # type: ignore[arg-type]
    assert inst.read_long(0x40, bits=64, **layout) == 2**64 - 2  # type: ignore[arg-type]
    inst.write_long(0x40, 2**64 - 1, bits=64, **layout)  # type: ignore[arg-type]
    assert meter.registers[0x40:0x44] == [0xFFFF] * 4
    # A double: 1.0 is 0x3FF0000000000000, laid out the same way as an integer.
    inst.write_float(0x50, 1.0, bits=64, **layout)  # type: ignore[arg-type]
    expected = [0x3FF0, 0, 0, 0]
    if order == "little":
        expected = [0xF03F, 0, 0, 0]
    if words == "little":
        expected.reverse()
    assert meter.registers[0x50:0x54] == expected
    for value in (1.0, -2.5e-300, 1.7976931348623157e308, math.pi):
        inst.write_float(0x50, value, bits=64, **layout)  # type: ignore[arg-type]
        assert inst.read_float(0x50, bits=64, **layout) == value  # type: ignore[arg-type]


#: The same layouts by the name profiles and ``from_registers`` give them.
ORDERS = {"ABCD": ("big", "big"), "CDAB": ("little", "big"), "BADC": ("big", "little")}
ORDERS["DCBA"] = ("little", "little")


@pytest.mark.parametrize("order", list(ORDERS))
def test_the_layout_by_its_order_name_and_by_its_aliases(rig: Rig, order: str) -> None:
    bus, _, meter, _ = rig
    inst = bb.Instrument(bus, 1)
    words, bytes_ = ORDERS[order]
    two, four = LAYOUTS[(words, bytes_)]
    inst.write_long(0x30, 0x01020304, order=order)  # type: ignore[arg-type]
    assert meter.registers[0x30:0x32] == two == bb.to_registers(0x01020304, "u32", order)  # type: ignore[arg-type]
    alias = {"word_order": words, "byte_order": bytes_}
    assert inst.read_long(0x30, **alias) == 0x01020304  # type: ignore[arg-type]
    inst.write_long(0x40, 0x0102030405060708, bits=64, **alias)  # type: ignore[arg-type]
    assert meter.registers[0x40:0x44] == four
    assert inst.read_long(0x40, bits=64, order=order.lower()) == 0x0102030405060708  # type: ignore[arg-type]
    inst.write_float(0x50, 21.5, order=order)  # type: ignore[arg-type]
    assert inst.read_float(0x50, **alias) == 21.5  # type: ignore[arg-type]
    inst.write_float(0x50, -0.5, **alias)  # type: ignore[arg-type]
    assert inst.read_float(0x50, order=order) == -0.5  # type: ignore[arg-type]
    assert bb.from_registers(meter.registers[0x50:0x52], "f32", order) == [-0.5]  # type: ignore[arg-type]


def test_an_order_and_its_aliases_together_are_refused(rig: Rig) -> None:
    bus, sim, _, _ = rig
    inst = bb.Instrument(bus, 1)
    sent = len(sim.requests)
    with pytest.raises(TypeError, match="not both"):
        inst.read_long(0, order="CDAB", word_order="little")
    with pytest.raises(TypeError, match="not both"):
        inst.write_float(0, 1.0, "big", order="ABCD")
    with pytest.raises(ValueError, match='order must be "ABCD", "CDAB", "BADC" or "DCBA"'):
        inst.read_float(0, order="big")  # type: ignore[arg-type]
    assert len(sim.requests) == sent
    assert inst.read_long(0, order=None, word_order="big") == inst.read_long(0)  # type: ignore[arg-type]


def test_64_bit_values_refused_before_anything_is_sent(rig: Rig) -> None:
    bus, sim, _, _ = rig
    inst = bb.Instrument(bus, 1)
    sent = len(sim.requests)
    for error, call in (
        (ValueError, lambda: inst.write_long(0, 2**64, bits=64)),
        (ValueError, lambda: inst.write_long(0, -1, bits=64)),
        (ValueError, lambda: inst.write_long(0, 2**63, True, bits=64)),
        (ValueError, lambda: inst.read_long(0xFFFD, bits=64)),
        (ValueError, lambda: inst.read_long(0, bits=16)),  # type: ignore[arg-type]
        (TypeError, lambda: inst.read_long(0, bits="64")),  # type: ignore[arg-type]
        (ValueError, lambda: inst.read_float(0, byte_order="middle")),  # type: ignore[arg-type]
        (TypeError, lambda: inst.read_float(0, byte_order=0)),  # type: ignore[arg-type]
        (ValueError, lambda: inst.write_float(0, math.inf, bits=64)),
        (ValueError, lambda: inst.write_float(0, math.nan, bits=64)),
    ):
        with pytest.raises(error):
            call()
    assert inst.read_long(0xFFFC, bits=64) == 0  # the last four registers are within reach
    assert len(sim.requests) == sent + 1


def test_text(rig: Rig) -> None:
    bus, _, meter, _ = rig
    inst = bb.Instrument(bus, 1)
    inst.write_string(0x40, "bench 3", 4)
    assert meter.registers[0x40:0x44] == [0x6265, 0x6E63, 0x6820, 0x3300]
    assert inst.read_string(0x40, 4) == "bench 3"
    inst.write_string(0x40, "Grüße", 3)  # Latin-1
    assert inst.read_string(0x40, 3) == "Grüße"
    inst.write_string(0x40, "", 4)
    assert inst.read_string(0x40, 4) == "" and meter.registers[0x40:0x44] == [0, 0, 0, 0]


def test_the_measured_value_moves_and_sv_is_settable() -> None:
    clock = FakeClock()
    meter = TaisongDevice(clock=clock, setpoint=500)
    with Simulator({1: meter}) as sim, bb.Instrument(sim.port) as inst:
        first = inst.read_register(0, signed=True)
        clock.now += 30.0
        later = inst.read_register(0, signed=True)
        assert first != later and abs(later - 500) < abs(first - 500)
        inst.write_register(5, 800)
        clock.now += 60.0
        assert abs(inst.read_register(0, signed=True) - 800) < 10


# ---- errors ---------------------------------------------------------------------------------


def test_bad_input_is_refused_before_anything_is_sent(rig: Rig) -> None:
    bus, sim, _, _ = rig
    inst = bb.Instrument(bus, 1)
    bad: list[tuple[type[Exception], object]] = [
        (ValueError, lambda: inst.read_registers(0, 0)),
        (ValueError, lambda: inst.read_registers(0xFFFF, 2)),
        (ValueError, lambda: inst.read_registers(-1, 1)),
        (ValueError, lambda: inst.write_registers(0, [])),
        (ValueError, lambda: inst.write_registers(0, [70000])),
        (ValueError, lambda: inst.write_register(0, 65536)),
        (ValueError, lambda: inst.write_register(0, -1)),
        (ValueError, lambda: inst.write_register(0, 32768, signed=True)),
        (ValueError, lambda: inst.write_register(0, 1.25, decimals=1)),
        (ValueError, lambda: inst.write_register(0, math.nan)),
        (ValueError, lambda: inst.write_register(0, 30000.02)),  # not rounded silently
        (ValueError, lambda: inst.write_register(0, 6553.496, decimals=1)),
        (TypeError, lambda: inst.write_registers(0, b"\x01\x02")),
        (TypeError, lambda: inst.write_register(0, 1, decimals=True)),  # type: ignore[arg-type]
        (TypeError, lambda: bb.Instrument(bus, 1, min_write_interval=True)),
        (ValueError, lambda: bb.Instrument(bus, 1, min_write_interval=2**2000)),
        (ValueError, lambda: inst.write_register(0, 1, decimals=10)),
        (ValueError, lambda: inst.write_register(0, 1, function=3)),
        (ValueError, lambda: inst.write_long(0, 2**32)),
        (ValueError, lambda: inst.write_long(0, -1)),
        (ValueError, lambda: inst.write_long(0, 2**31, signed=True)),
        (ValueError, lambda: inst.write_long(0, 1, word_order="middle")),  # type: ignore[arg-type]
        (ValueError, lambda: inst.write_float(0, math.inf)),
        (ValueError, lambda: inst.write_float(0, 1e39)),
        (ValueError, lambda: inst.write_string(0, "too long", 2)),
        (ValueError, lambda: inst.write_string(0, "Ω", 2)),
        (TypeError, lambda: inst.write_string(0, b"bytes", 2)),  # type: ignore[arg-type]
        (TypeError, lambda: inst.write_register(0, "1")),  # type: ignore[arg-type]
        (TypeError, lambda: inst.write_register(0, True)),
        (TypeError, lambda: inst.write_long(0, 1.0)),  # type: ignore[arg-type]
        (TypeError, lambda: inst.read_register(0, signed=1)),  # type: ignore[arg-type]
        (TypeError, lambda: inst.read_float(0, word_order=1)),  # type: ignore[arg-type]
        (ValueError, lambda: bb.Instrument(bus, 1, max_read=0)),
        (ValueError, lambda: bb.Instrument(bus, 1, max_write=124)),
        (ValueError, lambda: bb.Instrument(bus, 1, min_write_interval=-1.0)),
        (ValueError, lambda: bb.Instrument(bus, 0)),
    ]
    for error, call in bad:
        with pytest.raises(error):
            call()  # type: ignore[operator]
    assert sim.requests == []


def test_line_errors_raise_the_right_class(rig: Rig) -> None:
    bus, sim, _, _ = rig
    inst = bb.Instrument(bus, 1, timeout=0.05, retries=1)
    sim.set_silent(1)
    with pytest.raises(bb.ResponseTimeout):
        inst.read_register(0)
    sim.set_silent(1, False)
    sim.corrupt_next(2)
    with pytest.raises(bb.CrcError):
        inst.read_register(0)
    with pytest.raises(bb.ModbusException) as caught:
        inst.write_register(0x0000, 1)  # the measured value is read-only
    assert caught.value.code == 2
    with pytest.raises(bb.PortError):
        bb.Instrument("/dev/benchbus-no-such-port")


def test_counters_files_and_fifo_of_a_generic_instrument() -> None:
    from benchbus.sim import RegisterDevice

    device = RegisterDevice({0x20: 3, 0x21: 10, 0x22: 20, 0x23: 30})
    device.comm_event_count, device.comm_message_count, device.comm_events = 7, 9, b"\x20"
    with Simulator({1: device}) as sim, bb.Bus(sim.port) as bus:
        inst = bb.Instrument(bus, 1, min_write_interval=0.1)
        counter = inst.get_comm_event_counter()
        assert isinstance(counter, bb.CommEventCounter) and counter == (0, 7)
        # The 0x0B request: a message (not an event), logged.
        assert inst.get_comm_event_log() == bb.CommEventLog(0, 7, 10, b"\x40\x80\x20")
        inst.write_file_record([(2, 10, [1, 2, 3])])
        inst.write_file_record([(2, 13, [4])])  # paced as the instrument's other writes
        assert inst.read_file_record([(2, 10, 4), (1, 0, 1)]) == [[1, 2, 3, 4], [0]]
        assert inst.read_fifo_queue(0x20) == [10, 20, 30]
        writes = [t for t, f in zip(sim.request_times, sim.requests) if f[1] == 0x15]
        assert len(writes) == 2 and writes[1] - writes[0] >= 0.1
        with pytest.raises(ValueError, match="record"):
            inst.read_file_record([(2, 0x270F, 2)])
        assert [f[1] for f in sim.requests] == [0x0B, 0x0C, 0x15, 0x15, 0x14, 0x18]
