"""A simulated BLD2 / BLD3H / ZBLD.C20 brushless DC drive (pure Python, no pymodbus).

The register map, attributes and exception codes follow the vendors' Modbus RTU manuals
(BLD2/BLD3H appendix B, ZBLD.C20 protocol). The motor is a simple model evaluated lazily
on each access from a clock: the speed ramps linearly toward its target, and the telemetry
registers are computed from the speed.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import time
from collections.abc import Callable

from benchbus.sim._device import ClockedModel, Row, SimException, TableDevice

__all__ = ["COMM_LOSS_FAULT", "DriveDevice"]

# Exception codes with this family's meanings.
_ILLEGAL_COMMAND = 0x01  # not supported, or the drive is in an error state
_WRITE_FAILED = 0x04  # e.g. a function-code parameter written without 0x200E = 1
_READ_ONLY = 0x07
_NOT_WHILE_RUNNING = 0x08

# What the motor is doing (the drive's state also depends on power and faults).
_STOPPED = "stopped"
_RUN = "run"  # forward / reverse toward the setpoint
_JOG = "jog"
_STOPPING = "stopping"  # ramping down to 0, then stopped
_BRAKING = "braking"  # ramping down at 10x the decel rate, then stopped

_COMMAND = 0x2000
_SETPOINT = 0x2001
_POLE_PAIRS = 0x2002
_ACCEL = 0x2003
_DECEL = 0x2004
_COMMAND_SOURCE = 0x2006
_VIRTUAL_INPUTS = 0x200A
_VIRTUAL_OUTPUTS = 0x200B
_WRITE_ENABLE = 0x200E
_RESTORE_DEFAULTS = 0x200F
_HALL_CLEAR = 0x2011
_STOP_MODE = 0x2012

_F08_03_REPLY_DELAY = 0x0803
_F08_04_COMM_TIMEOUT = 0x0804
_F08_06_WRITE_REPLY = 0x0806

#: Registers at 0x2006..0x2009 are the same settings as these function-code parameters.
_ALIASES = {0x2006: 0x0001, 0x2007: 0x0002, 0x2008: 0x0800, 0x2009: 0x0801}

#: Hall sensor states in the order a 120-degree sensor set steps through them going forward.
_HALL_SEQUENCE = (1, 5, 4, 6, 2, 3)

#: The fault code of a communication-loss trip (F08.04 ran out). The manual names no code
#: for it (it documents only 0x0A, undervoltage): this value is the simulator's choice.
COMM_LOSS_FAULT = 0x0E

_RPM_FULL_SCALE = 3000.0  # the ramp times are for 0 <-> 3000 rpm
_BRAKE_FACTOR = 10.0
_HALL_COUNT_WRAP = 1 << 32
_TIME_EPSILON = 1e-9  # seconds: a ramp this close to its end has reached it


def _setting(default: int, low: int, high: int, stopped_only: bool = False) -> Row:
    """A writable register or parameter: default, range, and W/R* (only while stopped)."""
    return Row("rw-stopped" if stopped_only else "rw", low, high, default)


def _parameters(bld: bool) -> dict[int, Row]:
    """The function-code parameters Fgg.nn (address ``gg << 8 | nn``) the drive knows."""
    return {
        0x0000: _setting(0, 0, 2),  # F00.00
        0x0001: _setting(2, 0, 2 if bld else 3),  # F00.01 run command channel (2 = comm)
        0x0002: _setting(3, 0, 8 if bld else 6),  # F00.02 speed reference (3 = Modbus)
        0x0005: _setting(0, 0, 1, True),  # F00.05 communication channel (0 = Modbus)
        0x000A: _setting(5000, 100, 40000),  # F00.10 maximum frequency, 0.01 Hz
        0x0800: _setting(1, 1, 247, True),  # F08.00 station address
        0x0801: _setting(4, 0, 7 if bld else 6, True),  # F08.01 baud code (4 = 19200)
        0x0802: _setting(0, 0, 3, True),  # F08.02 parity (0 = 8N1)
        0x0803: _setting(5, 0, 200, True),  # F08.03 reply delay, ms
        0x0804: _setting(0, 0, 600, True),  # F08.04 communication-loss timeout, 0.1 s
        0x0805: _setting(0, 0, 0, True),  # F08.05 reserved
        0x0806: _setting(0, 0, 1, True),  # F08.06 1 = no reply to writes
    }


def _settings(bld: bool) -> dict[int, Row]:
    """The writable registers 0x2001..0x2012 (0x2000, the command, is handled apart)."""
    table = {
        0x2001: _setting(0, 0, 3000),  # speed setpoint, rpm
        0x2002: _setting(2, 1, 20, True),  # pole pairs
        0x2003: _setting(50, 1, 6000),  # accel time, 0.1 s
        0x2004: _setting(50, 1, 6000),  # decel time, 0.1 s
        0x2005: _setting(2, 0, 5 if bld else 3, True),  # control mode
        0x2006: _setting(2, 0, 2 if bld else 3),  # command source (= F00.01; 3 = C20 DIP)
        0x2007: _setting(3, 0, 8 if bld else 6),  # speed source (= F00.02)
        0x2008: _setting(1, 1, 127 if bld else 247, True),  # station address (= F08.00)
        0x2009: _setting(4, 0, 7 if bld else 6, True),  # baud code (= F08.01)
        0x200A: _setting(0, 0, 0x1FF),  # virtual input terminals
        0x200B: _setting(0, 0, 0x0F),  # virtual output terminals
        0x200E: _setting(0, 0, 1),  # function-code write enable
        0x200F: _setting(0, 0, 1, True),  # restore defaults (action)
    }
    if bld:
        table[0x2010] = _setting(0, 0, 0xFFFF)  # position reference (reserved)
        table[0x2011] = _setting(0, 0, 1)  # hall count clear (action)
        table[0x2012] = _setting(0, 0, 1)  # stop mode: 0 decelerate, 1 coast
    return table


def _rows(bld: bool, hall_registers: bool) -> dict[int, Row]:
    """Every register: the command, the settings and parameters, status and telemetry.

    The command, the aliases of parameters and the actions are the model's (no default).
    """
    rows = {_COMMAND: Row(low=1, high=9 if bld else 8, default=None)}
    for address, row in _settings(bld).items():
        live = address in _ALIASES or address in (_RESTORE_DEFAULTS, _HALL_CLEAR)
        rows[address] = dataclasses.replace(row, default=None) if live else row
    rows.update(_parameters(bld))
    readonly = [*range(0x2100, 0x2104), *range(0x3000, 0x3012)]
    if bld and hall_registers:
        readonly += [0x3012, 0x3013, 0x3014]
    rows.update(dict.fromkeys(readonly, Row("r", default=None)))
    return rows


@dataclasses.dataclass
class _Core:
    """The model's state a write can change (beside the words): copied before a write,
    put back if it fails."""

    t: float
    command: int = 0
    commands: list[int] = dataclasses.field(default_factory=list)
    motion: str = _STOPPED
    direction: int = 1
    speed: float = 0.0  # signed rpm
    revs: float = 0.0  # signed revolutions (for the hall value)
    edges: float = 0.0  # hall edges counted (for the hall count)
    fault: int = 0
    last_fault: int = 0
    powered: bool = True


class DriveDevice(ClockedModel, TableDevice):
    """A BLD2, BLD3H or ZBLD.C20 ("C20") brushless DC drive as its manuals describe it.

    ::

        drive = DriveDevice("BLD2")
        with Simulator(drive) as sim:
            ...  # the library writes 0x2001 = 1500 and 0x2000 = 1 (forward)
            drive.state, drive.speed  # 1, ramping toward 1500.0

    **Registers.** 0x2000 command (1 forward, 2 reverse, 3/4 jog forward/reverse, 5 stop,
    6 coast, 7 fault reset, 8 jog stop, 9 brake stop on BLD only), 0x2001..0x200F settings
    (0x2006..0x2009 are the same settings as F00.01, F00.02, F08.00 and F08.01; the
    station address and baud code are only stored), BLD only 0x2010..0x2012, status
    0x2100..0x2103, telemetry 0x3000..0x3011 and BLD only 0x3012..0x3014, and a small
    table of function-code parameters Fgg.nn at ``gg << 8 | nn`` (see :attr:`params`).

    **Exceptions.** 2 unknown address (including the BLD-only ones on a C20); 7 write to a
    read-only register; 4 parameter write without 0x200E = 1; 3 value out of range (or an
    unknown command); 1 run command (1..4) while in fault or off; 8 W/R* register written
    while the motor turns (running, jogging, stopping or braking). A 0x10 write is applied
    register by register in address order and is all or nothing.

    **One register a read.** Both manuals give the 0x03 request's register count as
    0x0001 and the reply's byte count as 2 (where 0x10 says N and 2 x N), so by default a
    read of more than one register is refused with exception 3, "illegal data value"
    (:attr:`max_read` is 1): an assumption, the manuals naming no code for it, and 0x06
    "frame error" being for a wrong frame length or CRC. A master tested against the
    default simulator therefore also works on a drive that reads one register a request
    (the library's :class:`benchbus.Drive` falls back to such reads and remembers it).
    ``single_register_reads=False`` answers block reads of up to 125 registers, for a
    firmware that does, or a test that wants fewer requests.

    **Motor.** Evaluated lazily from ``clock`` (plus :meth:`advance`) on every access: the
    speed ramps toward its target at 3000 rpm per accel time (0x2003) when speeding up and
    per decel time (0x2004) when slowing down, through 0 when the direction changes. While
    running, 0x2100 shows the commanded direction (1 or 2; jogging too). Stop (5) ramps to
    0 and then shows 3, or coasts when 0x2012 = 1; coast (6) stops at once; brake (9)
    shows 6 while ramping down at 10x the decel rate. The drive replies after F08.03 ms
    (:attr:`reply_delay`) and not at all to writes when F08.06 = 1
    (:attr:`answers_writes`). With F08.04 (communication-loss timeout, 0.1 s) above 0, a
    drive whose motor turns and which has had no request for that long (model time: its
    reads and writes, as the simulator hands them over) trips with :data:`COMM_LOSS_FAULT`
    and stops at once.
    """

    #: The models this class simulates.
    MODELS = ("BLD2", "BLD3H", "C20")
    #: Register 0x2100 (drive state): running forward.
    FORWARD = 1
    #: Register 0x2100: running in reverse.
    REVERSE = 2
    #: Register 0x2100: stopped.
    STOPPED = 3
    #: Register 0x2100: in fault.
    FAULT = 4
    #: Register 0x2100: off.
    OFF = 5
    #: Register 0x2100: braking.
    BRAKING = 6
    #: The jog speed, rpm.
    JOG_SPEED = 300
    #: Register 0x300A: software version x 0.01 (101 = 1.01).
    SOFTWARE_VERSION = 101
    #: DC bus voltage while powered, 0.1 V (register 0x3008).
    BUS_VOLTAGE = 3110

    def __init__(
        self,
        model: str = "BLD2",
        *,
        single_register_reads: bool = True,
        hall_registers: bool = True,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """A stopped, healthy drive with every setting at its default.

        ``model`` is "BLD2", "BLD3H" or "C20". ``single_register_reads`` (the default)
        refuses 0x03 requests for more than one register with exception 3, as the manuals'
        one-register read format suggests a real unit does; False answers block reads (see
        the class doc). ``hall_registers=False`` makes a BLD whose
        firmware lacks 0x3012..0x3014 (the manual says they depend on the software version):
        they answer exception 2. ``clock`` gives the time in seconds for the
        motor model (a test may pass a fake one and move it, or call :meth:`advance`).
        """
        if model not in self.MODELS:
            raise ValueError(f"model must be one of {', '.join(self.MODELS)}, not {model!r}")
        self._model = model
        self.single_register_reads = single_register_reads
        #: Overload flag, shown in status word 2 bit 4 (1 = overloaded on a BLD, 0 on a C20).
        self.overloaded: bool = False
        #: Whether a keypad is connected (status word 2 bit 7, BLD only).
        self.keypad_connected: bool = False
        #: Inverter temperature at rest, degC (register 0x300C adds a little per ampere).
        self.temperature: float = 25.0
        #: The three analog inputs in volts (registers 0x300F..0x3011, 0.00..10.00 V).
        self.analog_inputs: list[float] = [0.0, 0.0, 0.0]
        self._bld = model != "C20"
        self._params_table = _parameters(self._bld)
        super().__init__(_rows(self._bld, hall_registers))
        self._param_defaults = {a: self._words[a] for a in self._params_table}
        self._start_clock(clock)
        self._core = _Core(t=self._now())
        #: Model time of the last request that reached this unit (for F08.04).
        self._heard = self._core.t

    @property
    def model(self) -> str:
        """ "BLD2", "BLD3H" or "C20" (fixed: the register tables follow it)."""
        return self._model

    @property
    def single_register_reads(self) -> bool:
        """Whether a read (0x03) of more than one register is refused (exception 3): sets
        :attr:`max_read` to 1, or back to the protocol's 125."""
        return self.max_read == 1

    @single_register_reads.setter
    def single_register_reads(self, single: bool) -> None:
        self.max_read = 1 if single else 125

    # ---- line behaviour ---------------------------------------------------------------------

    @property
    def answers_writes(self) -> bool:  # type: ignore[override]
        """Whether writes are answered: F08.06 == 0."""
        return self._words[_F08_06_WRITE_REPLY] == 0

    @property
    def reply_delay(self) -> float:  # type: ignore[override]
        """Seconds each reply is held: F08.03 (ms) / 1000."""
        return self._words[_F08_03_REPLY_DELAY] / 1000.0

    # ---- the table's hooks ------------------------------------------------------------------

    #: A write to a status or telemetry register answers 7 (read-only).
    _readonly_code = _READ_ONLY
    #: A W/R* register written while the motor turns answers 8.
    _turning_code = _NOT_WHILE_RUNNING
    #: A 0x10 write is applied register by register in address order.
    _writes_in_turn = True

    def _arrive(self, write: bool) -> None:
        self._update()
        self._heard = self._core.t

    def _live(self, address: int) -> int:
        if address == _COMMAND:
            return self._core.command
        if address in _ALIASES:
            return self._words[_ALIASES[address]]
        if address in (_RESTORE_DEFAULTS, _HALL_CLEAR):
            return 0  # actions, not settings
        return self._status(address)

    def _refuse(self, address: int, value: int) -> None:
        if address in self._params_table and self._words[_WRITE_ENABLE] != 1:
            raise SimException(_WRITE_FAILED)

    def _store(self, address: int, value: int) -> None:
        if address == _COMMAND:
            self._command(value)
        elif address in _ALIASES:
            self._words[_ALIASES[address]] = value
        elif address == _RESTORE_DEFAULTS:
            if value == 1:
                self._words.update(self._param_defaults)
        elif address == _HALL_CLEAR:
            if value == 1:
                self._core.edges = 0.0
        else:
            self._words[address] = value

    def _save(self) -> object:
        return copy.deepcopy(self._core), dict(self._words)

    def _restore(self, saved: object) -> None:
        assert isinstance(saved, tuple)
        self._core, self._words = saved

    # ---- test access ----------------------------------------------------------------------

    @property
    def state(self) -> int:
        """Register 0x2100: 1 forward, 2 reverse, 3 stopped, 4 fault, 5 off, 6 braking."""
        with self._up_to_now():
            return self._state()

    @property
    def speed(self) -> float:
        """The motor's speed now, rpm, negative in reverse (rounded to 1e-6 rpm)."""
        with self._up_to_now():
            return round(self._core.speed, 6) + 0.0  # + 0.0: no -0.0

    @property
    def fault(self) -> int:
        """Register 0x2102: the active fault code, 0 = none."""
        with self._lock:
            return self._core.fault

    @property
    def commands(self) -> list[int]:
        """Every value accepted at 0x2000 (command), in order (a copy)."""
        with self._lock:
            return list(self._core.commands)

    @property
    def params(self) -> dict[int, int]:
        """The function-code parameters, ``{address: value}`` (a copy; see :meth:`set_param`).

        Addresses ``gg << 8 | nn`` for F00.00, F00.01, F00.02, F00.05, F00.10 and
        F08.00..F08.06.
        """
        with self._lock:
            return {a: self._words[a] for a in self._params_table}

    def set_param(self, address: int, value: int) -> None:
        """Set a function-code parameter directly, as the keypad would (any state).

        Raises KeyError for an unknown parameter and ValueError for a value out of range.
        """
        with self._lock:
            setting = self._params_table.get(address)
            if setting is None:
                raise KeyError(f"no function-code parameter at {address:#06x}")
            if isinstance(value, bool) or not isinstance(value, int):
                raise TypeError(f"a parameter value is an int, not {type(value).__name__}")
            if not setting.low <= value <= setting.high:
                raise ValueError(
                    f"parameter {address:#06x} is {setting.low}..{setting.high}, not {value}"
                )
            self._words[address] = value

    def peek(self, address: int) -> int:
        """The value a 0x03 read of ``address`` would answer now (KeyError if none)."""
        with self._up_to_now():
            try:
                return self._read_words(address, 1)[0]
            except SimException:
                raise KeyError(f"a {self.model} has no register {address:#06x}") from None

    @property
    def hall_count(self) -> int:
        """The 32-bit hall count (registers 0x3013/0x3014); settable, e.g. near a wrap."""
        with self._up_to_now():
            return math.floor(self._core.edges + 1e-6) % _HALL_COUNT_WRAP

    @hall_count.setter
    def hall_count(self, value: int) -> None:
        if not 0 <= value < _HALL_COUNT_WRAP:
            raise ValueError(f"the hall count is 0..2**32 - 1, not {value}")
        with self._up_to_now():
            self._core.edges = float(value)

    def inject_fault(self, code: int = 0x0A) -> None:
        """Trip with fault ``code`` (0x0A: undervoltage): state 4, the motor stops at once.

        0x2102 and 0x300B show the code; command 7 (fault reset) clears 0x2102.
        """
        if not 1 <= code <= 0xFFFF:
            raise ValueError(f"a fault code is 1..0xFFFF, not {code}")
        with self._up_to_now():
            self._halt()
            self._core.fault = code
            self._core.last_fault = code

    def power_off(self) -> None:
        """Put the drive in its OFF state (5): the motor stops at once, no bus voltage."""
        with self._up_to_now():
            self._halt()
            self._core.powered = False

    def power_on(self) -> None:
        """Leave the OFF state: stopped (3), or in fault (4) if a fault is still active."""
        with self._up_to_now():
            self._core.powered = True

    def __repr__(self) -> str:
        """Model, state, speed, setpoint and fault."""
        with self._up_to_now():
            core = self._core
            return (
                f"<DriveDevice {self.model} state={self._state()} speed={core.speed:.0f} rpm"
                f" setpoint={self._words[_SETPOINT]} rpm fault={core.fault:#04x}>"
            )

    # ---- the commands ---------------------------------------------------------------------------

    def _command(self, value: int) -> None:
        core = self._core
        if value <= 4 and (core.fault or not core.powered):
            raise SimException(_ILLEGAL_COMMAND)
        if value in (1, 2):
            core.motion, core.direction = _RUN, 1 if value == 1 else -1
        elif value in (3, 4):
            core.motion, core.direction = _JOG, 1 if value == 3 else -1
        elif value == 5 and self._turning():
            if self._bld and self._words[_STOP_MODE] == 1:
                self._halt()
            else:
                core.motion = _STOPPING
        elif value == 6:
            self._halt()
        elif value == 7:
            core.fault = 0
        elif value == 8 and core.motion == _JOG:
            core.motion = _STOPPING
        elif value == 9 and self._turning():
            core.motion = _BRAKING
        core.command = value
        core.commands.append(value)
        self._settle()

    def _status(self, address: int) -> int:
        core = self._core
        pole_pairs = self._words[_POLE_PAIRS]
        rpm = abs(core.speed)
        turning = self._turning()
        load = min(rpm, _RPM_FULL_SCALE) / _RPM_FULL_SCALE
        bus = self.BUS_VOLTAGE if core.powered else 0
        volts = round(bus * 0.95 * load) if turning else 0  # 0.1 V
        amps = round(30 + 270 * load) if turning else 0  # 0.01 A

        def centihertz(r: float) -> int:
            return min(0xFFFF, round(r * pole_pairs * 100 / 60))

        if address == 0x2100:
            return self._state()
        if address == 0x2101:
            word = 0x0001 if core.powered else 0
            if self.overloaded == self._bld:  # BLD: 1 = overloaded; C20: 0 = overloaded
                word |= 0x0010
            word |= (self._words[_ALIASES[_COMMAND_SOURCE]] & 0x3) << 5
            if self._bld and self.keypad_connected:
                word |= 0x0080
            return word
        if address == 0x2102:
            return core.fault
        if address == 0x2103:
            return 0x0030 if self.model == "BLD3H" else 0x0020
        if address == 0x3000:
            return centihertz(self._words[_SETPOINT])
        if address in (0x3001, 0x3002):
            return centihertz(rpm)
        if address == 0x3003:
            return volts
        if address == 0x3004:
            return amps
        if address == 0x3005:
            return self._words[_SETPOINT]
        if address == 0x3006:
            return round(rpm)
        if address == 0x3007:
            return min(2200, round(volts / 10 * amps / 100))
        if address == 0x3008:
            return bus
        if address == 0x3009:
            step = math.floor(core.revs * pole_pairs * 6 + 1e-6)
            return _HALL_SEQUENCE[step % 6]
        if address == 0x300A:
            return self.SOFTWARE_VERSION
        if address == 0x300B:
            return core.last_fault
        if address == 0x300C:
            return round((self.temperature + 0.5 * amps / 100) * 10) & 0xFFFF
        if address == 0x300D:
            return self._words[_VIRTUAL_INPUTS]
        if address == 0x300E:
            return self._words[_VIRTUAL_OUTPUTS]
        if 0x300F <= address <= 0x3011:
            volts_in = float(self.analog_inputs[address - 0x300F])
            return max(0, min(1000, round(volts_in * 100)))
        if address == 0x3012:
            return 0
        count = math.floor(core.edges + 1e-6) % _HALL_COUNT_WRAP
        return count >> 16 if address == 0x3013 else count & 0xFFFF

    # ---- the motor ------------------------------------------------------------------------------

    def _state(self) -> int:
        core = self._core
        if not core.powered:
            return self.OFF
        if core.fault:
            return self.FAULT
        if core.motion == _STOPPED:
            return self.STOPPED
        if core.motion == _BRAKING:
            return self.BRAKING
        return self.FORWARD if core.direction > 0 else self.REVERSE

    def _turning(self) -> bool:
        """Whether the drive is running, jogging, stopping or braking (W/R* locked)."""
        return self._core.motion != _STOPPED

    def _halt(self) -> None:
        """Stop the motor at once (coast, fault, power off)."""
        self._core.motion = _STOPPED
        self._core.speed = 0.0

    def _settle(self) -> None:
        """A stop or brake that has reached 0 rpm is over."""
        if self._core.motion in (_STOPPING, _BRAKING) and self._core.speed == 0.0:
            self._core.motion = _STOPPED

    def _target(self) -> float:
        core = self._core
        if core.motion == _RUN:
            return float(core.direction * self._words[_SETPOINT])
        if core.motion == _JOG:
            return float(core.direction * self.JOG_SPEED)
        return 0.0

    def _update(self) -> None:
        """Move the motor model from its last update to now; trip if F08.04 ran out."""
        core = self._core
        now = self._now()
        timeout = self._words[_F08_04_COMM_TIMEOUT] / 10
        trip_at = self._heard + timeout
        if timeout > 0 and self._turning() and not core.fault and trip_at <= now:
            self._move(trip_at)
            if self._turning():  # a stop may have ended before the timer ran out
                self._halt()
                core.fault = core.last_fault = COMM_LOSS_FAULT
        self._move(now)

    def _move(self, now: float) -> None:
        """Move the motor model from its last update to ``now``."""
        core = self._core
        dt, core.t = now - core.t, max(now, core.t)
        while dt > 0:
            target, speed = self._target(), core.speed
            if speed == target:
                self._turn(speed, speed, dt)
                break
            same_side = target != 0 and (target > 0) == (speed > 0)
            if speed != 0 and not (same_side and abs(target) > abs(speed)):
                goal = target if same_side else 0.0  # slow down, to 0 first if reversing
                rate = _RPM_FULL_SCALE / (self._words[_DECEL] / 10)
                if core.motion == _BRAKING:
                    rate *= _BRAKE_FACTOR
            else:
                goal = target
                rate = _RPM_FULL_SCALE / (self._words[_ACCEL] / 10)
            need = abs(goal - speed) / rate
            if need <= dt + _TIME_EPSILON:  # reached (within rounding of the time steps)
                step, new = need, goal
            else:
                step, new = dt, speed + math.copysign(rate * dt, goal - speed)
            self._turn(speed, new, step)
            core.speed = new
            dt -= step
            self._settle()

    def _turn(self, start: float, end: float, seconds: float) -> None:
        """Count the revolutions and hall edges of a linear ramp from ``start`` to ``end``."""
        core = self._core
        revs = (start + end) / 2 * seconds / 60
        core.revs += revs
        core.edges += abs(revs) * self._words[_POLE_PAIRS] * 6
