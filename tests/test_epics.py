"""benchbus.epics: devices served as EPICS process variables by ``benchbus ioc``, in a process
of its own, read and written by real EPICS clients in this one (caproto over Channel Access,
p4p over PV Access, ophyd-async's CA backend in a Bluesky plan), against simulated devices
whose registers are the truth. Everything stays on loopback, on ports of each test's own."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import caproto.threading.client as caproto_client
import pytest
from caproto import ChannelType
from epics_clients import (
    Epics,
    put,
    read,
    served,
    spawn,
    until,
    wait_for,
    writes,
)

import benchbus as bb
from benchbus._families import Family, command_families
from benchbus.epics import IOC, PV_NAME_MAX, RBV, loopback_env, pvs
from benchbus.sim import DriveDevice, ProfileDevice, Simulator

PROFILES = Path(__file__).resolve().parent.parent / "examples" / "profiles"
CONTROLLER = PROFILES / "flow_controller.toml"
SENSOR = PROFILES / "xy_md02.toml"
RELAYS = PROFILES / "relay_board.toml"


@pytest.fixture
def epics(monkeypatch: pytest.MonkeyPatch) -> Epics:
    env = loopback_env()
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    return Epics(env)


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


# ---- a bench file --------------------------------------------------------------------------

GOOD_BENCH = f"""[ioc]
period = 0.5

[[line]]
name = "rs485"
port = "/dev/ttyNONE0"
baudrate = 9600

[[device]]
line = "rs485"
family = "drive"
unit = 1
prefix = "LAB:SPINDLE:"
options = {{ family = "C20" }}

[[device]]
line = "rs485"
profile = "{SENSOR}"
unit = 2
prefix = "LAB:XY:"
period = 2.0
"""


def test_a_bench_file_gives_its_lines_and_devices() -> None:
    from benchbus._bench import read_bench

    path = Path(os.environ.get("TMPDIR", "/tmp")) / f"bench-{os.getpid()}.toml"
    path.write_text(GOOD_BENCH)
    try:
        bench = read_bench(path)
    finally:
        path.unlink()
    assert bench.period == 0.5 and bench.read_only is False
    (line,) = bench.lines
    assert (line.name, line.port, line.options) == ("rs485", "/dev/ttyNONE0", {"baudrate": 9600})
    drive, sensor = bench.devices
    assert (drive.family, drive.unit, drive.prefix, drive.options) == (
        "drive",
        1,
        "LAB:SPINDLE:",
        {"family": "C20"},
    )
    assert sensor.profile is not None and sensor.profile.name == "XY-MD02"
    assert (sensor.unit, sensor.period) == (2, 2.0)
    assert drive.line_defaults().baudrate == 19200 and sensor.line_defaults().baudrate == 9600


@pytest.mark.parametrize(
    ("change", "where"),
    [
        (("unit = 2", "unit = 300"), ":19: device[1].unit: must be 1 to 255, got 300"),
        (("unit = 2", 'unit = "2"'), ":19: device[1].unit: must be int, got '2'"),
        (('line = "rs485"\nprofile', 'line = "rs232"\nprofile'), ":17: device[1].line: no line"),
        (('family = "drive"', 'family = "lamp"'), ":11: device[0].family: no family 'lamp'"),
        (('{ family = "C20" }', '{ colour = "red" }'), ":14: device[0].options: "),
        (("period = 2.0", "period = -1"), ":21: device[1].period: must be a positive"),
        (('prefix = "LAB:XY:"', 'prefix = "LAB:SPINDLE:"'), ":20: device[1].prefix: 'LAB:SP"),
        (("baudrate = 9600", "speed = 9600"), ":7: line[0].speed: unknown key"),
        (("baudrate = 9600", 'parity = "X"'), ':7: line[0].parity: must be "N", "E" or "O"'),
        (("baudrate = 9600", "timeout = 0"), ":7: line[0].timeout: must be a positive"),
        (("period = 0.5", "period = 0"), ":2: ioc.period: must be a positive"),
        ((f'profile = "{SENSOR}"', 'profile = "nowhere.toml"'), ":18: device[1].profile: "),
        (('family = "drive"\n', ""), ":9: device[0]: give family or profile"),
    ],
)
def test_a_bench_files_mistake_names_its_file_line_and_key_before_any_port_opens(
    tmp_path: Path, change: tuple[str, str], where: str
) -> None:
    path = tmp_path / "bench.toml"
    old, new = change
    assert old in GOOD_BENCH
    path.write_text(GOOD_BENCH.replace(old, new, 1))
    result = subprocess.run(
        [sys.executable, "-m", "benchbus", "ioc", str(path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2, result.stderr
    assert f"{path}{where}" in result.stderr
    assert "ttyNONE0" not in result.stderr  # nothing tried to open the port


# ---- Channel Access, against a simulated device ------------------------------------------


@pytest.fixture
def controller() -> Iterator[tuple[Simulator[ProfileDevice], ProfileDevice]]:
    model = ProfileDevice(CONTROLLER, values={"setpoint": 75.5, "mode": "purge"})
    with Simulator({1: model}) as sim:
        yield sim, model
        assert sim.errors == []


def command_families_by_key() -> dict[str, Family]:
    return {f.key: f for f in command_families()}


def ioc_args(sim: Simulator[Any], profile: Path, prefix: str, *more: str) -> list[str]:
    return ["--profile", str(profile), "--port", sim.port, "--prefix", prefix, *more]


@pytest.fixture
def fc_served(
    epics: Epics, controller: tuple[Simulator[ProfileDevice], ProfileDevice]
) -> Iterator[tuple[Simulator[ProfileDevice], ProfileDevice, Any]]:
    """The simulated flow controller served by ``benchbus ioc`` under ``FC:`` (read every
    0.2 s), with a client: ``(sim, model, client)``."""
    sim, model = controller
    ctx = epics.client()
    args = ioc_args(sim, CONTROLLER, "FC:", "--period", "0.2")
    with served(args, epics.env, "FC:ioc:connected", ctx):
        yield sim, model, ctx


def test_every_record_kind_reads_with_its_value_units_precision_and_limits(
    fc_served: tuple[Simulator[ProfileDevice], ProfileDevice, Any],
) -> None:
    _, model, ctx = fc_served
    profile = bb.Profile(CONTROLLER)
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


def test_bools_are_bi_and_bo_records_with_their_two_states(epics: Epics) -> None:
    model = ProfileDevice(RELAYS)
    ctx = epics.client()
    with (
        Simulator({1: model}) as sim,
        served(ioc_args(sim, RELAYS, "RB:", "--period", "0.2"), epics.env, "RB:ioc:connected", ctx),
    ):
        relay = read(ctx, "RB:relay1_RBV")
        assert [s.decode() for s in relay.metadata.enum_strings] == ["false", "true"]
        assert relay.data[0] == int(model.value("relay1"))
        put(ctx, "RB:relay1", 1)
        assert model.value("relay1") is True
        wait_for("the readback", lambda: read(ctx, "RB:relay1_RBV").data[0] == 1)
        put(ctx, "RB:relay8", 1)  # write-only: an output record alone
        assert model.value("relay8") is True
        # Nothing read to show before that put (INVALID / UDF); once written, no alarm.
        assert read(ctx, "RB:relay8", "time").metadata.severity == 0
        model.set_value("input3", True)
        wait_for("an input follows", lambda: read(ctx, "RB:input3").data[0] == 1)


def test_a_shipped_profile_is_served_by_its_name(epics: Epics) -> None:
    model = ProfileDevice("pzem-016", values={"voltage": 229.8, "current": 1.234})
    ctx = epics.client()
    args = ["--profile", "pzem-016", "--port", "", "--prefix", "PM:", "--period", "0.2"]
    with Simulator({1: model}) as sim:
        args[3] = sim.port
        with served(args, epics.env, "PM:ioc:connected", ctx):
            voltage = read(ctx, "PM:voltage")
            assert (voltage.data[0], voltage.metadata.units.decode()) == (229.8, "V")
            assert math.isclose(read(ctx, "PM:current").data[0], 1.234, rel_tol=1e-9)
            put(ctx, "PM:power_alarm_threshold", 1500)
            assert model.value("power_alarm_threshold") == 1500


def test_puts_reach_the_wire_and_a_refused_put_sends_nothing_and_changes_nothing(
    fc_served: tuple[Simulator[ProfileDevice], ProfileDevice, Any],
) -> None:
    sim, model, ctx = fc_served
    put(ctx, "FC:setpoint", 80.25)
    assert model.value("setpoint") == 80.25
    wait_for("the readback", lambda: read(ctx, "FC:setpoint_RBV").data[0] == 80.25)
    model.set_value("setpoint", 60.0)  # changed at the device itself
    put(ctx, "FC:setpoint", 80.25)  # the value the record shows, written again
    assert model.value("setpoint") == 80.25
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


def test_puts_that_come_while_a_write_is_on_the_wire_are_written_in_their_order(
    fc_served: tuple[Simulator[ProfileDevice], ProfileDevice, Any],
) -> None:
    sim, model, ctx = fc_served
    setpoint, mode = ctx.get_pvs("FC:setpoint", "FC:mode", timeout=2)
    model.reply_delay = 0.1  # each write stays on the wire that long (the timeout: 0.2 s)
    before = len(writes(sim))
    setpoint.write([61.0], wait=False)  # plain puts, as a screen's slider sends
    time.sleep(0.05)
    setpoint.write([62.0], wait=False)  # waits in the record while 61 is written
    mode.write([0], wait=False)  # another record: processed, and queued, at once
    wait_for("every put written", lambda: len(writes(sim)) >= before + 3)
    model.reply_delay = 0.0
    assert model.value("setpoint") == 62.0 and model.value("mode") == "off"
    # In the order the records processed them: 61, the mode, then 62 once 61 was over.
    frames = writes(sim)[before:]
    assert [f[1] for f in frames] == [0x10, 0x06, 0x10]
    assert frames[0][7:11] != frames[2][7:11]  # two values: 62 was not lost
    wait_for("the record shows the last put", lambda: read(ctx, "FC:setpoint").data[0] == 62.0)
    assert read(ctx, "FC:setpoint", "time").metadata.severity == 0


SPARSE = """[device]
name = "sparse"
[[register]]
name = "speed"
address = 0
access = "rw"
enum = { 0 = "off", 10 = "slow", 20 = "fast", 99 = "boost" }
[[register]]
name = "label"
address = 1
type = "string"
length = 8
access = "rw"
[[register]]
name = "note"
address = 9
type = "string"
length = 12
"""


def test_an_enum_of_numbers_not_0_1_2_and_latin1_text_cross_channel_access_as_held(
    epics: Epics, tmp_path: Path
) -> None:
    profile = tmp_path / "sparse.toml"
    profile.write_text(SPARSE)
    model = ProfileDevice(profile)
    model.set_value("speed", "fast")  # 20: state 2
    model.set_value("label", "Messgerät °C")  # Latin-1, more bytes in UTF-8
    model.set_value("note", "température élevée arrêt")  # 24 characters, a long string
    ctx = epics.client()
    with (
        Simulator({1: model}) as sim,
        served(
            ioc_args(sim, profile, "SP:", "--period", "0.2"), epics.env, "SP:ioc:connected", ctx
        ),
    ):
        wait_for("the label's record", lambda: read(ctx, "SP:label", "time").metadata.severity == 0)
        assert writes(sim) == []  # showing the device's values wrote nothing back
        speed = read(ctx, "SP:speed_RBV")
        assert speed.data[0] == 2
        assert speed.metadata.enum_strings[2].decode() == "fast"
        put(ctx, "SP:speed", 3)  # state 3 is member 99
        assert model.value("speed") == "boost"
        wait_for("the readback", lambda: read(ctx, "SP:speed_RBV").data[0] == 3)
        assert read(ctx, "SP:label_RBV").data[0].decode() == "Messgerät °C"
        note = read(ctx, "SP:note", "native").data
        assert bytes(note).rstrip(b"\0").decode() == "température élevée arrêt"
        model.set_value("speed", "off")
        wait_for("state 0", lambda: read(ctx, "SP:speed_RBV").data[0] == 0)


def test_text_after_a_nul_is_not_shown_and_showing_it_writes_nothing(
    epics: Epics, tmp_path: Path
) -> None:
    profile = tmp_path / "sparse.toml"
    profile.write_text(SPARSE)
    model = ProfileDevice(profile)
    model.set_value("label", "PUMP\0old")  # a C string and what its buffer held before
    ctx = epics.client()
    with Simulator({1: model}) as sim:
        args = ioc_args(sim, profile, "NU:", "--period", "0.2")
        with served(args, epics.env, "NU:ioc:connected", ctx):
            wait_for("the label", lambda: read(ctx, "NU:label", "time").metadata.severity == 0)
            assert read(ctx, "NU:label").data[0].decode() == "PUMP"
            assert read(ctx, "NU:label_RBV").data[0].decode() == "PUMP"
            time.sleep(0.5)  # a few polls
            assert writes(sim) == []
            assert model.value("label") == "PUMP\0old"


def test_a_gateways_no_answer_is_the_line_failing_not_a_register_refused(epics: Epics) -> None:
    ctx = epics.client()
    with (
        Simulator({1: ProfileDevice(SENSOR)}) as sim,
        served(ioc_args(sim, SENSOR, "GW:", "--period", "0.2"), epics.env, "GW:ioc:connected", ctx),
    ):
        sim.answer_exception(0x0B, n=1000, unit=1)  # target device failed to respond
        wait_for("COMM", lambda: invalid_comm(ctx, "GW:temperature"))
        assert invalid_comm(ctx, "GW:humidity")
        assert read(ctx, "GW:ioc:connected").data[0] == 0
        assert "GatewayError" in read(ctx, "GW:ioc:error").data[0].decode()


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
        before = len(writes(sim))
        put(ctx, "FC:setpoint", 75.5)  # the value it shows: written all the same
        assert len(writes(sim)) == before + 1
        reading = read(ctx, "FC:setpoint", "time")
        assert (reading.data[0], reading.metadata.severity, reading.metadata.status) == (75.5, 0, 0)
        put(ctx, "FC:setpoint", 90.0)
        assert model.value("setpoint") == 90.0
    said = "FC:setpoint: put 250.0 refused: ModbusException: unit 1, function 0x10: exception 0x03"
    assert said in process.stderr_text  # type: ignore[attr-defined]


def test_a_silent_device_goes_invalid_comm_at_once_while_its_neighbour_keeps_updating(
    epics: Epics, tmp_path: Path
) -> None:
    near, far = ProfileDevice(SENSOR), ProfileDevice(SENSOR)
    ctx = epics.client()
    period, timeout = 0.2, 0.1
    with Simulator({1: near, 2: far}) as sim:
        bench = bench_file(tmp_path, sim.port, [("A:", 1), ("B:", 2)], SENSOR, period, timeout)
        with served([str(bench)], epics.env, "B:ioc:connected", ctx):
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


def test_before_its_first_read_a_record_is_invalid_and_no_value_is_trusted(
    epics: Epics,
) -> None:
    ctx = epics.client()
    model = ProfileDevice(SENSOR)
    model.reply_delay = 4.0  # the first read takes that long
    with Simulator({1: model}) as sim:
        args = ioc_args(sim, SENSOR, "U:", "--timeout", "5", "--retries", "0")
        with served(args, epics.env, "U:ioc:connected", ctx, ready_value=0):
            for name in ("U:temperature", "U:humidity", "U:unit_address_RBV"):
                md = read(ctx, name, "time").metadata
                assert (md.severity, md.status) == (3, 17), name  # INVALID, UDF
            model.reply_delay = 0.0
            wait_for("the first read", lambda: read(ctx, "U:ioc:connected").data[0] == 1)
            reading = read(ctx, "U:temperature", "time")
            assert (reading.data[0], reading.metadata.severity) == (21.5, 0)


def test_a_register_the_device_refuses_alarms_its_record_alone(
    epics: Epics, tmp_path: Path
) -> None:
    # The IOC's profile has a register beside the sensor's two that the sensor lacks.
    extra = '[[register]]\nname = "extra"\naddress = 0x0003\ntable = "input"\n'
    profile = tmp_path / "more.toml"
    profile.write_text(SENSOR.read_text() + "\n" + extra)
    model = ProfileDevice(SENSOR)
    ctx = epics.client()
    with (
        Simulator({1: model}) as sim,
        served(ioc_args(sim, profile, "S:", "--period", "0.2"), epics.env, "S:ioc:connected", ctx),
    ):
        (extra_pv,) = ctx.get_pvs("S:extra", timeout=2)
        wait_for(
            "INVALID/READ on the refused register",
            lambda: (lambda m: (m.severity, m.status) == (3, 1))(
                extra_pv.read(data_type="time", timeout=1).metadata
            ),
        )
        model.set_value("temperature", 24.5)
        wait_for("its neighbours read on", lambda: read(ctx, "S:temperature").data[0] == 24.5)
        for name in ("S:temperature", "S:humidity", "S:ioc:connected"):
            assert read(ctx, name, "time").metadata.severity == 0, name


def bench_file(
    folder: Path,
    port: str,
    units: list[tuple[str, int]],
    profile: Path,
    period: float,
    timeout: float,
) -> Path:
    """A bench file of ``units`` (prefix, unit) of ``profile`` on one line at ``port``."""
    devices = "".join(
        f'[[device]]\nline = "main"\nprofile = "{profile}"\nunit = {unit}\n'
        f'prefix = "{prefix}"\nperiod = {period}\n'
        for prefix, unit in units
    )
    path = folder / "bench.toml"
    path.write_text(f'[[line]]\nname = "main"\nport = "{port}"\ntimeout = {timeout}\n{devices}')
    return path


def invalid_comm(context: Any, name: str) -> bool:
    """Whether the PV ``name`` is in INVALID severity with COMM status."""
    md = read(context, name, "time").metadata
    return bool((md.severity, md.status) == (3, 9))


def test_a_lost_port_puts_every_record_in_comm_alarm_and_its_return_clears_it(
    epics: Epics, tmp_path: Path
) -> None:
    model = ProfileDevice(SENSOR)
    sim = Simulator({1: model, 2: ProfileDevice(SENSOR)})
    link = tmp_path / "ttyUSB0"
    sim.start()
    link.symlink_to(sim.port)
    period, timeout = 0.2, 0.1
    bench = bench_file(tmp_path, str(link), [("A:", 1), ("B:", 2)], SENSOR, period, timeout)
    ctx = epics.client()
    try:
        with served([str(bench)], epics.env, "B:ioc:connected", ctx):
            sim.stop()  # the adapter unplugged
            link.unlink()
            lost = time.monotonic()
            inputs = [p.name for p in pvs("A:", bb.Profile(SENSOR))[0] if p.kind.endswith("In")]
            inputs = [n for n in inputs if ":ioc:" not in n]
            for name in [*inputs, "B:temperature"]:
                wait_for(f"{name} INVALID/COMM", lambda n=name: invalid_comm(ctx, n), timeout=3)
            assert time.monotonic() - lost < period + 3 * timeout + 0.5
            assert read(ctx, "A:ioc:connected").data[0] == 0
            assert "PortError" in read(ctx, "A:ioc:error").data[0].decode()
            model.set_value("temperature", 30.5)
            sim.start()  # plugged in again: a new pty behind the same path
            link.symlink_to(sim.port)
            wait_for("A back", lambda: read(ctx, "A:temperature", "time").metadata.severity == 0)
            assert read(ctx, "A:temperature").data[0] == 30.5
            assert read(ctx, "A:ioc:connected").data[0] == 1
            assert read(ctx, "A:ioc:reopens").data[0] >= 1
    finally:
        sim.stop()


def eight_registers(folder: Path) -> Path:
    """A profile of 8 neighbouring holding registers, the first one writable."""
    rows = "".join(
        f'[[register]]\nname = "r{i}"\naddress = {i}\naccess = "{"rw" if i == 0 else "r"}"\n'
        for i in range(8)
    )
    path = folder / "eight.toml"
    path.write_text(f'[device]\nname = "eight"\n{rows}')
    return path


@pytest.mark.timing
def test_a_put_during_the_polls_of_10_devices_waits_for_the_request_on_the_line_not_the_cycle(
    epics: Epics, tmp_path: Path
) -> None:
    profile = eight_registers(tmp_path)
    models = {unit: ProfileDevice(profile) for unit in range(1, 11)}
    ctx = epics.client()
    units = [(f"D{unit}:", unit) for unit in models]
    with Simulator(models) as sim:
        bench = bench_file(tmp_path, sim.port, units, profile, 0.001, 0.2)
        with served([str(bench)], epics.env, "D10:ioc:connected", ctx):
            (target,) = ctx.get_pvs("D1:r0", timeout=2)
            target.wait_for_connection(timeout=5)
            began = time.monotonic()
            waits: list[int] = []
            for value in range(1, 21):
                time.sleep(0.013 * (value % 5))  # land at different points of a poll
                sent = time.monotonic()
                target.write([value], wait=True, timeout=5)
                assert models[1].value("r0") == value
                frames, times = sim.requests, sim.request_times
                at = max(i for i, f in enumerate(frames) if f[1] == 0x06 and f[0] == 1)
                before = [t for f, t in zip(frames[:at], times[:at]) if t > sent]
                waits.append(len(before))
            # The polls read one request a device (10 a cycle), without a pause between
            # them: a put waits for the request on the line (and, at most, the one that
            # started while the put crossed Channel Access), never for the cycle of 10.
            frames = zip(sim.requests, sim.request_times)
            polls = [f[0] for f, t in frames if t > began and f[1] == 0x03]
            assert set(polls) == set(models) and len(polls) > 40  # the polls kept the line busy
            print("requests a put waited behind:", waits)
            assert max(waits) <= 2, waits


#: An IOC made from Python, its misuses tried on the way (an IOC is one per process).
SCRIPT = """
import sys
import benchbus as bb
from benchbus.epics import Ioc

bus = bb.Bus(sys.argv[1], timeout=0.3)
device = bb.Device.from_profile(sys.argv[2], bus, unit=1)
ioc = Ioc(period=0.2)
for misuse in (lambda: Ioc(), lambda: ioc.add("X:", object()), lambda: ioc.start()):
    try:
        misuse()
    except (RuntimeError, TypeError) as exc:
        print(type(exc).__name__, exc)
ioc.add("X:", device)
try:
    ioc.add("Y:", bb.Device.from_profile(sys.argv[2], bus, unit=1))
    ioc.add("Y:", device)
except ValueError as exc:
    print(type(exc).__name__, exc)
ioc.start()
try:
    ioc.add("Z:", device)
except RuntimeError as exc:
    print(type(exc).__name__, exc)
print("serving", len(ioc.names), flush=True)
ioc.run()
"""


def test_an_ioc_made_from_python_is_one_per_process_and_takes_devices_before_it_starts(
    epics: Epics,
) -> None:
    ctx = epics.client()
    with Simulator({1: ProfileDevice(SENSOR)}) as sim:
        command = [sys.executable, "-c", SCRIPT, sim.port, str(SENSOR)]
        says = ("stdout", "serving")
        with served([], epics.env, "X:ioc:connected", ctx, command, serving=says) as process:
            assert read(ctx, "X:temperature").data[0] == 21.5
            assert read(ctx, "Y:temperature").data[0] == 21.5
    said = ("RuntimeError", "TypeError", "ValueError", "serving")  # not EPICS's own lines
    lines = [n for n in process.stdout_text.splitlines() if n.startswith(said)]  # type: ignore[attr-defined]
    assert lines[0].startswith("RuntimeError an EPICS IOC is one per process")
    assert lines[1].startswith("TypeError object has no register table to serve")
    assert lines[2] == "RuntimeError nothing to serve: add() a device before start()"
    assert lines[3].startswith("ValueError Y:temperature is served already (by Y: Device unit 1)")
    assert lines[4].startswith("RuntimeError the IOC has started and EPICS takes no records")
    assert lines[5].startswith("serving ")


def test_read_only_serves_readbacks_alone_and_access_security_refuses_writes(
    epics: Epics, controller: tuple[Simulator[ProfileDevice], ProfileDevice], tmp_path: Path
) -> None:
    sim, model = controller
    ctx = epics.client()
    with served(
        ioc_args(sim, CONTROLLER, "RO:", "--read-only"), epics.env, "RO:ioc:connected", ctx
    ):
        assert read(ctx, "RO:setpoint_RBV").data[0] == 75.5
        with pytest.raises(caproto_client.CaprotoTimeoutError):
            ctx.get_pvs("RO:setpoint", timeout=1)[0].wait_for_connection(timeout=1)
    rules = tmp_path / "readers.acf"
    rules.write_text("ASG(DEFAULT) {\n    RULE(1, READ)\n}\n")
    args = ioc_args(sim, CONTROLLER, "AS:", "--access-security", str(rules))
    with served(args, epics.env, "AS:ioc:connected", ctx):
        (setpoint,) = ctx.get_pvs("AS:setpoint", timeout=2)
        setpoint.wait_for_connection(timeout=3)
        before = len(writes(sim))
        assert setpoint.channel.access_rights == 1  # read, not write
        response = setpoint.write([60.0], wait=True, timeout=3)
        assert response.status.name == "ECA_NOWTACCESS"
        assert len(writes(sim)) == before and model.value("setpoint") == 75.5
        assert setpoint.read(timeout=3).data[0] == 75.5


STOPPING = """
import os, sys, time
import benchbus as bb
from benchbus.epics import Ioc

bus = bb.Bus(sys.argv[1], timeout=0.3)
ioc = Ioc(period=0.2)
ioc.add("ST:", bb.Device.from_profile(sys.argv[2], bus, unit=1))
ioc.start()
print("serving", flush=True)
while not os.path.exists(sys.argv[3]):
    time.sleep(0.02)
ioc.stop()
print("stopped", flush=True)
time.sleep(60)
"""


def test_once_stopping_the_ioc_refuses_puts_before_sending_anything(
    epics: Epics, tmp_path: Path
) -> None:
    model = ProfileDevice(SENSOR)
    go = tmp_path / "stop-now"
    ctx = epics.client()
    with Simulator({1: model}) as sim:
        command = [sys.executable, "-c", STOPPING, sim.port, str(SENSOR), str(go)]
        process = spawn(command, epics.env)
        try:
            until(process, "stdout", "serving", 20)
            put(ctx, "ST:temperature_correction", -1.0)
            assert model.value("temperature_correction") == -1.0
            go.touch()
            until(process, "stdout", "stopped", 20)
            before = len(writes(sim))
            put(ctx, "ST:temperature_correction", 2.0)
            assert len(writes(sim)) == before
            assert model.value("temperature_correction") == -1.0
            assert read(ctx, "ST:temperature_correction").data[0] == -1.0
        finally:
            process.kill()
            _, err = process.communicate(timeout=10)
    assert "put 2.0 refused: the IOC is stopping" in err


def test_the_shell_is_asked_for_and_leaving_it_ends_the_ioc(epics: Epics) -> None:
    with Simulator({1: ProfileDevice(SENSOR)}) as sim:
        done = subprocess.run(
            [sys.executable, "-m", "benchbus", "ioc", *ioc_args(sim, SENSOR, "SH:", "--shell")],
            env={**os.environ, **epics.env},
            input="print('served', len(ioc.names), ioc.started)\ndbl()\n",
            capture_output=True,
            text=True,
            timeout=60,
        )
    assert done.returncode == 0, done.stderr
    assert "served 24 True" in done.stdout
    assert "SH:temperature" in done.stdout  # EPICS's dbl() lists the record


def test_leaving_the_shell_with_exit_stops_the_motor(epics: Epics) -> None:
    model = DriveDevice(model="BLD2")
    forward, stopped = 1, 3
    ctx = epics.client()
    with Simulator({1: model}) as sim:
        args = ["drive", "--port", sim.port, "--prefix", "SH:", "--shell"]
        command = [sys.executable, "-m", "benchbus", "ioc", *args]
        process = spawn(command, epics.env, stdin=subprocess.PIPE)
        try:
            until(process, "stderr", "benchbus: ioc: serving", 20)
            put(ctx, "SH:decel_time", 0.1)
            put(ctx, "SH:speed_setpoint", 900)
            put(ctx, "SH:forward", 1)
            wait_for("the motor runs", lambda: model.state == forward)
            _, err = process.communicate("exit()\n", timeout=10)
        finally:
            process.kill()
        assert process.returncode == 0, err
        wait_for("the motor stops", lambda: model.state == stopped, timeout=2)


def test_an_access_security_file_epics_cannot_read_is_an_error_not_a_silent_ioc(
    epics: Epics, tmp_path: Path
) -> None:
    rules = tmp_path / "broken.acf"
    rules.write_text("ASG(DEFAULT) {\n    RULE(1, WRITE\n")  # a parenthesis short
    with Simulator({1: ProfileDevice(SENSOR)}) as sim:
        args = ioc_args(sim, SENSOR, "AS:", "--access-security", str(rules))
        done = subprocess.run(
            [sys.executable, "-m", "benchbus", "ioc", *args],
            env={**os.environ, **epics.env},
            stdin=subprocess.DEVNULL,
            capture_output=True,
            text=True,
            timeout=60,
        )
        with bb.Bus(sim.port) as bus:  # the line works for the next program
            assert bus.read_input_registers(1, 1, 1) == [215]
    assert done.returncode == 1, done.stderr
    assert "benchbus: the IOC did not start" in done.stderr
    assert "serving" not in done.stderr


def test_an_empty_interface_is_refused(epics: Epics) -> None:
    args = ["--profile", str(SENSOR), "--prefix", "X:", "--interface", " "]
    done = subprocess.run(
        [sys.executable, "-m", "benchbus", "ioc", *args],
        env={**os.environ, **epics.env},
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2
    assert "interface must name an address" in done.stderr


def test_serving_beyond_loopback_is_said_and_loopback_is_the_default(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    from benchbus.epics import serve_on

    for key in ("EPICS_CAS_INTF_ADDR_LIST", "EPICS_PVAS_INTF_ADDR_LIST"):
        monkeypatch.delenv(key, raising=False)
    for key in ("CAS_AUTO_BEACON", "CAS_BEACON", "PVAS_AUTO_BEACON", "PVAS_BEACON"):
        monkeypatch.delenv(f"EPICS_{key}_ADDR_LIST", raising=False)
    with caplog.at_level("WARNING", logger="benchbus.epics"):
        assert serve_on(None) == "127.0.0.1"
    assert os.environ["EPICS_PVAS_INTF_ADDR_LIST"] == "127.0.0.1"
    assert os.environ["EPICS_CAS_BEACON_ADDR_LIST"] == "127.255.255.255"
    assert caplog.records == []
    with caplog.at_level("WARNING", logger="benchbus.epics"):
        assert serve_on("192.0.2.7") == "192.0.2.7"  # documentation address: nothing binds
    assert os.environ["EPICS_CAS_INTF_ADDR_LIST"] == "192.0.2.7"
    assert os.environ["EPICS_PVAS_INTF_ADDR_LIST"] == "192.0.2.7"
    (warning,) = caplog.records
    assert "beyond loopback" in warning.getMessage()
    monkeypatch.setenv("EPICS_CAS_INTF_ADDR_LIST", "127.0.0.1")
    monkeypatch.setenv("EPICS_PVAS_INTF_ADDR_LIST", "")  # empty: every interface, to EPICS
    with caplog.at_level("WARNING", logger="benchbus.epics"):
        serve_on(None)
    assert len(caplog.records) == 2 and "beyond loopback" in caplog.records[1].getMessage()


# ---- PV Access -----------------------------------------------------------------------------


def test_pv_access_reads_values_with_their_metadata_and_puts_reach_the_wire(
    epics: Epics, fc_served: tuple[Simulator[ProfileDevice], ProfileDevice, Any]
) -> None:
    from p4p.client.thread import Context as PvaContext

    _, model, _ = fc_served
    env = epics.env
    conf = {
        key: env[key]
        for key in ("EPICS_PVA_ADDR_LIST", "EPICS_PVA_AUTO_ADDR_LIST", "EPICS_PVA_BROADCAST_PORT")
    }
    pva = PvaContext("pva", conf=conf, useenv=False)
    try:
        setpoint = pva.get("FC:setpoint_RBV", timeout=5)
        assert setpoint == 75.5
        assert setpoint.raw.display.units == "sccm"
        assert setpoint.raw.display.precision == 3
        assert (setpoint.raw.display.limitLow, setpoint.raw.display.limitHigh) == (0.0, 200.0)
        assert setpoint.severity == 0
        total = pva.get("FC:total", timeout=5)
        assert math.isclose(total, model.value("total"))
        assert total.raw.display.precision == 2 and total.raw.display.units == "scc"
        mode = pva.get("FC:mode_RBV", timeout=5)
        assert list(mode.raw.value.choices) == ["off", "control", "purge", "close"]
        assert mode.raw.value.choices[mode.raw.value.index] == model.value("mode")
        name = pva.get("FC:device_name_RBV", timeout=5)
        assert name == model.value("device_name")
        pva.put("FC:setpoint", 42.5, wait=True, timeout=5)
        assert model.value("setpoint") == 42.5
        pva.put("FC:mode", "off", wait=True, timeout=5)
        assert model.value("mode") == "off"
    finally:
        pva.close()


def test_two_iocs_on_two_lines_each_with_its_port_are_read_by_one_client(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    envs = [loopback_env(), loopback_env()]
    both = loopback_env(*envs)  # a client's: finds both
    assert both["EPICS_CA_ADDR_LIST"].split()[1:] == [e["EPICS_CA_ADDR_LIST"] for e in envs]
    for key, value in both.items():
        monkeypatch.setenv(key, value)
    ctx = caproto_client.Context()
    first, second = ProfileDevice(SENSOR), ProfileDevice(SENSOR)
    first.set_value("temperature", 21.5)
    second.set_value("temperature", 23.0)
    with (
        Simulator({1: first}) as a,
        Simulator({1: second}) as b,
        served(ioc_args(a, SENSOR, "BENCH1:"), envs[0], "BENCH1:ioc:connected", ctx),
        served(
            ioc_args(b, SENSOR, "BENCH2:"), envs[1], "BENCH2:ioc:connected", ctx, stop=signal.SIGINT
        ),
    ):
        assert read(ctx, "BENCH1:temperature").data[0] == 21.5
        assert read(ctx, "BENCH2:temperature").data[0] == 23.0


# ---- ophyd-async's EPICS backend in a Bluesky plan -------------------------------------------


def test_an_ophyd_async_epics_device_counts_and_moves_through_the_ioc(
    epics: Epics,
) -> None:
    import asyncio

    import bluesky.plan_stubs as bps
    from bluesky import RunEngine
    from bluesky.plans import count
    from ophyd_async.core import StandardReadable, StandardReadableFormat
    from ophyd_async.epics.core import epics_signal_r, epics_signal_rw_rbv

    class Sensor(StandardReadable):
        def __init__(self, prefix: str, name: str = "") -> None:
            with self.add_children_as_readables():
                self.temperature = epics_signal_r(float, f"ca://{prefix}temperature")
                self.humidity = epics_signal_r(float, f"ca://{prefix}humidity")
            with self.add_children_as_readables(StandardReadableFormat.CONFIG_SIGNAL):
                self.correction = epics_signal_rw_rbv(float, f"ca://{prefix}temperature_correction")
            super().__init__(name=name)

    model = ProfileDevice(SENSOR)
    model.set_value("temperature", 19.5)
    engine = RunEngine(call_returns_result=True)
    try:
        with (
            Simulator({1: model}) as sim,
            served(
                ioc_args(sim, SENSOR, "XY:", "--period", "0.2"),
                epics.env,
                "XY:ioc:connected",
                epics.client(),
            ),
        ):
            sensor = Sensor("XY:", name="sensor")
            asyncio.run_coroutine_threadsafe(sensor.connect(timeout=10), engine.loop).result(20)
            docs: list[tuple[str, dict[str, Any]]] = []
            engine(count([sensor], num=2), lambda name, doc: docs.append((name, doc)))
            descriptor = next(d for n, d in docs if n == "descriptor")
            assert descriptor["data_keys"]["sensor-temperature"]["units"] == "degC"
            assert descriptor["data_keys"]["sensor-temperature"]["source"].endswith(
                "XY:temperature"
            )
            events = [d for n, d in docs if n == "event"]
            assert [e["data"]["sensor-temperature"] for e in events] == [19.5, 19.5]
            assert events[0]["data"]["sensor-humidity"] == model.value("humidity")
            configuration = descriptor["configuration"]["sensor"]["data"]
            assert configuration["sensor-correction"] == model.value("temperature_correction")
            engine(bps.mv(sensor.correction, -1.5))
            assert model.value("temperature_correction") == -1.5
    finally:
        engine.loop.call_soon_threadsafe(engine.loop.stop)
        engine._th.join(timeout=5)


# ---- a built-in family ---------------------------------------------------------------------


@pytest.mark.parametrize("key", [f.key for f in command_families()])
def test_every_families_table_is_served_and_read_without_an_alarm(epics: Epics, key: str) -> None:
    """Each built-in family by name: every input record of its table read, none in alarm,
    its actions served."""
    family = command_families_by_key()[key]
    model = family.simulate(**family.bench_model)
    ctx = epics.client()
    with Simulator({1: model}) as sim:
        args = [key, "--port", sim.port, "--prefix", "F:", "--period", "0.2"]
        with served(args, epics.env, "F:ioc:connected", ctx):
            made, _ = pvs("F:", bb.Profile.family(key), actions=family.actions)
            inputs = [p.name for p in made if not p.output and p.register is not None]
            assert len(inputs) >= 20
            for name in inputs:
                reading = read(ctx, name, "time")
                assert (reading.metadata.severity, reading.metadata.status) == (0, 0), name
            for action in family.actions:
                assert read(ctx, f"F:{action}", "native") is not None


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
        with bb.Drive(sim.port) as drive:
            assert drive.speed == 0
