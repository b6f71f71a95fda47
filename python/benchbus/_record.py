"""Recordings: a device's measurements sampled on a steady clock, for notebooks and benches.

:meth:`benchbus.Drive.record` (and every device with ``sample()``) samples on absolute
deadlines (the Schedule of :meth:`benchbus.Bus.poll`) into a :class:`Recording`, which gives its
samples as CSV (standard library only), a pandas DataFrame (``pip install
'benchbus[data]'``) or a matplotlib plot (``pip install 'benchbus[plot]'``). pandas and
matplotlib are imported only when asked for.
"""

from __future__ import annotations

import csv
import io
import math
import os
import statistics
import sys
import time
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from datetime import datetime
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol, cast, overload

from benchbus._core import _Ticks
from benchbus._display import html_table, plural

if TYPE_CHECKING:
    import pandas
    from matplotlib.axes import Axes

__all__ = ["PeriodStats", "Recording", "record"]

#: Rows shown at each end of a long recording's HTML table.
_HTML_EDGE_ROWS = 5
#: Column names listed in a recording's repr before it shortens the list.
_REPR_COLUMNS = 6


class _Writer(Protocol):
    """Anything with ``write(str)``: a text file or ``io.StringIO``."""

    def write(self, text: str, /) -> object:
        """Write ``text``."""
        ...


class PeriodStats(NamedTuple):
    """How late the samples of a :class:`Recording` were taken against their deadlines,
    in seconds (NaN for an empty recording), and how many deadlines were skipped."""

    #: Mean lateness.
    mean: float
    #: Standard deviation of the lateness (population).
    std: float
    #: Largest lateness.
    max: float
    #: Deadlines skipped because a sample overran its period.
    missed: int


class Recording:
    """The samples of one :meth:`~benchbus.Drive.record` run.

    ``rec.times[i]`` is when sample ``i`` was taken and ``rec.deadlines[i]`` when it was
    due, both in seconds since the start; ``rec.columns[name][i]`` (or ``rec[name][i]``) is
    its value of ``name``. Deadlines are exact multiples of :attr:`interval`: a sample
    that overran skips the deadlines already past (counted in :attr:`missed`) instead of
    shifting the ones after it.

    ::

        rec = drive.record(5.0, 0.05)               # 5 s, a sample every 50 ms
        rec.to_csv("spin_up.csv")                   # standard library only
        df = rec.to_pandas()                        # pip install 'benchbus[data]'
        rec.plot(["speed"], path="spin_up.png")     # pip install 'benchbus[plot]'
        rec.period_stats()                          # lateness: mean, std, max, missed
    """

    def __init__(
        self,
        times: Iterable[float],
        deadlines: Iterable[float],
        columns: Mapping[str, Iterable[float]],
        *,
        interval: float,
        duration: float | None = None,
        missed: int = 0,
        device: str = "",
        start: datetime | None = None,
        clock_start: float | None = None,
        interrupted: bool = False,
        units: Mapping[str, str] | None = None,
    ) -> None:
        """A recording of the given samples (copied); every column as long as ``times``;
        ``units`` the unit of each column (a column it does not name has none)."""
        #: When each sample was taken, seconds since the start (the clock read just before
        #: the sample's request).
        self.times: list[float] = [float(t) for t in times]
        #: When each sample was due, seconds since the start: ``n * interval``.
        self.deadlines: list[float] = [float(d) for d in deadlines]
        #: The values, ``{name: [value per sample]}``, in the order the device gave them.
        self.columns: dict[str, list[float]] = {
            str(name): [float(v) for v in values] for name, values in columns.items()
        }
        #: The sampling period asked for, seconds.
        self.interval: float = float(interval)
        #: The duration asked for, seconds (None if not known).
        self.duration: float | None = None if duration is None else float(duration)
        #: Deadlines skipped because a sample overran its period.
        self.missed: int = int(missed)
        #: What was recorded, e.g. ``"Drive unit 1"``.
        self.device: str = device
        #: The wall-clock time of the start (local time, with its time zone).
        self.start: datetime | None = start
        #: The recording clock's reading at the start (``time.monotonic()`` by default), to
        #: line the samples up with other events on that clock.
        self.clock_start: float | None = clock_start
        #: Whether Ctrl-C ended the recording before its duration.
        self.interrupted: bool = interrupted
        #: The unit of each column, from the device's register table (``""`` for none).
        self.units: dict[str, str] = {
            name: str((units or {}).get(name, "")) for name in self.columns
        }
        if len(self.deadlines) != len(self.times) or any(
            len(values) != len(self.times) for values in self.columns.values()
        ):
            raise ValueError("times, deadlines and every column must have the same length")

    # ---- the samples -------------------------------------------------------------------------

    def __len__(self) -> int:
        """The number of samples."""
        return len(self.times)

    def __getitem__(self, name: str) -> list[float]:
        """The values of column ``name``, one per sample."""
        try:
            return self.columns[name]
        except KeyError:
            raise KeyError(f"no column {name!r}; the columns are {self._names_text()}") from None

    def _append(self, taken: float, deadline: float, values: Sequence[float]) -> None:
        """Add one sample: ``values`` in the order of :attr:`columns`."""
        self.times.append(taken)
        self.deadlines.append(deadline)
        for column, value in zip(self.columns.values(), values):
            column.append(value)

    def lateness(self) -> list[float]:
        """How late each sample was taken, seconds: ``times[i] - deadlines[i]``."""
        return [t - d for t, d in zip(self.times, self.deadlines)]

    def period_stats(self) -> PeriodStats:
        """Mean, standard deviation and maximum of :meth:`lateness`, and :attr:`missed`:
        how steadily the samples were taken."""
        late = self.lateness()
        if not late:
            return PeriodStats(math.nan, math.nan, math.nan, self.missed)
        return PeriodStats(statistics.fmean(late), statistics.pstdev(late), max(late), self.missed)

    # ---- export ------------------------------------------------------------------------------

    @overload
    def to_csv(self, path_or_buffer: None = None) -> str: ...
    @overload
    def to_csv(self, path_or_buffer: str | os.PathLike[str] | _Writer) -> None: ...
    def to_csv(self, path_or_buffer: str | os.PathLike[str] | _Writer | None = None) -> str | None:
        """The samples as CSV: a header ``time,<column>,...``, then one row per sample
        (time in seconds since the start; numbers as Python prints them, ``nan`` for a
        missing value). Written to a path or a text buffer, or returned as a str when
        ``path_or_buffer`` is None. Needs only the standard library."""
        if path_or_buffer is None:
            buffer = io.StringIO()
            self._write_csv(buffer)
            return buffer.getvalue()
        if isinstance(path_or_buffer, (str, os.PathLike)):
            with open(path_or_buffer, "w", newline="", encoding="utf-8") as file:
                self._write_csv(file)
            return None
        self._write_csv(path_or_buffer)
        return None

    def _write_csv(self, out: _Writer) -> None:
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(["time", *self.columns])
        values = list(self.columns.values())
        for i, taken in enumerate(self.times):
            writer.writerow([taken, *(column[i] for column in values)])

    def to_pandas(self) -> pandas.DataFrame:
        """The samples as a DataFrame: a column per measurement, indexed by ``time`` in
        seconds since the start. ``frame.attrs`` holds ``device``, ``interval``, ``start``,
        ``missed`` and ``units`` (the unit of each column, ``{"speed": "rpm", ...}``; ``""``
        for none). Needs pandas (``pip install 'benchbus[data]'``)."""
        try:
            import pandas as pd
        except ImportError as exc:
            raise ImportError(
                "Recording.to_pandas() needs pandas: pip install 'benchbus[data]'",
                name="pandas",
            ) from exc
        frame: pd.DataFrame = pd.DataFrame(
            dict(self.columns),
            index=pd.Index(self.times, name="time", dtype=float),
            columns=list(self.columns),
            dtype=float,
        )
        frame.attrs.update(
            device=self.device,
            interval=self.interval,
            start=self.start,
            missed=self.missed,
            units=self.unit_map(),
        )
        return frame

    def plot(
        self,
        columns: Iterable[str] | None = None,
        ax: Axes | None = None,
        path: str | os.PathLike[str] | None = None,
    ) -> Axes:
        """Plot ``columns`` (all by default) against time, one Axes per unit, and return
        the top one.

        Columns of one unit share an Axes, labelled with that unit; columns of several
        units (``speed`` in rpm, ``output_current`` in A) get an Axes each, stacked and
        sharing the time axis, so that each is drawn on its own scale
        (``ax.figure.axes`` lists them, top first).

        Without ``ax``, the plot gets a figure of its own: made through pyplot when pyplot
        is already in use or in a Jupyter kernel (so that it shows like any other plot
        there), otherwise a standalone ``matplotlib.figure.Figure``, which needs no
        backend or display. An ``ax`` of the caller's takes columns of one unit (several
        units are a ValueError: leave ``ax`` out, or plot one unit's columns on it).
        ``path`` saves the figure there, in the format its extension names (PNG without
        one). Nothing is shown: no ``plt.show()``. Needs matplotlib
        (``pip install 'benchbus[plot]'``).
        """
        try:
            from matplotlib.figure import Figure
        except ImportError as exc:
            raise ImportError(
                "Recording.plot() needs matplotlib: pip install 'benchbus[plot]'",
                name="matplotlib",
            ) from exc
        names = self._select(columns)
        units = self.unit_map()
        groups: dict[str, list[str]] = {}
        for name in names:
            groups.setdefault(units[name], []).append(name)
        if not groups:
            groups[""] = []
        if ax is not None and len(groups) > 1:
            listed = ", ".join(unit or "no unit" for unit in groups)
            raise ValueError(
                f"the columns are in {len(groups)} units ({listed}), an Axes each: leave out "
                "ax for stacked Axes, or plot the columns of one unit on it"
            )
        if ax is None:
            height = 4.0 if len(groups) == 1 else 1.0 + 2.25 * len(groups)
            if "matplotlib.pyplot" in sys.modules or "ipykernel" in sys.modules:
                import matplotlib.pyplot as plt

                figure = plt.figure(figsize=(8, height), layout="constrained")
            else:
                figure = Figure(figsize=(8, height), layout="constrained")
            grid = figure.subplots(len(groups), 1, sharex=True, squeeze=False)
            axes: list[Axes] = [grid[i, 0] for i in range(len(groups))]
        else:
            axes = [ax]
        for one, (unit, group) in zip(axes, groups.items()):
            for name in group:
                one.plot(self.times, self.columns[name], label=with_unit(name, unit))
            if unit:
                one.set_ylabel(unit)
            one.grid(True, alpha=0.3)
            if group:
                one.legend(loc="upper right" if len(axes) > 1 else "best")
        axes[-1].set_xlabel("time (s)")
        axes[0].set_title(self._title())
        if path is not None:
            root = axes[0].figure
            while not isinstance(root, Figure):  # a SubFigure's parent
                root = root.figure
            root.savefig(path, format=None if os.path.splitext(path)[1] else "png")
        return axes[0]

    def unit_map(self) -> dict[str, str]:
        """The unit of each column (``""`` for none), in column order."""
        return {name: self.units.get(name, "") for name in self.columns}

    def _select(self, columns: Iterable[str] | None) -> list[str]:
        """The column names asked for (all by default), checked."""
        if columns is None:
            return list(self.columns)
        names = check_columns(columns)
        for name in names:
            if name not in self.columns:
                raise ValueError(f"no column {name!r}; the columns are {self._names_text()}")
        return names

    # ---- display -----------------------------------------------------------------------------

    def _names_text(self) -> str:
        return ", ".join(self.columns) or "(none)"

    def _title(self) -> str:
        start = f" from {self.start:%Y-%m-%d %H:%M:%S}" if self.start is not None else ""
        return f"{self.device or 'recording'}{start}"

    def _summary(self) -> str:
        """``Drive unit 1: 30 samples every 0.05 s over 1.45 s, 0 missed``."""
        span = f" over {self.times[-1]:.3g} s" if self.times else ""
        count = plural(len(self), "sample")
        text = f"{count} every {self.interval:g} s{span}, {self.missed} missed"
        if self.interrupted:
            text += ", interrupted"
        return f"{self.device}: {text}" if self.device else text

    def __repr__(self) -> str:
        """``<Recording Drive unit 1: 30 samples every 0.05 s over 1.45 s, 0 missed;
        started 2025-01-31 10:00:00; columns pv, sv, mv>``."""
        names = list(self.columns)
        if len(names) > _REPR_COLUMNS:
            shown = ", ".join([*names[: _REPR_COLUMNS - 2], "...", *names[-2:]])
            listed = f"{len(names)} columns {shown}"
        else:
            listed = f"columns {', '.join(names) or '(none)'}"
        start = f"; started {self.start:%Y-%m-%d %H:%M:%S}" if self.start is not None else ""
        return f"<Recording {self._summary()}{start}; {listed}>"

    def _repr_html_(self) -> str:
        """A summary and the first and last rows as an HTML table, for notebooks."""
        stats = self.period_stats()
        lines = [self._summary()]
        if self.start is not None:
            lines.append(f"started {self.start:%Y-%m-%d %H:%M:%S %Z}".rstrip())
        if self.times:
            lines.append(f"lateness mean {stats.mean * 1e3:.2f} ms, max {stats.max * 1e3:.2f} ms")
        header = ["time (s)", *self.columns]
        values = list(self.columns.values())

        def row(i: int) -> list[object]:
            return [f"{self.times[i]:.3f}", *(column[i] for column in values)]

        n = len(self)
        if n > 2 * _HTML_EDGE_ROWS:
            rows = [row(i) for i in range(_HTML_EDGE_ROWS)]
            rows.append(["\u2026"] * len(header))
            rows.extend(row(i) for i in range(n - _HTML_EDGE_ROWS, n))
        else:
            rows = [row(i) for i in range(n)]
        numeric = [True] * len(header)
        return f"<div>{html_table(header, rows, caption='; '.join(lines), numeric=numeric)}</div>"


def with_unit(name: str, unit: str) -> str:
    """``speed (rpm)``; the name alone when there is no unit."""
    return f"{name} ({unit})" if unit else name


def check_seconds(name: str, value: object) -> float:
    """``value`` as a positive, finite number of seconds; TypeError or ValueError if not."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TypeError(f"{name} must be a number of seconds, got {type(value).__name__}")
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive, finite number of seconds, got {value!r}")
    return float(value)


def check_columns(columns: Iterable[str]) -> list[str]:
    """``columns`` as a list of distinct names; TypeError or ValueError if not."""
    if isinstance(columns, str) or not isinstance(columns, Iterable):
        raise TypeError('columns is a list of names (["speed"]), not ' + type(columns).__name__)
    names = list(columns)
    for name in names:
        if not isinstance(name, str):
            raise TypeError(f"a column name is a str, got {type(name).__name__}")
    if not names:
        raise ValueError("columns is empty: name at least one, or pass None for all")
    if len(set(names)) != len(names):
        raise ValueError(f"columns named twice: {names}")
    return names


def record(
    sample: Callable[[], Mapping[str, float]],
    duration: float,
    interval: float,
    *,
    device: str = "",
    columns: Iterable[str] | None = None,
    known: Iterable[str] | None = None,
    units: Mapping[str, str] | None = None,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> Recording:
    """Call ``sample()`` every ``interval`` seconds for ``duration`` seconds, on absolute
    deadlines: what :meth:`benchbus.Drive.record` and the other devices' ``record`` do.

    The arguments are checked before the first sample. The first sample sets the columns
    (``columns`` picks some of them, in that order: a name the device does not give is a
    ValueError then); a later sample without one of them records NaN for it. An exception
    from ``sample()`` ends the recording and goes on, carrying what was recorded before it
    as its ``recording`` attribute. Ctrl-C (KeyboardInterrupt) ends it too, and returns
    what was recorded, with ``interrupted`` set. ``units`` gives the unit of each column.

    A sample that takes longer than ``interval`` (a slow line, many single-register reads)
    makes the recording miss deadlines: at its end, one UserWarning then says how long a
    sample takes, the period achieved and how many deadlines were missed.
    """
    duration = check_seconds("duration", duration)
    interval = check_seconds("interval", interval)
    wanted = None if columns is None else check_columns(columns)
    for name, function in (("clock", clock), ("sleep", sleep)):
        if not callable(function):
            raise TypeError(f"{name} must be callable, got {type(function).__name__}")
    if wanted is not None and known is not None:
        # Refused before anything is sent when the device's names are ``known`` in advance.
        _first_columns(dict.fromkeys(known, 0.0), wanted)
    rec = Recording([], [], {}, interval=interval, duration=duration, device=device)
    names: list[str] | None = None
    spent: list[float] = []  # how long each sample took, seconds
    try:
        # The real clock and sleep are the schedule's own (it waits without the GIL).
        ticks = _Ticks(
            interval,
            duration,
            clock=None if clock is time.monotonic else clock,
            sleep=None if sleep is time.sleep else sleep,
        )
        for n, deadline, missed in ticks:
            if rec.clock_start is None:
                rec.clock_start = deadline - n * interval
                rec.start = datetime.now().astimezone()
            rec.missed += missed
            taken = clock() - rec.clock_start
            values = sample()
            spent.append(clock() - rec.clock_start - taken)
            if names is None:
                names = _first_columns(values, wanted)
                rec.columns = {name: [] for name in names}
                rec.units = {name: (units or {}).get(name, "") for name in names}
            rec._append(taken, n * interval, [float(values.get(name, math.nan)) for name in names])
    except KeyboardInterrupt:
        rec.interrupted = True
        _warn_if_too_short(rec, spent)
    except Exception as exc:
        kept = cast(Any, exc)
        try:
            kept.recording = rec
            if hasattr(kept, "add_note"):  # Python 3.11+: shown with the traceback
                count = plural(len(rec), "sample")
                kept.add_note(f"the {count} recorded before it are in .recording")
        except (AttributeError, TypeError):  # an exception that takes no attributes
            pass
        raise
    _warn_if_too_short(rec, spent)
    return rec


def _warn_if_too_short(rec: Recording, spent: list[float]) -> None:
    """Warn (once, at the end) when a sample took longer than the interval, so that
    deadlines were missed: with the period achieved and the count missed."""
    if not rec.missed or not spent or statistics.median(spent) <= rec.interval:
        return
    achieved = (rec.times[-1] - rec.times[0]) / (len(rec) - 1) if len(rec) > 1 else spent[0]
    enough = math.ceil(max(spent) * 100) / 100
    who = f"{rec.device}: " if rec.device else ""
    warnings.warn(
        f"{who}a sample takes {statistics.median(spent):.3g} s, longer than the interval of "
        f"{rec.interval:g} s: {plural(len(rec), 'sample')}, one every {achieved:.3g} s, and "
        f"{rec.missed} missed (record at an interval of {enough:g} s or more)",
        UserWarning,
        stacklevel=_outside_benchbus(),
    )


def _outside_benchbus() -> int:
    """The ``stacklevel`` that makes a warning of the caller point at the first frame
    outside benchbus: the user's call."""
    level = 1
    frame = sys._getframe(1)
    while frame.f_back is not None and frame.f_globals.get("__name__", "").startswith("benchbus."):
        frame = frame.f_back
        level += 1
    return level


def _first_columns(values: Mapping[str, float], wanted: list[str] | None) -> list[str]:
    """The columns of a recording: those of its first sample, or ``wanted`` among them."""
    if wanted is None:
        return list(values)
    missing = [name for name in wanted if name not in values]
    if missing:
        raise ValueError(
            f"the device gives no {', '.join(map(repr, missing))}; it gives "
            + (", ".join(values) or "nothing")
        )
    return wanted
