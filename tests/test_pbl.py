"""benchbus.PblDrive through the real serial path against the simulated PBL drive."""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Iterator

import pytest

import benchbus as bb
from benchbus.sim import PblDevice, Simulator
from conftest import FakeClock

Rig = tuple[bb.PblDrive, Simulator[PblDevice], PblDevice]


def h(text: str) -> bytes:
    return bytes.fromhex(text)


@contextlib.contextmanager
def open_pbl(unit: int = 0x11, **options: object) -> Iterator[Rig]:
    """A simulated PBL drive at ``unit`` and a PblDrive on its line."""
    device = PblDevice(**options)  # type: ignore[arg-type]
    with Simulator({unit: device}) as sim, bb.PblDrive(sim.port, unit=unit) as pbl:
        pbl.verify_identity()  # its reads out of the way of the frames a test counts
        sim.clear_log()
        yield pbl, sim, device


@pytest.fixture
def rig() -> Iterator[Rig]:
    with open_pbl() as opened:
        yield opened


def test_line_defaults_are_115200_8e1() -> None:
    with open_pbl() as (pbl, _, _):
        bus = pbl.bus
        assert (bus.baudrate, bus.parity, bus.stopbits) == (115200, "E", 1)
        assert bus.char_time == pytest.approx(11 / 115200, abs=1e-9)  # start + 8 + parity + stop
        assert bus.t3_5 == pytest.approx(0.00175)  # the fixed t3.5 above 19200 baud


# ---- the manual's three frames ------------------------------------------------------------


def test_manual_read_frame(rig: Rig) -> None:
    pbl, sim, device = rig
    for number, value in ((107, 0x006B), (108, 0x0013), (109, 0x0000)):
        device.set_param(number, value)
    assert pbl.read_parameters(0x6B, 3) == [0x006B, 0x0013, 0x0000]
    assert sim.requests[-1] == h("11 03 00 6B 00 03 76 87")
    assert sim.replies[-1] == h("11 03 06 00 6B 00 13 00 00 38 B9")


def test_manual_single_write_frame_and_its_count_reply(rig: Rig) -> None:
    pbl, sim, device = rig
    pbl.write_parameter(1, 3)  # INDEX.md: the value 3 the text names, whose CRC is 9A 9B
    assert sim.requests[-1] == h("11 06 00 01 00 03 9A 9B")
    assert sim.replies[-1] == h("11 06 00 01 00 01 1B 5A")
    assert device.peek(1) == 3
    # Only this family takes the count for an echo: a plain Bus call refuses it.
    with pytest.raises(bb.FrameError, match="echo"):
        pbl.bus.write_register(0x11, 1, 4)
    assert device.peek(1) == 4  # the drive did act; the reply is what was refused


def test_manual_multiple_write_frame(rig: Rig) -> None:
    pbl, sim, _ = rig
    pbl.bus.write_registers(0x11, 1, [0x000A, 0x0102])
    assert sim.requests[-1] == h("11 10 00 01 00 02 04 00 0A 01 02 C6 F0")
    assert sim.replies[-1] == h("11 10 00 01 00 02 12 98")


def test_a_drive_that_echoes_is_fine_too() -> None:
    with open_pbl(echo_writes=True) as (pbl, sim, _):
        pbl.speed_setpoint = 1200
        assert sim.replies[-1] == sim.requests[-1]


# ---- properties -----------------------------------------------------------------------------


def test_settings_round_trip(rig: Rig) -> None:
    pbl, _, device = rig
    cases: list[tuple[str, object, int]] = [
        ("control_mode", bb.PblControlMode.TORQUE, 100),
        ("pole_pairs", 4, 205),
        ("acceleration", 2500, 209),
        ("deceleration", 800, 210),
        ("speed_setpoint", 1800, 201),
        ("speed_source", 1, 202),
        ("direction_setting", bb.DirectionSetting.INVERTED, 203),
        ("start_stop_source", bb.StartStopSource.IO, 204),
        ("max_speed", 2800, 124),
        ("min_speed", 100, 123),
        ("decel_mode", bb.DecelMode.BRAKING, 114),
        ("analog_max_speed", 2000, 211),
    ]
    for name, value, number in cases:
        setattr(pbl, name, value)
        assert device.peek(number) == value, name
        got = getattr(pbl, name)
        assert got == value and type(got) is type(value), name
        assert pbl.read_parameter(name if name != "speed_setpoint" else 201) == value


def test_measurements_are_read_only(rig: Rig) -> None:
    pbl, sim, _ = rig
    sent = len(sim.requests)
    with pytest.raises(AttributeError):
        pbl.speed = 5  # type: ignore[misc]
    with pytest.raises(ValueError, match="read-only"):
        pbl.write_parameter("speed", 5)
    assert len(sim.requests) == sent


# ---- control, status, alarms ------------------------------------------------------------------


def test_start_ramps_and_stop() -> None:
    clock = FakeClock()
    with open_pbl(clock=clock) as (pbl, _, device):
        pbl.speed_setpoint = 3000
        pbl.acceleration = 1000
        pbl.write_parameter(0, 0x0010)  # another bit of the control word, to be kept
        pbl.start()
        assert device.peek(0) == 0x0011
        clock.now += 1.5
        assert pbl.speed == 1500
        assert pbl.status() == bb.PblStatus(True, bb.Direction.FORWARD)
        assert pbl.running
        t = pbl.telemetry()
        assert t["speed"] == 1500 and "reserved_22" not in t
        assert (pbl.current, pbl.power, pbl.bus_voltage) == (t["current"], t["power"], 48)
        assert pbl.hall_state in range(1, 7)
        assert t["current"] > 0 and t["bus_voltage"] > 0
        pbl.direction = bb.Direction.REVERSE
        assert device.peek(0) == 0x0013 and pbl.direction is bb.Direction.REVERSE
        clock.now += 10
        assert pbl.status() == bb.PblStatus(True, bb.Direction.REVERSE)
        pbl.stop()
        assert device.peek(0) == 0x0012
        clock.now += 10
        assert not pbl.running and pbl.speed == 0


def test_alarms(rig: Rig) -> None:
    pbl, _, device = rig
    assert pbl.alarm_word == 0 and pbl.alarms == frozenset()
    device.inject_alarm(0)
    device.inject_alarm(17)
    assert pbl.alarm_word == 0x0002_0001
    assert pbl.alarms == {"alarm bit 0", "alarm bit 17"}
    assert (pbl.read_parameter(4), pbl.read_parameter(5)) == (0x0001, 0x0002)
    device.clear_alarms()
    assert pbl.alarms == frozenset()


def test_parameters_in_blocks_the_manual_allows(rig: Rig) -> None:
    pbl, sim, _ = rig
    sim.clear_log()
    values = pbl.parameters()
    assert len(sim.requests) == 4  # 61 registers a reply at most (1..123 data bytes)
    assert all(r[4:6] <= b"\x00\x3d" for r in sim.requests)
    assert values["acceleration"] == 1000 and values["deceleration"] == 1000
    assert not any(name.startswith("reserved_") for name in values)
    table = bb.PblDrive.table()
    assert len(table) == 223 and table[209][1:4] == ("acceleration", "rpm/s", "W/R")
    assert set(values) == {row[1] for row in table if not row[1].startswith("reserved_")}


def test_restore_defaults_needs_a_power_cycle(rig: Rig) -> None:
    pbl, _, device = rig
    pbl.acceleration = 3000
    with pytest.warns(UserWarning, match="power"):
        pbl.restore_defaults()
    assert device.peek(214) == 1511 and device.restore_pending
    assert pbl.acceleration == 3000  # not before the power cycle
    device.power_cycle()
    assert pbl.acceleration == 1000


def test_errors_before_sending(rig: Rig) -> None:
    pbl, sim, _ = rig
    sent = len(sim.requests)
    for key, value in [(50, 1), (100, 3), (204, 3), (215, 0), ("drive_address", 256)]:
        with pytest.raises(ValueError):
            pbl.write_parameter(key, value)
    with pytest.raises(ValueError):
        pbl.read_parameter(223)
    with pytest.raises(ValueError):
        pbl.read_parameter("no_such_parameter")
    with pytest.raises(TypeError):
        pbl.read_parameter(True)  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        pbl.read_parameters(200, 30)
    with pytest.raises(ValueError):
        pbl.direction = 2  # type: ignore[assignment]
    assert len(sim.requests) == sent
    with pytest.raises(bb.ModbusException) as e:
        pbl.bus.read_holding_registers(0x11, 223, 1)
    assert e.value.code == 2


# ---- broadcast, sharing, lifecycle ------------------------------------------------------------


def test_answered_broadcast_does_not_confuse_the_next_transaction() -> None:
    one, two = PblDevice(), PblDevice()
    with Simulator({1: one, 2: two}) as sim, bb.Bus(sim.port, baudrate=115200, parity="E") as bus:
        first, second = bb.PblDrive(bus, 1), bb.PblDrive(bus, 2)
        bus.broadcast_write_register(201, 1000)
        assert one.peek(201) == two.peek(201) == 1000
        assert len(sim.replies) == 2  # both answered, as the manual says
        assert first.speed_setpoint == 1000 and second.speed_setpoint == 1000
        stats = bus.stats
        assert (stats.frame_errors, stats.crc_errors, stats.retries) == (0, 0, 0)


def test_leaving_the_block_stops_the_motor() -> None:
    device = PblDevice()
    with Simulator({0x11: device}) as sim:
        with pytest.raises(KeyboardInterrupt), bb.PblDrive(sim.port, unit=0x11) as pbl:
            pbl.speed_setpoint = 500
            pbl.start()
            assert device.peek(0) & 1
            raise KeyboardInterrupt
        assert device.peek(0) & 1 == 0
        assert pbl.bus.closed


def test_shared_bus_timeout() -> None:
    with Simulator({3: PblDevice()}) as sim, bb.Bus(sim.port, timeout=0.1, retries=0) as bus:
        pbl = bb.PblDrive(bus, 3, timeout=0.3, retries=1)
        assert pbl.unit == 3 and pbl.bus is bus
        sim.reply_delay = 0.15
        assert pbl.speed == 0  # its own timeout covers the delay
        with pytest.raises(bb.ResponseTimeout):
            bus.read_holding_registers(3, 50, 1)
        sim.reply_delay = 0
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            pbl.close()  # a shared Bus stays open
        assert not bus.closed


def test_the_simulator_and_the_table_agree_on_ranges(rig: Rig) -> None:
    """Each writable setting's range in PblDrive.table() is what the simulated drive takes."""
    pbl, _, device = rig
    for number, _, _, access, low, high in bb.PblDrive.table():
        if access != "W/R" or number < 100 or number == 214:
            continue
        device.set_param(number, int(high))  # the top of the table's range is accepted
        if high < 0xFFFF:
            with pytest.raises(ValueError):
                device.set_param(number, int(high) + 1)
        if low > 0:
            with pytest.raises(ValueError):
                device.set_param(number, int(low) - 1)
    assert pbl.read_parameter("low_duty_threshold") == 0xFFFF


def test_telemetry_is_a_dict_shown_as_a_table(rig: Rig) -> None:
    pbl, _, _ = rig
    telemetry = pbl.telemetry()
    assert isinstance(telemetry, dict) and isinstance(telemetry, bb.PblTelemetry)
    html = telemetry._repr_html_()
    assert "<td>bus_voltage</td><td>48</td><td>V</td>" in html
