"""The command line as a person meets it: one-line errors, the wrong device, a lost port,
plain words and ranges, units. Run as a user runs it, against the simulators."""

from __future__ import annotations

import fcntl
import os
import pty
import re
import select
import signal
import subprocess
import termios
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO

import pytest
from test_cli import MODULE, _env, ok, one_line_error, readline, run, start, table
from test_port_loss import Adapter

import benchbus as bb
from benchbus import cli
from benchbus.sim import (
    DriveDevice,
    J2Device,
    PblDevice,
    RegisterDevice,
    SimDevice,
    Simulator,
    TaisongDevice,
)

# ---- never a traceback -------------------------------------------------------------------------


def test_demo_on_a_port_without_the_unit_is_one_line(tmp_path: Path) -> None:
    """No unit 7: the read fails, the stop on leaving fails too; both are in one line."""
    with Simulator({1: DriveDevice("BLD2")}) as sim:
        done = run("demo", "--port", sim.port, "--unit", "7", "--out", tmp_path / "d.png")
    line = one_line_error(done, 1)
    assert "unit 7" in line and "could not stop the motor" in line
    assert not (tmp_path / "d.png").exists()


def test_traceback_shows_the_failed_stop_in_full(tmp_path: Path) -> None:
    with Simulator({1: DriveDevice("BLD2")}) as sim:
        done = run(
            "demo", "--port", sim.port, "--unit", "7", "--out", tmp_path / "d.png", "--traceback"
        )
    assert done.returncode == 1
    assert "Traceback" in done.stderr and "could not stop the motor" in done.stderr


def test_a_reader_that_goes_away_is_no_traceback() -> None:
    """``benchbus read ... | head -1``: the output pipe closes before it is written."""
    with Simulator({1: RegisterDevice()}) as sim:
        proc = subprocess.Popen(
            [*MODULE, "read", "--port", sim.port, "0", "100"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=_env(),
        )
        assert proc.stdout is not None and proc.stderr is not None
        proc.stdout.close()
        err = proc.stderr.read()
        status = proc.wait(timeout=30)
    assert status == 1
    assert "Traceback" not in err and "Exception ignored" not in err, err


class _Panic(BaseException):
    """What a panic in the compiled core reaches Python as (not an Exception)."""


def test_an_error_that_is_no_exception_is_one_line(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def panics(args: object) -> int:
        raise _Panic("index out of bounds")

    monkeypatch.setattr(cli.read, "run", panics)
    assert cli.main(["read", "--port", "/dev/null", "0"]) == 1
    err = capsys.readouterr().err.splitlines()
    assert err == [
        "benchbus: unexpected _Panic: index out of bounds (run again with --traceback to see where)"
    ]


# ---- the wrong device --------------------------------------------------------------------------

SIMULATED: dict[str, Callable[[], SimDevice]] = {
    "drive": lambda: DriveDevice("BLD2"),
    "pbl": PblDevice,
    "j2": J2Device,
}
NAMES = {"drive": "a BLD drive", "pbl": "a PBL drive", "j2": "a J2 controller"}
WRONG = [(cmd, dev) for cmd in SIMULATED for dev in SIMULATED if cmd != dev]


@pytest.mark.parametrize(("command", "device"), WRONG)
def test_status_and_monitor_refuse_another_family(command: str, device: str) -> None:
    with Simulator({1: SIMULATED[device]()}) as sim:
        for args in ([command, "status"], ["monitor", command, "--count", "1"]):
            done = run(*args, "--port", sim.port, "--timeout", "0.2")
            line = one_line_error(done, 1)
            assert f"unit 1 answers but is not {NAMES[command]}" in line, line
            assert f"(looks like {NAMES[device]}" in line, line
            assert done.stdout == ""


#: An action of each command that writes.
WRITING = {"drive": ["stop"], "pbl": ["stop"], "j2": ["set-sv", "50"]}


@pytest.mark.parametrize(("command", "device"), WRONG)
def test_a_writing_action_refuses_another_family_before_writing(command: str, device: str) -> None:
    with Simulator({1: SIMULATED[device]()}) as sim:
        done = run(command, *WRITING[command], "--port", sim.port, "--timeout", "0.2")
        line = one_line_error(done, 1)
        assert f"unit 1 answers but is not {NAMES[command]} (looks like {NAMES[device]}" in line
        assert f"see 'benchbus {device} --help', or check --port and --unit" in line
        assert not [f for f in sim.requests if f[1] in (0x06, 0x10)]


def test_status_shows_a_state_its_enum_does_not_list_with_its_number() -> None:
    # A drive (its model code at 0x2103) whose status word 1 holds 9, which no state is.
    with Simulator({1: RegisterDevice({0x2100: 9, 0x2103: 0x20})}) as sim:
        done = run("drive", "status", "--port", sim.port)
        assert ok(done)
        rows = table(done.stdout.splitlines())
        assert rows["state"] == "UNKNOWN(9)" and rows["model"] == "BLD2"


@pytest.mark.parametrize("command", list(SIMULATED))
def test_status_goes_on_with_its_own_family_and_an_unknown_device(command: str) -> None:
    with Simulator({1: SIMULATED[command](), 2: TaisongDevice()}) as sim:
        assert ok(run(command, "status", "--port", sim.port))
        # nothing recognises a Taisong meter as one of these: it is given the benefit of
        # the doubt (no refusal on a guess)
        done = run(command, "status", "--port", sim.port, "--unit", "2", "--timeout", "0.2")
        assert "answers but is not" not in done.stderr


# ---- a lost port -------------------------------------------------------------------------------


def _lines_until(stream: IO[str] | None, text: str, timeout: float = 10.0) -> list[str]:
    """Lines read from a child's pipe up to the one that holds ``text``."""
    lines = []
    end = time.monotonic() + timeout
    while not lines or text not in lines[-1]:
        lines.append(readline(stream, max(end - time.monotonic(), 0.01)))
    return lines


def test_monitor_rides_out_a_lost_port(tmp_path: Path) -> None:
    # A drive that answers block reads: one request a sample keeps to the 50 ms interval.
    drive = DriveDevice("BLD2", single_register_reads=False)
    adapter = Adapter(Simulator({1: drive}), tmp_path / "ttyUSB0")
    proc = start("monitor", "drive", "--port", adapter.port, "--interval", "0.05", "--count", "40")
    try:
        first = _lines_until(proc.stdout, "0.100")  # a few samples in
        adapter.unplug()
        lost = _lines_until(proc.stderr, "lost")
        assert lost == [f"benchbus: monitor: lost {adapter.port} ({lost[0].split('(', 1)[1]}"]
        assert "reconnecting" in lost[0]
        time.sleep(0.3)
        adapter.plug()
        back = _lines_until(proc.stderr, "is back")
        assert len(back) == 1 and back[0].startswith(f"benchbus: monitor: {adapter.port} is back")
        out, err = proc.communicate(timeout=30)
    finally:
        adapter.unplug()
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert err.splitlines() == ["40 samples"]
    assert len(first) + len(out.splitlines()) == 1 + 40  # the header and every sample


def test_monitor_no_reconnect_ends_at_a_lost_port(tmp_path: Path) -> None:
    # A drive that answers block reads: one request a sample keeps to the 50 ms interval.
    drive = DriveDevice("BLD2", single_register_reads=False)
    adapter = Adapter(Simulator({1: drive}), tmp_path / "ttyUSB0")
    proc = start("monitor", "drive", "--port", adapter.port, "--interval", "0.05", "--no-reconnect")
    try:
        _lines_until(proc.stdout, "0.100")
        adapter.unplug()
        _, err = proc.communicate(timeout=30)
    finally:
        adapter.unplug()
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 1
    assert len(err.splitlines()) == 1 and err.startswith("benchbus: "), err
    assert "Traceback" not in err


# ---- words, ranges and counts ------------------------------------------------------------------


def _on_a_terminal(*args: object, after: str) -> str:
    """``benchbus ARGS`` on a pseudo-terminal of its own, Ctrl-C typed once ``after`` shows:
    everything the terminal showed (the ^C echo included)."""
    master, slave = pty.openpty()

    def controlling_tty() -> None:
        os.setsid()
        fcntl.ioctl(0, termios.TIOCSCTTY, 0)

    proc = subprocess.Popen(
        [*MODULE, *map(str, args)],
        stdin=slave,
        stdout=slave,
        stderr=slave,
        env=_env(),
        preexec_fn=controlling_tty,
    )
    os.close(slave)
    seen = b""
    typed = False
    try:
        end = time.monotonic() + 20
        while time.monotonic() < end:
            ready, _, _ = select.select([master], [], [], 0.2)
            if ready:
                try:
                    chunk = os.read(master, 4096)
                except OSError:  # EIO: the child closed its end
                    break
                if not chunk:
                    break
                seen += chunk
            if not typed and after.encode() in seen:
                os.write(master, b"\x03")
                typed = True
        assert proc.wait(timeout=10) == 0
    finally:
        os.close(master)
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert typed, seen
    return seen.decode(errors="replace")


def test_monitor_summary_after_ctrl_c_starts_a_line_of_its_own() -> None:
    with Simulator({1: J2Device()}) as sim:
        shown = _on_a_terminal(
            "monitor", "j2", "--port", sim.port, "--interval", "0.05", after="sample 3"
        )
    assert "^C" in shown
    tail = shown[shown.rindex("^C") :]
    assert re.fullmatch(r"\^C\r\n\d+ samples\r\n", tail), repr(tail)


def test_one_sample_is_singular() -> None:
    with Simulator({1: J2Device()}) as sim:
        done = run("monitor", "j2", "--port", sim.port, "--count", "1")
    assert done.returncode == 0 and done.stderr == "1 sample\n"


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["read", "--port", "/dev/null", "1.5"], "'1.5' is not a whole number"),
        (["read", "--port", "/dev/null", "0", "--unit", "2.0"], "'2.0' is not a whole number"),
        (["read", "--port", "/dev/null", "--unit", "0", "0"], "give --unit 1 to 255"),
        (["read", "--port", "/dev/null", "--unit", "256", "0"], "unit must be 0 to 255, got 256"),
        (["write", "--port", "/dev/null", "0", "70000"], "(-32768 to 65535 raw)"),
    ],
)
def test_usage_errors_use_plain_words_and_ranges(args: list[str], says: str) -> None:
    line = one_line_error(run(*args), 2)
    assert says in line and ".." not in line, line


def test_library_errors_use_plain_ranges_and_public_names() -> None:
    """The messages raised from the compiled core, as a user of the Python API sees them."""
    with Simulator({1: J2Device(), 2: DriveDevice("BLD2")}) as sim, bb.Bus(sim.port) as bus:
        j2 = bb.J2Controller(bus, 1)
        j2.limits = (0, 200)
        with pytest.raises(ValueError) as caught:
            j2.sv = 250
        assert str(caught.value) == (
            "SV must be within the setpoint limits LSP to USP, 0 to 200, got 250 "
            "(set both with j2.limits = (low, high))"
        )
        with pytest.raises(ValueError, match=r"^unit must be 1 to 255, got 256$"):
            bus.read_holding_registers(256, 0, 1)
        with pytest.raises(ValueError, match=r"^count must be 1 to 125, got 126"):
            bus.read_holding_registers(1, 0, 126)
        with pytest.raises(ValueError, match=r"^accel_time must be 0.1 to 600 s, got 700"):
            bb.Drive(bus, 2).accel_time = 700
        with pytest.raises(ValueError, match=r"^parameter must be 0 to 222, got 300$"):
            bb.PblDrive(bus, 3).read_parameter(300)


def test_pbl_status_does_not_say_stopped_and_turning_at_once() -> None:
    with Simulator({1: PblDevice()}) as sim:
        status = table(ok(run("pbl", "status", "--port", sim.port)))
        assert status["running"] == "no" and "turning" not in status
        ok(run("pbl", "start", "--port", sim.port, "--speed", "900", "--take-control"))
        status = table(ok(run("pbl", "status", "--port", sim.port)))
        assert status["running"] == "yes, FORWARD"


# ---- units -------------------------------------------------------------------------------------


def test_monitor_shows_units_from_the_register_tables(tmp_path: Path) -> None:
    log = tmp_path / "drive.csv"
    with Simulator({1: DriveDevice("BLD2")}) as sim:
        fields = "speed,output_current,temperature,hall_state"
        args = ("monitor", "drive", "--port", sim.port, "--fields", fields, "--csv", log)
        lines = ok(run(*args, "--count", "1"))
    header = [cell.strip() for cell in re.split(r"\s{2,}", lines[0].strip())]
    assert header == [
        "t (s)",
        "speed (rpm)",
        "output_current (A)",
        "temperature (°C)",
        "hall_state",
    ]
    with log.open(encoding="utf-8") as f:
        first = f.readline().strip().split(",")
    assert first[:3] == ["time", "t (s)", "set_frequency (Hz)"]
    assert "speed (rpm)" in first and "temperature (°C)" in first and "hall_state" in first


def test_j2_status_shows_units() -> None:
    with Simulator({1: J2Device()}) as sim:
        status = table(ok(run("j2", "status", "--port", sim.port)))
    assert status["pv"].endswith(" °C") and status["sv"] == "100 °C" and status["mv"].endswith(" %")
    assert status["limits"] == "0 to 400 °C"


def test_drive_and_pbl_status_show_units_from_their_tables() -> None:
    with Simulator({1: DriveDevice("BLD2"), 2: PblDevice()}) as sim:
        drive = table(ok(run("drive", "status", "--port", sim.port)))
        pbl = table(ok(run("pbl", "status", "--port", sim.port, "--unit", "2")))
    assert drive["temperature"].endswith(" °C") and drive["output current"].endswith(" A")
    assert pbl["speed setpoint"].endswith(" rpm") and pbl["power"].endswith(" W")


def test_ctrl_c_with_a_drive_gone_silent_says_so_in_one_line(tmp_path: Path) -> None:
    """The demo on a port: the drive stops answering, then Ctrl-C. Neither putting its
    settings back nor the stop on leaving gets through: one line says all three."""
    with Simulator({1: DriveDevice("BLD2")}) as sim:
        proc = start("demo", "--port", sim.port, "--out", tmp_path / "d.png")
        try:
            _lines_until(proc.stdout, "spin up")
            sim.set_silent(1)
            time.sleep(0.1)
            proc.send_signal(signal.SIGINT)
            _, err = proc.communicate(timeout=30)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    (line,) = err.splitlines()
    assert line.startswith("benchbus: interrupted; ")
    assert "settings could not be put back" in line and "could not stop the motor" in line


def test_a_unit_above_the_drives_range_is_judged_too() -> None:
    """A J2 at unit 250 (J2 stations go to 255, drives to 247) asked as a PBL."""
    with Simulator({250: J2Device()}) as sim:
        line = one_line_error(run("pbl", "status", "--port", sim.port, "--unit", "250"), 1)
    assert "unit 250 answers but is not a PBL drive (looks like a J2 controller" in line
