"""The command line as a person meets it: one-line errors, the wrong device, a lost port,
plain words and ranges, units. Run as a user runs it, against the simulators."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import benchbus as bb
from benchbus import cli
from benchbus.sim import DriveDevice, RegisterDevice, Simulator
from test_cli import MODULE, _env, one_line_error, run

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

    monkeypatch.setattr(cli, "_cmd_read", panics)
    assert cli.main(["read", "--port", "/dev/null", "0"]) == 1
    err = capsys.readouterr().err.splitlines()
    assert err == [
        "benchbus: unexpected _Panic: index out of bounds (run again with --traceback to see where)"
    ]
