"""The examples of the README and of the documentation site's pages, and examples/*.py, run
as written, on simulated devices (and one on a third-party server)."""

from __future__ import annotations

import ast
import asyncio
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from pymodbus_peer import pymodbus_server

import benchbus as bb
from benchbus.sim import DriveDevice, J2Device, RegisterDevice, Simulator
from conftest import rtu

ROOT = Path(__file__).resolve().parent.parent


def doc_pages() -> list[Path]:
    """The README and every page of the documentation site."""
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def doc_blocks() -> list[str]:
    """Every Python block of the README and of the site's pages."""
    blocks = []
    for page in doc_pages():
        text = page.read_text("utf-8")
        blocks += re.findall(r"^ *```python\n(.*?)^ *```", text, flags=re.S | re.M)
    return [textwrap.dedent(block) for block in blocks]


#: What each test below picks its block by: every Python block of the README and of the
#: site's pages must be picked by exactly one, so that a new block cannot go untested.
PICKED_BY = (
    "bus.broadcast_write_register(",
    'bb.Drive("/dev/ttyUSB0"',
    "RegisterDevice(",
    "drive.record(",
    "def test_spin_up",
    "DriveDevice(",
    "PblDevice(",
    "J2Device(",
    "TaisongDevice(",
    "bus.poll(",
    "tcp://192.168.1.50:502",
    "bus.read_coils(",
    "bus.read_fifo_queue(",
    "bb.from_registers(",
    'framing="ascii"',
    "ProfileDevice(",
    'dev.baud = "b19200"',
    "sim_profile(",
    "Profile.family(",
    "benchbus.qcodes",
    "bb.aio.AsyncBus(",
    "benchbus.ophyd",
    "benchbus.epics",
    "Faults(",
    "bb.WrongDevice as",
    "bb.is_unknown(",
    "drive.set_many(",
    'bb.Device.from_profile("sdm630"',
)


def test_every_python_block_of_the_docs_is_run() -> None:
    for block in doc_blocks():
        assert sum(marker in block for marker in PICKED_BY) == 1, block


def test_readme_hardware_example_on_a_simulated_line(capsys: pytest.CaptureFixture[str]) -> None:
    """The first example, with the simulator's pty in place of /dev/ttyUSB0."""
    (block,) = [b for b in doc_blocks() if "bus.broadcast_write_register(" in b]
    drive = RegisterDevice({0x3006: 1450})
    meter = RegisterDevice(identity={0: "ACME", 1: "M-1", 2: "1.0"})
    with Simulator({1: drive, 2: meter}) as sim:
        exec(block.replace("/dev/ttyUSB0", sim.port), {})
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "{0: 'ACME', 1: 'M-1', 2: '1.0'}"
    assert out[1] == "[1, 2]"
    assert out[2].startswith("Stats(transactions=")
    assert drive.registers[0x2001] == 1500
    assert drive.registers[0x2003:0x2005] == [25, 25]
    # The broadcast reached both units.
    assert drive.registers[0x2000] == meter.registers[0x2000] == 5


def test_readme_hardware_drive_example(capsys: pytest.CaptureFixture[str]) -> None:
    """The README's drive on hardware, with a simulated BLD2's pty in place of /dev/ttyUSB0."""
    (block,) = [b for b in doc_blocks() if 'bb.Drive("/dev/ttyUSB0"' in b]
    device = DriveDevice("BLD2")
    with Simulator(device) as sim:
        exec(block.replace("/dev/ttyUSB0", sim.port), {})
    model, speed = capsys.readouterr().out.splitlines()
    assert model == "BLD2 DriveState.STOPPED"
    assert abs(int(speed.removesuffix(" rpm")) - 1500) <= 30
    # Leaving the block sent the stop (command 5 to 0x2000), its last request.
    assert device.peek(0x2000) == 5
    assert sim.requests[-1] == rtu("01 06 2000 0005")


def test_the_wrong_device_example(capsys: pytest.CaptureFixture[str]) -> None:
    """Concepts' drive made on a J2 controller's port: refused, and nothing written."""
    (block,) = [b for b in doc_blocks() if "bb.WrongDevice as" in b]
    with Simulator({1: J2Device(speedup=20)}) as sim:
        exec(block.replace("/dev/ttyUSB1", sim.port), {"bb": bb})
        assert not [f for f in sim.requests if f[1] in (0x06, 0x10)]
    said = [line.removeprefix("# ") for line in block.splitlines() if line.startswith("# ")]
    out = capsys.readouterr().out.splitlines()
    assert out == [" ".join(said[:-1]), said[-1]]


def test_the_unknown_enum_value_example(capsys: pytest.CaptureFixture[str]) -> None:
    """Concepts' drive state that DriveState does not list."""
    (block,) = [b for b in doc_blocks() if "bb.is_unknown(" in b]
    with Simulator({1: RegisterDevice({0x2100: 9})}) as sim, bb.Bus(sim.port) as bus:
        drive = bb.Drive(bus, 1, check_identity=False)
        exec(block, {"bb": bb, "drive": drive})
    shown = [line.split("# ")[1] for line in block.splitlines() if "print(" in line]
    assert capsys.readouterr().out.splitlines() == shown


def test_readme_networks_example(capsys: pytest.CaptureFixture[str]) -> None:
    """The Networks example, with a simulated Modbus TCP gateway in place of the real one."""
    (block,) = [b for b in doc_blocks() if "tcp://192.168.1.50:502" in b]
    drive = DriveDevice()
    with Simulator({1: drive}, network="tcp") as sim:
        exec(block.replace("tcp://192.168.1.50:502", sim.port), {})
        assert sim.requests, "it went through the simulated gateway"
    assert capsys.readouterr().out.splitlines() == ["1500"]
    assert drive.peek(0x2001) == 1500


def test_readme_functions_example(capsys: pytest.CaptureFixture[str]) -> None:
    """Every table's example, on a third-party server (pymodbus's, over RTU frames) in place
    of the device on /dev/ttyUSB1."""
    (block,) = [b for b in doc_blocks() if "bus.read_coils(" in b]
    with pymodbus_server(rtu=True) as url:
        exec(block.replace('"/dev/ttyUSB1", baudrate=9600', f'"{url}"'), {})
    assert capsys.readouterr().out.splitlines() == [
        "[True, False, True, True]",
        "[True, True, True, True, True, True]",
        "[False, True, False, True]",
        "[1000, 1001]",
        "0x17",
        "02 03 e8",
    ]


def test_counters_files_and_fifo_example(capsys: pytest.CaptureFixture[str]) -> None:
    """The example of 0x0B, 0x0C, 0x14, 0x15 and 0x18, on a simulated unit in the states of
    the specification's examples (6.9, 6.10, 6.14, 6.15, 6.18)."""
    (block,) = [b for b in doc_blocks() if "bus.read_fifo_queue(" in b]
    device = RegisterDevice({0x04DE: 2, 0x04DF: 0x01B8, 0x04E0: 0x1284})
    device.comm_busy, device.comm_event_count = True, 0x0108
    device.comm_message_count, device.comm_events = 0x0121, b"\x20\x00"
    device.files[3][9:11] = [0x33CD, 0x0040]
    with Simulator({1: device}) as sim:
        exec(block.replace("/dev/ttyUSB1", sim.port), {})
    assert capsys.readouterr().out.splitlines() == [
        "CommEventCounter(status=65535, event_count=264)",
        "290 40 80 20 00",  # the 0x0B before it: a message, logged (sent, received)
        "[[1711, 1214, 4109], [13261, 64]]",
        "[440, 4740]",
    ]
    assert device.files[4][7:10] == [0x06AF, 0x04BE, 0x100D]


def test_readme_ascii_example(capsys: pytest.CaptureFixture[str]) -> None:
    """The Modbus ASCII example, on the simulator's line speaking ASCII."""
    (block,) = [b for b in doc_blocks() if 'framing="ascii"' in b]
    device = RegisterDevice({0: 7, 1: 8})
    with Simulator({1: device}, framing="ascii") as sim:
        exec(block.replace("/dev/ttyUSB2", sim.port), {})
    assert capsys.readouterr().out.splitlines() == ["[7, 8]", "ascii 7 E 1"]
    assert device.registers[5] == 42


def test_readme_simulator_examples() -> None:
    blocks = [b for b in doc_blocks() if "RegisterDevice(" in b]
    assert len(blocks) >= 2  # a Bus on a simulator; the simulator's tables
    for block in blocks:
        exec(block, {})  # as written: it imports what it uses


def test_readme_profile_simulator_example(monkeypatch: pytest.MonkeyPatch) -> None:
    (block,) = [b for b in doc_blocks() if "ProfileDevice(" in b]
    monkeypatch.chdir(ROOT)  # the block names its profile from the repository's root
    exec(block, {})


def test_readme_profile_device_example(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The profile device, on the sensor's own simulator."""
    (block,) = [b for b in doc_blocks() if 'dev.baud = "b19200"' in b]
    from benchbus.sim import ProfileDevice

    monkeypatch.chdir(ROOT)  # the block names its profile from the repository's root
    sensor = ProfileDevice("examples/profiles/xy_md02.toml")
    with Simulator({1: sensor}) as sim:
        exec(block.replace("/dev/ttyUSB3", sim.port), {})
    assert capsys.readouterr().out.splitlines() == [
        "21.5 45.0",
        "Baud.b19200 %RH",
        "{'temperature': 21.5, 'humidity': 45.0}",
        "temperature_correction must be -10 to 10 degC, got 12",
    ]
    assert sensor.value("temperature_correction") == -0.5
    assert sensor.value("baud") == "b19200"


def test_shipped_profiles_example(capsys: pytest.CaptureFixture[str]) -> None:
    """The shipped SDM630 by name, on its simulator."""
    (block,) = [b for b in doc_blocks() if 'bb.Device.from_profile("sdm630"' in b]
    from benchbus.sim import ProfileDevice

    meter = ProfileDevice("sdm630", values={"voltage_l1": 231.5, "import_energy": 1234.5})
    with Simulator({1: meter}) as sim:
        exec(block.replace("/dev/ttyUSB0", sim.port), {})
    assert capsys.readouterr().out.splitlines() == [
        "231.5 1234.5",
        bb.Profile("sdm630").source,
    ]


def test_readme_profile_export_example() -> None:
    (block,) = [b for b in doc_blocks() if "Profile.family(" in b]
    exec(block, {})


def test_readme_poll_example(capsys: pytest.CaptureFixture[str]) -> None:
    """The polling loop, on a simulated drive's speed register, for 0.5 s instead of 10."""
    (block,) = [b for b in doc_blocks() if "bus.poll(" in b]
    with Simulator({1: RegisterDevice({0x3006: 1450})}) as sim, bb.Bus(sim.port) as bus:
        exec(block.replace("duration=10.0", "duration=0.5"), {"bus": bus})
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == " 0.0 s  1450"
    assert 3 <= len(lines) <= 5 and all(line.endswith(" s  1450") for line in lines)


def test_readme_drive_example(capsys: pytest.CaptureFixture[str]) -> None:
    (block,) = [b for b in doc_blocks() if "DriveDevice(" in b]
    exec(block, {})
    out = capsys.readouterr().out.splitlines()
    assert abs(int(out[0]) - 1500) <= 30
    assert out[1] == "DriveState.FORWARD None"
    frequency = float(out[2].split()[0])
    # 2 pole pairs by default. Of the speed reached, not of the one printed: that was read
    # within 30 rpm of it, maybe still ramping, and a loaded machine reads the telemetry later.
    assert abs(frequency - 1500 * 2 / 60) < 0.02
    assert out[3] == "5000"


def test_readme_pbl_example(capsys: pytest.CaptureFixture[str]) -> None:
    (block,) = [b for b in doc_blocks() if "PblDevice(" in b]
    exec(block, {})
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("PblStatus(running=True, direction=<Direction.REVERSE: 1>)")
    assert out[0].endswith("frozenset()")
    max_speed, count = out[1].split()
    assert int(max_speed) == 3000 and int(count) == 223 - 31


def test_readme_j2_example(capsys: pytest.CaptureFixture[str]) -> None:
    (block,) = [b for b in doc_blocks() if "J2Device(" in b]
    exec(block, {})
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "J2Mode.AUTO InputType.K -50.0 Pid(p=20.0, i=90.0, d=20.0)"
    assert out[1] == "J2Mode.MANUAL 35.0 43"


def test_readme_instrument_example(capsys: pytest.CaptureFixture[str]) -> None:
    (block,) = [b for b in doc_blocks() if "TaisongDevice(" in b]
    exec(block, {})
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "100 100"
    assert out[1] == "-12.5 123456789 21.5 bench 3"
    assert out[2].startswith(
        "Identification(vendor='TELEMECANIQUE', product_code='ATV31HU09M3S232'"
    )


@pytest.mark.skipif(sys.version_info < (3, 11), reason="QCoDeS needs Python 3.11")
def test_readme_qcodes_example(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """The QCoDeS example, on a simulated flow controller, its database in a temporary
    directory."""
    import qcodes
    from qcodes.instrument import Instrument

    from benchbus.sim import ProfileDevice

    (block,) = [b for b in doc_blocks() if "benchbus.qcodes" in b]
    model = ProfileDevice(ROOT / "examples" / "profiles" / "flow_controller.toml")
    monkeypatch.chdir(tmp_path)  # the block writes flows.db where it runs
    monkeypatch.setitem(qcodes.config.core, "db_location", qcodes.config.core.db_location)
    with Simulator({1: model}) as sim:
        block = block.replace("examples/profiles/", f"{ROOT}/examples/profiles/")
        exec(block.replace("/dev/ttyUSB3", sim.port), {})
        assert sim.errors == []
    assert not Instrument.exist("fc")
    assert capsys.readouterr().out.splitlines() == [
        "sccm <Numbers 0.0<=v<=200.0> False",
        "Starting experimental run with id: 1. ",  # QCoDeS says so
        "[49.75 49.75 49.75]",
    ]
    assert model.value("setpoint") == 100.0
    assert (tmp_path / "flows.db").is_file()


def test_readme_asyncio_example(capsys: pytest.CaptureFixture[str]) -> None:
    """The notebook cell, with its top-level await, on a simulated drive."""
    (block,) = [b for b in doc_blocks() if "bb.aio.AsyncBus(" in b]
    device = DriveDevice()
    with Simulator({1: device}) as sim:
        source = block.replace("/dev/ttyUSB4", sim.port)
        code = compile(source, "<README>", "exec", flags=ast.PyCF_ALLOW_TOP_LEVEL_AWAIT)

        async def cell() -> None:
            await eval(code, {})  # what a notebook does with a cell that awaits

        asyncio.run(cell())
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("0.0 s  ") and out[4].startswith("0.4 s  ")
    assert out[5] == "1500 1500"
    assert device.commands == [1, 5]


@pytest.mark.skipif(sys.version_info < (3, 11), reason="ophyd-async needs Python 3.11")
def test_readme_ophyd_example(capsys: pytest.CaptureFixture[str]) -> None:
    """The Bluesky example, on a simulated flow controller and a simulated drive."""
    from benchbus.sim import ProfileDevice

    (block,) = [b for b in doc_blocks() if "benchbus.ophyd" in b]
    model = ProfileDevice(ROOT / "examples" / "profiles" / "flow_controller.toml")
    drive = DriveDevice(single_register_reads=False)
    with Simulator({1: model}) as sim, Simulator(drive) as drive_sim:
        block = block.replace("examples/profiles/", f"{ROOT}/examples/profiles/")
        block = block.replace("/dev/ttyUSB3", sim.port).replace("/dev/ttyUSB4", drive_sim.port)
        exec(block, {"__name__": "readme"})
        assert sim.errors == drive_sim.errors == []
    units = "{'fc-flow': 'sccm', 'fc-total': 'scc', 'fc-gas_temperature': 'degC', "
    units += "'fc-runtime': 's', 'spindle-speed': 'rpm'}"
    assert capsys.readouterr().out.splitlines() == [units, "49.75 True", "49.75 True"]
    assert model.value("setpoint") == 100.0
    assert model.value("mode") == "control"
    assert drive.peek(0x2001) == 1500
    # Forward, the stop at the end of the plan, and the one leaving the with block sends.
    assert drive.commands == [1, 5, 5]


def test_epics_guide_example(monkeypatch: pytest.MonkeyPatch) -> None:
    """The IOC made from Python, in a process of its own (an IOC is one per process), on a
    simulated sensor and drive; read over Channel Access, then stopped by SIGTERM, which
    stops the drive."""
    from epics_clients import read, served

    from benchbus.epics import loopback_env, pvs
    from benchbus.sim import ProfileDevice

    (block,) = [b for b in doc_blocks() if "benchbus.epics" in b]
    env = loopback_env()
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    sensor = ProfileDevice(ROOT / "examples" / "profiles" / "xy_md02.toml")
    drive = DriveDevice()
    with Simulator({1: sensor, 2: drive}) as sim:
        code = block.replace("examples/profiles/", f"{ROOT}/examples/profiles/")
        code = code.replace("/dev/ttyUSB0", sim.port)
        import caproto.threading.client as caproto_client

        ctx = caproto_client.Context()
        command = [sys.executable, "-c", code]
        says = ("stdout", "")  # the block's first line of its own
        with served([], env, "LAB:SPINDLE:ioc:connected", ctx, command, serving=says) as process:
            assert read(ctx, "LAB:XY:temperature").data[0] == sensor.value("temperature")
            read(ctx, "LAB:SPINDLE:speed_setpoint")  # the drive's records are there
            ctx.get_pvs("LAB:SPINDLE:forward")[0].write([1], wait=True, timeout=5)
            assert drive.commands == [1]
        assert drive.commands == [1, 5]  # SIGTERM stopped it
        assert sim.errors == []
        with bb.Bus(sim.port) as bus:  # the line works for the next program
            stats = tuple(bus.stats.as_dict())
    profile = bb.Profile(ROOT / "examples" / "profiles" / "xy_md02.toml")
    actions = tuple(name for name, _ in bb.Drive.commands())
    served_pvs = pvs("LAB:XY:", profile, stats=stats)[0]
    served_pvs += pvs("LAB:SPINDLE:", bb.Profile.family("drive"), actions=actions, stats=stats)[0]
    said = [n for n in process.stdout_text.splitlines() if "PVs" in n]  # type: ignore[attr-defined]
    assert said == [f"{len(served_pvs)} PVs, such as LAB:XY:temperature"]


def test_readme_values_example(capsys: pytest.CaptureFixture[str]) -> None:
    (block,) = [b for b in doc_blocks() if "bb.from_registers(" in b]
    device = RegisterDevice()
    # 21.5 (0x41AC0000) and -0.5 (0xBF000000) as two floats, low word first.
    device.registers[0x0100:0x0104] = [0x0000, 0x41AC, 0x0000, 0xBF00]
    with Simulator({1: device}) as sim, bb.Bus(sim.port) as bus:
        exec(textwrap.dedent(block), {"bb": bb, "bus": bus})
        assert sim.peek(1, 0x0200, 2) == [0xFFFF, 0xFFFB]
    assert capsys.readouterr().out == "[21.5, -0.5]\n"


def test_readme_pytest_example(pytester: pytest.Pytester) -> None:
    (block,) = [b for b in doc_blocks() if "def test_spin_up" in b]
    pytester.makepyfile(test_readme_bench=block)
    pytester.runpytest_subprocess("-q").assert_outcomes(passed=2)


def test_readme_sim_profile_example(pytester: pytest.Pytester) -> None:
    (block,) = [b for b in doc_blocks() if "sim_profile(" in b]
    profiles = pytester.path / "examples" / "profiles"
    profiles.mkdir(parents=True)
    (profiles / "xy_md02.toml").write_bytes(
        (ROOT / "examples" / "profiles" / "xy_md02.toml").read_bytes()
    )
    pytester.makepyfile(test_readme_profile=block)
    pytester.runpytest_subprocess("-q").assert_outcomes(passed=1)


def test_registers_by_name_example(capsys: pytest.CaptureFixture[str]) -> None:
    """The concepts page's get_many / set_many, on a simulated drive."""
    (block,) = [b for b in doc_blocks() if "drive.set_many(" in b]
    with Simulator(DriveDevice("BLD2")) as sim, bb.Drive(sim.port, unit=1) as drive:
        exec(block, {"drive": drive})
        # Written to the manual's addresses (0x2001 rpm; 0x2003 in tenths of a second),
        # read one a request as the drive answers.
        words = [drive.bus.read_holding_registers(1, a, 1) for a in (0x2001, 0x2003)]
        assert words == [[1200], [25]]
    printed = capsys.readouterr().out.splitlines()
    assert printed == ["{'speed_setpoint': 1200, 'accel_time': 2.5}"]
    assert block.splitlines()[-1] == f"# {printed[0]}"


def test_faults_example(pytester: pytest.Pytester) -> None:
    """The testing guide's noisy-line test: one spoilt reply, retried, counted."""
    (block,) = [b for b in doc_blocks() if "Faults(" in b]
    pytester.makepyfile(test_faults_example=block)
    pytester.runpytest_subprocess("-q").assert_outcomes(passed=1)


def test_readme_recording_example() -> None:
    (block,) = [b for b in doc_blocks() if "drive.record(" in b]
    from benchbus.sim import DriveDevice

    fast = DriveDevice(single_register_reads=False)  # a telemetry sample in one request
    with Simulator(fast) as sim, bb.Drive(sim.port) as drive:
        drive.speed_setpoint = 600
        drive.forward()
        scope: dict[str, object] = {"drive": drive}
        exec(block.replace("10.0, 0.1", "1.0, 0.1"), scope)
        rec = scope["rec"]
        assert isinstance(rec, bb.Recording) and len(rec) == 10
        assert max(rec["speed"]) > 0


def run_example(name: str) -> str:
    """examples/``name``, in its own process as a user runs it; its output."""
    done = subprocess.run(
        [sys.executable, str(ROOT / "examples" / name)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_drive_bench_example_runs() -> None:
    out = run_example("drive_bench.py").splitlines()
    assert out[0].startswith("BLD2 on /dev/pts/") and out[0].endswith("DriveState.STOPPED")
    assert out[1].startswith("  running at 1") and "80.00 Hz" in out[1]
    assert out[2] == "  refused while running (code 8): not changeable while running"
    assert out[3] == "  DriveState.FAULT, fault 0x0A undervoltage"
    assert out[4] == "  after reset: DriveState.STOPPED, fault None"
    assert out[5] == "  left the block: the drive got command 5 (stop), DriveState.STOPPED"


def test_profiles_tour_runs() -> None:
    out = run_example("profiles/tour.py").splitlines()
    assert out[0] == "XY-MD02 (RS485 temperature and humidity sensor), 6 registers"
    assert "    temperature                        21.5 degC" in out
    assert "    baud                         Baud.b9600" in out
    assert "  one sample took 2 requests" in out  # input registers, then the settings
    assert "  wrote baud = 'b19200': reads back Baud.b19200" in out
    assert "  one sample took 4 requests" in out  # coils, inputs, two register reads
    assert "  wrote all_off = True: reads back True" in out
    assert "    total                           1234.56 scc" in out
    assert "  one sample took 8 requests" in out  # block_reads = false: one each
    assert "  wrote mode = 'purge': reads back Mode.purge" in out
    refused = [line for line in out if line.startswith("  refused:")]
    assert len(refused) == 3 and all(line.endswith("(0 requests sent)") for line in refused)


def test_first_steps_example_runs() -> None:
    stdout = run_example("first_steps.py")
    assert "measured value = 1000, setpoint = 250" in stdout
    assert "setpoint = 100, 0x0008..9 = [100, 200]" in stdout
    assert "refused at once" in stdout
    assert "silent unit" in stdout
