"""benchbus.J2Controller through the real serial path against the simulated J2 controller."""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Iterator

import pytest

import benchbus as bb
from benchbus.sim import J2Device, Simulator
from conftest import FakeClock

Rig = tuple[bb.J2Controller, Simulator[J2Device], J2Device]

WRITE_INTERVAL = 0.150


def h(text: str) -> bytes:
    return bytes.fromhex(text)


@contextlib.contextmanager
def open_j2(unit: int = 1, **options: object) -> Iterator[Rig]:
    """A simulated J2 at ``unit`` (on a clock that stands still) and a controller on its line."""
    options.setdefault("clock", FakeClock())
    device = J2Device(**options)  # type: ignore[arg-type]
    with Simulator({unit: device}, baudrate=9600) as sim, bb.J2Controller(sim.port, unit) as j2:
        j2.verify_identity()  # its reads out of the way of the frames a test counts
        sim.clear_log()
        yield j2, sim, device


@pytest.fixture
def rig() -> Iterator[Rig]:
    with open_j2() as opened:
        yield opened


def summary(frames: list[bytes]) -> list[tuple[int, int, int]]:
    """(function, address, count or value) of each request."""
    return [(f[1], int.from_bytes(f[2:4], "big"), int.from_bytes(f[4:6], "big")) for f in frames]


def writes(sim: Simulator[J2Device]) -> list[tuple[int, int, int]]:
    return [s for s in summary(sim.requests) if s[0] in (0x06, 0x10)]


def test_line_defaults_are_9600_8n1_and_19200_on_request() -> None:
    with open_j2() as (j2, _, _):
        bus = j2.bus
        assert (bus.baudrate, bus.parity, bus.stopbits) == (9600, "N", 1)
        assert bus.char_time == pytest.approx(10 / 9600, abs=1e-9)
        assert bus.t3_5 == pytest.approx(3.5 * 10 / 9600)
    with Simulator({1: J2Device()}) as sim, bb.J2Controller(sim.port, baudrate=19200) as j2:
        assert j2.bus.baudrate == 19200
    with pytest.raises(ValueError, match="9600 or 19200"):
        bb.J2Controller("/dev/null", baudrate=38400)


# ---- the manual's three frames ------------------------------------------------------------


def test_manual_read_frame(rig: Rig) -> None:
    j2, sim, device = rig
    device.set_value("SV", 100.0)
    assert j2.sv == 100.0
    assert sim.requests[-1] == h("01 03 00 06 00 01 64 0B")
    assert sim.replies[-1] == h("01 03 02 03 E8 B8 FA")


def test_manual_write_frames(rig: Rig) -> None:
    j2, sim, device = rig
    device.set_value("SV", 50.0)
    j2.sv = 100.0
    assert sim.requests[-1] == h("01 06 00 06 03 E8 69 75")
    assert sim.replies[-1] == h("01 06 00 06 03 E8 69 75")
    device.set_value("SV", 50.0)
    j2.write("SV", 100.0, function=0x10)
    assert sim.requests[-1] == h("01 10 00 06 00 01 02 03 E8 A6 88")
    assert sim.replies[-1] == h("01 10 00 06 00 01 E1 C8")
    assert device.value("SV") == 100.0


# ---- the manual's rules -------------------------------------------------------------------


def test_writes_are_150_ms_apart_on_the_wire() -> None:
    with open_j2() as (j2, sim, device):
        for value in (-10.0, -20.0, 30.0, 40.5):
            j2.alarm1 = value
        j2.pid = (12.5, 60.0, 15.0)
        times = [t for t, f in zip(sim.request_times, sim.requests) if f[1] in (0x06, 0x10)]
        assert len(times) == 7
        gaps = [b - a for a, b in zip(times, times[1:])]
        assert min(gaps) >= WRITE_INTERVAL, gaps
        assert device.write_violations == []
        assert device.value("AL1") == 40.5
        assert (device.value("P"), device.value("I"), device.value("D")) == (12.5, 60.0, 15.0)
        # The simulator does catch writes that come too soon (so the check above can fail).
        time.sleep(WRITE_INTERVAL + 0.05)
        j2.bus.write_register(1, 8, 1)
        with pytest.raises(bb.ModbusException) as caught:
            j2.bus.write_register(1, 8, 2)
        assert caught.value.code == 6
        assert len(device.write_violations) == 1
        assert device.value("AL1") == 0.1


def test_pacing_is_per_controller_and_other_units_are_not_held_up() -> None:
    clock = FakeClock()
    one, two = J2Device(clock=clock), J2Device(clock=clock)
    with Simulator({1: one, 2: two}, baudrate=9600) as sim, bb.Bus(sim.port, baudrate=9600) as bus:
        a, b = bb.J2Controller(bus, 1), bb.J2Controller(bus, 2)
        a.verify_identity(), b.verify_identity()
        sim.clear_log()
        burst = threading.Thread(target=lambda: a.write_many({"AL1": 1.0, "AL2": 2.0}))
        burst.start()
        deadline = time.monotonic() + 5
        while not sim.requests and time.monotonic() < deadline:
            time.sleep(0.001)
        # Unit 1's second write now waits 150 ms; unit 2 is served meanwhile.
        b.alarm1 = 3.0
        pv = b.pv
        burst.join(5)
        units = [(f[0], f[1]) for f in sim.requests]
        assert units == [(1, 6), (2, 6), (2, 3), (1, 6)]
        times = [t for t, f in zip(sim.request_times, sim.requests) if f[0] == 1]
        assert times[1] - times[0] >= WRITE_INTERVAL
        assert one.write_violations == two.write_violations == []
        assert pv == two.value("PV") and two.value("AL1") == 3.0 and one.value("AL2") == 2.0


def test_a_broadcast_counts_as_a_write_to_every_unit(rig: Rig) -> None:
    j2, sim, device = rig
    j2.alarm1 = 1.0
    j2.bus.broadcast_write_register(0x0A, 20)  # AL2 = 2.0 on every controller
    j2.alarm1 = 3.0
    times = [t for t, f in zip(sim.request_times, sim.requests) if f[1] == 6]
    assert [f[0] for f in sim.requests if f[1] == 6] == [1, 0, 1]
    assert min(b - a for a, b in zip(times, times[1:])) >= WRITE_INTERVAL
    assert device.write_violations == []
    assert (device.value("AL1"), device.value("AL2")) == (3.0, 2.0)


def test_parameters_are_read_in_blocks_of_at_most_16(rig: Rig) -> None:
    j2, sim, device = rig
    device.set_value("AL2", -12.5)
    device.set_value("FST", 80)
    sim.clear_log()
    values = j2.parameters()
    assert summary(sim.requests) == [
        (3, 0, 15),
        (3, 16, 15),
        (3, 32, 15),
        (3, 48, 15),
        (3, 128, 15),
        (3, 144, 13),
    ]
    names = [row[0] for row in bb.J2Controller.table()]
    assert list(values) == names and len(names) == 43
    for name in names:
        assert values[name] == device.value(name), name
    assert values["AL2"] == -12.5 and values["FST"] == 80 and isinstance(values["FST"], int)


def test_mv_needs_manual_mode(rig: Rig) -> None:
    j2, sim, device = rig
    assert j2.mode == bb.J2Mode.AUTO
    sim.clear_log()
    with pytest.raises(bb.StateError, match="manual mode") as caught:
        j2.mv = 30.0
    assert caught.value.unit == 1
    with pytest.raises(bb.StateError):
        j2.set_output(30.0)
    assert writes(sim) == []
    j2.set_output(30.0, switch_to_manual=True)
    assert writes(sim) == [(6, 0x80, 0), (6, 0, 300)]
    assert j2.mode == bb.J2Mode.MANUAL and j2.mv == 30.0 == device.value("MV")
    j2.mv = 12.5  # in manual mode, written at once
    assert j2.mv == 12.5


def test_rapnf_is_written_0_before_ramp_parameters(rig: Rig) -> None:
    j2, sim, device = rig
    j2.start_ramp()
    assert j2.ramp_running and device.value("RAPNF") == 1
    sim.clear_log()
    j2.write("RAP", 5.0)
    j2.write("RTM", 30.0)
    assert writes(sim) == [(6, 0x82, 0), (6, 0x26, 50), (6, 0x82, 0), (6, 0x28, 300)]
    assert not j2.ramp_running
    assert (device.value("RAP"), device.value("RTM")) == (5.0, 30.0)


def test_values_within_lsp_usp_follow_the_controllers_limits(rig: Rig) -> None:
    j2, sim, device = rig
    j2.limits = (-20.0, 150.0)
    assert j2.limits == bb.Limits(-20.0, 150.0)
    assert (device.value("LSP"), device.value("USP")) == (-20.0, 150.0)
    sim.clear_log()
    with pytest.raises(
        ValueError, match=r"SV must be within the setpoint limits LSP to USP, -20 to 150"
    ):
        j2.sv = 151.0
    with pytest.raises(ValueError, match="USP must stay >= LSP"):
        j2.write("USP", -30.0)
    assert writes(sim) == []
    j2.sv = -20.0
    assert device.value("SV") == -20.0
    # Raised past the old USP: USP goes first, so LSP never exceeds it on the way.
    sim.clear_log()
    j2.limits = (200.0, 400.0)
    assert writes(sim) == [(6, 0x16, 4000), (6, 0x14, 2000)]


def test_negative_values_round_trip_exactly(rig: Rig) -> None:
    j2, sim, device = rig
    j2.alarm1 = -50.0
    assert sim.requests[-1][:6] == h("01 06 00 08 FE 0C")
    j2.pv_offset = -5.0
    assert sim.requests[-1][:6] == h("01 06 00 34 FF CE")
    j2.write("GAP", -0.3)
    assert (j2.alarm1, j2.pv_offset, j2.read("GAP")) == (-50.0, -5.0, -0.3)
    assert (device.value("AL1"), device.value("PVOS")) == (-50.0, -5.0)


# ---- properties ---------------------------------------------------------------------------


def test_every_property_round_trips(rig: Rig) -> None:
    j2, _, device = rig
    j2.alarm2 = 250.5
    j2.pid = (30.5, 120.0, 0.0)
    j2.pid2 = bb.Pid(10.0, 0.0, 5.5)
    j2.mode = bb.J2Mode.MANUAL
    j2.input_type = bb.InputType.PT
    j2.decimal_point = 0
    j2.autotune = True
    assert j2.alarm2 == 250.5 == device.value("AL2")
    assert j2.pid == bb.Pid(30.5, 120.0, 0.0)
    assert j2.pid2 == (10.0, 0.0, 5.5)
    assert (device.value("P1"), device.value("I1"), device.value("D1")) == (10.0, 0.0, 5.5)
    assert j2.mode is bb.J2Mode.MANUAL and device.value("AM") == 0
    assert j2.input_type is bb.InputType.PT and device.value("INP") == 7
    assert j2.decimal_point == 0 and device.value("DP") == 0
    assert j2.autotune is True and device.value("AT") == 1
    j2.autotune = False
    assert j2.autotune is False
    j2.start_ramp()
    assert j2.ramp_running is True
    j2.stop_ramp()
    assert j2.ramp_running is False
    assert j2.read("cyt") == device.value("CYT")  # names in any case
    j2.write_many({"OUL": 5.0, "OUH": 95.0})
    assert j2.read_many(["OUH", "OUL"]) == [95.0, 5.0]
    j2.write_many([("OUL", 0.0)])
    assert j2.read_many(["OUL", "AM"]) == [0.0, 0]


def test_pv_is_measured_and_follows_the_process() -> None:
    clock = FakeClock()
    with open_j2(clock=clock, speedup=1.0) as (j2, _, device):
        start = j2.pv
        assert start == device.value("PV")
        with pytest.raises(AttributeError, match="cannot be set"):
            j2.pv = 1.0  # type: ignore[misc]
        with pytest.raises(ValueError, match="read-only"):
            j2.write("PV", 1.0)
        j2.sv = 100.0
        clock.now += 1200  # twenty minutes under the controller's own PID
        assert abs(j2.pv - 100.0) < abs(start - 100.0) / 4
        assert 0.0 <= j2.mv <= 100.0


def test_units_up_to_255() -> None:
    with open_j2(unit=255) as (j2, sim, _):
        assert j2.unit == 255
        j2.alarm1 = 1.0
        assert sim.requests[-1][0] == 255
    with Simulator({1: J2Device()}) as sim, bb.Bus(sim.port) as bus:
        for bad in (0, 256, -1):
            with pytest.raises(ValueError, match=r"1 to 255"):
                bb.J2Controller(bus, bad)


# ---- errors -------------------------------------------------------------------------------


def test_bad_input_is_refused_before_anything_is_sent(rig: Rig) -> None:
    j2, sim, _ = rig
    sim.clear_log()
    bad: list[tuple[type[Exception], object]] = [
        (ValueError, lambda: j2.read("XYZ")),
        (TypeError, lambda: j2.read(6)),  # type: ignore[arg-type]
        (ValueError, lambda: j2.write("AL1", 5000.0)),  # the manual's range, cut to 3276.7
        (ValueError, lambda: j2.write("AL1", -2000.0)),
        (ValueError, lambda: j2.write("P", 0.0)),
        (ValueError, lambda: j2.write("FST", 19)),
        (ValueError, lambda: j2.write("DIE", 0.45)),  # not a whole number of tenths
        (ValueError, lambda: j2.write("AL1", float("nan"))),
        (ValueError, lambda: j2.write("AL1", float("inf"))),
        (ValueError, lambda: j2.write("SV", 1.0, function=3)),
        (TypeError, lambda: j2.write("AL1", "1")),  # type: ignore[arg-type]
        (TypeError, lambda: j2.write("AL1", True)),
        (ValueError, lambda: j2.set_output(100.5)),
        (ValueError, lambda: j2.write_many({"OUL": 1.0, "OUH": 101.0})),  # none written
        (ValueError, lambda: setattr(j2, "pid", (1.0, 2.0))),
        (ValueError, lambda: setattr(j2, "limits", (10.0, 5.0))),
        (ValueError, lambda: setattr(j2, "limits", (1.0, 2.0, 3.0))),
        (TypeError, lambda: setattr(j2, "autotune", "yes")),
        (ValueError, lambda: setattr(j2, "autotune", 2)),
        (TypeError, lambda: j2.read_many("SV")),
        (TypeError, lambda: j2.write("SV", 1.0, function=6.0)),  # type: ignore[arg-type]
        (TypeError, lambda: setattr(j2, "mode", None)),
        (ValueError, lambda: setattr(j2, "input_type", 10)),
    ]
    for error, call in bad:
        with pytest.raises(error):
            call()  # type: ignore[operator]
    assert sim.requests == []
    with pytest.raises(ValueError, match=r"holds -3276\.8 to 3276\.7"):
        j2.alarm1 = 5000.0


def test_device_errors_raise_the_right_class(rig: Rig) -> None:
    j2, sim, _ = rig
    sim.answer_exception(4)
    with pytest.raises(bb.ModbusException) as caught:
        _ = j2.sv
    assert (caught.value.code, caught.value.unit, caught.value.function) == (4, 1, 3)
    sim.set_silent(1)
    with pytest.raises(bb.ResponseTimeout):
        _ = j2.pv
    sim.set_silent(1, False)
    sim.corrupt_next(3)  # every attempt (the Bus retries twice)
    with pytest.raises(bb.CrcError):
        _ = j2.pv
    # A read of more than 16 registers is refused by the unit itself.
    with pytest.raises(bb.ModbusException) as too_many:
        j2.bus.read_holding_registers(1, 0, 17)
    assert too_many.value.code == 3


def test_the_library_and_the_simulator_share_one_table() -> None:
    """The simulator's table is written apart from the library's; they must agree."""
    table = bb.J2Controller.table()
    assert [row[0] for row in table] == list(J2Device.PARAMETERS)
    for name, address, signed, writable, low, high, within_limits in table:
        assert J2Device.PARAMETERS[name] == (address, low, high, 10 if signed else 1), name
        assert writable == (name not in J2Device.READ_ONLY), name
        # The library holds only SV to LSP..USP; the simulator, as the manual reads, all of
        # these (the controller judges the others: see docs/devices/j2.md).
        assert within_limits == (name == "SV"), name
        assert name in J2Device.BETWEEN_LSP_USP or not within_limits, name


def test_hysteresis_is_left_to_the_controller(rig: Rig) -> None:
    """HY1 is "LSP~USP" in the manual; the library checks only the widest range."""
    j2, sim, _ = rig
    j2.limits = (100.0, 400.0)
    with pytest.raises(bb.ModbusException) as caught:
        j2.write("HY1", 1.0)  # the simulated controller reads the manual literally
    assert caught.value.code == 3
    assert writes(sim)[-1] == (6, 0x18, 10)
    with pytest.raises(ValueError):
        j2.write("HY1", -2000.0)  # out of the widest range: nothing sent


def test_port_errors() -> None:
    with pytest.raises(bb.PortError):
        bb.J2Controller("/dev/benchbus-no-such-port")
    with open_j2() as (j2, _, _):
        j2.close()
        with pytest.raises(bb.PortError, match="closed"):
            _ = j2.sv


def test_status_in_two_requests_and_as_a_table(rig: Rig) -> None:
    j2, sim, device = rig
    device.set_value("AL1", -5.0)
    sim.clear_log()
    status = j2.status()
    assert len(sim.requests) == 2
    assert (status.pv, status.sv, status.alarm1) == (device.value("PV"), 100.0, -5.0)
    assert status.mode is bb.J2Mode.AUTO and not status.autotune and not status.ramp_running
    html = status._repr_html_()
    assert "<td>alarm1</td><td>-5.0</td>" in html and "J2Mode.AUTO" in html
