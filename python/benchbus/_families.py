"""The device families benchbus knows, each declared once.

A :class:`Family` ties a kind of device (``"drive"``, ``"pbl"``, ``"j2"``, ``"instrument"``,
``"atv31"``) to its benchbus class, its line defaults (the class's ``LINE_DEFAULTS``), its
simulator in :mod:`benchbus.sim` (imported only when asked for: it needs the ``sim``
extra) and its model probe (:mod:`benchbus._recognise`). The command line (its device
commands, ``sim``, ``scan``'s model guess and the family check of ``status`` and
``monitor``), the pytest plugin and the demo all read :data:`FAMILIES`::

    family("pbl").line              # LineDefaults(baudrate=115200, parity='E', timeout=0.1, ...)
    family("j2").simulate(speedup=20)   # a benchbus.sim.J2Device
    mismatch(bus, 1, "j2")          # None, or the family unit 1 looks like instead
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

from benchbus._core import Bus
from benchbus._device import BusDevice, LineDefaults, add_note
from benchbus._drive import Drive
from benchbus._instrument import Instrument
from benchbus._j2 import J2Controller
from benchbus._pbl import PblDrive
from benchbus._recognise import Probe, drive_model, is_drive, is_j2, is_pbl, is_taisong
from benchbus.exceptions import FrameError, ModbusException, ResponseTimeout, WrongDevice

if TYPE_CHECKING:
    from benchbus.sim import SimDevice

__all__ = [
    "FAMILIES",
    "Family",
    "check_identity",
    "command_families",
    "command_keys",
    "family",
    "mismatch",
]


@dataclasses.dataclass(frozen=True)
class Family:
    """A kind of device: its class, line defaults, simulator and model probe."""

    #: The family's key (the command that talks to it, the pytest plugin's kind).
    key: str
    #: How a sentence names it: "a BLD drive".
    name: str
    #: The benchbus class that talks to it (None: a device only simulated).
    device: type[BusDevice] | None
    #: The name of its simulator class in :mod:`benchbus.sim`.
    simulator: str
    #: The options of ``benchbus sim`` its simulator takes (keywords of its constructor).
    sim_options: tuple[str, ...] = ()
    #: Whether a unit is one of the family (None: cannot tell); None: no test.
    test: Callable[[Probe], bool | None] | None = None
    #: What ``scan`` calls a unit its test recognises.
    label: str = ""
    #: What ``scan`` calls a unit of the family, from reads of its own, instead of
    #: ``label`` after the test (None: not one of the family).
    model: Callable[[Probe], str | None] | None = None
    #: Whether the command line has a command for it (``benchbus drive``, ...): the module
    #: ``benchbus.cli.<key>``.
    command: bool = False
    #: The keywords of its simulator for the pytest plugin's simulated device under test
    #: (``sim_<key>_model``); empty: the simulator's defaults.
    bench_model: Mapping[str, Any] = dataclasses.field(default_factory=dict, compare=False)
    #: The options its class is opened with on a simulated unit, from that unit.
    opened_with: Callable[[Any], dict[str, Any]] = lambda model: {}
    #: Its class's methods that act and take no arguments (a drive's commands), which
    #: :mod:`benchbus.epics` serves as records whose processing runs them.
    actions: tuple[str, ...] = ()

    @property
    def line(self) -> LineDefaults:
        """Its line defaults: its class's (the generic device's without a class)."""
        return (self.device or BusDevice).LINE_DEFAULTS

    def open(self, port_or_bus: str | Bus, unit: int, **options: Any) -> BusDevice:
        """Its benchbus device at ``unit`` on ``port_or_bus``, made with ``options``
        (``timeout``, ``family``...). ValueError for a family with no benchbus class."""
        if self.device is None:
            raise ValueError(f"{self.name} has no benchbus class, only a simulator")
        cls: Callable[..., BusDevice] = self.device
        return cls(port_or_bus, unit, **options)

    def simulate(self, **options: Any) -> SimDevice:
        """A new simulated device of the family, made with ``options``.

        Raises ImportError (saying what to install) without the ``sim`` extra."""
        import benchbus.sim

        cls: Callable[..., SimDevice] = getattr(benchbus.sim, self.simulator)
        return cls(**options)

    def verdict(self, probe: Probe) -> bool | None:
        """The family's test, with a timeout, a garbled reply or an exception that says
        nothing of the unit (busy, a gateway's) as 'cannot tell'."""
        if self.test is None:
            return None
        try:
            return self.test(probe)
        except (ResponseTimeout, FrameError, ModbusException):
            return None

    def identify(self, probe: Probe) -> str | None:
        """What ``scan`` calls the unit if it is one of the family, else None."""
        if self.model is None:
            return self.label if self.verdict(probe) else None
        try:
            return self.model(probe)
        except (ResponseTimeout, FrameError, ModbusException):
            return None


def _drive_family(model: Any) -> dict[str, Any]:
    """The ``family`` a :class:`Drive` takes for a simulated drive of ``model``."""
    return {"family": "C20" if model.model == "C20" else "BLD"}


#: The families, in the order they are tried when naming what a unit looks like.
FAMILIES = (
    Family(
        "drive",
        "a BLD drive",
        Drive,
        "DriveDevice",
        ("model",),
        test=is_drive,
        model=drive_model,
        command=True,
        bench_model={"model": "BLD2"},
        opened_with=_drive_family,
        actions=tuple(name for name, _ in Drive.commands()),
    ),
    Family(
        "pbl",
        "a PBL drive",
        PblDrive,
        "PblDevice",
        test=is_pbl,
        label="PBL",
        command=True,
        actions=("start", "stop"),
    ),
    Family(
        "j2",
        "a J2 controller",
        J2Controller,
        "J2Device",
        ("speedup",),
        test=is_j2,
        label="J2",
        command=True,
        bench_model={"speedup": 100.0},
        actions=("start_ramp", "stop_ramp"),
    ),
    Family(
        "instrument",
        "a Taisong meter",
        Instrument,
        "TaisongDevice",
        ("speedup",),
        test=is_taisong,
        label="Taisong",
        bench_model={"speedup": 10.0},
    ),
    Family("atv31", "the Taisong manual's ATV31 drive", None, "Atv31Device"),
)


def family(key: str) -> Family:
    """The family called ``key`` ("drive", "pbl", "j2", "instrument", "atv31")."""
    found = next((f for f in FAMILIES if f.key == key), None)
    if found is None:
        raise ValueError(f"no device family {key!r}: one of {', '.join(f.key for f in FAMILIES)}")
    return found


def command_families() -> tuple[Family, ...]:
    """The families the command line has a command for, in order."""
    return tuple(f for f in FAMILIES if f.command)


def command_keys() -> tuple[str, ...]:
    """The keys of the families the command line has a command for (``"drive"``...)."""
    return tuple(f.key for f in command_families())


def mismatch(
    bus: Bus, unit: int, key: str, *, timeout: float | None = None, retries: int | None = None
) -> Family | None:
    """None if ``unit`` may be of the family ``key``, else the family it looks like.

    The family's own test runs first (a unit that does not answer it raises the timeout);
    only if it does not recognise the unit are the other families with a command tried,
    and only a unit another family recognises is refused: one that no test recognises is
    given the benefit of the doubt. The reads go with ``timeout`` and ``retries`` (None:
    the Bus's).
    """
    expected = family(key)
    probe = Probe(bus, unit, timeout=timeout, retries=retries)
    if expected.test is None or expected.test(probe):
        return None
    return next((f for f in command_families() if f is not expected and f.verdict(probe)), None)


def check_identity(
    key: str, bus: Bus, unit: int, timeout: float | None = None, retries: int | None = None
) -> None:
    """Raise :class:`~benchbus.WrongDevice` if ``unit`` looks like another family than
    ``key`` (see :func:`mismatch`): the check a family's device makes before its first
    exchange. A timeout, a garbled reply or an exception that says nothing of the unit
    (busy, a gateway's) is raised with a note saying what was checked."""
    expected = family(key)
    try:
        other = mismatch(bus, unit, key, timeout=timeout, retries=retries)
    except (ResponseTimeout, FrameError, ModbusException) as exc:
        add_note(exc, f"while checking that unit {unit} is {expected.name}")
        raise
    if other is not None:
        made = expected.device.__name__ if expected.device else "device"
        raise WrongDevice(
            f"unit {unit} answers but is not {expected.name}: it looks like {other.name}. "
            f"Check the port and the unit, or make the {made} with check_identity=False "
            "if its identity registers differ from its manual's",
            unit=unit,
            expected=key,
            looks_like=other.key,
        )
