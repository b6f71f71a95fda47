"""benchbus.epics: devices served as EPICS process variables by ``benchbus ioc``, in a process
of its own, read and written by real EPICS clients in this one (caproto over Channel Access,
p4p over PV Access, ophyd-async's CA backend in a Bluesky plan), against simulated devices
whose registers are the truth. Everything stays on loopback, on ports of each test's own."""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

import benchbus as bb
from benchbus.epics import IOC, PV_NAME_MAX, RBV, pvs
from benchbus.sim import DriveDevice, ProfileDevice, Simulator

import caproto.threading.client as caproto_client
from caproto import ChannelType

PROFILES = Path(__file__).resolve().parent.parent / "examples" / "profiles"
CONTROLLER = PROFILES / "flow_controller.toml"
SENSOR = PROFILES / "xy_md02.toml"
RELAYS = PROFILES / "relay_board.toml"

#: Function codes that write.
WRITES = {0x05, 0x06, 0x0F, 0x10, 0x16, 0x17}


def free_port() -> int:
    """A port free on loopback for both TCP and UDP now."""
    while True:
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as tcp:
            tcp.bind(("127.0.0.1", 0))
            port = int(tcp.getsockname()[1])
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as udp:
                try:
                    udp.bind(("127.0.0.1", port))
                except OSError:
                    continue
        return port


@dataclasses.dataclass
class Epics:
    """The EPICS environment of one test: its own ports, loopback only."""

    ca_port: int
    env: dict[str, str]

    def client(self) -> Any:
        """A caproto Channel Access client context searching this test's IOCs."""
        return caproto_client.Context()


def epics_env(ca_ports: list[int], pva_port: int, pva_broadcast: int) -> dict[str, str]:
    """The variables that keep servers and clients on loopback and on these ports."""
    return {
        "EPICS_CAS_INTF_ADDR_LIST": "127.0.0.1",
        "EPICS_CA_ADDR_LIST": " ".join(f"127.0.0.1:{p}" for p in ca_ports),
        "EPICS_CA_AUTO_ADDR_LIST": "NO",
        "EPICS_CA_SERVER_PORT": str(ca_ports[0]),
        "EPICS_CA_REPEATER_PORT": str(free_port()),
        "EPICS_PVAS_INTF_ADDR_LIST": "127.0.0.1",
        "EPICS_PVA_ADDR_LIST": "127.0.0.1",
        "EPICS_PVA_AUTO_ADDR_LIST": "NO",
        "EPICS_PVAS_SERVER_PORT": str(pva_port),
        "EPICS_PVA_SERVER_PORT": str(pva_port),
        "EPICS_PVAS_BROADCAST_PORT": str(pva_broadcast),
        "EPICS_PVA_BROADCAST_PORT": str(pva_broadcast),
    }


@pytest.fixture
def epics(monkeypatch: pytest.MonkeyPatch) -> Epics:
    ca = free_port()
    env = epics_env([ca], free_port(), free_port())
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    return Epics(ca, env)


def wait_for(what: str, check: Callable[[], Any], timeout: float = 10.0) -> Any:
    """``check()``'s first true result within ``timeout`` s; fails naming ``what``."""
    deadline = time.monotonic() + timeout
    last: Any = None
    while time.monotonic() < deadline:
        try:
            last = check()
        except Exception as exc:  # a PV not yet connected, a read timed out
            last = exc
        else:
            if last:
                return last
        time.sleep(0.05)
    pytest.fail(f"{what}: not within {timeout} s (last: {last!r})")


@contextlib.contextmanager
def served(
    args: list[str], env: dict[str, str], ready: str, context: Any
) -> Iterator[subprocess.Popen[str]]:
    """``benchbus ioc ARGS`` in a process of its own until the block ends, once ``ready``
    (a PV) reads 1; SIGTERM then, which must end it cleanly within 2 s."""
    process = subprocess.Popen(
        [sys.executable, "-m", "benchbus", "ioc", *args],
        env={**os.environ, **env},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        (pv,) = context.get_pvs(ready, timeout=2)
        wait_for(f"{ready} = 1", lambda: pv.read(timeout=1).data[0] == 1, timeout=20)
        yield process
    except BaseException:
        process.kill()
        _, err = process.communicate(timeout=10)
        print(err)
        raise
    process.send_signal(signal.SIGTERM)
    started = time.monotonic()
    _, err = process.communicate(timeout=10)
    took = time.monotonic() - started
    assert process.returncode == 0, err
    assert took < 2.0, f"SIGTERM took {took:.1f} s"
    process.stderr_text = err  # type: ignore[attr-defined]


def read(context: Any, name: str, kind: str = "control") -> Any:
    """One read of the PV ``name`` with its ``kind`` of metadata."""
    (pv,) = context.get_pvs(name, timeout=2)
    return pv.read(data_type=kind, timeout=3)


def put(context: Any, name: str, value: Any) -> None:
    """A put that waits for the IOC to have processed it (put-callback)."""
    (pv,) = context.get_pvs(name, timeout=2)
    pv.write(value if isinstance(value, list) else [value], wait=True, timeout=5)


def writes(sim: Simulator[Any]) -> list[bytes]:
    """The write requests the simulator has received."""
    return [f for f in sim.requests if len(f) > 1 and f[1] in WRITES]


# ---- the records a declaration gives ------------------------------------------------------


def test_each_register_gives_its_records_by_its_access_and_type() -> None:
    profile = bb.Profile(CONTROLLER)
    made, warnings = pvs("FC:", profile, actions=("go",), stats=("timeouts",))
    kinds = {p.name: p.kind for p in made}
    assert warnings == []
    for r in profile.registers:
        if r.access == "r":
            assert f"FC:{r.name}" in kinds and f"FC:{r.name}{RBV}" not in kinds
            assert kinds[f"FC:{r.name}"].endswith("In")
        elif r.access == "w":
            assert kinds[f"FC:{r.name}"].endswith("Out") and f"FC:{r.name}{RBV}" not in kinds
        else:
            assert kinds[f"FC:{r.name}"].endswith("Out")
            assert kinds[f"FC:{r.name}{RBV}"].endswith("In")
    # f32 -> ai/ao; u32 scaled -> ai; enum -> mbb; i64 -> int64; u64 (beyond int64) -> ai;
    # a 16-character string -> stringin / stringout; a write-only u16 -> longout.
    assert kinds["FC:setpoint"] == "aOut" and kinds["FC:flow"] == "aIn"
    assert kinds["FC:total"] == "aIn" and kinds["FC:runtime"] == "aIn"
    assert kinds["FC:mode"] == "mbbOut" and kinds["FC:mode_RBV"] == "mbbIn"
    assert kinds["FC:zero_offset"] == "int64Out" and kinds["FC:gain"] == "aOut"
    assert kinds["FC:device_name"] == "stringOut" and kinds["FC:reset_total"] == "longOut"
    assert kinds["FC:go"] == "Action"
    assert kinds[f"FC:{IOC}connected"] == "boolIn" and kinds[f"FC:{IOC}timeouts"] == "longIn"
    fields = {p.name: p.fields for p in made}
    assert fields["FC:total"]["PREC"] == 2 and fields["FC:total"]["EGU"] == "scc"
    assert fields["FC:gas_temperature"]["PREC"] == 2
    assert fields["FC:flow"]["PREC"] == 3 and "LOPR" not in fields["FC:flow"]
    assert (fields["FC:setpoint"]["LOPR"], fields["FC:setpoint"]["HOPR"]) == (0.0, 200.0)
    assert (fields["FC:zero_offset"]["LOPR"], fields["FC:zero_offset"]["HOPR"]) == (
        -1000000,
        1000000,
    )
    for p in made:  # an output record never clamps a put to its drive limits
        assert "DRVL" not in p.fields and "DRVH" not in p.fields
    mode = next(p for p in made if p.name == "FC:mode")
    assert mode.states == ("off", "control", "purge", "close")
    # --read-only: no output record, no action.
    made, _ = pvs("FC:", profile, read_only=True, actions=("go",))
    names = {p.name for p in made}
    assert all(not p.output for p in made)
    assert "FC:setpoint_RBV" in names and "FC:setpoint" not in names
    assert "FC:reset_total" not in names and "FC:go" not in names


def test_enum_values_that_are_not_0_1_2_map_to_state_indices_and_long_names_shorten() -> None:
    members = ", ".join(f'{10 * i} = "member_{i}"' for i in range(3))
    long_name = "a_state_name_longer_than_the_record_holds"
    text = (
        '[device]\nname = "x"\n[[register]]\nname = "mode"\naddress = 0\naccess = "rw"\n'
        f'enum = {{ {members}, 99 = "{long_name}" }}\n'
        '[[register]]\nname = "level"\naddress = 1\nunit = "a_unit_of_many_letters"\n'
    )
    made, warnings = pvs("X:", bb.Profile.parse(text))
    mode = next(p for p in made if p.name == "X:mode")
    assert mode.numbers == (0, 10, 20, 99)
    assert mode.states[3] == long_name[:25]
    assert mode.shown(20) == 2 and mode.written(3) == 99
    assert mode.shown(7) is None  # a number the profile does not list
    with pytest.raises(ValueError, match="names no member"):
        mode.written(4)
    level = next(p for p in made if p.name == "X:level")
    assert level.fields["EGU"] == "a_unit_of_many_"
    assert any(long_name in w for w in warnings)
    assert any("a_unit_of_many_letters" in w for w in warnings)


def test_an_enum_of_more_than_16_members_is_its_number_and_its_members_name() -> None:
    members = ", ".join(f'{i} = "m{i}"' for i in range(17))
    text = (
        '[device]\nname = "x"\n[[register]]\nname = "sel"\naddress = 0\naccess = "rw"\n'
        f"enum = {{ {members} }}\n"
    )
    made, _ = pvs("X:", bb.Profile.parse(text))
    kinds = {p.name: p.kind for p in made}
    assert kinds["X:sel"] == "longOut" and kinds["X:sel_RBV"] == "longIn"
    assert kinds["X:sel_RBV_STR"] == "stringIn"
    name = next(p for p in made if p.name == "X:sel_RBV_STR")
    assert name.shown(16) == "16"


def test_a_pv_name_over_60_characters_is_an_error_naming_the_register() -> None:
    profile = bb.Profile(CONTROLLER)
    prefix = "P" * (PV_NAME_MAX - len("setpoint_RBV") + 1)
    with pytest.raises(ValueError, match=r"^setpoint: the PV name .* over EPICS's 60"):
        pvs(prefix, profile)


# ---- Channel Access, against a simulated device ------------------------------------------


@pytest.fixture
def controller() -> Iterator[tuple[Simulator[ProfileDevice], ProfileDevice]]:
    model = ProfileDevice(CONTROLLER, values={"setpoint": 75.5, "mode": "purge"})
    with Simulator({1: model}) as sim:
        yield sim, model
        assert sim.errors == []


def ioc_args(sim: Simulator[Any], profile: Path, prefix: str, *more: str) -> list[str]:
    return ["--profile", str(profile), "--port", sim.port, "--prefix", prefix, *more]


def test_every_record_kind_reads_with_its_value_units_precision_and_limits(
    epics: Epics, controller: tuple[Simulator[ProfileDevice], ProfileDevice]
) -> None:
    sim, model = controller
    ctx = epics.client()
    profile = bb.Profile(CONTROLLER)
    with served(
        ioc_args(sim, CONTROLLER, "FC:", "--period", "0.2"), epics.env, "FC:ioc:connected", ctx
    ):
        for r in profile.registers:
            if r.access == "w":
                continue
            name = f"FC:{r.name}" + (RBV if r.access != "r" else "")
            reading = read(ctx, name)
            md = reading.metadata
            truth = model.value(r.name)
            assert md.severity == 0, name
            if r.enum:
                assert [s.decode() for s in md.enum_strings] == list(r.enum.values())
                assert md.enum_strings[reading.data[0]].decode() == truth
            elif r.type == "string":
                assert reading.data[0].decode() == truth
            else:
                assert math.isclose(float(reading.data[0]), float(truth), rel_tol=1e-6), name
                assert md.units.decode() == r.unit
                if r.name in ("setpoint", "gain", "zero_offset"):
                    assert (md.lower_disp_limit, md.upper_disp_limit) == (r.min, r.max)
                    # No drive limits: an output record does not clamp a put.
                    for field in ("DRVL", "DRVH"):
                        assert read(ctx, f"FC:{r.name}.{field}", "native").data[0] == 0
        assert read(ctx, "FC:total").metadata.precision == 2
        assert read(ctx, "FC:flow").metadata.precision == 3
        # An output record starts at what the device holds, with no alarm.
        setpoint = read(ctx, "FC:setpoint", "time")
        assert (setpoint.data[0], setpoint.metadata.severity) == (75.5, 0)


def test_puts_reach_the_wire_and_a_refused_put_sends_nothing_and_changes_nothing(
    epics: Epics, controller: tuple[Simulator[ProfileDevice], ProfileDevice]
) -> None:
    sim, model = controller
    ctx = epics.client()
    with served(
        ioc_args(sim, CONTROLLER, "FC:", "--period", "0.2"), epics.env, "FC:ioc:connected", ctx
    ):
        put(ctx, "FC:setpoint", 80.25)
        assert model.value("setpoint") == 80.25
        wait_for("the readback", lambda: read(ctx, "FC:setpoint_RBV").data[0] == 80.25)
        put(ctx, "FC:zero_offset", -12345)
        assert model.value("zero_offset") == -12345
        put(ctx, "FC:device_name", "bench 7")
        assert model.value("device_name") == "bench 7"
        # Enums by state string: the member's number goes on the wire.
        (mode,) = ctx.get_pvs("FC:mode", timeout=2)
        mode.write(["close"], data_type=ChannelType.STRING, wait=True, timeout=5)
        assert model.value("mode") == "close"
        before = len(writes(sim))
        for name, bad in (("setpoint", 5000.0), ("gain", 0.1), ("zero_offset", 2_000_000)):
            put(ctx, f"FC:{name}", bad)
        assert len(writes(sim)) == before
        assert model.value("setpoint") == 80.25 and model.value("gain") == 1.0
        reading = read(ctx, "FC:setpoint", "time")
        assert (reading.data[0], reading.metadata.severity) == (80.25, 0)


def test_a_put_the_device_refuses_restores_the_record_and_raises_its_write_alarm(
    epics: Epics, tmp_path: Path
) -> None:
    # The IOC's profile allows a setpoint up to 300; the device's own table stops at 200.
    wider = tmp_path / "wider.toml"
    wider.write_text(CONTROLLER.read_text().replace("max = 200.0", "max = 300.0"))
    model = ProfileDevice(CONTROLLER, values={"setpoint": 75.5})
    ctx = epics.client()
    with (
        Simulator({1: model}) as sim,
        served(
            ioc_args(sim, wider, "FC:", "--period", "0.2"), epics.env, "FC:ioc:connected", ctx
        ) as process,
    ):
        before = len(writes(sim))
        put(ctx, "FC:setpoint", 250.0)
        assert len(writes(sim)) > before  # it went out, and the device said no
        assert model.value("setpoint") == 75.5
        reading = read(ctx, "FC:setpoint", "time")
        assert reading.data[0] == 75.5
        assert reading.metadata.status == 2 and reading.metadata.severity == 2  # WRITE, MAJOR
        put(ctx, "FC:setpoint", 90.0)  # the next good put clears the alarm
        reading = read(ctx, "FC:setpoint", "time")
        assert (reading.data[0], reading.metadata.severity, reading.metadata.status) == (90.0, 0, 0)
        assert model.value("setpoint") == 90.0
    assert "FC:setpoint: put 250.0 refused: ModbusException" in process.stderr_text  # type: ignore[attr-defined]


def test_a_silent_device_goes_invalid_comm_at_once_while_its_neighbour_keeps_updating(
    epics: Epics,
) -> None:
    near, far = ProfileDevice(SENSOR), ProfileDevice(SENSOR)
    ctx = epics.client()
    period, timeout = 0.2, 0.1
    bench = epics_bench(epics, [("A:", 1), ("B:", 2)], SENSOR, period, timeout)
    with Simulator({1: near, 2: far}) as sim:
        bench_file = bench(sim.port)
        with served([str(bench_file)], epics.env, "B:ioc:connected", ctx):
            wait_for("A connected", lambda: read(ctx, "A:ioc:connected").data[0] == 1)
            sim.set_silent(1)
            silenced = time.monotonic()
            (temperature,) = ctx.get_pvs("A:temperature", timeout=2)
            wait_for(
                "A INVALID/COMM",
                lambda: (lambda m: (m.severity, m.status) == (3, 9))(
                    temperature.read(data_type="time", timeout=1).metadata
                ),
            )
            took = time.monotonic() - silenced
            assert took < period + 3 * timeout + 0.5, took
            assert read(ctx, "A:ioc:connected").data[0] == 0
            far.set_value("temperature", 31.5)
            wait_for("B follows", lambda: read(ctx, "B:temperature").data[0] == 31.5)
            assert read(ctx, "B:temperature", "time").metadata.severity == 0
            sim.set_silent(1, False)
            wait_for(
                "A clears",
                lambda: temperature.read(data_type="time", timeout=1).metadata.severity == 0,
            )
            assert read(ctx, "A:ioc:failures").data[0] >= 1


def epics_bench(
    epics: Epics, units: list[tuple[str, int]], profile: Path, period: float, timeout: float
) -> Callable[[str], Path]:
    """A function that writes a bench file of ``units`` (prefix, unit) of ``profile`` on one
    line at ``port``."""

    def write(port: str) -> Path:
        folder = Path(os.environ.get("PYTEST_TMP", "/tmp"))
        path = folder / f"bench-{epics.ca_port}.toml"
        devices = "".join(
            f'[[device]]\nline = "main"\nprofile = "{profile}"\nunit = {unit}\n'
            f'prefix = "{prefix}"\nperiod = {period}\n'
            for prefix, unit in units
        )
        path.write_text(f'[[line]]\nname = "main"\nport = "{port}"\ntimeout = {timeout}\n{devices}')
        return path

    return write


# ---- a built-in family ---------------------------------------------------------------------


def test_a_drives_action_records_move_the_motor_and_sigterm_stops_it(epics: Epics) -> None:
    model = DriveDevice(model="BLD2")
    forward, stopped = 1, 3  # the manual's status word 1
    ctx = epics.client()
    with Simulator({1: model}) as sim:
        args = ["drive", "--port", sim.port, "--prefix", "SP:", "--period", "0.2"]
        with served(args, epics.env, "SP:ioc:connected", ctx):
            put(ctx, "SP:accel_time", 0.1)
            put(ctx, "SP:decel_time", 0.1)
            put(ctx, "SP:speed_setpoint", 1200)
            assert model.state == stopped
            put(ctx, "SP:forward", 1)
            wait_for("the motor runs", lambda: model.state == forward and model.speed > 1000)
            wait_for("the state record says so", lambda: read(ctx, "SP:state").data[0] == forward)
            wait_for("the speed record follows", lambda: read(ctx, "SP:speed").data[0] > 1000)
            # Writable only while stopped: refused while running, restored, WRITE alarm.
            poles = read(ctx, "SP:pole_pairs").data[0]
            put(ctx, "SP:pole_pairs", poles + 1)
            reading = read(ctx, "SP:pole_pairs", "time")
            assert reading.data[0] == poles and reading.metadata.status == 2
            put(ctx, "SP:stop", 1)
            wait_for("the motor stops", lambda: model.state == stopped)
            put(ctx, "SP:reverse", 1)
            wait_for("the motor runs again", lambda: model.speed < -1000)
        # SIGTERM stopped the motor before the IOC ended.
        wait_for("the motor stops on SIGTERM", lambda: model.state == stopped, timeout=2)
