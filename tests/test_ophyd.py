"""benchbus.ophyd: devices described by the example profiles and the built-in drive as
ophyd-async devices, each against its simulator: the signals' kinds, datatypes, units and
limits, Bluesky's RunEngine running count and mv plans whose documents hold what the
simulator holds, values refused before anything is sent, the drive as a motor on its speed
(ramping in the simulator, stopped by stop()), and the event loop left free while the line
is busy. (Python 3.11 and later: ophyd-async needs it; conftest.py leaves this file out
before.)"""

from __future__ import annotations

import asyncio
import math
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import bluesky.plan_stubs as bps
import pytest
from bluesky import RunEngine
from bluesky.plans import count
from bluesky.utils import FailedStatus
from ophyd_async.core import SignalR, SignalRW, SignalW, SubsetEnum

import benchbus as bb
from benchbus.ophyd import DriveDevice, RegisterDevice, datatype, device
from benchbus.sim import DriveDevice as SimDrive
from benchbus.sim import J2Device, PblDevice, ProfileDevice, Simulator

PROFILES = Path(__file__).resolve().parent.parent / "examples" / "profiles"
SENSOR = PROFILES / "xy_md02.toml"
RELAYS = PROFILES / "relay_board.toml"
CONTROLLER = PROFILES / "flow_controller.toml"

Docs = list[tuple[str, dict[str, Any]]]


@pytest.fixture
def RE() -> Iterator[RunEngine]:  # noqa: N802 (Bluesky's name for it)
    engine = RunEngine(call_returns_result=True)
    yield engine
    engine.loop.call_soon_threadsafe(engine.loop.stop)
    engine._th.join(timeout=5)  # the thread the RunEngine runs its loop in
    engine.loop.close()


def run(engine: RunEngine, plan: Any) -> Docs:
    """Run ``plan``, returning the documents it emitted."""
    docs: Docs = []
    engine(plan, lambda name, doc: docs.append((name, doc)))
    return docs


def on_loop(engine: RunEngine, coro: Any) -> Any:
    """Run ``coro`` on the RunEngine's event loop (where the devices live)."""
    return asyncio.run_coroutine_threadsafe(coro, engine.loop).result(timeout=30)


async def settle(signal: Any, value: Any) -> None:
    """``signal.set(value)``, called and awaited on the loop this runs on."""
    await signal.set(value)


@pytest.fixture
def controller() -> Iterator[tuple[Simulator[ProfileDevice], RegisterDevice, ProfileDevice]]:
    model = ProfileDevice(CONTROLLER, values={"setpoint": 75.5, "mode": "purge"})
    with Simulator({1: model}) as sim, bb.Bus(sim.port, timeout=0.5) as bus:
        yield sim, device(bb.Device.from_profile(CONTROLLER, bus), "fc"), model
        assert sim.errors == []


# ---- one signal per register, as the profile describes it -----------------------------------


def test_a_shipped_profile_by_name_counts(RE: RunEngine) -> None:  # noqa: N803
    model = ProfileDevice("xy-md02", values={"temperature": -3.5, "humidity": 40.2})
    with Simulator({1: model}) as sim, bb.Bus(sim.port, timeout=0.5) as bus:
        dev = device(bb.Device.from_profile("xy-md02", bus), "th")
        docs = run(RE, count([dev], num=1))
        event = docs[2][1]["data"]
        assert event["th-temperature"] == pytest.approx(-3.5)
        assert event["th-humidity"] == pytest.approx(40.2)
        assert docs[1][1]["data_keys"]["th-temperature"]["units"] == "degC"
        assert sim.errors == []


@pytest.mark.parametrize("path", [SENSOR, RELAYS, CONTROLLER], ids=lambda p: p.stem)
def test_every_register_is_a_signal_of_its_access_with_its_unit(
    RE: RunEngine,  # noqa: N803
    path: Path,
) -> None:
    profile = bb.Profile(path)
    with Simulator({1: ProfileDevice(path)}) as sim, bb.Bus(sim.port) as bus:
        dev = device(bb.Device.from_profile(path, bus), "dev")
        assert type(dev) is RegisterDevice
        assert list(dev.registers) == [r.name for r in profile.registers]
        for register in profile.registers:
            signal = dev.registers[register.name]
            assert getattr(dev, register.name) is signal
            assert signal.name == f"dev-{register.name}"
            assert isinstance(signal, SignalR) is (register.access != "w")
            assert isinstance(signal, SignalW) is (register.access != "r")
            assert signal.source == f"benchbus://{sim.port}/1/{register.name}"
            if register.access == "w":
                continue
            key = on_loop(RE, signal.describe())[signal.name]  # type: ignore[union-attr]
            assert key.get("units") == (register.unit or None)
            assert key["shape"] == []
            if register.access == "rw" and register.type not in ("bool", "string"):
                if not register.enum:
                    limits = {"low": register.min, "high": register.max}
                    assert key["limits"] == {"control": limits}
            else:
                assert "limits" not in key
        # Read-only registers go in events, read-and-write ones in the configuration.
        described = on_loop(RE, dev.describe())
        assert list(described) == [f"dev-{r.name}" for r in profile.registers if r.access == "r"]
        configured = on_loop(RE, dev.describe_configuration())
        assert list(configured) == [f"dev-{r.name}" for r in profile.registers if r.access == "rw"]


def test_datatypes_follow_the_register_types(
    controller: tuple[Simulator[ProfileDevice], RegisterDevice, ProfileDevice],
) -> None:
    _, dev, _ = controller
    kinds = {name: signal.datatype for name, signal in dev.registers.items()}
    assert kinds["setpoint"] is float  # f32
    assert kinds["total"] is float  # a scaled u32
    assert kinds["runtime"] is int  # u64
    assert kinds["zero_offset"] is int  # i64
    assert kinds["device_name"] is str
    mode = kinds["mode"]
    assert isinstance(mode, type) and issubclass(mode, SubsetEnum)
    assert [m.value for m in mode] == ["off", "control", "purge", "close"]
    assert [m.name for m in mode] == ["OFF", "CONTROL", "PURGE", "CLOSE"]


def test_enum_member_names_become_upper_case_python_names() -> None:
    text = (
        '[device]\nname = "x"\n[[register]]\nname = "line_speed"\naddress = 0\n'
        'access = "rw"\nenum = { 0 = "_9600", 1 = "on_off", 2 = "On_Off", 3 = "b9600" }\n'
    )
    (register,) = bb.Profile.parse(text).registers
    kind = datatype(register)
    assert kind.__name__ == "LineSpeed"
    assert {m.name: m.value for m in kind} == {
        "V__9600": "_9600",
        "ON_OFF": "on_off",
        "ON_OFF_": "On_Off",
        "B9600": "b9600",
    }


# ---- Bluesky plans ------------------------------------------------------------------------------


def test_count_documents_hold_what_the_simulator_holds(
    RE: RunEngine,  # noqa: N803
    controller: tuple[Simulator[ProfileDevice], RegisterDevice, ProfileDevice],
) -> None:
    _, dev, model = controller
    docs = run(RE, count([dev], num=3))
    names = [name for name, _ in docs]
    assert names == ["start", "descriptor", "event", "event", "event", "stop"]
    descriptor = docs[1][1]
    keys = descriptor["data_keys"]
    assert set(keys) == {"fc-flow", "fc-total", "fc-gas_temperature", "fc-runtime"}
    assert keys["fc-flow"]["units"] == "sccm"
    assert keys["fc-flow"]["dtype"] == "number"
    assert keys["fc-flow"]["shape"] == []
    assert keys["fc-total"]["units"] == "scc"
    assert keys["fc-total"]["precision"] == 2  # scale 0.01
    assert keys["fc-runtime"]["dtype"] == "integer"
    assert keys["fc-gas_temperature"]["units"] == "degC"
    config = descriptor["configuration"]["fc"]
    assert config["data"]["fc-setpoint"] == pytest.approx(75.5)
    assert config["data"]["fc-mode"] == "purge"
    assert config["data"]["fc-zero_offset"] == model.value("zero_offset") == -42
    assert config["data"]["fc-device_name"] == model.value("device_name")
    assert config["data_keys"]["fc-mode"]["choices"] == ["off", "control", "purge", "close"]
    assert config["data_keys"]["fc-mode"]["dtype"] == "string"
    assert config["data_keys"]["fc-setpoint"]["limits"] == {"control": {"low": 0.0, "high": 200.0}}
    for _, event in docs[2:5]:
        for name in ("flow", "total", "gas_temperature", "runtime"):
            held = model.value(name)
            assert isinstance(held, (int, float))
            assert math.isclose(event["data"][f"fc-{name}"], held, rel_tol=1e-6)
    assert docs[-1][1]["exit_status"] == "success"


def test_count_follows_the_simulator_between_events(RE: RunEngine) -> None:  # noqa: N803
    model = ProfileDevice(SENSOR, values={"temperature": -12.3})
    seen: list[float] = []

    def warm(name: str, doc: dict[str, Any]) -> None:
        if name == "event":
            seen.append(doc["data"]["sensor-temperature"])
            model.set_value("temperature", round(seen[-1] + 1.5, 1))

    with Simulator({1: model}) as sim, bb.Bus(sim.port) as bus:
        sensor = device(bb.Device.from_profile(SENSOR, bus), "sensor")
        RE(count([sensor], num=3), warm)
    assert seen == pytest.approx([-12.3, -10.8, -9.3])


def test_mv_writes_a_register_and_an_enum_by_name(
    RE: RunEngine,  # noqa: N803
    controller: tuple[Simulator[ProfileDevice], RegisterDevice, ProfileDevice],
) -> None:
    _, dev, model = controller
    RE(bps.mv(dev.setpoint, 120.25, dev.mode, "close", dev.zero_offset, 7))  # type: ignore[attr-defined]
    assert model.value("setpoint") == 120.25
    assert model.value("mode") == "close"
    assert model.value("zero_offset") == 7
    mode = on_loop(RE, dev.mode.get_value())  # type: ignore[attr-defined]
    assert mode == "close" and mode.name == "CLOSE"
    located = on_loop(RE, dev.setpoint.locate())  # type: ignore[attr-defined]
    assert located == {"setpoint": 120.25, "readback": 120.25}
    RE(bps.mv(dev.reset_total, 1))  # type: ignore[attr-defined]
    assert model.value("reset_total") == 1  # a write-only register: a SignalW


def test_an_enum_number_the_profile_does_not_list_reads_as_unknown(
    RE: RunEngine,  # noqa: N803
    controller: tuple[Simulator[ProfileDevice], RegisterDevice, ProfileDevice],
) -> None:
    _, dev, model = controller
    model.registers[0x0010] = 7  # mode: not a member
    value = on_loop(RE, dev.mode.get_value())  # type: ignore[attr-defined]
    assert value == "UNKNOWN(7)" and type(value) is str
    docs = run(RE, count([dev], num=1))
    config = next(doc for name, doc in docs if name == "descriptor")["configuration"]["fc"]
    assert config["data"]["fc-mode"] == "UNKNOWN(7)"


def test_a_bool_register(RE: RunEngine) -> None:  # noqa: N803
    model = ProfileDevice(RELAYS)
    with Simulator({1: model}) as sim, bb.Bus(sim.port) as bus:
        board = device(bb.Device.from_profile(RELAYS, bus), "board")
        RE(bps.mv(board.relay3, True))  # type: ignore[attr-defined]
        assert model.value("relay3") is True
        assert on_loop(RE, board.relay3.get_value()) is True  # type: ignore[attr-defined]
        key = on_loop(RE, board.relay3.describe())["board-relay3"]  # type: ignore[attr-defined]
        assert key["dtype"] == "boolean"
        sent = sim.request_count
        with pytest.raises(TypeError, match="bool"):
            on_loop(RE, settle(board.relay3, 1))  # type: ignore[attr-defined]
        assert sim.request_count == sent


@pytest.mark.parametrize(
    ("register", "value", "error", "match"),
    [
        ("setpoint", 200.5, ValueError, "0 to 200"),
        ("setpoint", "10", TypeError, "number"),
        ("setpoint", math.nan, ValueError, "finite"),
        ("zero_offset", 1.5, ValueError, "whole"),
        ("mode", "heat", ValueError, "off, control, purge, close"),
        ("mode", 1, TypeError, "name"),
        ("device_name", "x" * 17, ValueError, "16 characters"),
    ],
)
def test_bad_values_are_refused_before_anything_is_sent(
    RE: RunEngine,  # noqa: N803
    controller: tuple[Simulator[ProfileDevice], RegisterDevice, ProfileDevice],
    register: str,
    value: Any,
    error: type[Exception],
    match: str,
) -> None:
    sim, dev, _ = controller
    sent = sim.request_count
    with pytest.raises(error, match=match):
        on_loop(RE, settle(dev.registers[register], value))
    with pytest.raises(FailedStatus) as failed:
        RE(bps.mv(dev.registers[register], value))
    assert isinstance(failed.value.__cause__, error)
    assert match in str(failed.value.__cause__)
    assert sim.request_count == sent


def test_read_only_registers_refuse_set(
    RE: RunEngine,  # noqa: N803
    controller: tuple[Simulator[ProfileDevice], RegisterDevice, ProfileDevice],
) -> None:
    sim, dev, model = controller
    flow = dev.registers["flow"]
    assert isinstance(flow, SignalR) and not isinstance(flow, (SignalW, SignalRW))
    assert not hasattr(flow, "set")
    sent = sim.request_count
    with pytest.raises(ValueError, match="read-only"):
        on_loop(RE, dev.backends["flow"].put(1.0))
    with pytest.raises(AssertionError, match="does not implement all Movable methods"):
        RE(bps.mv(flow, 1.0))
    assert sim.request_count == sent
    assert model.value("flow") == 49.75


def test_a_name_bluesky_or_the_device_uses_gets_an_underscore(
    RE: RunEngine,  # noqa: N803
    tmp_path: Path,
) -> None:
    names = ["stage", "trigger", "log", "backends", "parent"]
    text = '[device]\nname = "x"\n' + "".join(
        f'[[register]]\nname = "{name}"\naddress = {n}\naccess = "rw"\n'
        for n, name in enumerate(names)
    )
    path = tmp_path / "x.toml"
    path.write_text(text)
    profile = bb.Profile(path)
    model = ProfileDevice(path, values={name: n + 10 for n, name in enumerate(names)})
    with Simulator({1: model}) as sim, bb.Bus(sim.port) as bus:
        dev = device(bb.Device.from_profile(profile, bus), "x")
        for n, name in enumerate(names):
            signal = getattr(dev, f"{name}_")
            assert signal is dev.registers[name]
            assert signal.name == f"x-{name}_"
            assert on_loop(RE, signal.get_value()) == n + 10
        assert isinstance(dev.backends, dict)  # the device's own attributes stay
        assert dev.parent is None
        docs = run(RE, count([dev], num=1))
        config = next(doc for name, doc in docs if name == "descriptor")["configuration"]["x"]
        assert config["data"]["x-stage_"] == 10


# ---- the drive: a motor on its speed -------------------------------------------------------------


@pytest.fixture
def spindle() -> Iterator[tuple[SimDrive, DriveDevice, bb.Drive]]:
    model = SimDrive(single_register_reads=False)
    with Simulator(model) as sim, bb.Drive(sim.port) as drive:
        drive.accel_time = 0.5  # 3000 rpm per 0.5 s: 1500 rpm in 0.25 s
        drive.decel_time = 0.5
        made = device(drive, "spindle", tolerance=20, poll_period=0.02)
        assert isinstance(made, DriveDevice)
        yield model, made, drive
        assert sim.errors == []


def test_mv_on_the_drive_waits_for_the_measured_speed(
    RE: RunEngine,  # noqa: N803
    spindle: tuple[SimDrive, DriveDevice, bb.Drive],
) -> None:
    model, motor, _ = spindle
    seen: list[float] = []

    def watch(status: Any) -> None:
        status.watch(lambda current, **_: seen.append(current))

    start = time.monotonic()
    status = on_loop(RE, _started(motor, 1500))
    watch(status)
    on_loop(RE, finish(status))
    took = time.monotonic() - start
    assert status.success
    assert abs(model.speed - 1500) <= 20 + 1  # within the tolerance when set() finished
    assert took >= 0.2  # it waited out the ramp (1480 rpm take 0.247 s)
    assert model.peek(0x2001) == 1500
    assert model.commands == [1]  # started forward
    assert any(0 < s < 1480 for s in seen), seen  # watchers saw it ramp
    # Running: a new speed does not send forward again, and mv waits for it too; the
    # RunEngine stops what a plan moved when the plan ends.
    during: list[tuple[float, list[int]]] = []

    def plan() -> Any:
        yield from bps.mv(motor, 600)
        during.append((model.speed, model.commands))

    RE(plan())
    ((speed, commands),) = during
    assert abs(speed - 600) <= 21
    assert commands == [1]
    assert model.commands == [1, 5]  # stopped at the end of the plan
    located = on_loop(RE, motor.speed_setpoint.locate())  # type: ignore[attr-defined]
    assert located["setpoint"] == 600


async def finish(status: Any) -> None:
    """Wait for ``status`` on its loop (10 s at most)."""
    await asyncio.wait_for(status, 10)


async def _started(motor: DriveDevice, rpm: float, **kwargs: Any) -> Any:
    """``motor.set(rpm)`` started on the loop (its status, not awaited)."""
    return motor.set(rpm, **kwargs)


def test_stop_stops_the_motor_and_ends_the_move(
    RE: RunEngine,  # noqa: N803
    spindle: tuple[SimDrive, DriveDevice, bb.Drive],
) -> None:
    model, motor, drive = spindle
    drive.accel_time = 30.0  # 100 rpm/s: far from 3000 rpm for a while
    status = on_loop(RE, _started(motor, 3000))
    time.sleep(0.3)
    assert not status.done
    on_loop(RE, motor.stop(success=False))
    with pytest.raises(RuntimeError, match="spindle was stopped"):
        on_loop(RE, finish(status))
    assert model.commands == [1, 5]  # forward, then stop
    # stop as a plan step (success=True) ends a move as done.
    status = on_loop(RE, _started(motor, 3000))
    time.sleep(0.2)
    RE(bps.stop(motor))
    on_loop(RE, finish(status))
    assert status.success
    assert model.commands[-1] == 5


def test_a_move_that_does_not_arrive_times_out(
    RE: RunEngine,  # noqa: N803
    spindle: tuple[SimDrive, DriveDevice, bb.Drive],
) -> None:
    model, motor, drive = spindle
    drive.accel_time = 60.0  # 50 rpm/s
    status = on_loop(RE, _started(motor, 3000, timeout=0.3))
    with pytest.raises(TimeoutError, match="not within 20 rpm of 3000 rpm"):
        on_loop(RE, finish(status))
    assert 0 < model.speed < 100


def test_drive_speed_out_of_range_is_refused_before_anything_is_sent(
    RE: RunEngine,  # noqa: N803
    spindle: tuple[SimDrive, DriveDevice, bb.Drive],
) -> None:
    model, motor, _ = spindle
    with pytest.raises(FailedStatus) as failed:
        RE(bps.mv(motor, 3500))
    assert isinstance(failed.value.__cause__, ValueError)
    assert "speed_setpoint must be 0 to 3000, got 3500" in str(failed.value.__cause__)
    assert 1 not in model.commands  # never started (the RunEngine stops what failed: 5)
    assert model.peek(0x2001) != 3500


def test_drive_registers_and_count(RE: RunEngine, spindle: Any) -> None:  # noqa: N803
    model, motor, _ = spindle
    docs = run(RE, count([motor], num=1))
    event = next(doc for name, doc in docs if name == "event")
    assert event["data"]["spindle-speed"] == 0
    assert event["data"]["spindle-state"] == 3  # stopped
    assert event["data"]["spindle-bus_voltage"] == pytest.approx(model.peek(0x3008) / 10)
    keys = next(doc for name, doc in docs if name == "descriptor")["data_keys"]
    assert keys["spindle-speed"]["units"] == "rpm"
    assert keys["spindle-speed"]["dtype"] == "integer"
    assert keys["spindle-bus_voltage"]["units"] == "V"


def test_a_pbl_drive_is_a_motor_on_its_internal_speed(RE: RunEngine) -> None:  # noqa: N803
    model = PblDevice()
    with Simulator({0x11: model}) as sim, bb.PblDrive(sim.port, 0x11) as pbl:
        pbl.start_stop_source = bb.StartStopSource.COMMUNICATION
        pbl.set("acceleration", 6000)  # rpm/s: 1500 rpm in 0.25 s
        motor = device(pbl, "pbl", tolerance=20, poll_period=0.02)
        assert isinstance(motor, DriveDevice)
        assert motor.control.setpoint == "internal_speed"
        during: list[tuple[float, bool]] = []

        def plan() -> Any:
            yield from bps.mv(motor, 1500)
            during.append((model.speed, model.running))

        start = time.monotonic()
        RE(plan())
        ((speed, running),) = during
        assert time.monotonic() - start >= 0.2  # it waited out the ramp
        assert abs(speed - 1500) <= 21 and running
        assert model.peek(201) == 1500
        assert model.peek(0) & 1 == 0  # the RunEngine's stop cleared the start bit
        assert sim.errors == []


def test_j2_is_wrapped_with_its_units_and_no_motor(RE: RunEngine) -> None:  # noqa: N803
    model = J2Device(clock=lambda: 0.0)
    with Simulator({3: model}) as sim, bb.J2Controller(sim.port, 3) as j2:
        dev = device(j2, "oven")
        assert type(dev) is RegisterDevice
        RE(bps.mv(dev.SV, 120.5))  # type: ignore[attr-defined]
        assert j2.get("SV") == 120.5
        docs = run(RE, count([dev], num=1))
        descriptor = next(doc for name, doc in docs if name == "descriptor")
        assert descriptor["data_keys"]["oven-PV"]["units"] == "°C"
        assert descriptor["data_keys"]["oven-PV"]["precision"] == 1
        event = next(doc for name, doc in docs if name == "event")
        assert event["data"]["oven-PV"] == j2.get("PV")
        assert descriptor["configuration"]["oven"]["data"]["oven-SV"] == 120.5
        assert sim.errors == []


def test_a_watched_signal_is_polled_and_survives_a_silent_unit(
    RE: RunEngine,  # noqa: N803
    caplog: pytest.LogCaptureFixture,
) -> None:
    model = ProfileDevice(SENSOR, values={"temperature": 20.0})
    with Simulator({1: model}) as sim, bb.Bus(sim.port, timeout=0.05, retries=0) as bus:
        sensor = device(bb.Device.from_profile(SENSOR, bus), "s", poll_period=0.02)

        async def watch() -> list[float]:
            seen: list[float] = []
            signal = sensor.temperature  # type: ignore[attr-defined]

            def note(readings: dict[str, Any]) -> None:
                seen.append(readings["s-temperature"]["value"])

            signal.subscribe_reading(note)
            await asyncio.sleep(0.1)
            model.set_value("temperature", 21.5)
            await asyncio.sleep(0.1)
            sim.set_silent(1)
            await asyncio.sleep(0.3)
            model.set_value("temperature", 23.0)
            sim.set_silent(1, False)
            await asyncio.sleep(0.2)
            signal.clear_sub(note)
            return seen

        seen = on_loop(RE, watch())
    assert seen == [20.0, 21.5, 23.0]  # each new value once, and on after the silence
    warnings = [r for r in caplog.records if r.name == "benchbus.ophyd"]
    assert len(warnings) == 1  # once for the whole silence
    assert "polling goes on" in warnings[0].getMessage()


# ---- the event loop stays free ------------------------------------------------------------------


def test_reads_leave_the_event_loop_free(RE: RunEngine) -> None:  # noqa: N803
    model = SimDrive(single_register_reads=False)
    model.set_param(0x0803, 200)  # F08.03: every reply 200 ms late
    with Simulator(model) as sim, bb.Drive(sim.port, timeout=1.0) as drive:
        motor = device(drive, "slow")

        async def ticks_during_a_read() -> tuple[int, int, str]:
            ticks = 0

            async def ticker() -> None:
                nonlocal ticks
                while True:
                    await asyncio.sleep(0.01)
                    ticks += 1

            task = asyncio.get_running_loop().create_task(ticker())
            speed = await motor.speed.get_value()  # type: ignore[attr-defined]
            task.cancel()
            return ticks, speed, threading.current_thread().name

        ticks, speed, _ = on_loop(RE, ticks_during_a_read())
    assert speed == 0
    assert ticks >= 10  # the loop ran on while the reply took 200 ms


def test_a_cancelled_read_sends_no_retry() -> None:
    """A read of an absent unit, cancelled during its first attempt, stops there: its
    token is cancelled, so the Bus starts no retry."""
    with Simulator({1: ProfileDevice(SENSOR)}) as sim, bb.Bus(sim.port, timeout=0.3) as bus:
        absent = device(bb.Device.from_profile(SENSOR, bus, unit=9, retries=3), "absent")

        async def cancelled() -> None:
            read = asyncio.ensure_future(absent.temperature.get_value())  # type: ignore[attr-defined]
            await asyncio.sleep(0.1)
            read.cancel()
            with pytest.raises(asyncio.CancelledError):
                await read
            await asyncio.sleep(0.8)  # what three retries would take

        asyncio.run(cancelled())
        assert sim.request_count == 1


def test_an_async_device_is_awaited_on_the_loop() -> None:
    """A device whose get / set are coroutine functions (an async device) is awaited as it
    is, not run in a thread."""
    calls: list[tuple[str, str]] = []

    class Async:
        def __init__(self, dev: bb.Device) -> None:
            self._dev = dev

        @property
        def profile(self) -> bb.Profile:
            return self._dev.profile

        async def get(self, name: str) -> Any:
            calls.append(("get", threading.current_thread().name))
            return self._dev.get(name)

        async def set(self, name: str, value: Any) -> None:
            calls.append(("set", threading.current_thread().name))
            self._dev.set(name, value)

    model = ProfileDevice(SENSOR, values={"temperature": 4.5})
    with Simulator({1: model}) as sim, bb.Bus(sim.port) as bus:
        dev = device(Async(bb.Device.from_profile(SENSOR, bus)), "s")  # type: ignore[arg-type]

        async def go() -> Any:
            await dev.temperature_correction.set(-0.5)  # type: ignore[attr-defined]
            return await dev.temperature.get_value()  # type: ignore[attr-defined]

        assert asyncio.run(go()) == 4.5
    assert model.value("temperature_correction") == -0.5
    main = threading.current_thread().name
    assert calls == [("set", main), ("get", main)]


def test_not_a_device_is_a_type_error() -> None:
    with pytest.raises(TypeError, match="benchbus device"):
        device(object(), "x")  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("option", "error"),
    [
        ({"tolerance": -1}, ValueError),
        ({"tolerance": "5"}, TypeError),
        ({"poll_period": math.inf}, ValueError),
        ({"timeout": 0}, ValueError),
        ({"timeout": True}, ValueError),
    ],
)
def test_bad_motor_options_are_refused(option: dict[str, Any], error: type[Exception]) -> None:
    with Simulator(SimDrive()) as sim, bb.Drive(sim.port) as drive:
        with pytest.raises(error):
            device(drive, "spindle", **option)
        assert sim.request_count == 0


def test_without_ophyd_async_the_module_imports_and_says_what_to_install() -> None:
    script = (
        "import sys\n"
        "sys.modules['ophyd_async'] = None\n"  # as if it were not installed
        "import benchbus.ophyd as o\n"
        "for attempt in (lambda: o.device(object(), 'x'), lambda: o.RegisterDevice):\n"
        "    try:\n"
        "        attempt()\n"
        "    except ImportError as exc:\n"
        "        print(exc)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True, timeout=60
    ).stdout.splitlines()
    assert len(out) == 2
    assert all("pip install 'benchbus[bluesky]'" in line for line in out)
