"""A serial port's check-up: what stands between a program and the devices on a port.

:func:`doctor` runs the checks of the compiled core (the OS probes live beside the serial
transport) and returns them as :class:`Finding` objects; ``benchbus doctor`` prints one line
for each::

    import benchbus as bb

    for finding in bb.doctor("/dev/ttyUSB0"):
        print(finding)          # "warn  latency-timer  FTDI latency timer 16 ms: ...  fix: ..."
    problems = [f for f in bb.doctor("/dev/ttyUSB0") if f.verdict == "fail"]
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Literal, cast

from benchbus._core import diagnose

__all__ = ["VERDICTS", "Finding", "Verdict", "doctor"]

#: How a finding stands: ``ok`` as it should be; ``info`` worth knowing, nothing to do;
#: ``warn`` works, but slower or less sure than it could (see the fix); ``fail`` stops
#: benchbus from using the port (see the fix).
Verdict = Literal["ok", "info", "warn", "fail"]

#: The verdicts, from the best to the worst.
VERDICTS: tuple[Verdict, ...] = ("ok", "info", "warn", "fail")


@dataclass(frozen=True)
class Finding:
    """One thing :func:`doctor` found about a port.

    ``name`` says what was checked: ``platform``, ``tty-vs-cu`` (macOS), ``port`` (it
    exists), ``holders`` (other processes that have it open; Linux), ``permissions``,
    ``open`` (exclusively, at the line format given; a port in use says who holds it on
    Linux), ``usb`` (the adapter's chip: FTDI, CH340, CP210x, PL2303...), ``latency-timer``
    (an FTDI adapter's, Linux), ``low-latency`` (the driver's mode, which benchbus asks for
    at every open on Linux), ``rs485`` (the kernel RS485 mode) and ``echo`` (whether a request
    comes back: a local echo). ``verdict`` is one of :data:`VERDICTS`; ``message`` says what
    was found and ``fix`` what to do about it (None when there is nothing to do).
    """

    #: What was checked: ``port``, ``permission``, ``usb``, ``latency-timer``, ...
    name: str
    #: One of :data:`VERDICTS`.
    verdict: Verdict
    #: What was found.
    message: str
    #: What to do about it (None when there is nothing to do).
    fix: str | None = None

    def __str__(self) -> str:
        """The finding in one line: verdict, name, message and fix."""
        fix = f"  fix: {self.fix}" if self.fix else ""
        return f"{self.verdict:<4}  {self.name:<13}  {self.message}{fix}"


def doctor(
    port: str | os.PathLike[str],
    *,
    baudrate: int = 19200,
    parity: str = "N",
    stopbits: int = 1,
    unit: int = 1,
    timeout: float = 0.1,
    sysfs_root: str | os.PathLike[str] | None = None,
    proc_root: str | os.PathLike[str] | None = None,
) -> list[Finding]:
    """Check the serial port ``port`` and return what was found, in order (see
    :class:`Finding`). The port must be free: it is opened (exclusively) at ``baudrate``,
    ``parity`` and ``stopbits``, and one harmless request goes out, a read of holding register
    0 from ``unit``, to see whether it comes back within ``timeout`` seconds (a local echo);
    then the port is closed. On Linux the open asks the driver for low latency, as every
    benchbus open does, and the RS485 check sets a mode that is off to what it is, to see
    whether the driver could switch it on. ``sysfs_root`` and ``proc_root`` read other trees
    than ``/sys`` and ``/proc`` (Linux; for tests).

    ValueError for a network port (``tcp://``, ``rtu+tcp://``) or a bad argument. Findings
    that cannot be checked on this system say so.
    """
    return [
        Finding(name, cast("Verdict", verdict), message, fix)
        for name, verdict, message, fix in diagnose(
            port, baudrate, parity, stopbits, unit, timeout, sysfs_root, proc_root
        )
    ]
