"""J2-series PID process/temperature controllers (manual 003) as Python objects.

The parameter table (names, addresses, signed tenths or unsigned integers, ranges) and the
manual's rules (150 ms between writes, 16 registers a request, MV only in manual mode,
RAPNF written 0 before a ramp parameter), the parameter groups (status, sample, PID sets,
limits) and every call to the controller live in the compiled base class (``J2Core``); this
module adds what belongs to Python: enums, named properties, the status object, named tuples,
the reprs and the context manager.
"""

from __future__ import annotations

import dataclasses
import os
from typing import NamedTuple, Union

from benchbus._core import Bus, J2Core, Profile
from benchbus._device import (
    BusDevice,
    MeasuredProperty,
    PrintableIntEnum,
    RegisterProperty,
    check_baudrate,
    to_enum,
    to_float,
    to_int,
)
from benchbus._display import dataclass_table
from benchbus._profile import profile_line

__all__ = ["InputType", "J2Controller", "J2Mode", "J2Parameter", "J2Status", "Limits", "Pid"]

#: A parameter value: a float for the signed table, an int for the unsigned one.
Value = Union[float, int]


class J2Mode(PrintableIntEnum):
    """Control mode (AM): the controller's PID sets the output, or the output is held."""

    MANUAL = 0
    AUTO = 1


class InputType(PrintableIntEnum):
    """Input type (INP), in the manual's order: thermocouples B S R T E J K, Pt100, Cu50,
    and a linear input."""

    B = 0
    S = 1
    R = 2
    T = 3
    E = 4
    J = 5
    K = 6
    PT = 7
    CU = 8
    LN = 9


class J2Parameter(NamedTuple):
    """One row of :meth:`J2Controller.table`: a parameter of manual 003."""

    #: The manual's name ("SV").
    name: str
    #: Its register address.
    address: int
    #: Signed tenths (read as a float) or an unsigned int.
    signed: bool
    #: Whether it may be written.
    writable: bool
    #: The lowest value a write takes.
    low: float
    #: The highest value a write takes.
    high: float
    #: Whether a write must also lie within the limits LSP..USP the controller holds.
    within_limits: bool


class Pid(NamedTuple):
    """A PID parameter set: proportional band P, integral time I, derivative time D."""

    #: Proportional band (0.1..3276.7).
    p: float
    #: Integral time (0..3276.7).
    i: float
    #: Derivative time (0..3276.7).
    d: float


class Limits(NamedTuple):
    """The setpoint limits LSP and USP."""

    #: Lowest setpoint (LSP).
    low: float
    #: Highest setpoint (USP).
    high: float


@dataclasses.dataclass(frozen=True)
class J2Status:
    """What a J2 controller is doing, in one snapshot (two requests)."""

    #: Process value (PV).
    pv: float
    #: Setpoint (SV).
    sv: float
    #: Output, percent (MV).
    mv: float
    #: Automatic or manual control (AM).
    mode: J2Mode
    #: Whether autotuning runs (AT).
    autotune: bool
    #: Whether a setpoint ramp runs (RAPNF).
    ramp_running: bool
    #: Alarm 1 value (AL1).
    alarm1: float
    #: Alarm 2 value (AL2).
    alarm2: float

    def _repr_html_(self) -> str:
        """A field / value / unit table, for notebooks."""
        return dataclass_table(self, {"mv": "%"})


class J2Controller(J2Core, BusDevice):
    """A J2-series PID temperature/process controller (manual 003), 9600 or 19200 8N1.

    ::

        with bb.J2Controller("/dev/ttyUSB0", unit=1) as j2:
            j2.sv = 120.0                  # setpoint, in the input's units
            print(j2.pv, j2.mv, j2.mode)   # 25.3 42.0 J2Mode.AUTO
            j2.alarm1 = -50.0              # negative values round-trip exactly
            j2.set_output(20.0, switch_to_manual=True)

    Given a path, the controller opens its own Bus at ``baudrate`` (9600 or 19200) 8N1;
    given a Bus, it shares it (``timeout`` / ``retries`` then apply to this controller's
    requests only). Units are 1..255, as the manual allows.

    Every parameter of both tables is reachable by name (:meth:`read`, :meth:`write`,
    :meth:`parameters`, :meth:`table`): the signed table as floats (tenths on the wire,
    two's complement), the unsigned one as ints. The manual's rules are applied for you:
    writes go at least 150 ms apart (the Bus waits, per controller, without holding up
    other units); at most 16 registers go in one request; ranges are checked before
    anything is sent (SV also against the limits LSP..USP the controller holds, read just
    before); MV is refused in automatic mode with :class:`~benchbus.StateError` unless you
    ask :meth:`set_output` to switch to manual; RAPNF is written 0 before RAP or RTM.
    The manual's upper limits of 3600 and 9999 are cut to 3276.7, the most a signed
    register in tenths holds. The manual also gives "LSP~USP" for HY1, HY2, HYS, RAP, TRL,
    TRH, SRT and TOP, which cannot be meant literally for a hysteresis or a ramp rate: the
    library checks those against -1999..3276.7 and leaves the rest to the controller (a
    refusal is a :class:`~benchbus.ModbusException`). Pacing applies to every
    J2Controller's writes to the unit and to broadcasts; a raw ``bus.write_register`` is
    not paced. Leaving a ``with`` block closes a Bus the controller opened; the controller
    goes on controlling.
    """

    #: Line format and reply timeout when the device opens its own Bus: the family file's
    #: ``[line]`` (9600 8N1, 0.3 s).
    LINE_DEFAULTS = profile_line(Profile.family("j2"))
    #: The family whose identity the device checks before its first exchange.
    IDENTITY = "j2"

    @property
    def profile(self) -> Profile:
        """The parameter table as a :class:`~benchbus.Profile` (``Profile.family("j2")``):
        a row for each name :meth:`get` and :meth:`set` take (the manual's, "SV"), with its
        unit, access and range."""
        return Profile.family("j2")

    pv: MeasuredProperty[J2Controller, float] = MeasuredProperty(
        "PV", to_float, "Process value (PV), read-only."
    )
    sv: RegisterProperty[J2Controller, float] = RegisterProperty(
        "SV", to_float, "Setpoint (SV), within LSP..USP."
    )
    mv: RegisterProperty[J2Controller, float] = RegisterProperty(
        "MV",
        to_float,
        "The output (MV), percent. Setting it needs manual mode: in automatic mode it raises "
        ":class:`~benchbus.StateError` (see :meth:`set_output`).",
    )
    alarm1: RegisterProperty[J2Controller, float] = RegisterProperty(
        "AL1", to_float, "Alarm 1 value (AL1), -1999..3276.7."
    )
    alarm2: RegisterProperty[J2Controller, float] = RegisterProperty(
        "AL2", to_float, "Alarm 2 value (AL2), -1999..3276.7."
    )
    pv_offset: RegisterProperty[J2Controller, float] = RegisterProperty(
        "PVOS", to_float, "Process value offset (PVOS), -50..50."
    )
    mode: RegisterProperty[J2Controller, J2Mode] = RegisterProperty(
        "AM", to_enum(J2Mode), "Automatic or manual control (AM)."
    )
    input_type: RegisterProperty[J2Controller, InputType] = RegisterProperty(
        "INP", to_enum(InputType), "Input type (INP)."
    )
    decimal_point: RegisterProperty[J2Controller, int] = RegisterProperty(
        "DP", to_int, "Decimal places shown (DP), 0..3."
    )

    def __init__(
        self,
        port_or_bus: str | os.PathLike[str] | Bus,
        unit: int = 1,
        baudrate: int = 9600,
        *,
        timeout: float | None = None,
        retries: int | None = None,
        check_identity: bool = True,
    ) -> None:
        """The controller at ``unit`` on a Bus, or on a port opened at ``baudrate`` 8N1.

        ``check_identity`` (default True): before its first exchange, the controller checks
        that the unit is a J2 controller (the reads ``benchbus scan`` names a unit by) and raises
        :class:`~benchbus.WrongDevice`, with nothing written, if it answers as another
        family; False skips the check, for a unit whose identity registers differ from
        its manual's.
        """
        check_baudrate(baudrate, (9600, 19200))
        line = self.LINE_DEFAULTS._replace(baudrate=baudrate)
        self._on_line(
            port_or_bus,
            unit,
            timeout=timeout,
            retries=retries,
            line=line,
            check_identity=check_identity,
        )

    def sample_units(self) -> dict[str, str]:
        """The unit of each field :meth:`sample` gives (``pv``, ``sv``: °C; ``mv``: %)."""
        units = self.units()
        return {f: units.get(f.upper(), "") for f in self.SAMPLE_FIELDS or ()}

    # ---- output and mode -----------------------------------------------------------------------

    @property
    def autotune(self) -> bool:
        """Whether autotuning runs (AT); set True to start it, False to stop it."""
        return bool(self.get("AT"))

    @autotune.setter
    def autotune(self, on: bool) -> None:
        if not isinstance(on, int):
            raise TypeError(f"autotune is True or False, got {type(on).__name__}")
        if on not in (0, 1):
            raise ValueError(f"autotune is True or False, got {on!r}")
        self.set("AT", int(on))

    @property
    def ramp_running(self) -> bool:
        """Whether a setpoint ramp runs (RAPNF reads 1)."""
        return bool(self.get("RAPNF"))
