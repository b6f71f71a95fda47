"""`benchbus demo` end to end, headless, as the README runs it; and the wire log."""

from __future__ import annotations

import io
import logging
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

import benchbus as bb
from benchbus.sim import RegisterDevice, Simulator

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def test_demo_runs_headless_and_writes_a_real_plot(tmp_path: Path) -> None:
    out = tmp_path / "demo.png"
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "MPLBACKEND")}
    done = subprocess.run(
        [sys.executable, "-m", "benchbus", "demo", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
        cwd=tmp_path,
        env=env,
    )
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0] == "benchbus demo on simulated devices"
    assert lines[-1] == f"plot written to {out.resolve()}"
    rows = [line.split() for line in lines[2:-1]]
    steps = {row[1] for row in rows}
    assert {"spin", "hold", "reverse", "stop"} <= steps
    drive = [float(row[-5]) for row in rows]
    pbl = [float(row[-4]) for row in rows]
    pv = [float(row[-3]) for row in rows]
    assert max(drive) > 1400 and min(drive) < -1400 and abs(drive[-1]) < 1  # up, reversed, off
    assert max(pbl) > 1100 and min(pbl) < -1100 and abs(pbl[-1]) < 1
    assert pv[-1] > pv[0] + 20  # heated toward 80
    data = out.read_bytes()
    assert data.startswith(PNG_SIGNATURE)
    import matplotlib.image

    image = matplotlib.image.imread(out)
    assert image.shape[0] >= 400 and image.shape[1] >= 600
    assert image.std() > 0.05  # not a blank canvas


def test_enable_wire_log_shows_every_frame_once() -> None:
    buf = io.StringIO()
    logger = bb.enable_wire_log(buf)
    bb.enable_wire_log(buf)  # no second handler
    try:
        with Simulator({1: RegisterDevice({6: 1000})}) as sim, bb.Bus(sim.port) as bus:
            bus.read_holding_registers(1, 6, 1)
        lines = buf.getvalue().splitlines()
        assert [line.split(" benchbus.wire ")[1] for line in lines] == [
            "-> 01 03 00 06 00 01 64 0B",
            "<- 01 03 02 03 E8 B8 FA",
        ]
        assert logger.name == "benchbus.wire" and logger.level == logging.DEBUG
    finally:
        logger.setLevel(logging.NOTSET)
        for handler in list(logger.handlers):
            if getattr(handler, "_benchbus_wire", False):
                logger.removeHandler(handler)
        bb.refresh_logging()


def test_the_hardware_session_puts_the_drive_settings_back() -> None:
    from benchbus._demo import _hardware
    from benchbus.sim import DriveDevice

    with Simulator({1: DriveDevice()}) as sim:
        with bb.Drive(sim.port) as drive:
            drive.accel_time = 2.5
            drive.speed_setpoint = 900
        with _hardware(sim.port, 1) as devices:
            devices.drive.accel_time = 1.0
            devices.drive.speed_setpoint = 1500
            devices.drive.forward()
        with bb.Drive(sim.port) as drive:
            assert (drive.accel_time, drive.speed_setpoint) == (2.5, 900)
            assert drive.state == bb.DriveState.STOPPED or drive.speed < 1500


def test_demo_plot_labels_carry_units_and_show_the_output(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The plot's axes name their units (from the devices' tables), the J2's output MV is
    plotted, and no label speaks of the simulation's speed-up."""
    from benchbus import _demo

    figures = []
    plot = _demo._plot

    def keep(*args: Any) -> Any:
        figures.append(plot(*args))
        return figures[-1]

    monkeypatch.setattr(_demo, "_plot", keep)
    monkeypatch.setattr(_demo, "STEPS", ((0.0, "spin up"), (1.5, "end")))
    out = io.StringIO()
    _demo.run(out=tmp_path / "demo.png", stream=out)
    header = out.getvalue().splitlines()[1]
    assert "drive rpm" in header and "J2 PV °C" in header and "J2 MV %" in header
    (fig,) = figures
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert labels[0].startswith("speed (rpm")
    assert "temperature (°C)" in labels and "output MV (%)" in labels
    assert not any("x20" in label or "process x" in label for label in labels)
    mv_ax = fig.axes[labels.index("output MV (%)")]
    (mv,) = mv_ax.get_lines()
    assert len(mv.get_ydata()) >= 5 and max(mv.get_ydata()) > 0  # heating


def test_the_demos_plot_is_ignored_by_git_where_make_demo_writes_it() -> None:
    """``make demo`` runs in the clone's top folder and writes the plot there, by default:
    git ignores that file, and only that one (a plot named with --out is the user's)."""
    from benchbus import _demo

    root = Path(__file__).resolve().parent.parent
    ignored = (root / ".gitignore").read_text(encoding="utf-8").splitlines()
    assert f"/{_demo.DEFAULT_OUT}" in ignored
    assert "demo:" in (root / "Makefile").read_text(encoding="utf-8")
    assert not any(line.endswith(".png") and line != f"/{_demo.DEFAULT_OUT}" for line in ignored)
