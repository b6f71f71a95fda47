"""``benchbus monitor``: a live table of a device's measurements, optionally logged to CSV."""

from __future__ import annotations

import argparse
import contextlib
import csv
import datetime
import os
import sys
import time
from typing import IO, Any

import benchbus as bb
from benchbus._core import _Ticks as ticks
from benchbus._display import plural
from benchbus._families import command_keys
from benchbus._record import with_unit
from benchbus.cli._args import (
    PROG,
    Parser,
    add_profile_option,
    integer,
    seconds,
)
from benchbus.cli._errors import CliError, UsageError, end_ctrl_c_line, interrupted, one_line
from benchbus.cli._line import (
    check_family,
    open_bus,
    open_device,
    open_profiled,
    opt,
    profile_of,
    profile_options,
)
from benchbus.cli._output import csv_number, fmt, shown, text_table

__all__ = ["DRIVE_FIELDS", "HELP", "CsvLog", "LiveTable", "add_arguments", "run"]


#: What a drive's monitor shows unless --fields says otherwise (its sample has ~20 fields).
DRIVE_FIELDS = (
    "speed",
    "speed_reference",
    "output_frequency",
    "output_current",
    "output_voltage",
    "bus_voltage",
    "output_power",
    "temperature",
)


class CsvLog:
    """Samples appended to a CSV file: ``time`` (ISO 8601), ``t (s)``, then the fields, each
    named with its unit (``speed (rpm)``)."""

    def __init__(self, path: str, units: dict[str, str]) -> None:
        self.path = path
        self.units = units
        self._file: IO[str] | None = None
        self._writer: Any = None

    @staticmethod
    def check(path: str) -> None:
        """Refuse a ``path`` the log could not be appended to (a missing folder, a folder,
        no permission) as a UsageError, before any port is opened; a new file is made and
        removed again."""
        existed = os.path.lexists(path)
        try:
            with open(path, "a", encoding="utf-8"):
                pass
        except OSError as exc:
            reason = exc.strerror or str(exc)
            raise UsageError(f"--csv {path}: cannot write there ({reason})") from None
        if not existed:
            with contextlib.suppress(OSError):
                os.remove(path)

    def write(self, when: datetime.datetime, t: float, sample: dict[str, Any]) -> None:
        """Append one row (the header first, if the file is new or empty)."""
        header = [
            "time",
            with_unit("t", "s"),
            *(with_unit(k, self.units.get(k, "")) for k in sample),
        ]
        if self._file is None:
            existing = self._header()
            if existing is not None and existing != header:
                raise CliError(
                    f"{self.path} has other columns ({','.join(existing)}): choose another file"
                )
            self._file = open(self.path, "a", newline="", encoding="utf-8")  # noqa: SIM115
            self._writer = csv.writer(self._file)
            if existing is None:
                self._writer.writerow(header)
        row = [when.isoformat(timespec="milliseconds"), f"{t:.3f}"]
        self._writer.writerow(row + [csv_number(v) for v in sample.values()])
        self._file.flush()

    def _header(self) -> list[str] | None:
        try:
            with open(self.path, newline="", encoding="utf-8") as f:
                return next(csv.reader(f), None)
        except FileNotFoundError:
            return None

    def close(self) -> None:
        """Close the file."""
        if self._file is not None:
            self._file.close()
            self._file = None


class LiveTable:
    """The monitor's screen: redrawn in place on a terminal, a line per sample otherwise."""

    def __init__(
        self, stream: IO[str], title: str, fields: list[str], units: dict[str, str], tty: bool
    ) -> None:
        self.stream = stream
        self.title = title
        self.fields = fields
        self.units = [units.get(f, "") for f in fields]
        self.tty = tty
        self._drawn = 0
        self._header = [with_unit("t", "s"), *map(with_unit, fields, self.units)]
        self._widths = [max(len(h), 9) for h in self._header]

    def show(self, n: int, t: float, missed: int, sample: dict[str, Any]) -> None:
        """Show one sample."""
        values = [shown(sample[f]) for f in self.fields]
        if self.tty:
            late = f", {missed} deadlines missed" if missed else ""
            lines = [self.title, f"sample {n}  t {t:.1f} s{late}  (Ctrl-C to stop)"]
            rows = [[f, v.rjust(12), u] for f, v, u in zip(self.fields, values, self.units)]
            lines += text_table(None, rows)
            out = f"\x1b[{self._drawn}A\r" if self._drawn else ""
            out += "".join(f"{line}\x1b[K\n" for line in lines)
            self._drawn = len(lines)
        else:
            out = ""
            if n == 1:
                out += self._row(self._header) + "\n"
            out += self._row([f"{t:.3f}", *values]) + "\n"
        self.stream.write(out)
        self.stream.flush()

    def below(self) -> None:
        """Draw the next sample below what was printed since (not over it)."""
        self._drawn = 0

    def _row(self, cells: list[str]) -> str:
        return "  ".join(c.rjust(w) for c, w in zip(cells, self._widths))


def run(args: argparse.Namespace) -> int:
    """Run ``benchbus monitor`` as ``args`` say; the exit status."""
    profile = profile_of(args)
    if (profile is None) == (args.device is None):
        wanted = f"give a device ({'|'.join(command_keys())}) or --profile FILE"
        raise UsageError(f"{wanted}, not both" if profile is not None else wanted)
    if profile is not None and opt(args, "family") is not None:
        raise UsageError("--family goes with drive: a profile says what the device is")
    kind: str = "profile" if profile is not None else args.device
    log: CsvLog | None = None
    samples = 0
    lost: float | None = None  # when the port was lost, while it is
    line = kind if profile is None else profile_options(profile)
    if args.csv:
        CsvLog.check(args.csv)
    with open_bus(args, line, reconnect=args.reconnect) as bus:
        if profile is None:
            device = open_device(bus, args, kind)
            check_family(device, kind)
        else:
            device = open_profiled(bus, args, profile)
            kind = profile.name
        units = device.sample_units()
        log = CsvLog(args.csv, units) if args.csv else None
        title = f"{kind} unit {device.unit} on {bus.port}, every {fmt(args.interval)} s"
        table: LiveTable | None = None
        try:
            for n, _deadline, missed in ticks(args.interval, args.duration):
                try:
                    sample = device.sample()
                except bb.PortError as exc:
                    if not args.reconnect:
                        raise
                    if lost is None:
                        lost = time.monotonic()
                        _note(table, f"lost {bus.port} ({one_line(exc)}): reconnecting")
                    continue
                if lost is not None:
                    _note(table, f"{bus.port} is back after {time.monotonic() - lost:.1f} s")
                    lost = None
                now = datetime.datetime.now().astimezone()
                t = n * args.interval
                if table is None:
                    fields = _fields(args.fields, kind, sample)
                    table = LiveTable(sys.stdout, title, fields, units, sys.stdout.isatty())
                samples += 1
                if log is not None:
                    log.write(now, t, sample)
                table.show(samples, t, missed, sample)
                if args.count is not None and samples >= args.count:
                    break
        except (KeyboardInterrupt, SystemError) as exc:
            if not interrupted(exc):
                raise
            end_ctrl_c_line()
        finally:
            if log is not None:
                log.close()
    where = f", appended to {args.csv}" if args.csv else ""
    print(f"{plural(samples, 'sample')}{where}", file=sys.stderr)
    return 0


def _note(table: LiveTable | None, text: str) -> None:
    """One line on stderr while the monitor runs, below the table (redrawn after it)."""
    print(f"{PROG}: monitor: {text}", file=sys.stderr, flush=True)
    if table is not None:
        table.below()


def _fields(spec: str | None, kind: str, sample: dict[str, Any]) -> list[str]:
    if spec is None or spec.strip() == "all":
        if spec is None and kind == "drive":
            return [f for f in DRIVE_FIELDS if f in sample]
        return list(sample)
    names = [f.strip() for f in spec.split(",") if f.strip()]
    unknown = [f for f in names if f not in sample]
    if unknown or not names:
        raise UsageError(
            f"no measurement {', '.join(unknown) or spec!r}: choose from {', '.join(sample)}"
        )
    return names


#: What ``benchbus monitor`` does, as ``--help`` says.
HELP = "a live table of a device's (or a device profile's) measurements until Ctrl-C"
#: The rest of its ``--help``.
EPILOG = (
    "On a terminal the table is redrawn in place; otherwise one line is printed "
    "per sample. Samples are taken on a steady clock (deadlines that pass while a "
    "sample is read are skipped, and counted). The CSV file gets every measurement, "
    "with a header when the file is new; an existing file must have the same columns. "
    "A lost port (an adapter unplugged) is reported in one line and reopened at each "
    "sample until it is back. With --profile FILE instead of a family, every readable "
    "register of that device profile but strings (enums by their members' names in the "
    "table, their numbers in the CSV file; bools true or false, 1 or 0)."
)
#: Its line options (see :func:`benchbus.cli._args.line_options`).
LINE_OPTIONS = {"unit": True}
#: Whether it takes ``--family``.
FAMILY_OPTION = True


def add_arguments(parser: Parser, parents: list[Parser]) -> None:
    """The arguments of ``benchbus monitor`` (``parents``: its option groups, for its actions)."""
    kinds = command_keys()
    parser.add_argument("device", nargs="?", choices=kinds, metavar="|".join(kinds))
    add_profile_option(parser, "monitor its registers")
    parser.add_argument(
        "--interval", type=seconds, default=0.5, metavar="S", help="seconds between samples"
    )
    until = parser.add_mutually_exclusive_group()
    until.add_argument(
        "--count", type=integer(1, 10**9, "count"), metavar="N", help="stop after N samples"
    )
    until.add_argument("--duration", type=seconds, metavar="S", help="stop after S seconds")
    parser.add_argument("--csv", metavar="FILE", help="append each sample to FILE")
    parser.add_argument(
        "--no-reconnect",
        dest="reconnect",
        action="store_false",
        help="end with an error when the port is lost (default: say so, reopen it and go on)",
    )
    parser.add_argument(
        "--fields",
        metavar="NAMES",
        help="comma-separated measurements to show (default: all; for a drive, the main ones)",
    )
