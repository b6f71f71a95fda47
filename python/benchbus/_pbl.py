"""PBL-series BLDC drives (manual 002) as Python objects.

The parameter table (0..222: names, units, read-only or writable, ranges), the sample block
and every call to the drive live in the compiled base class (``PblCore``); this module adds
what belongs to Python: enums, named properties, the status object, the reprs and the context
manager.
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from typing import NamedTuple

from benchbus._core import Bus, PblCore, Profile
from benchbus._device import (
    MeasuredProperty,
    MotorDevice,
    PrintableIntEnum,
    RegisterProperty,
    to_enum,
    to_int,
)
from benchbus._display import dataclass_table, field_table
from benchbus._profile import profile_line

__all__ = [
    "DecelMode",
    "Direction",
    "DirectionSetting",
    "PblControlMode",
    "PblDrive",
    "PblParameter",
    "PblStatus",
    "PblTelemetry",
    "StartStopSource",
]


class Direction(PrintableIntEnum):
    """Direction of rotation: bit 1 of the control word (0) and of the status word (2)."""

    FORWARD = 0
    REVERSE = 1


class PblControlMode(PrintableIntEnum):
    """Control mode (parameter 100)."""

    SPEED_LOOP = 0
    DUTY_CYCLE = 1
    TORQUE = 2


class DirectionSetting(PrintableIntEnum):
    """Direction setting (parameter 203): run as commanded, or the other way."""

    NORMAL = 0
    INVERTED = 1


class StartStopSource(PrintableIntEnum):
    """Where start and stop come from (parameter 204)."""

    KEYS = 0
    IO = 1
    COMMUNICATION = 2


class DecelMode(PrintableIntEnum):
    """How the drive slows down (parameter 114)."""

    NATURAL = 0
    BRAKING = 1


class PblParameter(NamedTuple):
    """One row of :meth:`PblDrive.table`: a parameter of manual 002."""

    #: The parameter's number, 0..222 (its register address).
    number: int
    #: Its name (``get``, ``set``, ``read_parameter`` take it).
    name: str
    #: Its unit ("rpm", "V"...; ``""`` for none).
    unit: str
    #: "R" (read-only) or "W/R".
    access: str
    #: The lowest value a write takes.
    low: float
    #: The highest value a write takes.
    high: float


@dataclasses.dataclass(frozen=True)
class PblStatus:
    """The status word (parameter 2) as the drive reports it."""

    #: The motor is moving (bit 0).
    running: bool
    #: The direction it turns (bit 1).
    direction: Direction

    def _repr_html_(self) -> str:
        """A field / value table, for notebooks."""
        return dataclass_table(self)


class PblTelemetry(dict[str, int]):
    """Parameters 0..99 by name (a plain dict of ints), shown as a table in notebooks."""

    def _repr_html_(self) -> str:
        """A parameter / value / unit table, for notebooks."""
        units = {row.name: row.unit for row in PblCore.table()}
        return field_table("PblTelemetry", ((k, v, units.get(k, "")) for k, v in self.items()))


class PblDrive(PblCore, MotorDevice):
    """A PBL-series BLDC drive (manual 002): parameters 0..222, 115200 8E1 by default.

    ::

        with bb.PblDrive("/dev/ttyUSB0", unit=0x11) as pbl:
            pbl.start_stop_source = bb.StartStopSource.COMMUNICATION
            pbl.speed_setpoint = 1500          # rpm (parameter 201, internal speed)
            pbl.direction = bb.Direction.REVERSE
            pbl.start()
            print(pbl.speed, pbl.status())
        # leaving the block stops the motor, also after an exception or Ctrl-C

    Given a path, the drive opens its own Bus at 115200 8E1; given a Bus, it shares it
    (``timeout`` / ``retries`` then apply to this drive's requests only). Any parameter is
    reachable by number or by name (:meth:`read_parameter`, :meth:`write_parameter`,
    :meth:`parameters`, :meth:`table`); values are the raw words in the manual's units.
    These drives answer a single-register write with a count of 1 instead of the echo,
    which is accepted for this family only. They also act on and answer a broadcast
    (``bus.broadcast_write_register``): the Bus waits for no reply and drops what comes.
    """

    #: Line format and reply timeout when the device opens its own Bus: the family file's
    #: ``[line]`` (115200 8E1, 0.1 s).
    LINE_DEFAULTS = profile_line(Profile.family("pbl"))
    #: The family whose identity the device checks before its first exchange.
    IDENTITY = "pbl"

    @property
    def profile(self) -> Profile:
        """The parameter table as a :class:`~benchbus.Profile` (``Profile.family("pbl")``):
        a row for each name :meth:`get` and :meth:`set` take, with its unit, access and
        range."""
        return Profile.family("pbl")

    control_mode: RegisterProperty[PblDrive, PblControlMode] = RegisterProperty(
        "control_mode", to_enum(PblControlMode), "Mode (100)."
    )
    pole_pairs: RegisterProperty[PblDrive, int] = RegisterProperty(
        "pole_pairs", to_int, "Motor pole pairs (205)."
    )
    acceleration: RegisterProperty[PblDrive, int] = RegisterProperty(
        "acceleration", to_int, "Acceleration, rpm/s (209)."
    )
    deceleration: RegisterProperty[PblDrive, int] = RegisterProperty(
        "deceleration", to_int, "Deceleration, rpm/s (210)."
    )
    speed_setpoint: RegisterProperty[PblDrive, int] = RegisterProperty(
        "internal_speed", to_int, "Speed setpoint: the internal speed, rpm (201)."
    )
    speed_source: RegisterProperty[PblDrive, int] = RegisterProperty(
        "speed_source", to_int, "Speed command source (202)."
    )
    direction_setting: RegisterProperty[PblDrive, DirectionSetting] = RegisterProperty(
        "direction_setting", to_enum(DirectionSetting), "Normal or inverted direction (203)."
    )
    start_stop_source: RegisterProperty[PblDrive, StartStopSource] = RegisterProperty(
        "start_stop_source", to_enum(StartStopSource), "Where start/stop come from (204)."
    )
    max_speed: RegisterProperty[PblDrive, int] = RegisterProperty(
        "max_speed", to_int, "Maximum speed, rpm (124)."
    )
    min_speed: RegisterProperty[PblDrive, int] = RegisterProperty(
        "min_speed", to_int, "Minimum speed, rpm (123)."
    )
    decel_mode: RegisterProperty[PblDrive, DecelMode] = RegisterProperty(
        "decel_mode", to_enum(DecelMode), "Natural or braking (114)."
    )
    analog_max_speed: RegisterProperty[PblDrive, int] = RegisterProperty(
        "analog_max_speed", to_int, "Speed at the analog input's maximum, rpm (211)."
    )

    speed: MeasuredProperty[PblDrive, int] = MeasuredProperty(
        "speed", to_int, "Measured speed, rpm (50)."
    )
    bus_voltage: MeasuredProperty[PblDrive, int] = MeasuredProperty(
        "bus_voltage", to_int, "DC bus voltage, V (51)."
    )
    analog_speed_input: MeasuredProperty[PblDrive, int] = MeasuredProperty(
        "analog_speed_input", to_int, "Analog speed input, mV (52)."
    )
    current: MeasuredProperty[PblDrive, int] = MeasuredProperty(
        "current", to_int, "Motor current, A (53)."
    )
    power: MeasuredProperty[PblDrive, int] = MeasuredProperty(
        "power", to_int, "Motor power, W (54)."
    )
    hall_state: MeasuredProperty[PblDrive, int] = MeasuredProperty(
        "hall_state", to_int, "Hall sensor state (6)."
    )

    def __init__(
        self,
        port_or_bus: str | os.PathLike[str] | Bus,
        unit: int = 1,
        *,
        timeout: float | None = None,
        retries: int | None = None,
        check_identity: bool = True,
    ) -> None:
        """The drive at ``unit`` on a Bus, or on a port opened at 115200 8E1.

        ``check_identity`` (default True): before its first exchange, the drive checks
        that the unit is a PBL drive (the reads ``benchbus scan`` names a unit by) and raises
        :class:`~benchbus.WrongDevice`, with nothing written, if it answers as another
        family; False skips the check, for a unit whose identity registers differ from
        its manual's.
        """
        self._on_line(
            port_or_bus, unit, timeout=timeout, retries=retries, check_identity=check_identity
        )

    def restore_defaults(self) -> None:
        """Ask for the factory defaults (1511 to parameter 214).

        The drive applies them only after a power cycle; a ``UserWarning`` says so.
        """
        self._restore_defaults()
        warnings.warn(
            f"unit {self.unit}: defaults restored at the next power-up; power-cycle the drive",
            UserWarning,
            stacklevel=2,
        )
