"""Which device family answers at a unit, from a few reads each family answers its own way.

Each family has one small test, run on a :class:`Probe` that caches the replies, so a read
two tests share goes out once. A test says True (it is one), False (it is not) or None (it
cannot tell: the unit refused a read the family would answer, or garbled it), and a unit is
never judged on a read it refused. The tests are the families' model probes in
:mod:`benchbus._families`, which runs them.
"""

from __future__ import annotations

from typing import Any

from benchbus._core import Bus, DriveCore
from benchbus._drive import Drive, DriveState, Model
from benchbus._instrument import TAISONG_MAX_READ, Instrument
from benchbus._j2 import J2Controller
from benchbus._pbl import PblDrive
from benchbus.exceptions import FrameError, ModbusException, ResponseTimeout

__all__ = ["Probe", "drive_model", "is_drive", "is_j2", "is_pbl", "is_taisong"]


#: The exception codes by which a unit refuses a read it cannot answer (illegal function,
#: address or value, device failure), which tell what it is; the others (busy, a gateway's)
#: say nothing of it.
REFUSALS = frozenset({1, 2, 3, 4})


def refused(exc: ModbusException) -> bool:
    """Whether ``exc`` is the unit refusing the read (see :data:`REFUSALS`)."""
    return exc.code in REFUSALS


class Probe:
    """The replies of one unit, each read sent once: words, or the exception code."""

    def __init__(
        self, bus: Bus, unit: int, *, timeout: float | None = None, retries: int | None = None
    ) -> None:
        """Reads go to ``unit`` on ``bus``, with ``timeout`` and ``retries`` (None: the
        Bus's), as do those of the family devices the tests make."""
        self.bus = bus
        self.unit = unit
        self.timeout = timeout
        self.retries = retries
        self._reader = Instrument(bus, unit, max_read=125, timeout=timeout, retries=retries)
        self._replies: dict[tuple[int, int], list[int] | int] = {}

    def timing(self) -> dict[str, Any]:
        """The keywords a family device made for a test takes: the probe's timing, and no
        identity check of its own (the test is that check)."""
        return {"timeout": self.timeout, "retries": self.retries, "check_identity": False}

    def read(self, address: int, count: int = 1) -> list[int] | int:
        """``count`` registers from ``address``, or the exception code the unit answered.

        A timeout or a garbled reply is raised (the unit may be absent), and so is an
        exception that says nothing of the read (see :func:`refused`)."""
        key = (address, count)
        if key not in self._replies:
            try:
                self._replies[key] = self._reader.read_registers(address, count)
            except ModbusException as exc:
                if not refused(exc):
                    raise
                self._replies[key] = exc.code
        return self._replies[key]

    def answers(self, address: int, count: int = 1) -> bool:
        """Whether the unit answers this read with registers (not an exception, a timeout or
        a garbled reply)."""
        try:
            return isinstance(self.read(address, count), list)
        except (ResponseTimeout, FrameError):
            return False


def is_drive(probe: Probe) -> bool | None:
    """The identification code (0x2103) names a model the manuals list."""
    try:
        drive = Drive(probe.bus, probe.unit, **probe.timing())
    except ValueError:  # a unit no drive can have (above 247)
        return False
    try:
        model = drive.model
    except ModbusException as exc:
        if not refused(exc):
            raise
        return None
    return isinstance(model, Model)


_DRIVE_STATES = {s.value for s in DriveState}


def drive_model(probe: Probe) -> str | None:
    """``Drive BLD2`` (the model) if the drive's ``state`` register (0x2100) holds a drive
    state (1..6) and ``model_id`` (0x2103) a model code, else None. A code both drive
    families use (0x20: BLD2 or C20) is told apart by the BLD-only ``stop_mode`` (0x2012): a
    drive that answers it is a BLD. The addresses come from the drive's register table."""
    try:
        rows = Drive(probe.bus, probe.unit, **probe.timing()).registers()
    except ValueError:  # a unit no drive can have (above 247)
        return None
    address = {row[0]: row[1] for row in rows}
    state = probe.read(address["state"])
    if not isinstance(state, list) or not state or state[0] not in _DRIVE_STATES:
        return None
    code = probe.read(address["model_id"])
    if not isinstance(code, list) or not code:
        return None
    bld, c20 = (DriveCore.model_from_id(f, code[0]) for f in ("BLD", "C20"))
    name = bld if bld == c20 or probe.answers(address["stop_mode"]) else c20
    return None if name is None else f"Drive {Model(name)}"


#: The PBL's last parameter: the one after it is refused as an illegal address (code 2).
_PBL_LAST = max(row[0] for row in PblDrive.table())


def is_pbl(probe: Probe) -> bool | None:
    """The last parameter reads and the one after it is refused as an illegal address."""
    last = probe.read(_PBL_LAST)
    if not isinstance(last, list):
        return None
    return probe.read(_PBL_LAST + 1) == 2


def is_j2(probe: Probe) -> bool | None:
    """AM is 0 or 1, LSP < USP with SV between them, and an unused address reads (as 0)."""
    try:
        am, low, high, sv = J2Controller(probe.bus, probe.unit, **probe.timing()).read_many(
            ["AM", "LSP", "USP", "SV"]
        )
    except ModbusException as exc:
        if not refused(exc):
            raise
        return None
    if am not in (0, 1) or not low < high or not low <= sv <= high:
        return False
    return isinstance(probe.read(_PBL_LAST + 1), list)


def is_taisong(probe: Probe) -> bool:
    """A read of 37 registers from 0 is answered and one of 38 refused with exception 3
    (the meter's request limit)."""
    return isinstance(probe.read(0, TAISONG_MAX_READ), list) and (
        probe.read(0, TAISONG_MAX_READ + 1) == 3
    )
