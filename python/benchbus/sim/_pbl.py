"""A simulated PBL-series brushless DC drive (pure Python, no pymodbus).

The register map follows the vendor's Modbus RTU manual for the PBL series: the drive's
parameters 0..222 are holding registers at the same addresses, read with 0x03 and written
with 0x06 and 0x10. The motor is a simple model evaluated lazily on each access from a
clock: the speed ramps linearly toward its target, and the measurement registers are
computed from the speed.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping
from types import MappingProxyType

from benchbus.sim._device import ClockedModel, Row, TableDevice
from benchbus.sim._rtu import count_echo

__all__ = ["PblDevice"]

_PARAMETERS = 223  # 0..222

# Live values (0..99): what the model computes.
_CONTROL_LOW, _CONTROL_HIGH = 0, 1
_STATUS_LOW = 2
_ALARMS_LOW, _ALARMS_HIGH = 4, 5
_HALL, _POSITION, _SPEED, _CURRENT = 6, 7, 8, 9
_BUS_VOLTAGE = 13
_ACTUAL_SPEED, _BUS_VOLTS, _ANALOG_MV, _AMPS, _WATTS = 50, 51, 52, 53, 54
_DUTY = 58
_HALL_BRIDGE = 60
_AD_ANALOG = 61
_PLANNED_SPEED = 65

# Settings (100..222) the model uses.
_FIRST_SETTING = 100
_BRAKE_MODE = 114  # 0 natural deceleration, 1 brake deceleration (faster)
_MAX_SPEED = 124
_INTERNAL_SPEED = 201
_DIRECTION = 203  # 0 normal, 1 inverted
_START_SOURCE = 204  # 0 keys, 1 external IO, 2 communication
_POLE_PAIRS = 205
_ACCEL = 209  # rpm/s
_DECEL = 210  # rpm/s
_RESTORE = 214
_RESTORE_CODE = 1511
_COMMUNICATION = 2

#: Defaults of the settings 100..222 that are not 0. The manual gives 209, 210 and 212;
#: the others are made-up values of the kind a drive leaves the factory with.
_DEFAULTS: dict[int, int] = {
    101: 1,  # use the current loop
    105: 2,  # motor pole pairs (engineering group; 205 is the one the model uses)
    106: 1000,  # acceleration (engineering group; not used by the model)
    107: 1000,  # deceleration (engineering group; not used by the model)
    113: 2,  # PWM frequency: 16 kHz
    115: 1,  # trapezoidal drive waveform
    120: 1,  # a hall speed sensor is fitted
    124: 3000,  # maximum speed, rpm
    125: 18,  # minimum bus voltage, V
    126: 60,  # maximum bus voltage, V
    127: 56,  # brake resistor on above, V
    128: 52,  # brake resistor off below, V
    129: 54,  # bus voltage that slows the deceleration, V
    133: 3000,  # longest braking, ms
    134: 10000,  # brake cool-down, ms
    139: 1,  # over-current protection on
    140: 10,  # rated current
    141: 200,  # overload ratio, % of the rated current (the manual's own example)
    142: 100,  # continuous current, % of the rated current
    143: 3000,  # overload integration time, ms
    146: 1,  # bus voltage protection on
    147: 1,  # MCU over-temperature protection on
    148: 1,  # hall fault protection on
    149: 1,  # stall protection on
    150: 1,  # peak current limit on
    152: 1,  # over-temperature protection on
    156: 65535,  # speed loop output limit
    157: 4095,  # current loop limit, current AD reading
    159: 65535,  # speed loop integral limit
    160: 65535,  # current loop integral limit
    171: 65535,  # PWM duty limit (65535 = 100 %)
    172: 4095,  # largest negative current
    173: 4095,  # largest positive current
    179: 65535,  # duty limit slew (65535 = 100 %)
    186: 200,  # rated power, W
    204: _COMMUNICATION,  # start/stop by the communication control word
    205: 2,  # motor pole pairs
    209: 1000,  # acceleration, rpm/s (the manual's default)
    210: 1000,  # deceleration, rpm/s (the manual's default)
    211: 3000,  # speed at the analog input's maximum, rpm
    212: 100,  # analog input zero offset, mV (the manual's default)
    213: 10,  # speed step of one key press, rpm
    215: 1,  # drive address
    221: 3200,  # user analog input maximum, mV
    222: 100,  # user analog input minimum, mV
}


def _ranges() -> dict[int, tuple[int, int]]:
    """``{address: (low, high)}`` of the settings 100..222 (default 0..65535)."""
    table = dict.fromkeys(range(_FIRST_SETTING, _PARAMETERS), (0, 0xFFFF))
    flags = [101, 112, *range(114, 122), 139, *range(146, 151), 152, 158, 180]
    # 192 and 198 are duty thresholds (191 compares against P2.92), not flags.
    flags += [189, 190, 191, 195, 196, 197, _DIRECTION]
    table.update(dict.fromkeys(flags, (0, 1)))
    table.update({100: (0, 2), 113: (0, 3), 151: (0, 2), 161: (0, 999), 162: (0, 999)})
    table.update({_START_SOURCE: (0, 2), 215: (1, 255), 217: (0, 2)})
    table.update(dict.fromkeys((212, 221, 222), (0, 3299)))
    return table


_RANGES = _ranges()

#: Every parameter: the control word (0, 1), the live values (2..99: a write is taken and
#: ignored) and the settings (100..222).
_ROWS = {
    _CONTROL_LOW: Row(),
    _CONTROL_HIGH: Row(),
    **dict.fromkeys(range(_CONTROL_HIGH + 1, _FIRST_SETTING), Row("r", default=None)),
    **{a: Row(low=lo, high=hi) for a, (lo, hi) in _RANGES.items()},  # at power-up: DEFAULTS
}

#: Hall sensor states in the order a 120-degree sensor set steps through them going forward.
_HALL_SEQUENCE = (1, 5, 4, 6, 2, 3)

_BRAKE_FACTOR = 4.0  # 114 = 1: a stop decelerates this much faster
_TIME_EPSILON = 1e-9  # seconds: a ramp this close to its end has reached it
_AD_FULL_SCALE = 4095  # 12-bit converter ...
_AD_REFERENCE_MV = 3300  # ... on a 3.3 V reference


@dataclasses.dataclass
class _Core:
    """The motor's state (the settings and the control word are the table's words)."""

    t: float
    speed: float = 0.0  # signed rpm
    revs: float = 0.0  # signed revolutions since power-up
    direction: int = 1  # of the last motion: 1 forward, -1 reverse
    alarms: int = 0


class PblDevice(ClockedModel, TableDevice):
    """A PBL-series brushless DC drive as its Modbus manual describes it.

    ::

        drive = PblDevice()
        with Simulator({0x11: drive}) as sim:
            ...  # the library writes 201 = 1500 (internal speed) and 0 = 1 (start)
            drive.running, drive.speed  # True, ramping toward 1500.0 at 1000 rpm/s

    **Registers.** Parameters 0..222 at the same addresses; 223 and up answer exception 2
    (a block that runs past 222 too). 0 is the control word's low half (bit 0: 0 stop,
    1 start; bit 1: 0 forward, 1 reverse), 1 its high half (stored only). 2..99 are live
    status and measurement values: a write to them is answered normally and ignored (the
    manual's own 0x10 example writes 0001..0002); 22..49 (reserved) read 0. 100..222 are
    the settings, each range checked: a value out of range answers exception 3 and a 0x10
    write is all or nothing. Ranges: 100, 151, 204, 217 0..2; 113 0..3; 161, 162 0..999;
    212, 221, 222 0..3299; 215 1..255; the on/off settings (101, 112, 114..121, 139,
    146..150, 152, 158, 180, 189..192, 195..198, 203) 0..1; any other 0..65535. See
    :attr:`DEFAULTS` for the values at power-up.

    **Request size.** The manual's frame holds 1..123 data bytes: a read (0x03) may ask
    for at most 61 parameters (a byte count and 122 data bytes in the reply) and a 0x10
    write carry at most 59 (address, count, byte count and 118 data bytes), as
    :attr:`max_read` / :attr:`max_write`. More is answered with exception 3 (illegal data
    value): an assumption, as the manual names no exception codes; 3 is the Modbus
    specification's answer to a quantity out of range.

    **Replies.** As the manual shows them: a 0x06 write is answered with the address and
    a register count of 1 instead of the written value, unless ``echo_writes``; a
    broadcast (unit 0) is acted on and answered with the unit's own address, unless
    ``answers_broadcast`` is False.

    **Motor.** Evaluated lazily from ``clock`` (plus :meth:`advance`) on every access.
    While control word bit 0 is 1, 204 (start/stop source) is 2 (communication) and no
    alarm is active, the speed ramps toward min(201 internal speed, 124 maximum speed) at
    209 rpm/s when speeding up and 210 rpm/s when slowing down, in the direction of
    control word bit 1 XOR 203 (direction inversion); a reversal ramps through 0. Bit 0 =
    0 (or 204 set to anything but 2) ramps down to 0 at 210 rpm/s, 4x faster when 114
    (deceleration mode) is 1. An acceleration or deceleration of 0 changes the speed at
    once. 201 may change while running. 100 (control mode), 123 (minimum speed), 202
    (speed source), 116 and the other settings are only stored.

    **Live values.** 2 status (bit 0: 1 while started or turning; bit 1: direction of
    motion, 1 reverse), 3 = 0, 4/5 alarm bits 0..15/16..31 (:meth:`inject_alarm`), 6 hall
    state 1..6, 7 position in hall steps (revolutions x 205 pole pairs x 6, 16-bit wrap,
    down in reverse), 8 and 50 speed, rpm, 9, 53 and 73 current, whole A, 13 and 51 bus
    voltage, V (:attr:`bus_voltage`), 52 and 72 analog speed input, mV
    (:attr:`analog_input_mv`), 54 and 74 power, W (bus voltage x current), 58 and 78 duty
    cycle (65535 = 100 %, as 171), 60, 80 and 90 hall state in bits 0..2 and bit 3 = 1
    while the bridge drives the motor, 61, 81 and 91 the analog input's raw reading
    (12 bits on 3.3 V), 65, 85 and 95 the planned (ramp) speed, rpm; the others read 0.

    **Power.** :meth:`power_cycle` stops the motor, clears the control word, the alarms
    and the position, and restores every setting to its default if 214 was 1511.
    """

    #: The settings 100..222 at power-up (read-only mapping).
    DEFAULTS: Mapping[int, int] = MappingProxyType(
        {a: _DEFAULTS.get(a, 0) for a in range(_FIRST_SETTING, _PARAMETERS)}
    )
    #: Number of parameters: addresses 0..222.
    PARAMETERS = _PARAMETERS
    #: Most parameters one read asks for: the manual's frame holds at most 123 data bytes.
    max_read = 61
    #: Most parameters one write carries (as :attr:`max_read`).
    max_write = 59
    #: Motor current just above 0 rpm, A (linear up to :attr:`FULL_SPEED_CURRENT`, 0 at
    #: rest; registers 9 and 53 show it rounded to whole amperes).
    NO_LOAD_CURRENT = 0.5
    #: Motor current at :attr:`FULL_SPEED`, A.
    FULL_SPEED_CURRENT = 5.0
    #: Speed at which the current model reaches :attr:`FULL_SPEED_CURRENT`, rpm.
    FULL_SPEED = 3000.0
    #: Speed at 100 % duty cycle (register 58), rpm.
    NO_LOAD_SPEED = 4000.0

    def __init__(
        self,
        *,
        echo_writes: bool = False,
        answers_broadcast: bool = True,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """A stopped drive without alarms, every setting at its default.

        ``echo_writes=True`` answers 0x06 writes with the standard echo instead of the
        manual's register count. ``answers_broadcast=False`` acts on broadcasts silently,
        as standard Modbus units do. ``clock`` gives the time in seconds for the motor
        model (a test may pass a fake one and move it, or call :meth:`advance`).
        """
        #: Whether a 0x06 write is answered with the standard echo (True) or, as the
        #: manual shows, with the address and a register count of 1 (False).
        self.echo_writes: bool = bool(echo_writes)
        #: Whether a broadcast (unit 0) is answered with the unit's own address, as the
        #: manual shows (False: acted on silently, as standard Modbus units do).
        self.answers_broadcast = bool(answers_broadcast)
        #: DC bus voltage, V (registers 13 and 51).
        self.bus_voltage: int = 48
        #: The analog speed input, mV (registers 52 and 72).
        self.analog_input_mv: int = 0
        super().__init__(_ROWS)
        self._words.update(self.DEFAULTS)  # the class's, which a subclass may change
        self._start_clock(clock)
        self._core = _Core(t=self._now())

    # ---- Modbus handlers ----------------------------------------------------------------------

    #: A write to a live value (2..99) is answered normally and ignored.
    _readonly_code = None

    def shape_reply(self, request: bytes, reply: bytes) -> bytes:
        """A 0x06 reply carries a register count of 1 instead of the value, unless echoing."""
        return reply if self.echo_writes else count_echo(reply)

    # ---- test access ----------------------------------------------------------------------

    @property
    def speed(self) -> float:
        """The motor's speed now, rpm, negative in reverse (rounded to 1e-6 rpm)."""
        with self._up_to_now():
            return round(self._core.speed, 6) + 0.0  # + 0.0: no -0.0

    @property
    def running(self) -> bool:
        """Status bit 0: started (control word, source and alarms allow it) or turning."""
        with self._up_to_now():
            return self._running()

    @property
    def alarms(self) -> int:
        """The 32 alarm bits (register 5 high half, register 4 low half)."""
        with self._lock:
            return self._core.alarms

    @property
    def params(self) -> dict[int, int]:
        """The settings 100..222, ``{address: value}`` (a copy; see :meth:`set_param`)."""
        with self._lock:
            return {a: self._words[a] for a in self.DEFAULTS}

    @property
    def restore_pending(self) -> bool:
        """Whether the next :meth:`power_cycle` restores the defaults (214 == 1511)."""
        with self._lock:
            return self._words[_RESTORE] == _RESTORE_CODE

    def set_param(self, address: int, value: int) -> None:
        """Set a setting (100..222) directly, as the keys would, range checked.

        Raises KeyError for an address outside 100..222, TypeError for a value that is not
        an int and ValueError for a value out of range.
        """
        if isinstance(value, bool) or not isinstance(value, int):
            raise TypeError(f"a parameter value is an int, not {type(value).__name__}")
        if address not in _RANGES:
            raise KeyError(f"no setting at {address!r}: settings are 100..222")
        low, high = _RANGES[address]
        if not low <= value <= high:
            raise ValueError(f"parameter {address} is {low}..{high}, not {value}")
        with self._up_to_now():
            self._words[address] = value

    def peek(self, address: int) -> int:
        """The value a 0x03 read of ``address`` would answer now (KeyError past 222)."""
        if isinstance(address, bool) or not isinstance(address, int):
            raise TypeError(f"a parameter address is an int, not {type(address).__name__}")
        if not 0 <= address < _PARAMETERS:
            raise KeyError(f"a PBL drive has no parameter {address}")
        with self._up_to_now():
            return self._read_words(address, 1)[0]

    def inject_alarm(self, bit: int) -> None:
        """Raise alarm ``bit`` (0..31): registers 4/5 show it, the motor stops at once.

        The control word stays as written, but the motor does not run while any alarm is
        active; after :meth:`clear_alarms` a control word with bit 0 = 1 starts it again.
        """
        if isinstance(bit, bool) or not isinstance(bit, int) or not 0 <= bit <= 31:
            raise ValueError(f"an alarm bit is 0..31, not {bit!r}")
        with self._up_to_now():
            self._core.alarms |= 1 << bit
            self._core.speed = 0.0

    def clear_alarms(self) -> None:
        """Clear every alarm bit."""
        with self._up_to_now():
            self._core.alarms = 0

    def power_cycle(self) -> None:
        """Switch the drive off and on again.

        The motor stops at once, the control word (0, 1), the alarms and the position
        clear, and if 214 is 1511 every setting returns to its default (214 to 0).
        """
        with self._up_to_now():
            core = self._core
            core.speed, core.revs, core.direction = 0.0, 0.0, 1
            self._words[_CONTROL_LOW] = self._words[_CONTROL_HIGH] = 0
            core.alarms = 0
            if self._words[_RESTORE] == _RESTORE_CODE:
                self._words.update(self.DEFAULTS)

    def __repr__(self) -> str:
        """Speed, target, control word and alarms."""
        with self._up_to_now():
            core = self._core
            state = "running" if self._running() else "stopped"
            return (
                f"<PblDevice {state} speed={core.speed:.0f} rpm target={self._target():.0f} rpm"
                f" control={self._words[_CONTROL_LOW]:#06x} alarms={core.alarms:#010x}>"
            )

    # ---- register access ----------------------------------------------------------------------

    def _live(self, address: int) -> int:
        """A live value (2..99)."""
        if 72 <= address <= 89:  # 72..89 repeat 52..69
            address -= 20
        elif 90 <= address <= 99:  # 90..99 repeat 60..69
            address -= 30
        core = self._core
        rpm = abs(core.speed)
        amps = self._amps()
        if address == _STATUS_LOW:
            return int(self._running()) | self._reversing() << 1
        if address == _ALARMS_LOW:
            return core.alarms & 0xFFFF
        if address == _ALARMS_HIGH:
            return core.alarms >> 16
        if address == _HALL:
            return _HALL_SEQUENCE[self._hall_step() % 6]
        if address == _POSITION:
            return self._hall_step() & 0xFFFF
        if address in (_SPEED, _ACTUAL_SPEED, _PLANNED_SPEED):
            return min(0xFFFF, round(rpm))
        if address in (_CURRENT, _AMPS):
            return round(amps)
        if address in (_BUS_VOLTAGE, _BUS_VOLTS):
            return max(0, min(0xFFFF, int(self.bus_voltage)))
        if address == _ANALOG_MV:
            return max(0, min(0xFFFF, int(self.analog_input_mv)))
        if address == _WATTS:
            return min(0xFFFF, round(max(0, int(self.bus_voltage)) * amps))
        if address == _DUTY:
            return min(0xFFFF, round(0xFFFF * rpm / self.NO_LOAD_SPEED))
        if address == _HALL_BRIDGE:
            return _HALL_SEQUENCE[self._hall_step() % 6] | int(self._driving()) << 3
        if address == _AD_ANALOG:
            millivolts = max(0, min(_AD_REFERENCE_MV, int(self.analog_input_mv)))
            return round(millivolts * _AD_FULL_SCALE / _AD_REFERENCE_MV)
        return 0

    def _amps(self) -> float:
        rpm = abs(self._core.speed)
        if rpm == 0:
            return 0.0
        slope = (self.FULL_SPEED_CURRENT - self.NO_LOAD_CURRENT) / self.FULL_SPEED
        return self.NO_LOAD_CURRENT + slope * min(rpm, self.FULL_SPEED)

    def _hall_step(self) -> int:
        """Hall steps since power-up: revolutions x pole pairs x 6, down in reverse."""
        return math.floor(self._core.revs * self._words[_POLE_PAIRS] * 6 + 1e-6)

    # ---- the motor ------------------------------------------------------------------------------

    def _driving(self) -> bool:
        """Whether the control word runs the motor: bit 0, communication source, no alarm."""
        core = self._core
        return (
            bool(self._words[_CONTROL_LOW] & 1)
            and self._words[_START_SOURCE] == _COMMUNICATION
            and not core.alarms
        )

    def _running(self) -> bool:
        return self._driving() or self._core.speed != 0.0

    def _commanded_direction(self) -> int:
        reverse = (self._words[_CONTROL_LOW] >> 1 & 1) ^ self._words[_DIRECTION]
        return -1 if reverse else 1

    def _reversing(self) -> int:
        """Status bit 1: the direction of motion (at rest: commanded, or the last one)."""
        speed = self._core.speed
        if speed != 0.0:
            return int(speed < 0)
        if self._driving():
            return int(self._commanded_direction() < 0)
        return int(self._core.direction < 0)

    def _target(self) -> float:
        if not self._driving():
            return 0.0
        rpm = min(self._words[_INTERNAL_SPEED], self._words[_MAX_SPEED])
        return float(self._commanded_direction() * rpm)

    def _update(self) -> None:
        """Move the motor model from its last update to now."""
        core = self._core
        now = self._now()
        dt, core.t = now - core.t, max(now, core.t)
        while True:
            target, speed = self._target(), core.speed
            if speed == target:
                break
            same_side = target != 0 and (target > 0) == (speed > 0)
            if speed != 0 and not (same_side and abs(target) > abs(speed)):
                goal = target if same_side else 0.0  # slow down, to 0 first if reversing
                rate = float(self._words[_DECEL])
                if not self._driving() and self._words[_BRAKE_MODE] == 1:
                    rate *= _BRAKE_FACTOR
            else:
                goal = target
                rate = float(self._words[_ACCEL])
            need = abs(goal - speed) / rate if rate > 0 else 0.0  # 0: at once
            if need <= dt + _TIME_EPSILON:  # reached (within rounding of the time steps)
                step, new = min(need, max(dt, 0.0)), goal
            elif dt > 0:
                step, new = dt, speed + math.copysign(rate * dt, goal - speed)
            else:
                break
            self._turn(speed, new, step)
            core.speed = new
            dt -= step
        if dt > 0:
            self._turn(core.speed, core.speed, dt)

    def _turn(self, start: float, end: float, seconds: float) -> None:
        """Count the revolutions of a linear ramp from ``start`` to ``end`` rpm."""
        core = self._core
        core.revs += (start + end) / 2 * seconds / 60
        if end != 0.0:
            core.direction = 1 if end > 0 else -1
