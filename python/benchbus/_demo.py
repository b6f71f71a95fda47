"""``benchbus demo``: a short, visible bench session, on simulated devices or real hardware.

With no port it starts three simulated devices on pseudo-terminals, each on a line of its
family's format: a BLD drive (19200 8N1), a PBL drive (115200 8E1) and a J2 temperature
controller (9600 8N1, its process sped up). It spins both motors up, holds, reverses and
stops them while the J2 heats toward a setpoint, prints a live table, and writes a plot of
speed and temperature against time as a PNG. With a port it runs the drive's part of the
session on a real BLD drive at that port instead.
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

import benchbus as bb
from benchbus._core import _Ticks as ticks
from benchbus._device import add_note
from benchbus._families import family

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from benchbus._drive import Drive
    from benchbus._j2 import J2Controller
    from benchbus._pbl import PblDrive
    from benchbus.sim import SimDevice

__all__ = ["run"]

#: Seconds between samples.
INTERVAL = 0.25
#: The session: (second, what happens). Each step runs once its second has come.
STEPS = (
    (0.0, "spin up"),
    (4.0, "hold"),
    (6.0, "reverse"),
    (10.0, "stop"),
    (13.0, "end"),
)
#: Setpoints of the session.
DRIVE_RPM, PBL_RPM, J2_SV = 1500, 1200, 80.0
#: How much faster than real time the simulated J2's thermal process runs.
J2_SPEEDUP = 20.0
PBL_UNIT = 0x11


@dataclass
class _Devices:
    drive: Drive
    pbl: PblDrive | None = None
    j2: J2Controller | None = None


@dataclass
class _Trace:
    t: list[float] = field(default_factory=list)
    columns: dict[str, list[float]] = field(default_factory=dict)

    def add(self, t: float, values: dict[str, float]) -> None:
        self.t.append(t)
        for name, value in values.items():
            self.columns.setdefault(name, []).append(value)


def _check_matplotlib() -> None:
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise ImportError(
            "the demo writes a plot and needs matplotlib: pip install 'benchbus[demo]'"
        ) from None


@contextlib.contextmanager
def _simulated() -> Iterator[_Devices]:
    """Three simulated devices, each on its own line at its family's format."""
    from benchbus.sim import Simulator

    def simulator(kind: str, unit: int, **options: Any) -> Simulator[SimDevice]:
        of = family(kind)
        return Simulator({unit: of.simulate(**options)}, baudrate=of.line.baudrate)

    with contextlib.ExitStack() as stack:
        drive_sim = stack.enter_context(simulator("drive", 1, model="BLD2"))
        pbl_sim = stack.enter_context(simulator("pbl", PBL_UNIT))
        j2_sim = stack.enter_context(simulator("j2", 1, speedup=J2_SPEEDUP))
        drive = stack.enter_context(bb.Drive(drive_sim.port, unit=1))
        pbl = stack.enter_context(bb.PblDrive(pbl_sim.port, unit=PBL_UNIT))
        j2 = stack.enter_context(bb.J2Controller(j2_sim.port, unit=1))
        yield _Devices(drive, pbl, j2)


@contextlib.contextmanager
def _hardware(port: str, unit: int) -> Iterator[_Devices]:
    """The drive at ``port``; the settings the session changes are put back afterwards."""
    with bb.Drive(port, unit=unit) as drive:
        kept = {name: drive.get(name) for name in ("accel_time", "decel_time", "speed_setpoint")}

        def restore() -> None:
            drive.stop()
            for name, value in kept.items():
                drive.set(name, value)

        try:
            yield _Devices(drive)
        except BaseException as exc:
            try:
                restore()
            except Exception as failure:  # the error that ended the session goes on
                add_note(exc, f"the drive's settings could not be put back ({failure})")
            raise
        restore()


def _prepare(d: _Devices) -> None:
    d.drive.accel_time = 1.0
    d.drive.decel_time = 1.0
    if d.pbl is not None:
        d.pbl.start_stop_source = bb.StartStopSource.COMMUNICATION
        d.pbl.acceleration = 1000
        d.pbl.deceleration = 1000
    if d.j2 is not None:
        d.j2.sv = J2_SV


def _act(d: _Devices, step: str) -> None:
    if step == "spin up":
        d.drive.speed_setpoint = DRIVE_RPM
        d.drive.forward()
        if d.pbl is not None:
            d.pbl.speed_setpoint = PBL_RPM
            d.pbl.direction = bb.Direction.FORWARD
            d.pbl.start()
    elif step == "reverse":
        d.drive.reverse()
        if d.pbl is not None:
            d.pbl.direction = bb.Direction.REVERSE
    elif step == "stop":
        d.drive.stop()
        if d.pbl is not None:
            d.pbl.stop()


def _sample(d: _Devices, sign: list[float]) -> dict[str, float]:
    speed = d.drive.speed
    # The speed register holds a magnitude and the state the direction asked for: the sign
    # follows the state only once the motor has slowed through zero.
    asked = -1.0 if d.drive.state == bb.DriveState.REVERSE else 1.0
    if speed < 50:
        sign[0] = asked
    values = {"drive_rpm": sign[0] * speed + 0.0}
    if d.pbl is not None:
        status = d.pbl.status()
        turning = -1.0 if status.direction == bb.Direction.REVERSE else 1.0
        values["pbl_rpm"] = turning * d.pbl.speed + 0.0
    if d.j2 is not None:
        values.update({f"j2_{k}": v for k, v in d.j2.sample().items()})
    return values


_HEAD = {
    "drive_rpm": "drive",
    "pbl_rpm": "PBL",
    "j2_pv": "J2 PV",
    "j2_sv": "J2 SV",
    "j2_mv": "J2 MV",
}


def _units(d: _Devices) -> dict[str, str]:
    """The unit of each column, from the devices' tables."""
    units = {"drive_rpm": d.drive.sample_units()["speed"]}
    if d.pbl is not None:
        units["pbl_rpm"] = d.pbl.sample_units()["speed"]
    if d.j2 is not None:
        units.update({f"j2_{k}": v for k, v in d.j2.sample_units().items()})
    return units


def _head(name: str, units: dict[str, str]) -> str:
    """A column's heading with its unit: ``drive rpm``, ``J2 PV °C``."""
    return f"{_HEAD[name]} {units.get(name, '')}".rstrip()


def _row(t: float, step: str, values: dict[str, float]) -> str:
    cells = "".join(f"{values[k]:>11.1f}" for k in values)
    return f"{t:6.2f}  {step:<8}{cells}"


def _plot(trace: _Trace, units: dict[str, str], out: Path) -> Figure:
    """Speeds above; the J2's PV and SV, and its output MV on an axis of its own, below."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 6), layout="constrained")
    speed_ax, temp_ax = fig.subplots(2, 1, sharex=True)
    for name in ("drive_rpm", "pbl_rpm"):
        if name in trace.columns:
            speed_ax.plot(trace.t, trace.columns[name], label=_HEAD[name])
    speed_ax.set_ylabel(f"speed ({units['drive_rpm']}; negative: reverse)")
    speed_ax.legend(loc="upper right")
    speed_ax.grid(True, alpha=0.3)
    if "j2_pv" in trace.columns:
        lines = temp_ax.plot(trace.t, trace.columns["j2_pv"], label="PV")
        lines += temp_ax.plot(trace.t, trace.columns["j2_sv"], "--", label="SV")
        temp_ax.set_ylabel(f"temperature ({units['j2_pv']})")
        mv_ax = temp_ax.twinx()
        lines += mv_ax.plot(trace.t, trace.columns["j2_mv"], ":", color="tab:red", label="MV")
        mv_ax.set_ylabel(f"output MV ({units['j2_mv']})")
        mv_ax.set_ylim(0, 105)
        temp_ax.legend(lines, [line.get_label() for line in lines], loc="center right")
    temp_ax.grid(True, alpha=0.3)
    temp_ax.set_xlabel("time (s)")
    for at, step in STEPS[1:-1]:
        for ax in (speed_ax, temp_ax):
            ax.axvline(at, color="grey", lw=0.8, ls=":")
        speed_ax.annotate(step, (at, 0), xytext=(3, 3), textcoords="offset points", fontsize=8)
    fig.suptitle("benchbus demo")
    fig.savefig(out, dpi=100)
    return fig


#: The PNG the demo writes without ``out``, in the current directory (git ignores it at the
#: top of a clone, where ``make demo`` runs).
DEFAULT_OUT = "benchbus-demo.png"


def run(
    port: str | None = None,
    out: str | os.PathLike[str] | None = None,
    *,
    unit: int = 1,
    stream: TextIO | None = None,
) -> Path:
    """Run the demo session; the path of the PNG written.

    ``port`` None runs it on simulated devices; a path runs the drive's part on a real BLD
    drive at ``unit`` there. ``out`` is the PNG to write (default ``benchbus-demo.png`` in
    the current directory). The table goes to ``stream`` (default stdout). The motors are
    stopped on the way out, also after an error or Ctrl-C.
    """
    _check_matplotlib()
    stream = sys.stdout if stream is None else stream
    target = Path(out if out is not None else DEFAULT_OUT).resolve()
    if not target.parent.is_dir():
        raise FileNotFoundError(f"no directory {target.parent} to write the plot in")
    trace = _Trace()
    devices = _simulated() if port is None else _hardware(port, unit)
    with devices as d:
        where = "simulated devices" if port is None else f"the drive at {port}, unit {unit}"
        print(f"benchbus demo on {where}", file=stream)
        _prepare(d)
        steps = list(STEPS)
        step = ""
        header = ""
        sign = [1.0]
        units = _units(d)
        start = time.monotonic()
        for _, deadline, _ in ticks(INTERVAL):
            t = deadline - start
            while steps and steps[0][0] <= t + 1e-9:
                step = steps.pop(0)[1]
                _act(d, step)
            if step == "end":
                break
            values = _sample(d, sign)
            trace.add(t, values)
            if not header:
                header = "     t  step    " + "".join(f"{_head(k, units):>11}" for k in values)
                print(header, file=stream)
            print(_row(t, step, values), file=stream, flush=True)
    _plot(trace, units, target)
    print(f"plot written to {target}", file=stream)
    return target
