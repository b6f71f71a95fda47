"""A simulated J2-series PID temperature controller (pure Python, no pymodbus).

The register map follows the vendor's Modbus RTU manual for the J2 series: a signed table
(16-bit two's complement, scaled x10) of parameters at the even addresses 0..62 and an
unsigned table (x1) at the even addresses 128..156. Behind the registers sits a first-order
thermal process under the controller's own PID loop, evaluated lazily on each access in
fixed steps of process time taken from a clock (optionally sped up).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping
from types import MappingProxyType

from benchbus.sim._device import ClockedModel, Row, SimException, TableDevice, pace_write

__all__ = ["J2Device"]

_BAD_VALUE = SimException.ILLEGAL_DATA_VALUE
_REFUSED = SimException.SERVER_DEVICE_FAILURE

_MAX_REGISTERS = 16
_SIGNED_SCALE, _UNSIGNED_SCALE = 10, 1
_WORD_LOW, _WORD_HIGH = -0x8000, 0x7FFF  # a signed register, raw

# The signed table: name, address, manual range (engineering units). None: LSP~USP.
_SIGNED_ROWS: tuple[tuple[str, int, float | None, float | None], ...] = (
    ("MV", 0, 0.0, 100.0),
    ("PV", 2, None, None),  # read-only; the manual says LSP~USP
    ("SV", 6, None, None),
    ("AL1", 8, -1999.0, 9999.0),
    ("AL2", 10, -1999.0, 9999.0),
    ("P", 14, 0.1, 3600.0),
    ("I", 16, 0.0, 3600.0),
    ("D", 18, 0.0, 3600.0),
    ("LSP", 20, -1999.0, 9999.0),
    ("USP", 22, -1999.0, 9999.0),
    ("HY1", 24, None, None),
    ("HY2", 26, None, None),
    ("HYS", 30, None, None),
    ("OUL", 32, 0.0, 100.0),
    ("OUH", 34, 0.0, 100.0),
    ("GAP", 36, -50.0, 50.0),
    ("RAP", 38, None, None),
    ("RTM", 40, 0.0, 3600.0),
    ("P1", 42, 0.1, 3600.0),
    ("I1", 44, 0.0, 3600.0),
    ("D1", 46, 0.0, 3600.0),
    ("TRL", 48, None, None),
    ("TRH", 50, None, None),
    ("PVOS", 52, -50.0, 50.0),
    ("SRT", 54, None, None),
    ("LMO", 56, 0.0, 100.0),
    ("TOP", 58, None, None),
    ("U0", 60, 0.0, 100.0),
    ("DIE", 62, 0.5, 5.0),
)

# The unsigned table: name, address, range.
_UNSIGNED_ROWS: tuple[tuple[str, int, int, int], ...] = (
    ("AM", 128, 0, 1),
    ("RAPNF", 130, 0, 1),
    ("AT", 132, 0, 1),
    ("CYT", 134, 0, 250),
    ("AD1", 136, 0, 9),
    ("AD2", 138, 0, 9),
    ("CYT1", 142, 0, 250),
    ("MAN", 144, 0, 1),
    ("SFT", 146, 0, 99),
    ("DP", 148, 0, 3),
    ("TH", 150, 0, 2),
    ("INP", 152, 0, 9),
    ("OUD", 154, 0, 1),
    ("FST", 156, 20, 120),
)

#: Power-up values that are not 0, engineering units.
_DEFAULTS: dict[str, float] = {
    "SV": 100.0,
    # Tuned to the process (the manual gives no defaults): I = TAU cancels the process's
    # lag, so PV settles at SV without overshoot; a first-order process needs no D.
    "P": 40.0,
    "I": 120.0,
    "D": 0.0,
    "USP": 400.0,
    "OUH": 100.0,
    "RAP": 10.0,  # degrees per minute: a ramp started with RAPNF = 1 takes its time
    "P1": 40.0,  # the manual's range starts at 0.1
    "I1": 120.0,
    "D1": 0.0,
    "DIE": 1.0,
    "AM": 1.0,
    "CYT": 2.0,
    "DP": 1.0,
    "INP": 6.0,  # K thermocouple
    "FST": 50.0,
}

#: P, I, D after an autotune (fixed: the simulation does not identify the process).
_TUNED: dict[str, float] = {"P": 20.0, "I": 300.0, "D": 15.0}


@dataclasses.dataclass(frozen=True)
class _Param:
    name: str
    address: int
    low: int  # raw (signed for the signed table)
    high: int
    scale: int
    between_limits: bool  # the range is LSP~USP
    writable: bool


def _signed_param(name: str, address: int, low: float | None, high: float | None) -> _Param:
    if name == "PV":
        return _Param(name, address, _WORD_LOW, _WORD_HIGH, _SIGNED_SCALE, False, False)
    if low is None or high is None:  # LSP~USP: the table shows the widest LSP..USP
        low, high = -1999.0, 9999.0
        between = True
    else:
        between = False
    raw_low = max(round(low * _SIGNED_SCALE), _WORD_LOW)
    raw_high = min(round(high * _SIGNED_SCALE), _WORD_HIGH)
    return _Param(name, address, raw_low, raw_high, _SIGNED_SCALE, between, True)


_PARAMS: dict[str, _Param] = {
    **{row[0]: _signed_param(*row) for row in _SIGNED_ROWS},
    **{n: _Param(n, a, lo, hi, _UNSIGNED_SCALE, False, True) for n, a, lo, hi in _UNSIGNED_ROWS},
}
_BY_ADDRESS: dict[int, _Param] = {p.address: p for p in _PARAMS.values()}
_LIVE = frozenset({"MV", "PV", "RAPNF", "AT"})  # values the model keeps, not stored words


def _row(p: _Param) -> Row:
    """The table's row of ``p``: a stored word (its power-up value is the device's
    ``DEFAULTS``), unless the model keeps the value."""
    default = None if p.name in _LIVE else 0
    access = "rw" if p.writable else "r"
    return Row(access, p.low, p.high, default, signed=p.scale == _SIGNED_SCALE)


_ROWS = {p.address: _row(p) for p in _PARAMS.values()}


def _public_table(names: list[str]) -> Mapping[str, tuple[int, float, float, int]]:
    table = {}
    for name in names:
        p = _PARAMS[name]
        table[name] = (p.address, p.low / p.scale, p.high / p.scale, p.scale)
    return MappingProxyType(table)


def _to_signed(word: int) -> int:
    return word - 0x10000 if word & 0x8000 else word


def _clamp(value: float, low: float, high: float) -> float:
    return low if value < low else high if value > high else value


@dataclasses.dataclass
class _Core:
    """The controller's state: stored parameters, the process and the control loop."""

    temperature: float
    previous: float  # the temperature at the previous step (derivative on PV)
    setpoint: float  # the working setpoint (SV, or the ramp on its way to SV)
    mv: float = 0.0  # output, %
    manual: float = 0.0  # the output in manual mode, %
    rate: float = 0.0  # the temperature's rate of change, filtered, degrees/s
    integral: float = 0.0  # the PID's integral term, % of output
    ramping: bool = False
    tuning: float = 0.0  # process seconds of autotune left; 0: not tuning
    held: float | None = None
    steps: int = 0  # process steps taken since the start


class J2Device(ClockedModel, TableDevice):
    """A J2-series PID temperature controller as its Modbus manual describes it.

    ::

        controller = J2Device(speedup=100)  # the process runs 100x faster than real time
        with Simulator({1: controller}) as sim:
            ...  # the library reads PV (address 2) and writes SV (address 6)
            controller.pv, controller.mv  # heating toward SV = 100.0

    **Registers.** The signed table (two's complement, x10: 100.0 is 1000) holds MV 0,
    PV 2 (read-only), SV 6, AL1 8, AL2 10, P 14, I 16, D 18, LSP 20, USP 22, HY1 24, HY2 26,
    HYS 30, OUL 32, OUH 34, GAP 36, RAP 38, RTM 40, P1 42, I1 44, D1 46, TRL 48, TRH 50,
    PVOS 52, SRT 54, LMO 56, TOP 58, U0 60, DIE 62; the unsigned table (x1) AM 128,
    RAPNF 130, AT 132, CYT 134, AD1 136, AD2 138, CYT1 142, MAN 144, SFT 146, DP 148,
    TH 150, INP 152, OUD 154, FST 156 (:attr:`SIGNED_TABLE`, :attr:`UNSIGNED_TABLE`). A read
    (0x03) of 1..16 registers anywhere in 0..0xFFFF answers these words and 0 for every
    other address (the NC rows 4, 12, 28, 140, the odd addresses, anything outside the
    tables). More than 16 registers answer exception 3 (the manual's limit, as
    :attr:`max_read` / :attr:`max_write`; which exception a real controller gives is not
    documented, 3 is the Modbus specification's for a quantity out of range), a block past
    0xFFFF exception 2.

    **Writes** (0x06, 0x10) are all or nothing, checked in this order:

    - exception 3: more than 16 registers (refused before the controller handles the
      write, so it does not count for the pacing below);
    - exception 6 (server device busy): the request came less than :attr:`write_interval`
      seconds after the previous write request (see *Write pacing*);
    - exception 2: a block past 0xFFFF, or any address in it that is not a writable
      parameter (PV, NC, an odd address, an address outside the tables). As parameters sit
      at even addresses only, a 0x10 of two registers or more always answers 2: one request
      writes one parameter;
    - exception 3: a value out of its range (decoded as signed x10 in the signed table,
      unsigned x1 in the other), or a write that would leave LSP > USP. The manual's ranges
      intersected with what a signed x10 register holds (-3276.8..3276.7): MV, OUL, OUH,
      LMO, U0 0..100; AL1, AL2, LSP, USP -1999..3276.7; P, P1 0.1..3276.7; I, D, RTM, I1, D1
      0..3276.7; GAP, PVOS -50..50; DIE 0.5..5; SV, HY1, HY2, HYS, RAP, TRL, TRH, SRT, TOP
      LSP..USP (those in effect after the request); AM, RAPNF, AT, MAN, OUD 0..1; CYT, CYT1
      0..250; AD1, AD2, INP 0..9; SFT 0..99; DP 0..3; TH 0..2; FST 20..120. Values already
      stored stay as they are when LSP or USP change; the control loop limits the working
      setpoint to LSP..USP;
    - exception 4 (the manual's rules, checked against the state the request leads to):
      MV while AM = 1 (auto; the manual: write AM = 0 first), RAP or RTM while a ramp runs
      (RAPNF reads 1; the manual: write RAPNF = 0 first). As one request writes one
      parameter, "AM = 0 and MV in the same 0x10" cannot happen (and MV and AM are 128
      addresses apart anyway).

    **Write pacing.** The manual asks for at least 150 ms between write commands, whatever
    their addresses, or the instrument "may fail". This model answers a write request
    that comes sooner with exception 6 and writes nothing: a deliberate choice, so that a
    master that does not pace its writes fails visibly instead of losing a write silently.
    The interval is measured in real time (``time.monotonic``, never the sped-up process
    clock) between the arrivals of consecutive write requests at this device, whatever
    their outcome: a refused write (by 6 or any other exception) counts as much as an
    accepted one, so a master that retries at once is refused again. Every arrival is
    appended to :attr:`write_times` and every interval that was too short to
    :attr:`write_violations`: the violations are exactly the gaps between consecutive
    write times that are shorter than the interval. A request reaches the device a little
    after it is complete on the line (usually well under a millisecond;
    ``Simulator.request_times`` has the line's times), so a master should keep a margin over
    the 150 ms.

    **Process.** A first-order plant, dT/dt = (:attr:`GAIN` x MV / 100 - (T - ambient)) /
    :attr:`TAU`, is stepped in fixed steps of :attr:`STEP` process seconds, lazily on each
    access, from ``clock`` x ``speedup`` (plus :meth:`advance`). Once the process is at rest
    (T, MV and the PID's state no longer move; no ramp, no autotune) the remaining steps
    are skipped, so a long idle time costs nothing. PV = T +
    PVOS, rounded to 0.1 and limited to the register. In auto (AM = 1) a positional PID
    computes MV at each step from the working setpoint W and PV: proportional band P
    degrees (100 % output per P degrees of error), integral time I seconds (0: the integral
    term holds its value), derivative time D seconds (0: none; on the measurement, so a
    setpoint change does not kick, filtered over D / 8 seconds), output limited to OUL..OUH
    (OUL wins if OUL > OUH); against windup the integral term stops while the output is
    saturated and stays within OUL..OUH. In manual (AM = 0) MV stays as written. Going to
    manual keeps the last automatic MV; going back to auto starts from the current MV as far
    as the integral term can make up the difference (bumpless near the setpoint). MV is a
    continuous output: CYT (cycle time) is only stored. The other parameters (alarms,
    hysteresis, the second PID set, GAP, DP, INP, ...) are stored only.

    **Ramp** (a guess: the manual says no more than how RAPNF reads and is written). Writing
    RAPNF = 1 starts a ramp of the working setpoint from the current PV toward SV at RAP
    degrees per minute, even if one runs (RAP <= 0: W is SV at once and the ramp ends). It
    follows SV if SV changes meanwhile. RAPNF reads 1 while it runs and 0 once W has reached
    SV; writing 0 ends it (W = SV). RTM is stored only.

    **Autotune** (a guess too). Writing AT = 1 runs a relay test for :attr:`AUTOTUNE_TIME`
    process seconds, in either mode (MV = OUH while PV < W, else OUL; a second AT = 1 does
    not restart it, AM may change meanwhile); then AT reads 0 and P, I, D take the values
    of :attr:`TUNED`. Writing AT = 0 aborts it and leaves P, I, D as they were. Either way
    the output goes back to the mode: in auto the PID goes on from the relay's output, in
    manual MV returns to the manual value (an MV written during the test is kept for then).

    **Test access.** :meth:`value` and :meth:`set_value` by parameter name,
    :attr:`pv`, :attr:`mv`, :attr:`temperature`, :attr:`setpoint`, :attr:`auto`,
    :meth:`hold_temperature` and :meth:`advance`. See :attr:`DEFAULTS` for the power-up
    values (SV 100.0, P 40.0, I 120, D 0, USP 400.0, RAP 10.0 degrees a minute, AM 1
    auto, INP 6 = K, ...). The power-up PID is tuned to the process: I = :attr:`TAU` cancels
    its lag (with a longer I, the integral term winds up while PV rises, and PV ends over
    SV for minutes), so from ambient PV settles at SV without overshoot, within 0.3 degrees
    of an SV of 80 after about 200 process seconds; the tuned values settle within 1 degree
    after about 90.
    """

    #: The signed table, ``{name: (address, low, high, scale)}`` (read-only mapping). Ranges
    #: are in engineering units and limited to what a register holds; for the names in
    #: :attr:`BETWEEN_LSP_USP` they are the widest LSP..USP (the check uses the LSP and USP
    #: in effect). PV is read-only and spans the whole register.
    SIGNED_TABLE: Mapping[str, tuple[int, float, float, int]] = _public_table(
        [row[0] for row in _SIGNED_ROWS]
    )
    #: The unsigned table, ``{name: (address, low, high, scale)}`` (read-only mapping).
    UNSIGNED_TABLE: Mapping[str, tuple[int, float, float, int]] = _public_table(
        [row[0] for row in _UNSIGNED_ROWS]
    )
    #: Both tables in one mapping, in address order.
    PARAMETERS: Mapping[str, tuple[int, float, float, int]] = MappingProxyType(
        {**SIGNED_TABLE, **UNSIGNED_TABLE}
    )
    #: The parameters whose range is LSP~USP.
    BETWEEN_LSP_USP: frozenset[str] = frozenset(n for n, p in _PARAMS.items() if p.between_limits)
    #: The parameters that cannot be written.
    READ_ONLY: frozenset[str] = frozenset({"PV"})
    #: Every parameter's value at power-up, engineering units (read-only mapping; MV is the
    #: initial output, PV is not included).
    DEFAULTS: Mapping[str, float] = MappingProxyType(
        {n: _DEFAULTS.get(n, 0.0) for n in _PARAMS if n != "PV"}
    )
    #: P, I, D after an autotune (read-only mapping).
    TUNED: Mapping[str, float] = MappingProxyType(dict(_TUNED))
    #: Most registers one read or write may carry (the manual's 16).
    MAX_REGISTERS = _MAX_REGISTERS
    #: Most registers one read may carry: :attr:`MAX_REGISTERS`.
    max_read = _MAX_REGISTERS
    #: Most registers one write may carry: :attr:`MAX_REGISTERS`.
    max_write = _MAX_REGISTERS
    #: Process gain: temperature rise over ambient at 100 % output, degrees.
    GAIN = 400.0
    #: Process time constant, seconds.
    TAU = 120.0
    #: The model's step, process seconds.
    STEP = 0.1
    #: The derivative's filter time constant is D / DERIVATIVE_FILTER.
    DERIVATIVE_FILTER = 8.0
    #: How long an autotune runs, process seconds.
    AUTOTUNE_TIME = 60.0

    def __init__(
        self,
        *,
        speedup: float = 1.0,
        clock: Callable[[], float] = time.monotonic,
        ambient: float = 25.0,
        write_interval: float = 0.150,
    ) -> None:
        """A controller at power-up: every parameter at its default, the process at ambient.

        ``clock`` gives the time in seconds (a test may pass a fake one and move it, or call
        :meth:`advance`); the process runs ``speedup`` times faster. ``ambient`` is the
        temperature the process starts at and cools to, degrees. ``write_interval`` is the
        shortest time between write requests, real seconds (0: no pacing).
        """
        speedup = float(speedup)
        if not (math.isfinite(speedup) and speedup > 0):
            raise ValueError(f"speedup must be > 0, not {speedup}")
        ambient = float(ambient)
        if not math.isfinite(ambient):
            raise ValueError(f"ambient must be a finite temperature, not {ambient}")
        write_interval = float(write_interval)
        if not (math.isfinite(write_interval) and write_interval >= 0):
            raise ValueError(f"write_interval must be >= 0, not {write_interval}")
        #: How many times faster than ``clock`` the process runs.
        self.speedup: float = speedup
        #: The temperature the process cools to, degrees.
        self.ambient: float = ambient
        #: Shortest time between two write requests, real seconds; sooner: exception 6.
        self.write_interval: float = write_interval
        #: ``time.monotonic()`` at the arrival of each write request, refused or not.
        self.write_times: list[float] = []
        #: Each too-short interval between two write requests, seconds (answered with 6).
        self.write_violations: list[float] = []
        super().__init__(_ROWS)
        for name, value in self.DEFAULTS.items():  # the class's, which a subclass may change
            if name not in _LIVE:
                self._put(name, round(value * _PARAMS[name].scale))
        self._start_clock(clock)
        self._core = _Core(temperature=ambient, previous=ambient, setpoint=0.0)
        self._core.setpoint = self._target()

    # ---- the table's hooks ------------------------------------------------------------------

    #: A read answers 0 for every address that is not a parameter.
    _read_gaps = "all"

    def _arrive(self, write: bool) -> None:
        if write:
            pace_write(self.write_times, self.write_violations, self.write_interval)
        self._update()

    def _live(self, address: int) -> int:
        return self._raw(_BY_ADDRESS[address].name) & 0xFFFF

    def _store(self, address: int, value: int) -> None:
        """Check the manual's rules on the state the write leads to, then apply it."""
        param = _BY_ADDRESS[address]
        changes = {param.name: _to_signed(value) if param.scale == _SIGNED_SCALE else value}
        problem = self._check(changes)
        if problem is not None:
            raise SimException(_BAD_VALUE if problem[0] == "range" else _REFUSED)
        self._apply(changes)

    # ---- test access ----------------------------------------------------------------------

    @property
    def pv(self) -> float:
        """The PV register now, degrees: temperature + PVOS, rounded to 0.1."""
        return self.value("PV")

    @property
    def mv(self) -> float:
        """The output now, % (unrounded; the MV register shows it rounded to 0.1)."""
        with self._up_to_now():
            return self._core.mv

    @property
    def temperature(self) -> float:
        """The process temperature now, degrees (unrounded, without PVOS)."""
        with self._up_to_now():
            return self._core.temperature

    @property
    def setpoint(self) -> float:
        """The working setpoint now, degrees: SV limited to LSP..USP, or the ramp toward it."""
        with self._up_to_now():
            return self._core.setpoint

    @property
    def auto(self) -> bool:
        """Whether the controller is in automatic mode (AM = 1)."""
        with self._lock:
            return self._stored("AM") == 1

    def value(self, name: str) -> float:
        """The value a read of parameter ``name`` gives now, engineering units.

        ``name`` as in :attr:`PARAMETERS`, any case (``value("SV")`` is 100.0 at power-up).
        Raises KeyError for a name that is not a parameter.
        """
        param = self._param(name)
        with self._up_to_now():
            return self._raw(param.name) / param.scale

    def set_value(self, name: str, value: float) -> None:
        """Set parameter ``name`` as the keys would: checked like a write, without pacing.

        ``value`` is in engineering units, rounded to the register's resolution (0.1 or 1).
        It has the effects a write has (AM switches bumplessly, RAPNF starts or ends a ramp,
        AT starts or aborts an autotune). Raises KeyError for a name that is not a writable
        parameter, TypeError for a value that is not a number, ValueError for a value out of
        range (or LSP > USP) and RuntimeError where a write would answer exception 4.
        """
        param = self._param(name)
        if not param.writable:
            raise KeyError(f"{param.name} is read-only (see hold_temperature)")
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise TypeError(f"a parameter value is a number, not {type(value).__name__}")
        if not math.isfinite(value):
            raise ValueError(f"{param.name} must be finite, not {value}")
        raw = round(value * param.scale)
        with self._up_to_now():
            problem = self._check({param.name: raw})
            if problem is not None:
                kind, message = problem
                raise (ValueError if kind == "range" else RuntimeError)(message)
            self._apply({param.name: raw})

    def hold_temperature(self, value: float | None) -> None:
        """Freeze the process at ``value`` degrees from now on; None lets it go on from there.

        The control loop keeps running on the held temperature.
        """
        if value is not None:
            value = float(value)
            if not math.isfinite(value):
                raise ValueError(f"a temperature is finite, not {value}")
        with self._up_to_now():
            core = self._core
            core.held = value
            if value is not None:
                core.temperature = core.previous = value  # no derivative kick

    def __repr__(self) -> str:
        """Mode, PV, working setpoint and output."""
        with self._up_to_now():
            core = self._core
            mode = "auto" if self._stored("AM") == 1 else "manual"
            extra = " ramping" if core.ramping else ""
            extra += " tuning" if core.tuning > 0 else ""
            return (
                f"<J2Device {mode}{extra} PV={self._raw('PV') / 10:.1f}"
                f" W={core.setpoint:.1f} SV={self._eng('SV'):.1f} MV={core.mv:.1f}%>"
            )

    # ---- parameters -------------------------------------------------------------------------

    @staticmethod
    def _param(name: str) -> _Param:
        if not isinstance(name, str):
            raise KeyError(f"a parameter name is a str, not {type(name).__name__}")
        param = _PARAMS.get(name.upper())
        if param is None:
            raise KeyError(f"a J2 controller has no parameter {name!r}")
        return param

    def _raw(self, name: str) -> int:
        """The raw value of ``name`` now (signed for the signed table)."""
        core = self._core
        if name == "PV":
            return round(_clamp((core.temperature + self._eng("PVOS")) * 10, -32768, 32767))
        if name == "MV":
            return round(core.mv * _SIGNED_SCALE)
        if name == "RAPNF":
            return int(core.ramping)
        if name == "AT":
            return int(core.tuning > 0)
        return self._stored(name)

    def _stored(self, name: str) -> int:
        """A stored parameter, raw (signed for the signed table)."""
        param = _PARAMS[name]
        word = self._words[param.address]
        return _to_signed(word) if param.scale == _SIGNED_SCALE else word

    def _put(self, name: str, raw: int) -> None:
        """Store parameter ``name`` from its raw value."""
        self._words[_PARAMS[name].address] = raw & 0xFFFF

    def _eng(self, name: str) -> float:
        """A stored parameter in engineering units."""
        return self._stored(name) / _PARAMS[name].scale

    def _check(self, changes: dict[str, int]) -> tuple[str, str] | None:
        """Why ``changes`` (raw, by name) cannot be written: ("range" | "state", text)."""

        def after(name: str) -> int:
            return changes[name] if name in changes else self._raw(name)

        lsp, usp = after("LSP"), after("USP")
        if lsp > usp:
            return "range", f"LSP ({lsp / 10:g}) cannot exceed USP ({usp / 10:g})"
        for name, raw in changes.items():
            param = _PARAMS[name]
            low, high = (lsp, usp) if param.between_limits else (param.low, param.high)
            if not low <= raw <= high:
                shown = f"{low / param.scale:g}..{high / param.scale:g}"
                return "range", f"{name} is {shown}, not {raw / param.scale:g}"
        if "MV" in changes and after("AM") == 1:
            return "state", "MV can be written in manual mode only (AM = 0)"
        if ("RAP" in changes or "RTM" in changes) and after("RAPNF") == 1:
            return "state", "RAP and RTM cannot be written while a ramp runs (RAPNF = 1)"
        return None

    def _apply(self, changes: dict[str, int]) -> None:
        """Store checked ``changes`` in address order, with their effects."""
        core = self._core
        for name in sorted(changes, key=lambda n: _PARAMS[n].address):
            raw = changes[name]
            if name == "MV":
                core.manual = raw / _SIGNED_SCALE
                if core.tuning <= 0:
                    core.mv = core.manual
            elif name == "RAPNF":
                if raw:
                    self._start_ramp()
                else:
                    core.ramping = False
                    core.setpoint = self._target()
            elif name == "AT":
                if not raw and core.tuning > 0:
                    self._end_tuning()
                elif raw and core.tuning <= 0:
                    core.tuning = self.AUTOTUNE_TIME
            elif name == "AM":
                was = self._stored("AM")
                self._put("AM", raw)
                if raw == 0 and was == 1:
                    core.manual = core.mv
                elif raw == 1 and was == 0 and core.tuning <= 0:
                    self._bumpless()
            else:
                self._put(name, raw)
                if name in ("SV", "LSP", "USP") and not core.ramping:
                    core.setpoint = self._target()

    # ---- the process and the control loop ---------------------------------------------------

    def _target(self) -> float:
        """SV limited to LSP..USP."""
        return _clamp(self._eng("SV"), self._eng("LSP"), self._eng("USP"))

    def _measured(self) -> float:
        return self._core.temperature + self._eng("PVOS")

    def _start_ramp(self) -> None:
        core = self._core
        core.setpoint = self._measured()
        core.ramping = True
        if self._eng("RAP") <= 0 or core.setpoint == self._target():
            core.ramping = False
            core.setpoint = self._target()

    def _limits(self) -> tuple[float, float]:
        low, high = self._eng("OUL"), self._eng("OUH")
        return low, max(low, high)

    def _gain(self) -> float:
        return 100.0 / self._eng("P")

    def _bumpless(self) -> None:
        """Make the PID's output continue from the current MV."""
        core = self._core
        proportional = self._gain() * (core.setpoint - self._measured())
        core.integral = _clamp(core.mv - proportional - self._derivative(), *self._limits())

    def _end_tuning(self) -> None:
        """Give the output back to the mode: the PID (bumpless) or the manual MV."""
        core = self._core
        core.tuning = 0.0
        if self._stored("AM") == 1:
            self._bumpless()
        else:
            core.mv = core.manual

    def _derivative(self) -> float:
        """The PID's derivative term, % (on the measurement, filtered)."""
        return -self._gain() * self._eng("D") * self._core.rate

    def _update(self) -> None:
        """Step the process from its last step to now."""
        core = self._core
        due = math.floor(self._now() / self.STEP + 1e-9)
        while core.steps < due:
            at_rest = self._step()
            core.steps += 1
            if at_rest:
                core.steps = due

    def _step(self) -> bool:
        """One step; whether the process is at rest (no state moves any more)."""
        core = self._core
        temperature, mv, rate, integral = core.temperature, core.mv, core.rate, core.integral
        target = self._target()
        if core.ramping:
            move = self._eng("RAP") / 60.0 * self.STEP
            if abs(target - core.setpoint) <= move:
                core.setpoint, core.ramping = target, False
            else:
                core.setpoint += math.copysign(move, target - core.setpoint)
        else:
            core.setpoint = target
        # The rate of change through a first-order filter of D / DERIVATIVE_FILTER seconds
        # (an unfiltered one-step derivative would make the loop chatter).
        lag = self._eng("D") / self.DERIVATIVE_FILTER
        core.rate += (temperature - core.previous) / (lag + self.STEP) - core.rate * (
            self.STEP / (lag + self.STEP)
        )
        if core.tuning > 0:
            low, high = self._limits()
            core.mv = high if self._measured() < core.setpoint else low
            core.tuning -= self.STEP
            if core.tuning <= 1e-9:
                for name, value in self.TUNED.items():
                    self._put(name, round(value * _SIGNED_SCALE))
                self._end_tuning()
        elif self._stored("AM") == 1:
            core.mv = self._pid()
        else:
            core.mv = core.manual
        core.previous = temperature
        if core.held is None:
            settled = self.ambient + self.GAIN * core.mv / 100.0
            decay = math.exp(-self.STEP / self.TAU)
            core.temperature = settled + (temperature - settled) * decay
        return (
            not core.ramping
            and core.tuning <= 0
            and abs(core.temperature - temperature) < 1e-9
            and abs(core.mv - mv) < 1e-9
            and abs(core.rate - rate) < 1e-9
            and abs(core.integral - integral) < 1e-9
        )

    def _pid(self) -> float:
        """The automatic output for this step (positional PID, conditional integration)."""
        core = self._core
        gain = self._gain()
        error = core.setpoint - self._measured()
        proportional = gain * error
        derivative = self._derivative()
        integral_time = self._eng("I")
        integral = core.integral
        if integral_time > 0:
            integral += gain * error * self.STEP / integral_time
        low, high = self._limits()
        output = proportional + integral + derivative
        saturated = (output > high and error > 0) or (output < low and error < 0)
        if not saturated:
            core.integral = _clamp(integral, low, high)
        return _clamp(proportional + core.integral + derivative, low, high)
