"""The pytest plugin (benchbus.pytest_plugin), run inside pytest with pytester.

The plugin loads through its ``pytest11`` entry point in the inner runs, in process and in
a subprocess alike. The ``--benchbus-port`` runs point at a Simulator started here, which
stands in for the real line.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

import benchbus as bb
from benchbus import pytest_plugin
from benchbus._families import FAMILIES, Family
from benchbus.sim import DriveDevice, J2Device, Simulator

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "bench" / "test_motor_bench.py"
PROFILES = ROOT / "examples" / "profiles"

SIMULATED_HEADER = "benchbus: simulated devices (tests marked hardware skipped: no --benchbus-port)"
SKIP_REASON = "needs a real device: run with --benchbus-port PATH"


@pytest.fixture(autouse=True)
def _plugins_autoload(monkeypatch: pytest.MonkeyPatch) -> None:
    """The inner runs load plugins from their entry points, whatever the environment says."""
    monkeypatch.delenv("PYTEST_DISABLE_PLUGIN_AUTOLOAD", raising=False)
    monkeypatch.delenv("PYTEST_ADDOPTS", raising=False)


@pytest.fixture
def rig() -> Iterator[tuple[Simulator[DriveDevice | J2Device], DriveDevice, J2Device]]:
    """A real line for --benchbus-port: a BLD2 drive at unit 1, a J2 controller at unit 2."""
    drive, j2 = DriveDevice("BLD2"), J2Device(speedup=100)
    devices: dict[int, DriveDevice | J2Device] = {1: drive, 2: j2}
    with Simulator(devices) as sim:
        yield sim, drive, j2


def sim_threads() -> set[threading.Thread]:
    return {t for t in threading.enumerate() if t.name.startswith("benchbus-sim")}


def open_fds() -> int:
    return len(os.listdir("/proc/self/fd"))


def test_importing_the_plugin_imports_no_simulator() -> None:
    """pytest loads the plugin into every run: it must not pull in pymodbus."""
    code = (
        "import sys, benchbus.pytest_plugin\n"
        "print(sorted(m for m in sys.modules if m.startswith(('pymodbus', 'serial', "
        "'benchbus.sim'))))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True
    )
    assert done.stdout.strip() == "[]"


SIM_TESTS = """
import time

import pytest

import benchbus as bb
from benchbus.sim import DriveDevice, J2Device, PblDevice, Simulator, TaisongDevice


def test_drive(sim_drive):
    drive, sim, model = sim_drive
    assert isinstance(drive, bb.Drive) and isinstance(sim, Simulator)
    assert isinstance(model, DriveDevice) and model.model == "BLD2"
    assert (drive.unit, drive.bus.port, drive.bus.baudrate) == (1, sim.port, 19200)
    drive.accel_time = 0.1
    drive.speed_setpoint = 900
    drive.forward()
    assert abs(drive.wait_for_speed(900, tolerance=20, timeout=3) - 900) <= 20
    assert model.state == model.FORWARD and abs(model.speed - 900) <= 20
    assert model.commands == [1]
    assert sim.requests[-1][:2] == bytes([1, 0x03])
    model.inject_fault(0x0A)
    assert drive.state == bb.DriveState.FAULT and drive.fault.code == 0x0A
    with pytest.raises(bb.ModbusException) as refused:
        drive.forward()
    assert refused.value.code == 1
    sim.set_silent(1)
    with pytest.raises(bb.ResponseTimeout):
        drive.speed


def test_pbl(sim_pbl):
    pbl, sim, model = sim_pbl
    assert isinstance(pbl, bb.PblDrive) and isinstance(model, PblDevice)
    assert (pbl.unit, pbl.bus.port, pbl.bus.baudrate, pbl.bus.parity) == (1, sim.port, 115200, "E")
    pbl.acceleration = 0  # at once
    pbl.speed_setpoint = 1200
    pbl.start()
    assert model.running and model.speed == 1200
    assert pbl.speed == 1200
    model.inject_alarm(3)
    assert pbl.alarm_word == 1 << 3 and model.speed == 0
    sim.corrupt_next(3)
    with pytest.raises(bb.CrcError):
        pbl.speed


def test_j2(sim_j2):
    j2, sim, model = sim_j2
    assert isinstance(j2, bb.J2Controller) and isinstance(model, J2Device)
    assert (j2.unit, j2.bus.baudrate, model.speedup) == (1, 9600, 100)
    j2.sv = 60.0
    assert model.value("SV") == 60.0
    deadline = time.monotonic() + 5
    while abs(j2.pv - 60.0) > 3:
        assert time.monotonic() < deadline, "the sped-up process does not heat"
        time.sleep(0.05)
    sim.answer_exception(4, unit=1)
    with pytest.raises(bb.ModbusException) as refused:
        j2.sv = 70.0
    assert refused.value.code == 4
    assert model.value("SV") == 60.0


def test_instrument(sim_instrument):
    meter, sim, model = sim_instrument
    assert isinstance(meter, bb.Instrument) and isinstance(model, TaisongDevice)
    assert (meter.unit, meter.bus.baudrate, model.speedup) == (1, 9600, 10)
    meter.write_register(0x0005, 500)
    assert model.sv == 500
    model.hold(123)
    assert meter.read_register(0x0000) == 123
    sim.set_silent(None)
    with pytest.raises(bb.ResponseTimeout):
        meter.read_register(0x0000)
"""

C20_TESTS = """
import pytest

import benchbus as bb
from benchbus.sim import DriveDevice


@pytest.fixture
def sim_drive_model():
    return DriveDevice("C20")


def test_an_overridden_model(sim_drive):
    assert sim_drive.model.model == "C20"
    assert sim_drive.device.family == "C20" and sim_drive.device.model == bb.Model.C20


def test_bench_on_the_overridden_model(bench_drive, benchbus_port):
    assert benchbus_port is None
    assert bench_drive.model == bb.Model.C20
"""


def test_sim_fixtures_give_device_simulator_and_model(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_inner_sim=SIM_TESTS, test_inner_c20=C20_TESTS)
    result = pytester.runpytest_inprocess("-p", "no:cacheprovider")
    result.assert_outcomes(passed=6)


def test_each_family_of_the_registry_has_its_three_fixtures_documented(
    pytester: pytest.Pytester,
) -> None:
    result = pytester.runpytest_inprocess("-p", "no:cacheprovider", "--fixtures")
    listed = result.stdout.str()
    for of in FAMILIES:
        names = [f"sim_{of.key}_model", f"sim_{of.key}", f"bench_{of.key}"]
        for name in names:
            assert (f"\n{name} -- " in listed) == (of.device is not None), (name, listed)
        if of.device is not None:
            # Each says what it gives: the simulator and how it is made, the class.
            assert f"benchbus.sim.{of.simulator}(" in listed
            assert f"benchbus.{of.device.__name__}" in listed


XY_TESTS = """
import benchbus as bb
from benchbus.sim import TaisongDevice


def test_sim(sim_xy):
    meter, sim, model = sim_xy
    assert isinstance(meter, bb.Instrument) and isinstance(model, TaisongDevice)
    assert model.speedup == 5.0
    meter.write_register(0x0005, 321)
    assert model.sv == 321


def test_bench(bench_xy, sim_xy_model):
    assert isinstance(bench_xy, bb.Instrument) and sim_xy_model.speedup == 5.0
    sim_xy_model.hold(77)
    assert bench_xy.read_register(0x0000) == 77
"""


def test_a_family_added_to_the_registry_gets_its_fixtures(
    pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    xy = Family(
        "xy",
        "an XY meter",
        bb.Instrument,
        "TaisongDevice",
        ("speedup",),
        bench_model={"speedup": 5.0},
    )
    for name in ("sim_xy_model", "sim_xy", "bench_xy"):
        monkeypatch.setattr(pytest_plugin, name, None, raising=False)  # gone after the test
    pytest_plugin._add_fixtures(xy)
    pytester.makepyfile(test_inner_xy=XY_TESTS)
    result = pytester.runpytest_inprocess("-p", "no:cacheprovider")
    result.assert_outcomes(passed=2)


def test_a_failing_test_still_closes_everything(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(
        """
        import threading
        from pathlib import Path


        def test_sim_fails(sim_drive, sim_pbl, sim_j2, sim_instrument):
            sim_drive.sim.set_silent(None)  # closing must not need the line
            sim_drive.model.inject_fault(0x0A)
            threads = [t for t in threading.enumerate() if t.name.startswith("benchbus-sim")]
            Path("during.txt").write_text(str(len(threads)))
            assert False, "inner failure"


        def test_bench_fails(bench_drive, bench_pbl, bench_j2, bench_instrument):
            bench_drive.speed_setpoint = 500
            bench_drive.forward()
            bench_pbl.start()
            raise RuntimeError("inner error")


        def test_closed_by_the_test(sim_pbl, bench_drive):
            sim_pbl.device.close()
            bench_drive.close()
            assert False, "inner failure"
        """
    )
    threads, fds = sim_threads(), open_fds()
    result = pytester.runpytest_inprocess("-p", "no:cacheprovider")
    result.assert_outcomes(failed=3)  # and no errors: every teardown went through
    result.stdout.fnmatch_lines(["*AssertionError: inner failure*", "*RuntimeError: inner error"])
    assert int((pytester.path / "during.txt").read_text()) >= 8  # 4 simulators, 2 threads each
    assert sim_threads() <= threads
    assert open_fds() == fds


HARDWARE_TESTS = """
import pytest

import benchbus as bb


def test_either(bench_drive, benchbus_port):
    assert bench_drive.state == bb.DriveState.STOPPED


@pytest.mark.hardware
def test_on_the_line(bench_drive, bench_j2, benchbus_port):
    assert bench_drive.bus.port == benchbus_port
    assert bench_drive.bus is bench_j2.bus  # one Bus for the line
    assert (bench_drive.unit, bench_j2.unit, bench_drive.bus.baudrate) == (1, 2, 19200)
    bench_drive.accel_time = 0.1
    bench_drive.speed_setpoint = 600
    bench_drive.forward()
    bench_drive.wait_for_speed(600, tolerance=20, timeout=3)
    bench_j2.sv = 55.0
    assert bench_j2.sv == 55.0


@pytest.mark.hardware
def test_fails_while_running(bench_drive):
    bench_drive.speed_setpoint = 700
    bench_drive.forward()
    assert False, "inner failure"
"""


def test_hardware_tests_are_skipped_without_a_port(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_inner_hardware=HARDWARE_TESTS)
    result = pytester.runpytest_inprocess("-p", "no:cacheprovider", "-rs", "--strict-markers")
    result.assert_outcomes(passed=1, skipped=2)
    skipped = f"SKIPPED [[]1[]] test_inner_hardware.py:*: {SKIP_REASON}"
    result.stdout.fnmatch_lines([SIMULATED_HEADER, skipped, skipped])


def test_hardware_tests_run_on_the_port(
    pytester: pytest.Pytester,
    rig: tuple[Simulator[DriveDevice | J2Device], DriveDevice, J2Device],
) -> None:
    sim, drive, j2 = rig
    pytester.makepyfile(test_inner_hardware=HARDWARE_TESTS)
    args = ("--benchbus-port", sim.port, "--benchbus-unit", "j2=2", "--benchbus-baudrate", "19200")
    result = pytester.runpytest_inprocess("-p", "no:cacheprovider", "--strict-markers", *args)
    result.assert_outcomes(passed=2, failed=1)
    result.stdout.fnmatch_lines(
        [
            f"benchbus: devices on {sim.port} (units: drive 1, pbl 1, j2 2, instrument 1;"
            " 19200 baud, parity of the family)"
        ]
    )
    assert SIMULATED_HEADER not in result.stdout.str()
    # Every test ended with a stop, the failing one too: forward (1) and stop (5).
    assert drive.commands == [5, 1, 5, 1, 5]
    assert drive.state == DriveDevice.STOPPED or drive.speed < 700
    assert j2.value("SV") == 55.0


def test_devices_on_one_line_need_one_line_format(
    pytester: pytest.Pytester,
    rig: tuple[Simulator[DriveDevice | J2Device], DriveDevice, J2Device],
) -> None:
    sim, drive, _ = rig
    pytester.makepyfile(
        """
        def test_two(bench_drive, bench_j2):
            pass
        """
    )
    result = pytester.runpytest_inprocess("-p", "no:cacheprovider", "--benchbus-port", sim.port)
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(
        [
            f"bench_drive and bench_j2 share {sim.port}, but their line formats differ"
            " (19200 8N1 and 9600 8N1): give the line's with --benchbus-baudrate and"
            " --benchbus-parity"
        ]
    )
    assert drive.commands == [5]  # the drive opened first was stopped and closed all the same


@pytest.mark.parametrize(
    ("option", "message"),
    [
        ("--benchbus-unit=oven=2", "argument --benchbus-unit: 'oven' is not one of drive, pbl,*"),
        ("--benchbus-unit=256", "argument --benchbus-unit: a unit address is 1 to 255, not 256"),
        ("--benchbus-baudrate=fast", "argument --benchbus-baudrate: 'fast' is not a baud rate"),
        ("--benchbus-parity=X", "argument --benchbus-parity: invalid choice: 'X'*"),
    ],
)
def test_bad_options_are_usage_errors(pytester: pytest.Pytester, option: str, message: str) -> None:
    result = pytester.runpytest_inprocess(option)
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines([f"*error: {message}"])


def test_the_example_bench_passes_simulated_and_on_a_line(
    pytester: pytest.Pytester,
    rig: tuple[Simulator[DriveDevice | J2Device], DriveDevice, J2Device],
) -> None:
    shutil.copy(EXAMPLE, pytester.path)
    # In a fresh process, as a user runs it: the plugin comes from its entry point.
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", "-rs")
    result.assert_outcomes(passed=6, skipped=2)
    result.stdout.fnmatch_lines([SIMULATED_HEADER])

    sim, drive, j2 = rig
    args = ("--benchbus-port", sim.port, "--benchbus-unit", "j2=2", "--benchbus-baudrate", "19200")
    result = pytester.runpytest_inprocess("-p", "no:cacheprovider", *args)
    result.assert_outcomes(passed=8)
    assert drive.commands.count(1) == 3  # three tests ran the drive on the line
    assert drive.state == DriveDevice.STOPPED
    assert j2.value("SV") == j2.DEFAULTS["SV"]  # the setpoint was put back


PROFILE_TESTS = """
import threading
from pathlib import Path

import pytest

import benchbus as bb
from benchbus.pytest_plugin import ProfileBench
from benchbus.sim import ProfileDevice, Simulator

PROFILES = Path({profiles!r})


def sim_threads():
    return [t for t in threading.enumerate() if t.name.startswith("benchbus-sim")]


def test_defaults_and_values(sim_profile):
    bench = sim_profile(PROFILES / "xy_md02.toml", unit=3, values={{"humidity": 51.2}})
    assert isinstance(bench, ProfileBench) and isinstance(bench.model, ProfileDevice)
    assert isinstance(bench.sim, Simulator) and bench.unit == 3
    assert bench.port == bench.sim.port == bench.bus.port and bench.port.startswith("/dev/")
    assert bench.baudrate == bench.sim.baudrate == bench.bus.baudrate == 9600  # its [line]
    assert (bench.bus.parity, bench.bus.timeout, bench.framing) == ("N", 0.5, "rtu")
    # temperature 21.5 (its default) and humidity 51.2 (values=), 0.1 a count
    assert bench.bus.read_input_registers(3, 0x0001, 2) == [215, 512]
    assert bench.bus.read_holding_registers(3, 0x0101, 2) == [1, 0]  # unit_address, b9600
    bench.bus.write_register(3, 0x0102, 2)
    assert bench.model.value("baud") == "b19200"
    assert bench.sim.requests[-1][:2] == bytes([3, 0x06])
    with pytest.raises(bb.ResponseTimeout):
        bench.bus.read_input_registers(1, 0x0001, 1)  # only unit 3 answers
    # The device on that Bus, in engineering units.
    assert isinstance(bench.device, bb.Device) and bench.device.unit == 3
    assert bench.device.humidity == 51.2 and bench.device.baud.name == "b19200"
    bench.device.temperature_correction = -0.5
    assert bench.model.value("temperature_correction") == -0.5


def test_several_profiles_each_on_its_own_simulator(sim_profile):
    flow = sim_profile(PROFILES / "flow_controller.toml", values={{"mode": "purge"}})
    relays = sim_profile(PROFILES / "relay_board.toml", baudrate=38400, framing="ascii")
    assert flow.port != relays.port and flow.sim is not relays.sim
    assert (flow.baudrate, flow.bus.parity, flow.bus.timeout) == (19200, "E", 0.2)
    assert bb.from_registers(flow.bus.read_holding_registers(1, 0, 2), "f32", "CDAB") == [50.0]
    assert flow.bus.read_holding_registers(1, 0x10, 1) == [2]  # purge
    assert (relays.baudrate, relays.framing) == (38400, "ascii")
    assert (relays.sim.baudrate, relays.sim.framing) == (38400, "ascii")
    # Another framing than the profile's (RTU 8N1): the Bus's own format for it, 7E1.
    assert (relays.bus.framing, relays.bus.bytesize, relays.bus.parity) == ("ascii", 7, "E")
    assert relays.bus.read_coils(1, 0, 3) == [True, False, False]


def test_a_broken_profile_starts_nothing(sim_profile, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[device]\\nname = "x"\\n\\n[[register]]\\nname = "a"\\naddress = 70000\\n')
    before = sim_threads()
    with pytest.raises(bb.ProfileError, match=r"bad.toml:6: register\\[0\\].address"):
        sim_profile(bad)
    assert sim_threads() == before


def test_fails_with_simulators_running(sim_profile):
    sim_profile(PROFILES / "xy_md02.toml")
    sim_profile(PROFILES / "relay_board.toml").sim.set_silent(None)
    Path("during.txt").write_text(str(len(sim_threads())))
    assert False, "inner failure"
"""


def test_sim_profile_serves_profiles_and_stops_them_after(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_inner_profile=PROFILE_TESTS.format(profiles=str(PROFILES)))
    threads, fds = sim_threads(), open_fds()
    result = pytester.runpytest_inprocess("-p", "no:cacheprovider")
    result.assert_outcomes(passed=3, failed=1)  # and no errors: every teardown went through
    result.stdout.fnmatch_lines(["*AssertionError: inner failure*"])
    assert int((pytester.path / "during.txt").read_text()) >= len(threads) + 4  # 2 each
    assert sim_threads() <= threads  # every simulator stopped
    assert open_fds() == fds  # every pseudo-terminal and Bus closed


WRONG_BENCH = """
import benchbus as bb


def test_reads(bench_drive):
    assert isinstance(bench_drive.speed, int)
"""


ABSENT_BENCH = """
def test_nothing_yet(bench_drive):
    assert bench_drive.unit == 3
"""


def test_a_bench_device_that_does_not_answer_is_not_refused_at_setup(
    pytester: pytest.Pytester,
    rig: tuple[Simulator[DriveDevice | J2Device], DriveDevice, J2Device],
) -> None:
    # No unit 3 on the line: the check at setup times out, which says nothing of its family,
    # so the test runs (the drive is checked when it first answers); the stop at teardown
    # is what meets the silence.
    sim, _, _ = rig
    pytester.makepyfile(test_inner_absent=ABSENT_BENCH)
    args = ["--benchbus-port", sim.port, "--benchbus-unit", "drive=3"]
    args += ["--benchbus-baudrate", "19200"]
    result = pytester.runpytest_inprocess("-p", "no:cacheprovider", *args)
    result.assert_outcomes(passed=1, errors=1)
    assert "WrongDevice" not in result.stdout.str()
    result.stdout.fnmatch_lines(["*ERROR at teardown of test_nothing_yet*", "*ResponseTimeout*"])
    assert [f[1] for f in sim.requests if f[0] == 3] and not [
        f for f in sim.requests if f[0] == 3 and f[1] in (0x06, 0x10)
    ]


@pytest.mark.parametrize("checked", [True, False])
def test_a_bench_device_of_another_family_fails_the_setup(
    pytester: pytest.Pytester,
    rig: tuple[Simulator[DriveDevice | J2Device], DriveDevice, J2Device],
    checked: bool,
) -> None:
    sim, _, j2 = rig
    pytester.makepyfile(test_inner_wrong=WRONG_BENCH)
    args = ["--benchbus-port", sim.port, "--benchbus-unit", "drive=2"]
    args += ["--benchbus-baudrate", "19200"]
    if not checked:
        args.append("--benchbus-no-identity-check")
    result = pytester.runpytest_inprocess("-p", "no:cacheprovider", *args)
    if checked:
        result.assert_outcomes(errors=1)
        result.stdout.fnmatch_lines(["*WrongDevice: unit 2 answers but is not a BLD drive*"])
    else:  # unchecked, the drive reads the J2's zeros, and its stop at teardown is refused
        result.assert_outcomes(passed=1, errors=1)
        result.stdout.fnmatch_lines(["*ModbusException: unit 2, function 0x06*"])
    writes = [f for f in sim.requests if f[0] == 2 and f[1] in (0x06, 0x10)]
    assert bool(writes) is not checked  # only the unchecked drive's stop reached the J2
    assert j2.value("SV") == J2Device(speedup=100).value("SV")
