"""BLD2 / BLD3H / ZBLD.C20 brushless DC drives as Python objects.

The register table, the command table, scaling, checks and every call to the drive live in
the compiled base class (``DriveCore``); this module adds what belongs to Python: enums,
snapshot dataclasses, named properties, the keepalive, the context manager and waiting for a
speed.
"""

from __future__ import annotations

import dataclasses
import enum
import logging
import os
import threading
import time
from typing import Any, NamedTuple

from benchbus._core import Bus, DriveCore, Profile
from benchbus._device import (
    MeasuredProperty,
    MotorDevice,
    PrintableIntEnum,
    RegisterProperty,
    as_enum,
    to_enum,
    to_float,
    to_int,
)
from benchbus._display import dataclass_table
from benchbus._keepalive import KeepAlive, check_interval
from benchbus._profile import profile_line

__all__ = [
    "C20ControlMode",
    "CommandSource",
    "ControlMode",
    "Drive",
    "DriveRegister",
    "DriveState",
    "DriveStatus",
    "DriveTelemetry",
    "Fault",
    "Model",
    "SpeedSource",
    "StopMode",
]

log = logging.getLogger("benchbus.drive")


class DriveState(PrintableIntEnum):
    """Drive status word 1 (0x2100)."""

    FORWARD = 1
    REVERSE = 2
    STOPPED = 3
    FAULT = 4
    OFF = 5
    BRAKING = 6


class ControlMode(PrintableIntEnum):
    """Control mode (0x2005) of a BLD2 / BLD3H drive.

    The drive also takes 5, which its manual lists as reserved (read back as the int 5).
    """

    TEST = 0
    HALL_OPEN_LOOP = 1
    HALL_CLOSED_LOOP = 2
    HALL_VECTOR = 3
    SENSORLESS_VECTOR = 4


class C20ControlMode(PrintableIntEnum):
    """Control mode (0x2005) of a ZBLD.C20 drive."""

    TEST = 0
    OPEN_LOOP = 1
    CLOSED_LOOP = 2
    DIP_SWITCH = 3


class CommandSource(PrintableIntEnum):
    """Where run commands come from (0x2006), and the control source of status word 2."""

    KEYPAD = 0
    TERMINAL = 1
    COMMUNICATION = 2
    #: C20 only (SW3); "reserved" on the BLD.
    DIP_SWITCH = 3


class SpeedSource(PrintableIntEnum):
    """Where the speed reference comes from (0x2007). The C20 has 0..6."""

    KEYPAD = 0
    AI1 = 1
    AI2 = 2
    MODBUS = 3
    MULTI_SPEED = 4
    DIP_SWITCH = 5
    SIMPLE_PLC = 6
    PULSE = 7
    CAN = 8


class StopMode(PrintableIntEnum):
    """What the stop command does (0x2012, BLD only)."""

    DECELERATE = 0
    COAST = 1


class Model(str, enum.Enum):
    """The drive model, from its identification code (0x2103)."""

    BLD2 = "BLD2"
    BLD3H = "BLD3H"
    C20 = "C20"

    def __str__(self) -> str:
        """The model name, ``BLD2``."""
        return self.value


@dataclasses.dataclass(frozen=True)
class Fault:
    """A drive fault: its code (0x2102) and name ("unknown fault 0xNN" when unnamed)."""

    #: The fault code, from 0x2102.
    code: int
    #: Its name ("unknown fault 0xNN" when unnamed).
    name: str

    def __str__(self) -> str:
        """``0x0A undervoltage``."""
        return f"0x{self.code:02X} {self.name}"


@dataclasses.dataclass(frozen=True)
class DriveStatus:
    """Status words 1 and 2 and the fault code (0x2100..0x2102), read at once."""

    #: Status word 1.
    state: DriveState
    #: The DC bus voltage is established (word 2 bit 0).
    bus_voltage_ready: bool
    #: The drive reports overload (word 2 bit 4; its polarity differs on the C20).
    overloaded: bool
    #: Who controls the drive (word 2 bits 5..6).
    control_source: CommandSource
    #: A keypad is connected (word 2 bit 7); None on the C20, which does not say.
    keypad_connected: bool | None
    #: The active fault, or None.
    fault: Fault | None

    def _repr_html_(self) -> str:
        """A field / value table, for notebooks."""
        return dataclass_table(self)


@dataclasses.dataclass(frozen=True)
class DriveTelemetry:
    """One snapshot of the measurement registers 0x3000.., in engineering units."""

    #: Set frequency, Hz (0x3000).
    set_frequency: float
    #: Output frequency, Hz (0x3001); rpm x pole pairs / 60.
    output_frequency: float
    #: Ramp reference frequency, Hz (0x3002).
    ramp_frequency: float
    #: Output voltage, V (0x3003).
    output_voltage: float
    #: Output current, A (0x3004).
    output_current: float
    #: Speed reference, rpm (0x3005).
    speed_reference: int
    #: Measured motor speed, rpm (0x3006).
    speed: int
    #: Output power, W (0x3007).
    output_power: int
    #: DC bus voltage, V (0x3008).
    bus_voltage: float
    #: Hall sensor state 0..7 (0x3009).
    hall_state: int
    #: Software version, e.g. 1.01 (0x300A).
    software_version: float
    #: Code of the most recent fault, 0 for none (0x300B).
    last_fault: int
    #: Inverter temperature, degC (0x300C; signed).
    temperature: float
    #: Input terminal bits (0x300D).
    input_terminals: int
    #: Output terminal bits (0x300E).
    output_terminals: int
    #: Analog input 1, V (0x300F).
    ai1_voltage: float
    #: Analog input 2, V (0x3010).
    ai2_voltage: float
    #: Analog input 3, V (0x3011).
    ai3_voltage: float
    #: The 32-bit hall count (0x3013 high, 0x3014 low); None on the C20, or on a BLD whose
    #: firmware lacks these registers.
    hall_count: int | None
    #: The unit of each field above, from the drive's register table (``"Hz"``, ``"A"``...;
    #: ``""`` for counts and bit fields).
    units: dict[str, str] = dataclasses.field(default_factory=dict, compare=False, repr=False)

    def _repr_html_(self) -> str:
        """A field / value / unit table, for notebooks."""
        return dataclass_table(self, self.units)


class DriveRegister(NamedTuple):
    """One row of a drive's register table (:meth:`Drive.registers`), as its family has it."""

    #: The name ``get`` / ``set`` take (``"speed_setpoint"``).
    name: str
    #: Register address.
    address: int
    #: Engineering value = raw word x scale (0.1 for tenths).
    scale: float
    #: Unit of the engineering value (``"rpm"``, ``"s"``; ``""`` for none).
    unit: str
    #: ``"R"`` read-only, ``"W/R"`` writable, ``"W/R*"`` writable while stopped only.
    access: str
    #: Lowest value a write may carry (0.0 for a read-only register).
    low: float
    #: Highest value a write may carry.
    high: float


#: The family (manual) each model follows, from the core's model table.
_MODEL_FAMILY = {Model(name): family for name, _id, family in DriveCore.models()}


def _control_mode(drive: Drive, raw: Any) -> ControlMode | C20ControlMode:
    """The control mode in the enum of the drive's family."""
    if drive.family == "C20":
        return as_enum(C20ControlMode, int(raw))
    return as_enum(ControlMode, int(raw))


class Drive(DriveCore, MotorDevice):
    """A BLD2 / BLD3H or ZBLD.C20 brushless DC drive (manuals 000 and 001).

    ::

        with bb.Drive("/dev/ttyUSB0", unit=1) as drive:   # 19200 8N1, the drives' default
            drive.speed_setpoint = 1500                    # rpm
            drive.accel_time = 2.5                         # seconds
            drive.forward()
            drive.wait_for_speed(1500, tolerance=20, timeout=10)
            print(drive.telemetry())
        # leaving the block stops the motor, also after an exception or Ctrl-C

    Given a path, the drive opens its own Bus at 19200 8N1 (timeout 0.25 s, which covers
    the longest reply delay F08.03 allows) and closes it on :meth:`close`; given a Bus, it
    shares it, with the Bus's timeout unless ``timeout=`` gives the drive its own.
    ``family="C20"`` for a ZBLD.C20 (it has no brake and reads overload with the opposite
    polarity). ``write_ack=False`` for a drive set to F08.06 = 1, which answers no
    write: writes are then sent once and not awaited.

    Exception replies raise :class:`benchbus.ModbusException` with the manual's meaning
    (0x08 "not changeable while running", 0x07 read-only...); values out of range raise
    ``ValueError`` before anything is sent. If the drive refuses a multi-register read, the
    reads fall back to one register per request, and the drive remembers it.

    The actions (:meth:`forward`, :meth:`stop`, :meth:`jog_forward`...) are the rows of the
    drive's command table (:meth:`commands`), each a method of the compiled base.
    """

    #: Line format and reply timeout when the device opens its own Bus: the family file's
    #: ``[line]`` (19200 8N1, 0.25 s).
    LINE_DEFAULTS = profile_line(Profile.family("drive"))
    #: The family whose identity the device checks before its first exchange.
    IDENTITY = "drive"

    @property
    def profile(self) -> Profile:
        """The drive's register table as a :class:`~benchbus.Profile`
        (``Profile.family("drive")``, the family's file; ``"drive-c20"``, its C20 model, on
        a C20): a row for each name :meth:`get` and :meth:`set` take, with its unit, access
        and range."""
        return Profile.family("drive-c20" if self.family == "C20" else "drive")

    speed_setpoint: RegisterProperty[Drive, int] = RegisterProperty(
        "speed_setpoint", to_int, "Speed setpoint, rpm 0..3000 (0x2001)."
    )
    pole_pairs: RegisterProperty[Drive, int] = RegisterProperty(
        "pole_pairs", to_int, "Motor pole pairs, 1..20 (0x2002; stopped only)."
    )
    accel_time: RegisterProperty[Drive, float] = RegisterProperty(
        "accel_time", to_float, "Acceleration time, s 0.1..600.0 in steps of 0.1 (0x2003)."
    )
    decel_time: RegisterProperty[Drive, float] = RegisterProperty(
        "decel_time", to_float, "Deceleration time, s 0.1..600.0 in steps of 0.1 (0x2004)."
    )
    control_mode: RegisterProperty[Drive, ControlMode | C20ControlMode] = RegisterProperty(
        "control_mode",
        _control_mode,
        "Control mode (0x2005; stopped only): ControlMode, or C20ControlMode on a C20.",
    )
    command_source: RegisterProperty[Drive, CommandSource] = RegisterProperty(
        "command_source", to_enum(CommandSource), "Where run commands come from (0x2006)."
    )
    speed_source: RegisterProperty[Drive, SpeedSource] = RegisterProperty(
        "speed_source", to_enum(SpeedSource), "Where the speed reference comes from (0x2007)."
    )
    virtual_inputs: RegisterProperty[Drive, int] = RegisterProperty(
        "virtual_inputs", to_int, "Virtual input terminal bits, 0..0x1FF (0x200A)."
    )
    virtual_outputs: RegisterProperty[Drive, int] = RegisterProperty(
        "virtual_outputs", to_int, "Virtual output terminal bits, 0..0x0F (0x200B)."
    )
    stop_mode: RegisterProperty[Drive, StopMode] = RegisterProperty(
        "stop_mode", to_enum(StopMode), "What stop() does, BLD only (0x2012): StopMode."
    )
    speed: MeasuredProperty[Drive, int] = MeasuredProperty(
        "speed", to_int, "Measured motor speed, rpm (0x3006); a magnitude in both directions."
    )
    state: MeasuredProperty[Drive, DriveState] = MeasuredProperty(
        "state", to_enum(DriveState), "Status word 1 (0x2100)."
    )

    def __init__(
        self,
        port_or_bus: str | os.PathLike[str] | Bus,
        unit: int = 1,
        *,
        family: str = "BLD",
        write_ack: bool = True,
        timeout: float | None = None,
        retries: int | None = None,
        check_identity: bool = True,
    ) -> None:
        """The drive at ``unit`` on a Bus, or on a port opened at 19200 8N1.

        ``timeout`` and ``retries`` are the drive's own: on a port it opens, they set the Bus
        (0.25 s and 2 by default); on a shared Bus, they replace the Bus's for this drive's
        requests only (None: the Bus's).

        ``check_identity`` (default True): before its first exchange, the drive checks
        that the unit is a BLD or C20 drive (the reads ``benchbus scan`` names a unit by) and raises
        :class:`~benchbus.WrongDevice`, with nothing written, if it answers as another
        family; False skips the check, for a unit whose identity registers differ from
        its manual's.
        """
        self._keepalive: KeepAlive | None = None
        self._keepalive_lock = threading.Lock()
        self._on_line(
            port_or_bus,
            unit,
            family,
            write_ack,
            timeout=timeout,
            retries=retries,
            check_identity=check_identity,
        )

    # ---- identity ------------------------------------------------------------------------

    @property
    def model(self) -> Model | int:
        """The model from its identification code (0x2103), or the raw code if unknown."""
        model = self._model()
        if isinstance(model, Model) and _MODEL_FAMILY[model] != self.family:
            log.warning(
                "unit %d identifies as %s but this Drive was made for family %s: status bit 4"
                " (overload) is read with that family's polarity",
                self.unit,
                model,
                self.family,
            )
        return model

    # ---- status and measurements -----------------------------------------------------------

    @property
    def fault(self) -> Fault | None:
        """The active fault (0x2102), or None."""
        return self.status().fault

    def wait_for_speed(
        self, rpm: float, tolerance: float = 10.0, timeout: float = 10.0, interval: float = 0.05
    ) -> int:
        """Poll :attr:`speed` until it is within ``tolerance`` rpm of ``rpm``; return it.

        Raises ``TimeoutError`` (not a bus error: the drive answers, the motor is not there)
        when ``timeout`` seconds pass first, and :class:`benchbus.BenchbusError` if the drive
        stops answering. The speed register holds a magnitude: ``rpm`` is >= 0 in both
        directions.
        """
        for name, value in (
            ("rpm", rpm),
            ("tolerance", tolerance),
            ("timeout", timeout),
            ("interval", interval),
        ):
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError(f"{name} must be a number, got {type(value).__name__}")
        top = next(row.high for row in self.registers() if row.name == "speed_setpoint")
        for name, value in (("rpm", rpm), ("tolerance", tolerance)):
            if not 0 <= value <= top:
                raise ValueError(f"{name} must be 0 to {top:g} rpm, got {value}")
        if not 0 < timeout <= 3600:
            raise ValueError(f"timeout must be 0 < s <= 3600, got {timeout}")
        if not 0 < interval <= 10:
            raise ValueError(f"interval must be 0 < s <= 10, got {interval}")
        deadline = time.monotonic() + timeout
        while True:
            speed = self.speed
            if abs(speed - rpm) <= tolerance:
                return speed
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(
                    f"unit {self.unit}: speed {speed} rpm, not within {tolerance} rpm of "
                    f"{rpm} rpm after {timeout} s"
                )
            time.sleep(min(interval, left))

    # ---- configuration ---------------------------------------------------------------------

    @property
    def station_address(self) -> int:
        """The station address the drive has stored (0x2008)."""
        return int(self.get("station_address"))

    def set_station_address(self, address: int) -> None:
        """Store a new station address (0x2008; stopped only; BLD 1..127, C20 1..247).

        The drive answers at the new address from then on: open a new Drive with it.
        """
        self.set("station_address", address)

    def restore_defaults(self) -> None:
        """Restore every function-code parameter to its factory value (0x200F; stopped only)."""
        self.set("restore_defaults", 1)

    def clear_hall_count(self) -> None:
        """Set the 32-bit hall count to 0 (0x2011, BLD only)."""
        self.set("hall_count_clear", 1)

    @property
    def comm_loss_timeout(self) -> float:
        """The drive's communication-loss timeout F08.04, seconds; 0.0 = off (the default).

        With it set, a drive that hears no request for that long trips (state FAULT) and
        stops its motor: pair it with :meth:`keepalive` so that only a dead host (or a dead
        line) lets it run out. Set 0 or 0.1..60.0 s, in steps of 0.1 s (rounded to the
        nearest); anything else raises TypeError / ValueError before anything is sent. F08.04
        is W/R*: writing it while the motor turns is refused by the drive (exception 0x08).
        BLD family only: the ZBLD.C20 manual lists no F08.04, so a C20 raises ValueError.
        """
        return self.read_setting("comm_loss_timeout")

    @comm_loss_timeout.setter
    def comm_loss_timeout(self, seconds: float) -> None:
        self.write_setting("comm_loss_timeout", seconds)

    def keepalive(self, interval: float = 0.5) -> KeepAlive:
        """Read the drive state every ``interval`` seconds (0.01..60) from a daemon thread.

        ::

            drive.comm_loss_timeout = 1.0      # F08.04: trip after 1 s without a request
            drive.keepalive(0.25)              # ... which never happens while we live
            drive.forward()

        The reads go on absolute deadlines, so the drive's F08.04 timer never runs out while
        the host lives; if the process dies, the reads stop and the drive trips and stops
        the motor. Choose ``interval`` well under :attr:`comm_loss_timeout` (a third or less
        leaves room for a retried read). A failed read is logged at WARNING on
        ``benchbus.device`` and counted in the returned :class:`benchbus.KeepAlive`'s
        ``errors``; the thread goes on. The reads share the Bus with the caller's requests
        (the Bus serialises them).

        One keepalive per drive: while one runs, a second call raises RuntimeError (stop the
        first to change the interval). :meth:`close` (and leaving the drive's ``with``
        block) stops it.
        """
        period = check_interval(interval)
        with self._keepalive_lock:
            if self._keepalive is not None and self._keepalive.running:
                raise RuntimeError(
                    f"unit {self.unit}: a keepalive is already running (every"
                    f" {self._keepalive.interval} s); stop() it first"
                )
            self._keepalive = KeepAlive(
                lambda: self.get("state"), period, f"benchbus keepalive unit {self.unit}"
            )
            return self._keepalive

    # ---- lifecycle -------------------------------------------------------------------------

    def close(self) -> None:
        """Stop the :meth:`keepalive` thread, if any, then close the Bus if the drive
        opened it (a shared Bus stays open)."""
        with self._keepalive_lock:
            keepalive, self._keepalive = self._keepalive, None
        if keepalive is not None:
            keepalive.stop()
        super().close()

    def __repr__(self) -> str:
        """Unit, family and bus."""
        return f"<Drive unit={self.unit} family={self.family} on {self.bus!r}>"
