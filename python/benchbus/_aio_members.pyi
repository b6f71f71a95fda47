"""The families' async devices (benchbus.aio) and their members, for type checkers.

Generated from the sync classes by ``python -m benchbus._aio_stubgen``: do not edit.
"""

from collections.abc import Callable, Coroutine, Iterable, Mapping
from typing import Any, ClassVar, Literal

from benchbus._core import Profile, _Layout, _Order, _Read
from benchbus._device import BusDevice, LineDefaults, PrintableIntEnum
from benchbus._drive import (
    C20ControlMode,
    CommandSource,
    ControlMode,
    DriveRegister,
    DriveState,
    DriveStatus,
    DriveTelemetry,
    Fault,
    Model,
    SpeedSource,
    StopMode,
)
from benchbus._drive import Drive as _SyncDrive
from benchbus._instrument import Identification
from benchbus._instrument import Instrument as _SyncInstrument
from benchbus._j2 import InputType, J2Mode, J2Parameter, J2Status, Limits, Pid
from benchbus._j2 import J2Controller as _SyncJ2Controller
from benchbus._keepalive import KeepAlive
from benchbus._pbl import (
    DecelMode,
    Direction,
    DirectionSetting,
    PblControlMode,
    PblParameter,
    PblStatus,
    PblTelemetry,
    StartStopSource,
)
from benchbus._pbl import PblDrive as _SyncPblDrive
from benchbus._record import Recording
from benchbus._results import CommEventCounter, CommEventLog
from benchbus.aio import AsyncDevice

__all__: list[str] = ["Drive", "Instrument", "J2Controller", "PblDrive"]
SYNC_CLASSES: tuple[type[BusDevice], ...]

class BusDeviceMembers:
    """The members every async device serves from the sync classes' shared bases
    (:class:`benchbus._device.BusDevice` and the compiled ``_Station``), for type checkers:
    each family's members class extends it."""

    IDENTITY: ClassVar[str | None]
    "The family whose identity the device checks before its first exchange (a key of ``benchbus._families``); None: no check (a device of any kind)."
    SAMPLE_FIELDS: tuple[str, ...] | None
    "The names :meth:`sample` gives (None: not known in advance), so that a bad ``record(columns=...)`` is refused before anything is sent."

    async def close(self) -> None:
        """Close the Bus if the device opened it (a shared Bus stays open)."""

    async def record(
        self,
        duration: float,
        interval: float,
        *,
        columns: Iterable[str] | None = None,
        clock: Callable[[], float] = ...,
        sleep: Callable[[float], None] = ...,
    ) -> Recording:
        """Take :meth:`sample` every ``interval`` seconds for ``duration`` seconds.

        ::

            rec = drive.record(5.0, 0.05)     # 100 samples, 50 ms apart
            rec.to_pandas().describe()        # or rec.to_csv(path), rec.plot(["speed"])

        Samples are taken on absolute deadlines ``n * interval`` after the start, the
        last one before ``duration``: time spent on the wire never adds up to drift. A
        sample that overruns its period skips the deadlines already past (the recording
        counts them in ``missed``) rather than taking late ones in a burst; when samples
        take longer than ``interval`` itself, a UserWarning at the end says so, with the
        period achieved and the count missed. Each sample
        keeps the time it was actually taken, read from ``clock`` just before its
        request; ``clock`` and ``sleep`` are injectable for tests.

        ``columns`` keeps only those measurements, in that order (a name the device does
        not give raises ValueError at the first sample); by default every one. A
        ``duration`` or ``interval`` that is not a positive, finite number raises
        TypeError or ValueError before anything is sent; an ``interval`` longer than
        ``duration`` gives one sample.

        A bus error ends the recording and is raised; the samples taken before it are in
        the exception's ``recording`` attribute. Ctrl-C ends it and returns the samples
        taken so far, with the recording's ``interrupted`` set."""

    async def sample(self) -> dict[str, float]:
        """One snapshot of the device's main measurements, ``{name: value}`` as numbers, in
        as few requests as the device allows: what :meth:`record`, ``benchbus monitor`` and
        the demo sample. Devices without fixed measurements raise ``TypeError``."""

    def sample_units(self) -> dict[str, str]:
        """The unit of each field :meth:`sample` gives, from the family's table (``""`` for
        none): ``{"speed": "rpm", ...}``, what ``benchbus monitor`` and recordings show."""

    @property
    def unit(self) -> int:
        """The device's unit address."""

    def units(self) -> dict[str, str]:
        """The unit of each register or parameter by name, from the family's table (``""``
        for none; empty for a device without a fixed table)."""

    async def verify_identity(self) -> None:
        """Checks now, if not done yet, that the unit is of the device's family (what the
        device's first exchange does): ``WrongDevice`` if it answers as another family, a
        timeout if it does not answer (it is checked again on the next call). Nothing to
        check for a device made with ``check_identity=False`` or without an identity (an
        ``Instrument``, a profile's ``Device``)."""

class DeviceMembers(BusDeviceMembers):
    """The members of :class:`benchbus.aio.Device`, for type checkers."""

    LINE_DEFAULTS: LineDefaults
    "Line format and reply timeout when the profile says nothing of them."
    SAMPLE_FIELDS: tuple[str, ...] | None
    "The readable registers :meth:`sample` gives (every readable one but strings)."
    enums: Mapping[str, type[PrintableIntEnum]]
    "Each enum register's enum class, by register name."

    async def get(self, name: str) -> Any:
        """:meth:`read`, under the name every benchbus device reads a register by."""

    async def get_many(self, names: Iterable[str]) -> dict[str, Any]:
        """:meth:`read_many`, under the name every benchbus device reads registers by."""

    @property
    def profile(self) -> Profile:
        """The profile the device follows."""

    async def read(self, name: str) -> Any:
        """The register ``name``, in engineering units (an enum member, a bool, a str)."""

    async def read_many(self, names: Iterable[str]) -> dict[str, Any]:
        """The registers ``names``, ``{name: value}`` in that order, read in the fewest
        requests the profile allows (:meth:`Profile.plan` shows which)."""

    async def sample(self) -> dict[str, Any]:
        """Every readable register but strings, ``{name: value}`` in the profile's order, in
        the fewest requests the profile allows: what :meth:`record` and ``benchbus
        monitor`` take."""

    async def set(self, name: str, value: Any) -> None:
        """:meth:`write`, under the name every benchbus device writes a register by."""

    async def set_many(self, values: Mapping[str, Any] | Iterable[tuple[str, Any]]) -> None:
        """Write ``values`` (``{name: value}`` or ``(name, value)`` pairs) in order, each as
        :meth:`write` does; every value is checked before the first is sent (the decimal
        places the values need read first)."""

    def units(self) -> dict[str, str]:
        """The unit of every register by name ("" for none)."""

    async def write(self, name: str, value: Any) -> None:
        """Write ``value`` (engineering units; an enum by member, name or number) to the
        register ``name``, checked before anything is sent (for a register with
        ``decimals``: against the widest range its places allow, then at its places, read
        first, before it is written)."""

class DriveMembers(BusDeviceMembers):
    """The members of :class:`benchbus.aio.Drive`, for type checkers."""

    IDENTITY: ClassVar[str | None]
    "The family whose identity the device checks before its first exchange."
    LINE_DEFAULTS: LineDefaults
    "Line format and reply timeout when the device opens its own Bus: the family file's ``[line]`` (19200 8N1, 0.25 s)."
    SAMPLE_FIELDS: tuple[str, ...] | None
    "The names :meth:`sample` gives: the fields of :meth:`telemetry`."

    @property
    def accel_time(self) -> Coroutine[Any, Any, float]:
        """Acceleration time, s 0.1..600.0 in steps of 0.1 (0x2003)."""

    @property
    def baud_rate(self) -> Coroutine[Any, Any, int]:
        """The line speed the drive has stored (0x2009), in bits per second (the raw code if
        the manuals do not list it)."""

    @property
    def block_reads(self) -> bool | None:
        """Whether the drive answers multi-register reads; None until one was tried."""

    async def brake(self) -> None:
        """Brake stop, BLD only; ValueError on a C20 (command 9)."""

    async def clear_hall_count(self) -> None:
        """Set the 32-bit hall count to 0 (0x2011, BLD only)."""

    async def close(self) -> None:
        """Stop the :meth:`keepalive` thread, if any, then close the Bus if the drive
        opened it (a shared Bus stays open)."""

    async def coast(self) -> None:
        """Free stop (emergency stop): cut the output and let the motor coast (command 6)."""

    @property
    def comm_loss_timeout(self) -> Coroutine[Any, Any, float]:
        """The drive's communication-loss timeout F08.04, seconds; 0.0 = off (the default).

        With it set, a drive that hears no request for that long trips (state FAULT) and
        stops its motor: pair it with :meth:`keepalive` so that only a dead host (or a dead
        line) lets it run out. Set 0 or 0.1..60.0 s, in steps of 0.1 s (rounded to the
        nearest); anything else raises TypeError / ValueError before anything is sent. F08.04
        is W/R*: writing it while the motor turns is refused by the drive (exception 0x08).
        BLD family only: the ZBLD.C20 manual lists no F08.04, so a C20 raises ValueError."""

    @property
    def command_source(self) -> Coroutine[Any, Any, CommandSource]:
        """Where run commands come from (0x2006)."""

    @staticmethod
    def commands() -> list[tuple[str, int]]:
        """The command table: ``(name, code)`` of every value the command register 0x2000
        takes, in code order, the brake stop (BLD only) included; each is a method."""

    @property
    def control_mode(self) -> Coroutine[Any, Any, ControlMode | C20ControlMode]:
        """Control mode (0x2005; stopped only): ControlMode, or C20ControlMode on a C20."""

    @property
    def decel_time(self) -> Coroutine[Any, Any, float]:
        """Deceleration time, s 0.1..600.0 in steps of 0.1 (0x2004)."""

    @property
    def family(self) -> str:
        """ "BLD" (BLD2, BLD3H) or "C20"."""

    @property
    def fault(self) -> Coroutine[Any, Any, Fault | None]:
        """The active fault (0x2102), or None."""

    async def forward(self) -> None:
        """Run forward at the speed setpoint (command 1)."""

    async def get(self, name: str) -> int | float:
        """Reads the register called ``name`` (see the table), in engineering units: an
        int, or a float for a scaled register; a member of its enum where the
        device's class names its values."""

    async def get_many(self, names: Iterable[str]) -> dict[str, int | float]:
        """Reads the registers called ``names`` (a list), ``{name: value}`` in that order,
        each as :meth:`get` gives it,
        in as few requests as the table's limits allow (neighbours share one)."""

    async def jog_forward(self) -> None:
        """Jog forward (command 3)."""

    async def jog_reverse(self) -> None:
        """Jog in reverse (command 4)."""

    async def jog_stop(self) -> None:
        """End a jog (command 8)."""

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
        block) stops it."""

    @property
    def model(self) -> Coroutine[Any, Any, Model | int]:
        """The model from its identification code (0x2103), or the raw code if unknown."""

    @staticmethod
    def model_from_id(family: str, id: int) -> str | None:
        """The model an identification code (0x2103) names on a drive of ``family``: "BLD2",
        "BLD3H" or "C20", or None for a code the manuals do not list."""

    @staticmethod
    def models() -> list[tuple[str, int, str]]:
        """The model table: ``(name, identification code, family)`` of each model the manuals
        name."""

    @property
    def pole_pairs(self) -> Coroutine[Any, Any, int]:
        """Motor pole pairs, 1..20 (0x2002; stopped only)."""

    @property
    def profile(self) -> Profile:
        """The drive's register table as a :class:`~benchbus.Profile`
        (``Profile.family("drive")``, the family's file; ``"drive-c20"``, its C20 model, on
        a C20): a row for each name :meth:`get` and :meth:`set` take, with its unit, access
        and range."""

    async def read_parameter(self, code: str) -> int:
        """The raw value of function-code parameter ``code``, e.g. ``"F00.10"``.

        Fgg.nn lives at ``gg << 8 | nn``; a parameter the drive lacks raises
        :class:`benchbus.ModbusException` (code 2)."""

    async def read_setting(self, name: str) -> float:
        """Reads the setting called ``name`` (a function-code parameter in engineering units,
        "comm_loss_timeout" for F08.04)."""

    def registers(self) -> list[DriveRegister]:
        """The register table of this drive's family: a ``DriveRegister`` ``(name, address,
        scale, unit, access, low, high)`` for each register; access is "R", "W/R" or "W/R*"."""

    async def reset_fault(self) -> None:
        """Reset a fault (command 7)."""

    async def restore_defaults(self) -> None:
        """Restore every function-code parameter to its factory value (0x200F; stopped only)."""

    @property
    def retries(self) -> int:
        """Retries of the drive's requests (its own, or the Bus's)."""

    async def reverse(self) -> None:
        """Run in reverse at the speed setpoint (command 2)."""

    async def sample(self) -> dict[str, float]:
        """The numeric fields of :meth:`telemetry` as floats (one request where the drive
        allows); ``hall_count`` only where the drive has it."""

    async def set(self, name: str, value: float) -> None:
        """Writes ``value`` (engineering units) to the register called ``name``, checked
        against its range, steps, access and the family's rules before anything is sent."""

    async def set_baud_rate(self, bps: int) -> None:
        """Store a new line speed (0x2009; stopped only): 1200..115200 (C20 up to 57600).

        The drive talks at the new speed from then on: open a new Bus at it."""

    async def set_many(self, values: Mapping[str, float] | Iterable[tuple[str, float]]) -> None:
        """Writes ``values`` (``{name: value}`` or ``(name, value)`` pairs) in order, each
        as :meth:`set` does. Every value is checked against its register (range,
        steps, access) before the first is sent; the family's rules are checked write
        by write, so a refusal there leaves the earlier writes done."""

    async def set_station_address(self, address: int) -> None:
        """Store a new station address (0x2008; stopped only; BLD 1..127, C20 1..247).

        The drive answers at the new address from then on: open a new Drive with it."""

    @property
    def speed(self) -> Coroutine[Any, Any, int]:
        """Measured motor speed, rpm (0x3006); a magnitude in both directions."""

    @property
    def speed_setpoint(self) -> Coroutine[Any, Any, int]:
        """Speed setpoint, rpm 0..3000 (0x2001)."""

    @property
    def speed_source(self) -> Coroutine[Any, Any, SpeedSource]:
        """Where the speed reference comes from (0x2007)."""

    @property
    def state(self) -> Coroutine[Any, Any, DriveState]:
        """Status word 1 (0x2100)."""

    @property
    def station_address(self) -> Coroutine[Any, Any, int]:
        """The station address the drive has stored (0x2008)."""

    async def status(self) -> DriveStatus:
        """Status words 1 and 2 and the fault code, read in one request where allowed."""

    async def stop(self) -> None:
        """Stop: decelerate, or as :attr:`stop_mode` says (command 5)."""

    @property
    def stop_mode(self) -> Coroutine[Any, Any, StopMode]:
        """What stop() does, BLD only (0x2012): StopMode."""

    async def telemetry(self) -> DriveTelemetry:
        """All measurement registers in one snapshot (one request where the drive allows)."""

    @property
    def timeout(self) -> float:
        """Reply timeout of the drive's requests, in seconds (its own, or the Bus's)."""

    def units(self) -> dict[str, str]:
        """The unit of each register by name, from :meth:`registers` (``""`` for none)."""

    @property
    def virtual_inputs(self) -> Coroutine[Any, Any, int]:
        """Virtual input terminal bits, 0..0x1FF (0x200A)."""

    @property
    def virtual_outputs(self) -> Coroutine[Any, Any, int]:
        """Virtual output terminal bits, 0..0x0F (0x200B)."""

    async def wait_for_speed(
        self, rpm: float, tolerance: float = 10.0, timeout: float = 10.0, interval: float = 0.05
    ) -> int:
        """Poll :attr:`speed` until it is within ``tolerance`` rpm of ``rpm``; return it.

        Raises ``TimeoutError`` (not a bus error: the drive answers, the motor is not there)
        when ``timeout`` seconds pass first, and :class:`benchbus.BenchbusError` if the drive
        stops answering. The speed register holds a magnitude: ``rpm`` is >= 0 in both
        directions."""

    @property
    def write_ack(self) -> bool:
        """Whether writes are answered (False for a drive set to F08.06 = 1)."""

    async def write_parameter(self, code: str, value: int) -> None:
        """Write the raw ``value`` (0..0xFFFF) to function-code parameter ``code``.

        Sets the write enable 0x200E to 1 first when it is not, and puts it back afterwards,
        also when the write fails; a refusal raises :class:`benchbus.ModbusException` naming
        the parameter (0x03 out of range, 0x08 not while running...)."""

    async def write_setting(self, name: str, value: float) -> None:
        """Writes ``value`` (engineering units) to the setting called ``name``, enabling 0x200E
        around it; the value and the family are checked before anything is sent."""

class InstrumentMembers(BusDeviceMembers):
    """The members of :class:`benchbus.aio.Instrument`, for type checkers."""

    LINE_DEFAULTS: LineDefaults
    "Line format and reply timeout when the device opens its own Bus."

    async def get_comm_event_counter(self) -> CommEventCounter:
        """The status word (0xFFFF busy, 0x0000 not) and event counter (function 0x0B), as a
        ``CommEventCounter(status, event_count)``."""

    async def get_comm_event_log(self) -> CommEventLog:
        """The status word, event and message counters and events (function 0x0C), as a
        ``CommEventLog(status, event_count, message_count, events)``."""

    async def identify(
        self, level: Literal["basic", "regular", "extended"] = "basic"
    ) -> Identification:
        """Read Device Identification (0x2B / MEI 0x0E) from object 0, following "more
        follows" until the device has sent them all.

        A device without the function raises :class:`~benchbus.ModbusException` with code 1
        (its ``meaning`` says so)."""

    @property
    def max_read(self) -> int:
        """Most registers one read asks for."""

    @property
    def max_read_bits(self) -> int:
        """Most coils or discrete inputs one read asks for."""

    @property
    def max_write(self) -> int:
        """Most registers one write carries."""

    @property
    def max_write_bits(self) -> int:
        """Most coils one write carries."""

    @property
    def min_write_interval(self) -> float:
        """Least time between two writes, seconds."""

    async def read_coil(self, address: int) -> bool:
        """One coil (0x01)."""

    async def read_coils(self, address: int, count: int) -> list[bool]:
        """``count`` coils from ``address`` (0x01), in requests of at most ``max_read_bits``."""

    async def read_discrete_input(self, address: int) -> bool:
        """One discrete input (0x02)."""

    async def read_discrete_inputs(self, address: int, count: int) -> list[bool]:
        """``count`` discrete inputs from ``address`` (0x02), in requests of at most
        ``max_read_bits``."""

    async def read_fifo_queue(self, address: int) -> list[int]:
        """The values queued in the FIFO whose count register is at ``address`` (function
        0x18), oldest first: at most 31."""

    async def read_file_record(self, groups: Iterable[tuple[int, int, int]]) -> list[list[int]]:
        """File records (function 0x14): for each group ``(file, record, length)``,
        ``length`` registers from record ``record`` of file ``file``; one list per group."""

    async def read_float(
        self,
        address: int,
        word_order: _Order | None = None,
        *,
        byte_order: _Order | None = None,
        bits: Literal[32, 64] = 32,
        function: _Read = 3,
        order: _Layout = "ABCD",
    ) -> float:
        """An IEEE 754 float of ``bits`` (32: single, 64: double) over 2 or 4 registers, laid
        out as :meth:`read_long` reads an integer (``order``, or its aliases ``word_order`` /
        ``byte_order``)."""

    async def read_long(
        self,
        address: int,
        signed: bool = False,
        word_order: _Order | None = None,
        *,
        byte_order: _Order | None = None,
        bits: Literal[32, 64] = 32,
        function: _Read = 3,
        order: _Layout = "ABCD",
    ) -> int:
        """An integer of ``bits`` (32 or 64) over the 2 or 4 registers from ``address``,
        signed or not, laid out by ``order``, as profiles and :func:`benchbus.from_registers`
        name it: ``"ABCD"`` (most significant register and byte first), ``"CDAB"`` (words
        swapped), ``"BADC"`` (bytes swapped in each register) or ``"DCBA"``.

        For 0x01020304: ABCD ``[0x0102, 0x0304]``, CDAB ``[0x0304, 0x0102]``, BADC
        ``[0x0201, 0x0403]``, DCBA ``[0x0403, 0x0201]``; a 64-bit value lies the same way
        over four registers.

        ``word_order`` (which register first) and ``byte_order`` (which byte of each
        register first), each ``"big"`` or ``"little"``, are accepted aliases:
        ``word_order="little"`` is ``order="CDAB"``, ``byte_order="little"`` ``"BADC"``.
        Giving ``order`` with either is a TypeError."""

    async def read_register(
        self, address: int, decimals: int = 0, signed: bool = False, *, function: _Read = 3
    ) -> int | float:
        """One register as a value: ``raw / 10**decimals`` (an int when ``decimals`` is 0),
        two's complement if ``signed``; ``function=4`` reads an input register instead of a
        holding register (3)."""

    async def read_registers(self, address: int, count: int, *, function: _Read = 3) -> list[int]:
        """``count`` raw registers from ``address``, in requests of at most ``max_read``
        (``function=4``: input registers)."""

    async def read_string(self, address: int, count: int, *, function: _Read = 3) -> str:
        """``count`` registers as text, two Latin-1 characters a register (high byte first),
        without the NULs that pad it (``function=4``: input registers)."""

    async def write_coil(self, address: int, value: bool) -> None:
        """Set one coil on (True) or off (False) with 0x05; the reply must echo it."""

    async def write_coils(self, address: int, values: Iterable[bool]) -> None:
        """Set the coils from ``address`` to ``values`` (True or False each) with 0x0F, in
        requests of at most ``max_write_bits``."""

    async def write_file_record(self, groups: Iterable[tuple[int, int, Iterable[int]]]) -> None:
        """Write file records (function 0x15): for each group ``(file, record, values)``,
        ``values`` from record ``record`` of file ``file``; the reply must echo the request."""

    async def write_float(
        self,
        address: int,
        value: float,
        word_order: _Order | None = None,
        *,
        byte_order: _Order | None = None,
        bits: Literal[32, 64] = 32,
        order: _Layout = "ABCD",
    ) -> None:
        """Write an IEEE 754 float of ``bits`` (32 or 64) over 2 or 4 registers (NaN,
        infinities and, in 32 bits, numbers beyond a single's range are refused), laid out
        as :meth:`read_long` reads an integer (``order``, or its aliases ``word_order`` /
        ``byte_order``)."""

    async def write_long(
        self,
        address: int,
        value: int,
        signed: bool = False,
        word_order: _Order | None = None,
        *,
        byte_order: _Order | None = None,
        bits: Literal[32, 64] = 32,
        order: _Layout = "ABCD",
    ) -> None:
        """Write an integer of ``bits`` (32 or 64) over 2 or 4 registers, laid out as
        :meth:`read_long` reads it (``order``, or its aliases ``word_order`` /
        ``byte_order``), in one request (more if ``max_write`` is smaller)."""

    async def write_register(
        self,
        address: int,
        value: float,
        decimals: int = 0,
        signed: bool = False,
        *,
        function: int = 6,
    ) -> None:
        """Write ``value * 10**decimals`` to one register with 0x06 (or 0x10 if ``function``
        is 16). A value that does not fit or has more decimals raises ValueError before
        anything is sent."""

    async def write_registers(self, address: int, values: Iterable[int]) -> None:
        """Write raw ``values`` from ``address`` with 0x10, in requests of at most
        ``max_write``."""

    async def write_string(self, address: int, text: str, count: int) -> None:
        """Write ``text`` into ``count`` registers, two characters a register, padded with
        NULs (longer text or characters outside Latin-1 raise ValueError)."""

class J2ControllerMembers(BusDeviceMembers):
    """The members of :class:`benchbus.aio.J2Controller`, for type checkers."""

    IDENTITY: ClassVar[str | None]
    "The family whose identity the device checks before its first exchange."
    LINE_DEFAULTS: LineDefaults
    "Line format and reply timeout when the device opens its own Bus: the family file's ``[line]`` (9600 8N1, 0.3 s)."
    SAMPLE_FIELDS: tuple[str, ...] | None
    "The names :meth:`sample` gives: ``pv``, ``sv``, ``mv``."

    @property
    def alarm1(self) -> Coroutine[Any, Any, float]:
        """Alarm 1 value (AL1), -1999..3276.7."""

    @property
    def alarm2(self) -> Coroutine[Any, Any, float]:
        """Alarm 2 value (AL2), -1999..3276.7."""

    @property
    def autotune(self) -> Coroutine[Any, Any, bool]:
        """Whether autotuning runs (AT); set True to start it, False to stop it."""

    @property
    def decimal_point(self) -> Coroutine[Any, Any, int]:
        """Decimal places shown (DP), 0..3."""

    async def get(self, name: str) -> int | float:
        """Reads the register called ``name`` (see the table), in engineering units: an
        int, or a float for a scaled register; a member of its enum where the
        device's class names its values."""

    async def get_many(self, names: Iterable[str]) -> dict[str, int | float]:
        """Reads the registers called ``names`` (a list), ``{name: value}`` in that order,
        each as :meth:`get` gives it,
        in as few requests as the table's limits allow (neighbours share one)."""

    @property
    def input_type(self) -> Coroutine[Any, Any, InputType]:
        """Input type (INP)."""

    @property
    def limits(self) -> Coroutine[Any, Any, Limits]:
        """The setpoint limits (LSP, USP), read in one request. Set them with a ``(low, high)``
        pair: they are written in the order that keeps LSP <= USP."""

    @property
    def mode(self) -> Coroutine[Any, Any, J2Mode]:
        """Automatic or manual control (AM)."""

    @property
    def mv(self) -> Coroutine[Any, Any, float]:
        """The output (MV), percent. Setting it needs manual mode: in automatic mode it raises
        :class:`~benchbus.StateError` (see :meth:`set_output`)."""

    async def parameters(self) -> dict[str, int | float]:
        """Every parameter, `{name: value}`, in six requests of at most 16 registers."""

    @property
    def pid(self) -> Coroutine[Any, Any, Pid]:
        """The first PID set (P, I, D), read in one request; set it with a 3-tuple."""

    @property
    def pid2(self) -> Coroutine[Any, Any, Pid]:
        """The second PID set (P1, I1, D1), read in one request; set it with a 3-tuple."""

    @property
    def profile(self) -> Profile:
        """The parameter table as a :class:`~benchbus.Profile` (``Profile.family("j2")``):
        a row for each name :meth:`get` and :meth:`set` take (the manual's, "SV"), with its
        unit, access and range."""

    @property
    def pv(self) -> Coroutine[Any, Any, float]:
        """Process value (PV), read-only."""

    @property
    def pv_offset(self) -> Coroutine[Any, Any, float]:
        """Process value offset (PVOS), -50..50."""

    @property
    def ramp_running(self) -> Coroutine[Any, Any, bool]:
        """Whether a setpoint ramp runs (RAPNF reads 1)."""

    async def read(self, name: str) -> int | float:
        """One parameter by its manual name ("SV", "AL1", "INP"; any case): a float for the
        signed table, an int for the unsigned one (a member of its enum, as :meth:`get`)."""

    async def read_many(self, names: Iterable[str]) -> list[int | float]:
        """Several parameters by name, in as few requests as the 16-register limit allows (each
        as :meth:`read` gives it)."""

    async def sample(self) -> dict[str, float]:
        """PV, SV and MV (``{"pv": .., "sv": .., "mv": ..}``), in one request."""

    def sample_units(self) -> dict[str, str]:
        """The unit of each field :meth:`sample` gives (``pv``, ``sv``: °C; ``mv``: %)."""

    async def set(self, name: str, value: float) -> None:
        """Writes ``value`` (engineering units) to the register called ``name``, checked
        against its range, steps, access and the family's rules before anything is sent."""

    async def set_many(self, values: Mapping[str, float] | Iterable[tuple[str, float]]) -> None:
        """Writes ``values`` (``{name: value}`` or ``(name, value)`` pairs) in order, each
        as :meth:`set` does. Every value is checked against its register (range,
        steps, access) before the first is sent; the family's rules are checked write
        by write, so a refusal there leaves the earlier writes done."""

    async def set_output(self, percent: float, switch_to_manual: bool = False) -> None:
        """Set the output MV to ``percent`` (0..100).

        The manual allows MV only in manual mode: in automatic mode this raises
        :class:`~benchbus.StateError`, unless ``switch_to_manual`` (then AM is written 0
        first, and the controller stays in manual mode)."""

    async def start_ramp(self) -> None:
        """Start the setpoint ramp (RAPNF = 1)."""

    async def status(self) -> J2Status:
        """PV, SV, MV, mode, autotune, ramp and alarm values, in two requests."""

    async def stop_ramp(self) -> None:
        """End the setpoint ramp (RAPNF = 0)."""

    @property
    def sv(self) -> Coroutine[Any, Any, float]:
        """Setpoint (SV), within LSP..USP."""

    @staticmethod
    def table() -> list[J2Parameter]:
        """The parameter table: a :class:`~benchbus.J2Parameter` (name, address, signed,
        writable, low, high, within_limits) for each parameter."""

    @staticmethod
    def units() -> dict[str, str]:
        """The unit of each parameter by its manual name (``"PV"``), from the family's table
        (``""`` for none; a linear input, INP = LN, reads in its own scale, not °C)."""

    async def write(self, name: str, value: float, *, function: int = 6) -> None:
        """Write one parameter by name, with the manual's rules (see the class).

        ``function`` is 0x06 (write single register) or 0x10 (write multiple registers,
        here one); the manual shows both for SV."""

    async def write_many(self, values: Mapping[str, float] | Iterable[tuple[str, float]]) -> None:
        """Write several parameters in order, each as :meth:`write` does.

        ``values`` is ``{name: value}`` or ``(name, value)`` pairs. Every value is checked
        against its fixed range before the first is sent; the checks that need the
        controller (SV within its limits, MV in manual mode) are made write by write, so a
        refusal there leaves the earlier writes done."""

class PblDriveMembers(BusDeviceMembers):
    """The members of :class:`benchbus.aio.PblDrive`, for type checkers."""

    IDENTITY: ClassVar[str | None]
    "The family whose identity the device checks before its first exchange."
    LINE_DEFAULTS: LineDefaults
    "Line format and reply timeout when the device opens its own Bus: the family file's ``[line]`` (115200 8E1, 0.1 s)."
    SAMPLE_FIELDS: tuple[str, ...] | None
    "The names :meth:`sample` gives: parameters 50..54."

    @property
    def acceleration(self) -> Coroutine[Any, Any, int]:
        """Acceleration, rpm/s (209)."""

    @property
    def alarm_word(self) -> Coroutine[Any, Any, int]:
        """The 32-bit alarm word (parameter 5 high, 4 low)."""

    @property
    def alarms(self) -> Coroutine[Any, Any, frozenset[str]]:
        """The active alarm bits by name ("alarm bit N": the manual names none)."""

    @property
    def analog_max_speed(self) -> Coroutine[Any, Any, int]:
        """Speed at the analog input's maximum, rpm (211)."""

    @property
    def analog_speed_input(self) -> Coroutine[Any, Any, int]:
        """Analog speed input, mV (52)."""

    @property
    def bus_voltage(self) -> Coroutine[Any, Any, int]:
        """DC bus voltage, V (51)."""

    @property
    def control_mode(self) -> Coroutine[Any, Any, PblControlMode]:
        """Mode (100)."""

    @property
    def current(self) -> Coroutine[Any, Any, int]:
        """Motor current, A (53)."""

    @property
    def decel_mode(self) -> Coroutine[Any, Any, DecelMode]:
        """Natural or braking (114)."""

    @property
    def deceleration(self) -> Coroutine[Any, Any, int]:
        """Deceleration, rpm/s (210)."""

    @property
    def direction(self) -> Coroutine[Any, Any, Direction]:
        """The direction asked for: bit 1 of the control word (see :meth:`status` for the
        direction the motor turns). Setting it keeps the control word's other bits."""

    @property
    def direction_setting(self) -> Coroutine[Any, Any, DirectionSetting]:
        """Normal or inverted direction (203)."""

    async def get(self, name: str) -> int:
        """Reads the register called ``name`` (see the table), in engineering units: an
        int, or a float for a scaled register; a member of its enum where the
        device's class names its values."""

    async def get_many(self, names: Iterable[str]) -> dict[str, int]:
        """Reads the registers called ``names`` (a list), ``{name: value}`` in that order,
        each as :meth:`get` gives it,
        in as few requests as the table's limits allow (neighbours share one)."""

    @property
    def hall_state(self) -> Coroutine[Any, Any, int]:
        """Hall sensor state (6)."""

    @property
    def max_speed(self) -> Coroutine[Any, Any, int]:
        """Maximum speed, rpm (124)."""

    @property
    def min_speed(self) -> Coroutine[Any, Any, int]:
        """Minimum speed, rpm (123)."""

    async def parameters(self) -> dict[str, int]:
        """Every documented parameter, `{name: value}`, in four requests (61 a reply)."""

    @property
    def pole_pairs(self) -> Coroutine[Any, Any, int]:
        """Motor pole pairs (205)."""

    @property
    def power(self) -> Coroutine[Any, Any, int]:
        """Motor power, W (54)."""

    @property
    def profile(self) -> Profile:
        """The parameter table as a :class:`~benchbus.Profile` (``Profile.family("pbl")``):
        a row for each name :meth:`get` and :meth:`set` take, with its unit, access and
        range."""

    async def read_parameter(self, key: int | str) -> int:
        """Reads one parameter, by number or name."""

    async def read_parameters(self, start: int | str, count: int) -> list[int]:
        """Reads `count` parameters from `start` (in as few requests as allowed)."""

    async def restore_defaults(self) -> None:
        """Ask for the factory defaults (1511 to parameter 214).

        The drive applies them only after a power cycle; a ``UserWarning`` says so."""

    @property
    def running(self) -> Coroutine[Any, Any, bool]:
        """Whether the motor is moving (status word bit 0)."""

    async def sample(self) -> dict[str, float]:
        """Speed (rpm), bus voltage (V), analog speed input (mV), current (A) and power (W):
        parameters 50..54, in one request."""

    async def set(self, name: str, value: float) -> None:
        """Writes ``value`` (engineering units) to the register called ``name``, checked
        against its range, steps, access and the family's rules before anything is sent."""

    async def set_many(self, values: Mapping[str, float] | Iterable[tuple[str, float]]) -> None:
        """Writes ``values`` (``{name: value}`` or ``(name, value)`` pairs) in order, each
        as :meth:`set` does. Every value is checked against its register (range,
        steps, access) before the first is sent; the family's rules are checked write
        by write, so a refusal there leaves the earlier writes done."""

    @property
    def speed(self) -> Coroutine[Any, Any, int]:
        """Measured speed, rpm (50)."""

    @property
    def speed_setpoint(self) -> Coroutine[Any, Any, int]:
        """Speed setpoint: the internal speed, rpm (201)."""

    @property
    def speed_source(self) -> Coroutine[Any, Any, int]:
        """Speed command source (202)."""

    async def start(self) -> None:
        """Start: set bit 0 of the control word, keeping its other bits."""

    @property
    def start_stop_source(self) -> Coroutine[Any, Any, StartStopSource]:
        """Where start/stop come from (204)."""

    async def status(self) -> PblStatus:
        """The status word: running, and the direction the motor turns."""

    async def stop(self) -> None:
        """Stop: clear bit 0 of the control word, keeping its other bits."""

    @staticmethod
    def table() -> list[PblParameter]:
        """The parameter table: a :class:`~benchbus.PblParameter` (number, name, unit, access,
        low, high) for each parameter; access "R" or "W/R"."""

    async def telemetry(self) -> PblTelemetry:
        """Parameters 0..99 (status and measurements) by name, in two requests: a dict, shown
        as a table in notebooks."""

    def units(self) -> dict[str, str]:
        """The unit of each parameter by name, from :meth:`table` (``""`` for none)."""

    async def write_parameter(self, key: int | str, value: int) -> None:
        """Writes one parameter, by number or name, checked against the table first."""

class Drive(AsyncDevice[_SyncDrive], DriveMembers):
    """:class:`benchbus.Drive` for asyncio (see :class:`AsyncDevice`)."""

class Instrument(AsyncDevice[_SyncInstrument], InstrumentMembers):
    """:class:`benchbus.Instrument` for asyncio (see :class:`AsyncDevice`)."""

class J2Controller(AsyncDevice[_SyncJ2Controller], J2ControllerMembers):
    """:class:`benchbus.J2Controller` for asyncio (see :class:`AsyncDevice`)."""

class PblDrive(AsyncDevice[_SyncPblDrive], PblDriveMembers):
    """:class:`benchbus.PblDrive` for asyncio (see :class:`AsyncDevice`)."""
