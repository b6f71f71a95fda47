"""Recordings: ``device.record()`` on the
simulators, the Recording's exports and the notebook displays of status objects.

Timing is checked two ways: with a fake clock and sleep, where every deadline and every
sample time is known exactly, and in real time on a simulated drive, where the deadlines
are still exact and the actual times are held to bounds generous enough for a loaded CI
machine. The tests in real time, and those whose line has a short timeout, are marked
``timing`` (run by themselves, see tests/conftest.py).
"""

from __future__ import annotations

import csv
import io
import math
import os
import subprocess
import sys
import time
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import Any

import pytest

import benchbus as bb
from benchbus._record import PeriodStats, Recording, record
from benchbus.sim import DriveDevice, J2Device, PblDevice, Simulator

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


class FakeTime:
    """A clock that moves only when slept on (or moved by hand), for exact timing tests.

    ``oversleep`` seconds are added to every sleep, as a busy machine would.
    """

    def __init__(self, now: float = 1024.0, oversleep: float = 0.0) -> None:
        self.now = now
        self.oversleep = oversleep
        self.sleeps: list[float] = []

    def clock(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        assert seconds > 0
        self.sleeps.append(seconds)
        self.now += seconds + self.oversleep


class ProcessClock:
    """A clock for a simulated device's model, moved by hand."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


@contextmanager
def drive_line(
    timeout: float = 0.3, retries: int = 1, **device: Any
) -> Iterator[tuple[Simulator[DriveDevice], bb.Drive, DriveDevice]]:
    """A simulated BLD2 drive at unit 1 and a Drive on a Bus of its own (closed after)."""
    sim_drive = DriveDevice("BLD2", **device)
    with Simulator({1: sim_drive}) as sim, bb.Bus(sim.port, timeout=timeout) as bus:
        yield sim, bb.Drive(bus, unit=1, retries=retries), sim_drive


def recording(n: int = 3, **kwargs: Any) -> Recording:
    """A small hand-made recording: ``n`` samples 0.5 s apart of columns a and b."""
    times = [i * 0.5 for i in range(n)]
    columns = {"a": [float(i) for i in range(n)], "b": [10.0 + i / 4 for i in range(n)]}
    kwargs.setdefault("interval", 0.5)
    return Recording(times, times, columns, **kwargs)


# ---- record() on a fake clock --------------------------------------------------------------------


def test_record_on_a_fake_clock_is_drift_free_and_counts_overruns(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A real simulated drive, a fake clock: every sample costs 1/16 s of fake time, the
    fifth 7/8 s, which passes two deadlines."""
    fake = FakeTime()
    with drive_line() as (_, drive, _):
        real_sample = drive.sample
        calls = 0

        def slow_sample() -> dict[str, float]:
            nonlocal calls
            fake.now += 0.875 if calls == 4 else 0.0625
            calls += 1
            return real_sample()

        monkeypatch.setattr(drive, "sample", slow_sample)
        rec = drive.record(3.0, 0.25, clock=fake.clock, sleep=fake.sleep)
    ticks_taken = [0, 1, 2, 3, 4, 7, 8, 9, 10, 11]
    assert len(rec) == len(ticks_taken) and rec.missed == 2
    assert rec.deadlines == [n * 0.25 for n in ticks_taken]
    assert rec.times == [n * 0.25 for n in ticks_taken[:5]] + [1.875] + [
        n * 0.25 for n in ticks_taken[6:]
    ]
    assert rec.clock_start == 1024.0 and rec.interval == 0.25 and rec.duration == 3.0
    assert rec.period_stats() == PeriodStats(0.125 / 10, pytest.approx(0.0375), 0.125, 2)
    assert rec.lateness()[5] == 0.125
    assert rec.device == "Drive unit 1" and not rec.interrupted


def test_record_stays_on_its_deadlines_when_every_sleep_overshoots() -> None:
    fake = FakeTime(oversleep=0.01)
    values = iter(range(1000))

    def sample() -> dict[str, float]:
        fake.now += 0.02
        return {"x": float(next(values))}

    rec = record(sample, 10.0, 0.125, clock=fake.clock, sleep=fake.sleep)
    assert len(rec) == 80 and rec.missed == 0
    assert rec.deadlines == [n * 0.125 for n in range(80)]
    assert rec.times[-1] == pytest.approx(79 * 0.125 + 0.01)  # 10 ms late, not 80 x 30 ms
    assert rec["x"] == [float(n) for n in range(80)]


def test_record_keeps_the_columns_asked_for_in_that_order() -> None:
    fake = FakeTime()
    with drive_line() as (_, drive, _):
        rec = drive.record(
            1.0, 0.25, columns=("output_frequency", "speed"), clock=fake.clock, sleep=fake.sleep
        )
        assert list(rec.columns) == ["output_frequency", "speed"]
        assert len(rec) == 4 and all(len(v) == 4 for v in rec.columns.values())
        with pytest.raises(ValueError, match=r"no 'rpm'.*speed") as caught:
            drive.record(1.0, 0.25, columns=["rpm"], clock=fake.clock, sleep=fake.sleep)
        # Refused before the first sample: the device's names are known in advance.
        assert not hasattr(caught.value, "recording")


def test_a_missing_value_in_a_later_sample_is_nan() -> None:
    fake = FakeTime()
    samples = iter([{"a": 1.0, "b": 2.0}, {"a": 3.0}, {"a": 5.0, "b": 6.0, "c": 7.0}])
    rec = record(lambda: next(samples), 0.75, 0.25, clock=fake.clock, sleep=fake.sleep)
    assert list(rec.columns) == ["a", "b"] and rec["a"] == [1.0, 3.0, 5.0]
    assert rec["b"][0] == 2.0 and math.isnan(rec["b"][1]) and rec["b"][2] == 6.0


# ---- record() in real time on the simulators ----------------------------------------------------


@pytest.mark.timing
def test_record_a_drive_spinning_up_in_real_time() -> None:
    with drive_line(single_register_reads=False) as (sim, drive, _):  # one request a sample
        drive.accel_time = 1.0  # 0..3000 rpm in 1 s: 1500 rpm after 0.5 s
        drive.speed_setpoint = 1500
        drive.forward()
        sim.clear_log()
        before = time.monotonic()
        rec = drive.record(1.5, 0.05, columns=["speed", "output_frequency"])
        after = time.monotonic()
        request_times = list(sim.request_times)
        drive.stop()

    # Deadlines: exact multiples of the interval from the start, the last before 1.5 s.
    # On a quiet machine that is all 30; a loaded one may skip some, and counts them.
    ks = [round(d / 0.05) for d in rec.deadlines]
    assert rec.deadlines == [k * 0.05 for k in ks]
    assert ks[0] == 0 and ks == sorted(set(ks)) and 20 <= ks[-1] <= 29
    assert len(rec) + rec.missed == ks[-1] + 1
    assert len(rec) >= 15

    # Actual times: never before the deadline, late by little, no drift to the end.
    assert rec.clock_start is not None and before <= rec.clock_start <= before + 0.5
    late = rec.lateness()
    assert min(late) >= -0.001 and rec.period_stats().mean < 0.05 and max(late) < 0.5
    assert 1.45 <= after - before < 1.5 + 1.0
    assert rec.start is not None and rec.start.tzinfo is not None
    assert abs(rec.start - datetime.now(timezone.utc)) < timedelta(seconds=10)

    # Seen from the simulated drive: each sample's request reaches it soon after the
    # sample's time, on the same monotonic clock.
    for taken in rec.times:
        arrival = next(t for t in request_times if t >= rec.clock_start + taken)
        assert arrival - (rec.clock_start + taken) < 0.3

    # The values are the drive's: ramping up to the setpoint, frequency = rpm x 2 / 60.
    speed, frequency = rec["speed"], rec["output_frequency"]
    assert speed == sorted(speed) and speed[0] < 1500 and speed[-1] == 1500
    for rpm, hz in zip(speed, frequency):
        assert hz == pytest.approx(rpm * 2 / 60, abs=0.03)


@pytest.mark.timing
def test_record_a_j2_heating_matches_the_simulator(monkeypatch: pytest.MonkeyPatch) -> None:
    process = ProcessClock()
    controller = J2Device(clock=process)
    with Simulator({2: controller}) as sim, bb.Bus(sim.port, timeout=0.3) as bus:
        j2 = bb.J2Controller(bus, unit=2)
        j2.sv = 150.0
        real_sample = j2.sample
        expected: list[tuple[float, float, float]] = []

        def sample_then_look() -> dict[str, float]:
            process.now += 7.0  # seven process seconds between samples
            values = real_sample()
            expected.append((controller.pv, controller.value("SV"), controller.value("MV")))
            return values

        monkeypatch.setattr(j2, "sample", sample_then_look)
        rec = j2.record(0.5, 0.1)
    assert list(rec.columns) == ["pv", "sv", "mv"] and 1 <= len(rec) <= 5
    assert list(zip(rec["pv"], rec["sv"], rec["mv"])) == expected
    assert rec["pv"] == sorted(rec["pv"]) and rec["pv"][-1] > 25.0  # heating
    assert rec.device == "J2Controller unit 2"


def test_record_a_pbl_drive() -> None:
    fake = FakeTime()
    with Simulator({0x11: PblDevice()}) as sim, bb.PblDrive(sim.port, unit=0x11) as pbl:
        pbl.verify_identity()
        sim.clear_log()
        rec = pbl.record(0.5, 0.125, clock=fake.clock, sleep=fake.sleep)
        assert len(sim.requests) == 4  # one request a sample
    assert list(rec.columns) == ["speed", "bus_voltage", "analog_speed_input", "current", "power"]
    assert len(rec) == 4 and rec.deadlines == [0.0, 0.125, 0.25, 0.375]
    assert rec["speed"] == [0.0] * 4 and rec["bus_voltage"][0] > 0
    assert rec.device == "PblDrive unit 17"


@pytest.mark.timing
def test_a_bus_error_ends_the_recording_and_keeps_what_was_sampled(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    fake = FakeTime()
    with drive_line(timeout=0.05, retries=0) as (sim, drive, _):
        real_sample = drive.sample
        calls = 0

        def failing() -> dict[str, float]:
            nonlocal calls
            calls += 1
            if calls == 4:
                sim.set_silent(1)
            return real_sample()

        monkeypatch.setattr(drive, "sample", failing)
        with pytest.raises(bb.ResponseTimeout) as caught:
            drive.record(5.0, 0.25, clock=fake.clock, sleep=fake.sleep)
        sim.set_silent(1, False)
    kept = caught.value.recording  # type: ignore[attr-defined]
    assert isinstance(kept, Recording) and len(kept) == 3
    assert kept.deadlines == [0.0, 0.25, 0.5] and not kept.interrupted
    if sys.version_info >= (3, 11):
        assert "3 samples recorded before it are in .recording" in caught.value.__notes__[0]


def test_ctrl_c_returns_the_recording_so_far(monkeypatch: pytest.MonkeyPatch) -> None:
    fake = FakeTime()
    with drive_line() as (_, drive, _):
        real_sample = drive.sample
        calls = 0

        def interrupted() -> dict[str, float]:
            nonlocal calls
            calls += 1
            if calls == 4:
                raise KeyboardInterrupt
            return real_sample()

        monkeypatch.setattr(drive, "sample", interrupted)
        rec = drive.record(5.0, 0.25, clock=fake.clock, sleep=fake.sleep)
        assert len(rec) == 3 and rec.interrupted
        assert "interrupted" in repr(rec)

        # Ctrl-C while waiting for the next deadline, too.
        monkeypatch.setattr(drive, "sample", real_sample)
        sleeps = 0

        def sleep(seconds: float) -> None:
            nonlocal sleeps
            sleeps += 1
            if sleeps == 3:
                raise KeyboardInterrupt
            fake.sleep(seconds)

        rec = drive.record(5.0, 0.25, clock=fake.clock, sleep=sleep)
        assert len(rec) == 3 and rec.interrupted


BAD_SECONDS: list[tuple[Any, type[Exception]]] = [
    (0, ValueError),
    (-1.0, ValueError),
    (math.nan, ValueError),
    (math.inf, ValueError),
    ("1", TypeError),
    (None, TypeError),
    (True, TypeError),
]


def test_bad_arguments_are_refused_before_anything_is_sent() -> None:
    with drive_line() as (sim, drive, _):
        sim.clear_log()
        for value, error in BAD_SECONDS:
            with pytest.raises(error, match="duration"):
                drive.record(value, 0.1)
            with pytest.raises(error, match="interval"):
                drive.record(1.0, value)
        with pytest.raises(TypeError, match="list of names"):
            drive.record(1.0, 0.1, columns="speed")
        with pytest.raises(TypeError, match="str"):
            drive.record(1.0, 0.1, columns=[1])  # type: ignore[list-item]
        with pytest.raises(ValueError, match="empty"):
            drive.record(1.0, 0.1, columns=[])
        with pytest.raises(ValueError, match="twice"):
            drive.record(1.0, 0.1, columns=["speed", "speed"])
        assert sim.requests == []
        # An interval longer than the duration is fine: one sample.
        assert len(drive.record(0.05, 10.0)) == 1
        inst = bb.Instrument(drive.bus, unit=1)
        sim.clear_log()
        with pytest.raises(TypeError, match="no fixed measurements"):
            inst.record(1.0, 0.1)
        assert sim.requests == []


# ---- the Recording -------------------------------------------------------------------------------


def test_recording_basics() -> None:
    rec = recording(4, device="Drive unit 1")
    assert len(rec) == 4 and rec["a"] == [0.0, 1.0, 2.0, 3.0]
    with pytest.raises(KeyError, match="the columns are a, b"):
        rec["c"]
    with pytest.raises(ValueError, match="same length"):
        Recording([0.0], [0.0, 1.0], {"a": [1.0]}, interval=1.0)
    empty = Recording([], [], {"a": []}, interval=0.1)
    assert len(empty) == 0 and all(math.isnan(x) for x in empty.period_stats()[:3])
    assert bb.Recording is Recording


def test_to_csv_text_file_and_buffer(tmp_path: Path) -> None:
    rec = Recording([0.0, 0.5], [0.0, 0.5], {"a": [1.0, 2.5], "b": [3.0, math.nan]}, interval=0.5)
    expected = "time,a,b\n0.0,1.0,3.0\n0.5,2.5,nan\n"
    assert rec.to_csv() == expected
    assert rec.to_csv(tmp_path / "rec.csv") is None
    assert (tmp_path / "rec.csv").read_bytes() == expected.encode()
    rec.to_csv(str(tmp_path / "again.csv"))
    assert (tmp_path / "again.csv").read_text() == expected
    buffer = io.StringIO()
    rec.to_csv(buffer)
    assert buffer.getvalue() == expected


def test_to_csv_round_trips_a_real_recording() -> None:
    fake = FakeTime()
    with drive_line() as (_, drive, _):
        rec = drive.record(1.0, 0.25, clock=fake.clock, sleep=fake.sleep)
    rows = list(csv.reader(io.StringIO(rec.to_csv())))
    assert rows[0] == ["time", *rec.columns]
    assert len(rows) == 1 + len(rec)
    for i, row in enumerate(rows[1:]):
        assert float(row[0]) == rec.times[i]
        assert [float(x) for x in row[1:]] == [rec.columns[c][i] for c in rec.columns]


def test_to_pandas() -> None:
    pd = pytest.importorskip("pandas")
    start = datetime(2025, 1, 31, 10, 0, tzinfo=timezone.utc)
    rec = recording(5, device="J2Controller unit 2", start=start, missed=1)
    frame = rec.to_pandas()
    assert isinstance(frame, pd.DataFrame)
    assert frame.shape == (5, 2) and list(frame.columns) == ["a", "b"]
    assert frame.index.name == "time" and list(frame.index) == rec.times
    assert list(frame["b"]) == rec["b"] and frame["a"].dtype == float
    assert frame.attrs == {
        "device": "J2Controller unit 2",
        "interval": 0.5,
        "start": start,
        "missed": 1,
        "units": {"a": "", "b": ""},
    }
    empty = Recording([], [], {"pv": []}, interval=0.1).to_pandas()
    assert empty.shape == (0, 1) and empty.index.name == "time"


def test_plot_returns_the_axes_and_writes_a_real_png(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    from matplotlib.axes import Axes
    from matplotlib.image import imread

    rec = recording(6, device="Drive unit 1")
    ax = rec.plot(path=tmp_path / "rec.png")
    assert isinstance(ax, Axes)
    assert [line.get_label() for line in ax.get_lines()] == ["a", "b"]
    assert list(ax.get_lines()[1].get_xdata()) == rec.times
    assert list(ax.get_lines()[1].get_ydata()) == rec["b"]
    assert ax.get_xlabel() == "time (s)" and ax.get_title() == "Drive unit 1"
    data = (tmp_path / "rec.png").read_bytes()
    assert data.startswith(PNG_SIGNATURE)
    image = imread(tmp_path / "rec.png")
    assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100

    # On an Axes of the caller's, a chosen column; no extension still makes a PNG.
    other = rec.plot(["b"], ax=ax, path=tmp_path / "plain")
    assert other is ax and [line.get_label() for line in ax.get_lines()] == ["a", "b", "b"]
    assert (tmp_path / "plain").read_bytes().startswith(PNG_SIGNATURE)
    with pytest.raises(ValueError, match="no column 'c'"):
        rec.plot(["c"])


def test_plot_works_headless_without_pyplot(tmp_path: Path) -> None:
    """In a fresh process with no display and no backend chosen, plot() saves its PNG
    without importing pyplot (no backend, no global figure list)."""
    pytest.importorskip("matplotlib")
    script = (
        "import sys\n"
        "from benchbus import Recording\n"
        "rec = Recording([0.0, 1.0], [0.0, 1.0], {'x': [1.0, 2.0]}, interval=1.0)\n"
        f"rec.plot(path={str(tmp_path / 'headless.png')!r})\n"
        "print('matplotlib.pyplot' in sys.modules)\n"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "MPLBACKEND")}
    done = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False"
    assert (tmp_path / "headless.png").read_bytes().startswith(PNG_SIGNATURE)


def test_missing_pandas_says_which_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "pandas", None)
    rec = recording()
    with pytest.raises(ImportError, match=r"pip install 'benchbus\[data\]'"):
        rec.to_pandas()
    assert rec.to_csv().startswith("time,a,b\n")  # CSV needs no pandas


def test_missing_matplotlib_says_which_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    with pytest.raises(ImportError, match=r"pip install 'benchbus\[plot\]'"):
        recording().plot()


def test_recording_repr() -> None:
    start = datetime(2025, 1, 31, 10, 0, 5)
    rec = recording(4, device="Drive unit 1", start=start, missed=2)
    assert repr(rec) == (
        "<Recording Drive unit 1: 4 samples every 0.5 s over 1.5 s, 2 missed; "
        "started 2025-01-31 10:00:05; columns a, b>"
    )
    wide = Recording([0.0], [0.0], {f"c{i}": [1.0] for i in range(10)}, interval=0.1)
    assert repr(wide) == (
        "<Recording 1 sample every 0.1 s over 0 s, 0 missed; "
        "10 columns c0, c1, c2, c3, ..., c8, c9>"
    )


def test_recording_html_shows_a_summary_and_both_ends() -> None:
    rec = recording(30, device="Drive unit 1")
    page = rec._repr_html_()
    assert "Drive unit 1: 30 samples every 0.5 s over 14.5 s, 0 missed" in page
    assert "lateness mean 0.00 ms, max 0.00 ms" in page
    assert '<th style="text-align: right">time (s)</th>' in page
    assert page.count("<tr>") == 1 + 5 + 1 + 5  # header, first 5, the gap, last 5
    assert ">0.000<" in page and ">14.500<" in page and ">\u2026<" in page
    assert ">10.0<" in page and ">17.25<" in page  # column b, first and last
    assert ">5.000<" not in page  # the middle is left out
    short = recording(3)._repr_html_()
    assert short.count("<tr>") == 1 + 3 and "\u2026" not in short
    odd = Recording([0.0], [0.0], {"<b>": [1.0]}, interval=1.0, device="R&D")
    assert "&lt;b&gt;" in odd._repr_html_() and "R&amp;D" in odd._repr_html_()
    assert "<b>" not in odd._repr_html_()


# ---- status objects in notebooks ----------------------------------------------------------------


def test_drive_status_and_telemetry_html() -> None:
    status = bb.DriveStatus(
        state=bb.DriveState.FAULT,
        bus_voltage_ready=True,
        overloaded=False,
        control_source=bb.CommandSource.COMMUNICATION,
        keypad_connected=None,
        fault=bb.Fault(0x0A, "undervoltage"),
    )
    page = status._repr_html_()
    assert "<caption" in page and ">DriveStatus<" in page
    assert "<tr><td>state</td><td>DriveState.FAULT</td></tr>" in page
    assert "<tr><td>fault</td><td>0x0A undervoltage</td></tr>" in page
    assert "<tr><td>keypad_connected</td><td>None</td></tr>" in page
    assert "<th>unit</th>" not in page  # no field has a unit
    # The dataclass repr stays as it was.
    assert repr(status).startswith("DriveStatus(state=<DriveState.FAULT: 4>, ")

    clock = ProcessClock()
    with drive_line(clock=clock) as (_, drive, _):
        drive.accel_time = 1.0
        drive.speed_setpoint = 1200
        drive.forward()
        clock.now += 5.0
        telemetry = drive.telemetry()
        page = drive.status()._repr_html_()
        assert "<tr><td>state</td><td>DriveState.FORWARD</td></tr>" in page
    page = telemetry._repr_html_()
    assert "<th>field</th><th>value</th><th>unit</th>" in page
    assert "<tr><td>speed</td><td>1200</td><td>rpm</td></tr>" in page
    frequency = telemetry.output_frequency
    assert f"<tr><td>output_frequency</td><td>{frequency!r}</td><td>Hz</td>" in page
    assert "<tr><td>hall_state</td>" in page and "units" not in page
    assert repr(telemetry).startswith("DriveTelemetry(set_frequency=40.0, ")


def test_pbl_status_html() -> None:
    status = bb.PblStatus(True, bb.Direction.REVERSE)
    page = status._repr_html_()
    assert "<tr><td>running</td><td>True</td></tr>" in page
    assert "<tr><td>direction</td><td>Direction.REVERSE</td></tr>" in page
    assert repr(status) == "PblStatus(running=True, direction=<Direction.REVERSE: 1>)"


def test_identification_html() -> None:
    ident = bb.Identification(
        vendor="ACME <Labs>",
        product_code="M-1",
        revision=None,
        objects={0: "ACME <Labs>", 1: "M-1", 4: "Meter", 0x80: "bench 3"},
        conformity=0x81,
    )
    page = ident._repr_html_()
    assert "<tr><td>vendor</td><td>ACME &lt;Labs&gt;</td></tr>" in page
    assert "<tr><td>revision</td><td>None</td></tr>" in page
    assert "<tr><td>product_name</td><td>Meter</td></tr>" in page
    assert "<tr><td>object 0x80</td><td>bench 3</td></tr>" in page
    assert "<tr><td>conformity</td><td>0x81</td></tr>" in page
    assert page.index(">vendor<") < page.index(">product_name<") < page.index(">object 0x80<")
    assert repr(ident).startswith("Identification(vendor='ACME <Labs>', product_code='M-1'")


def test_display_helpers_format_and_escape() -> None:
    from benchbus._display import format_value, html_table

    assert format_value(bb.DriveState.FORWARD) == "DriveState.FORWARD"
    assert format_value(math.nan) == "nan" and format_value(0.1) == "0.1"
    assert format_value(bb.Model.BLD2) == "BLD2"
    table = html_table(("a&b",), [("<x>",)], caption='"c"')
    assert table == (
        '<table><caption style="text-align: left">&quot;c&quot;</caption>'
        "<thead><tr><th>a&amp;b</th></tr></thead><tbody><tr><td>&lt;x&gt;</td></tr></tbody>"
        "</table>"
    )


def test_unknown_columns_are_refused_before_anything_is_sent() -> None:
    from benchbus.sim import J2Device, Simulator

    with Simulator({1: J2Device()}) as sim, bb.J2Controller(sim.port) as j2:
        with pytest.raises(ValueError, match="'zz'"):
            j2.record(1.0, 0.1, columns=["pv", "zz"])
        assert sim.requests == []


# ---- a sample slower than the interval -----------------------------------------------------------


def test_a_sample_slower_than_the_interval_warns_once_with_the_period_and_the_missed() -> None:
    """21 single reads take 165 ms: at 100 ms a recording of 5 s misses every other
    deadline or so, and says so once, at the end."""
    fake = FakeTime()

    def sample() -> dict[str, float]:
        fake.now += 0.165
        return {"speed": 0.0}

    with pytest.warns(UserWarning) as caught:
        rec = record(sample, 5.0, 0.1, device="Drive unit 1", clock=fake.clock, sleep=fake.sleep)
    assert len(caught) == 1 and caught[0].filename == __file__
    message = str(caught[0].message)
    assert rec.missed > 0 and len(rec) + rec.missed == 50
    period = (rec.times[-1] - rec.times[0]) / (len(rec) - 1)
    assert message.startswith("Drive unit 1: a sample takes 0.165 s, longer than the interval")
    assert f"{len(rec)} samples, one every {period:.3g} s, and {rec.missed} missed" in message
    assert "interval of 0.17 s or more" in message


def test_a_drive_recording_too_fast_for_its_line_warns_where_it_was_called(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    fake = FakeTime()
    with drive_line() as (_, drive, _):
        real_sample = drive.sample

        def slow_sample() -> dict[str, float]:
            fake.now += 0.6
            return real_sample()

        monkeypatch.setattr(drive, "sample", slow_sample)
        with pytest.warns(UserWarning, match="missed") as caught:
            rec = drive.record(2.0, 0.25, clock=fake.clock, sleep=fake.sleep)
    assert len(caught) == 1 and caught[0].filename == __file__ and rec.missed > 0
    assert str(caught[0].message).startswith("Drive unit 1: a sample takes 0.6 s")


def test_one_late_sample_is_no_reason_to_warn() -> None:
    fake = FakeTime()
    calls = 0

    def sample() -> dict[str, float]:
        nonlocal calls
        fake.now += 0.875 if calls == 4 else 0.0625
        calls += 1
        return {"x": 1.0}

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rec = record(sample, 3.0, 0.25, clock=fake.clock, sleep=fake.sleep)
    assert rec.missed == 2


# ---- plot: an Axes per unit ----------------------------------------------------------------------


def test_plot_gives_each_unit_an_axes_of_its_own_sharing_time(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    times = [0.0, 0.5, 1.0]
    rec = Recording(
        times,
        times,
        {"speed": [0.0, 1000.0, 2000.0], "current": [0.2, 1.4, 1.4], "ref": [0.0, 1500.0, 2000.0]},
        interval=0.5,
        units={"speed": "rpm", "current": "A", "ref": "rpm"},
        device="Drive unit 1",
    )
    top = rec.plot(path=tmp_path / "two.png")
    axes = top.figure.axes
    assert len(axes) == 2 and axes[0] is top
    assert [line.get_label() for line in axes[0].get_lines()] == ["speed (rpm)", "ref (rpm)"]
    assert [line.get_label() for line in axes[1].get_lines()] == ["current (A)"]
    assert [ax.get_ylabel() for ax in axes] == ["rpm", "A"]
    assert axes[0].get_ylim()[1] < 2500 and axes[1].get_ylim()[1] < 2  # each on its own scale
    assert axes[0].get_shared_x_axes().joined(axes[0], axes[1])
    assert axes[1].get_xlabel() == "time (s)" and top.get_title() == "Drive unit 1"
    assert (tmp_path / "two.png").read_bytes().startswith(PNG_SIGNATURE)
    # One unit: one Axes, labelled with it.
    one = rec.plot(["current"])
    assert len(one.figure.axes) == 1 and one.get_ylabel() == "A"
    # An Axes of the caller's takes one unit's columns.
    assert rec.plot(["speed", "ref"], ax=one) is one
    with pytest.raises(ValueError, match=r"2 units \(rpm, A\)"):
        rec.plot(ax=one)
