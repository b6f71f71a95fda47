"""Which device family answers at a unit, from a few reads each family answers its own way.

Each family has one small test (:data:`FAMILIES`), run on a :class:`Probe` that caches the
replies, so a read two tests share goes out once. A test says True (it is one), False (it
is not) or None (it cannot tell: the unit refused a read the family would answer, or garbled
it), and a unit is never judged on a read it refused::

    mismatch(bus, 1, "j2")   # None, or the family unit 1 looks like instead (FAMILIES[1])
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from benchbus._core import Bus
from benchbus._drive import Drive, Model
from benchbus._j2 import J2Controller
from benchbus._pbl import PblDrive
from benchbus.exceptions import FrameError, ModbusException, ResponseTimeout

__all__ = ["FAMILIES", "Family", "Probe", "family", "mismatch", "recognise", "verdict"]


class Probe:
    """The replies of one unit, each read sent once: words, or the exception code."""

    def __init__(self, bus: Bus, unit: int) -> None:
        """Reads go to ``unit`` on ``bus``."""
        self.bus = bus
        self.unit = unit
        self._replies: dict[tuple[int, int], list[int] | int] = {}

    def read(self, address: int, count: int = 1) -> list[int] | int:
        """``count`` registers from ``address``, or the exception code the unit answered.

        A timeout or a garbled reply is raised (the unit may be absent)."""
        key = (address, count)
        if key not in self._replies:
            try:
                self._replies[key] = self.bus.read_holding_registers(self.unit, address, count)
            except ModbusException as exc:
                self._replies[key] = exc.code
        return self._replies[key]


def _bld(probe: Probe) -> bool | None:
    """The identification code (0x2103) names a model the manuals list."""
    try:
        drive = Drive(probe.bus, probe.unit)
    except ValueError:  # a unit no drive can have (above 247)
        return False
    try:
        model = drive.model
    except ModbusException:
        return None
    return isinstance(model, Model)


#: The PBL's last parameter: the one after it is refused as an illegal address (code 2).
_PBL_LAST = max(row[0] for row in PblDrive.table())


def _pbl(probe: Probe) -> bool | None:
    """The last parameter reads and the one after it is refused as an illegal address."""
    last = probe.read(_PBL_LAST)
    if not isinstance(last, list):
        return None
    return probe.read(_PBL_LAST + 1) == 2


def _j2(probe: Probe) -> bool | None:
    """AM is 0 or 1, LSP < USP with SV between them, and an unused address reads (as 0)."""
    try:
        am, low, high, sv = J2Controller(probe.bus, probe.unit).read_many(
            ["AM", "LSP", "USP", "SV"]
        )
    except ModbusException:
        return None
    if am not in (0, 1) or not low < high or not low <= sv <= high:
        return False
    return isinstance(probe.read(_PBL_LAST + 1), list)


@dataclasses.dataclass(frozen=True)
class Family:
    """A device family the command line can recognise."""

    #: The family's key (the command that talks to it).
    key: str
    #: How a sentence names it: "a BLD drive".
    name: str
    #: Whether a unit is one of the family (None: cannot tell).
    test: Callable[[Probe], bool | None]


#: The families, in the order they are tried when naming what a unit looks like.
FAMILIES = (
    Family("drive", "a BLD drive", _bld),
    Family("pbl", "a PBL drive", _pbl),
    Family("j2", "a J2 controller", _j2),
)


def verdict(family: Family, probe: Probe) -> bool | None:
    """The family's test, with a timeout or a garbled reply as 'cannot tell'."""
    try:
        return family.test(probe)
    except (ResponseTimeout, FrameError):
        return None


def recognise(bus: Bus, unit: int) -> Family | None:
    """The first family the unit at ``unit`` is recognised as, or None."""
    probe = Probe(bus, unit)
    return next((f for f in FAMILIES if verdict(f, probe)), None)


def family(key: str) -> Family:
    """The family called ``key`` ("drive", "pbl", "j2")."""
    return next(f for f in FAMILIES if f.key == key)


def mismatch(bus: Bus, unit: int, key: str) -> Family | None:
    """None if ``unit`` may be of the family ``key``, else the family it looks like.

    The family's own test runs first (a unit that does not answer it raises the timeout);
    only if it does not recognise the unit are the others tried, and only a unit another
    family recognises is refused: one that no test recognises is given the benefit of the
    doubt.
    """
    expected = family(key)
    probe = Probe(bus, unit)
    if expected.test(probe):
        return None
    return next((f for f in FAMILIES if f is not expected and verdict(f, probe)), None)
