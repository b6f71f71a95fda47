"""The benchbus pytest plugin: devices as fixtures, simulated or real, for test benches.

pytest loads it wherever benchbus is installed (entry point ``pytest11``); it adds fixtures,
options and a marker, and changes nothing else. It imports neither pymodbus nor the
simulators until a test asks for a simulated device, so the real-device fixtures work
without ``benchbus[sim]``.

::

    import pytest
    import benchbus as bb

    def test_spins_up(bench_drive):        # the real drive with --benchbus-port, else simulated
        bench_drive.accel_time = 0.5
        bench_drive.speed_setpoint = 1200
        bench_drive.forward()
        assert abs(bench_drive.wait_for_speed(1200, tolerance=20, timeout=5) - 1200) <= 20

    def test_undervoltage_trips(sim_drive):   # always simulated: the simulator is at hand
        sim_drive.model.inject_fault(0x0A)
        with pytest.raises(bb.ModbusException):
            sim_drive.device.forward()

    @pytest.mark.hardware                     # skipped unless --benchbus-port is given
    def test_the_real_motor_draws_current(bench_drive): ...

**Simulated devices.** ``sim_drive``, ``sim_pbl``, ``sim_j2`` and ``sim_instrument`` start a
:class:`benchbus.sim.Simulator` with one device at unit 1 on a pseudo-terminal, open the
benchbus device on it with the family's own line defaults, and yield a :class:`SimBench`:
``.device`` (:class:`benchbus.Drive`, :class:`~benchbus.PblDrive`,
:class:`~benchbus.J2Controller`, :class:`~benchbus.Instrument`), ``.sim`` (the Simulator:
frame logs, ``set_silent``, ``corrupt_next``, ``answer_exception``, ``reply_delay``...) and
``.model`` (the simulated device: its state, and its own faults such as
``DriveDevice.inject_fault``); ``device, sim, model = sim_drive`` unpacks it. Afterwards the
device is closed (no stop is sent: the simulator goes with it, so a test may leave it in
any state, silent or faulted) and the simulator stopped, also when the test fails.

The simulated devices come from the fixtures ``sim_drive_model`` (a BLD2
:class:`~benchbus.sim.DriveDevice`; a C20 model is opened with ``family="C20"``),
``sim_pbl_model`` (a :class:`~benchbus.sim.PblDevice` at unit 1, the drive address it has at
power-up; the manual's example frames use 0x11), ``sim_j2_model`` (a
:class:`~benchbus.sim.J2Device` whose process runs :data:`J2_SPEEDUP` times faster than real
time, so heating to a setpoint takes about a second) and ``sim_instrument_model`` (a
:class:`~benchbus.sim.TaisongDevice` running :data:`INSTRUMENT_SPEEDUP` times faster).
Override one in a ``conftest.py`` or a test module to simulate something else::

    @pytest.fixture
    def sim_drive_model():
        return DriveDevice("C20", single_register_reads=False)  # block reads answered

**Device profiles.** ``sim_profile`` is a factory: ``sim_profile(path, *, unit=1,
values=None, baudrate=None, framing=None)`` serves the device profile (a TOML file of
registers) at ``path`` as a :class:`benchbus.sim.ProfileDevice` at ``unit``, with its
``default`` values and then ``values`` (engineering values by register name), on a
Simulator and pseudo-terminal of its own, and returns a :class:`ProfileBench`: ``.port``,
``.unit``, ``.baudrate``, ``.framing``, ``.model`` (the ProfileDevice: ``value(name)``,
``set_value(name, v)``), ``.sim`` (the Simulator) and ``.bus``, a :class:`benchbus.Bus` open
on the port at the profile's ``[line]`` (``baudrate`` and ``framing`` given here win over
it, and another framing than the profile's takes the Bus's character format for it, 7E1 for
ASCII; where the profile is silent, a Bus's defaults at 19200 baud). Reading the device is
the test's, on ``.bus`` at ``.unit``. Each call starts another simulator (one profile and
one unit each, so two profiles never share a line); after the test every Bus is closed and
every simulator stopped, also when the test fails. A broken profile raises
:class:`benchbus.ProfileError` (file, line, key) from the call, before anything starts::

    def test_the_sensor(sim_profile):
        bench = sim_profile("xy_md02.toml", values={"temperature": 23.4})
        assert bench.bus.read_input_registers(bench.unit, 0x0001, 1) == [234]

**Real or simulated.** ``bench_drive``, ``bench_pbl``, ``bench_j2`` and ``bench_instrument``
yield the device alone: on the port given with ``--benchbus-port`` if there is one,
otherwise on a simulator as above (from the same ``sim_*_model`` fixtures), so one test runs
on both. Afterwards a drive is stopped (as leaving its ``with`` block does; a stop that
fails is a teardown error, since the motor may still turn) and the device closed; a J2
controller goes on controlling. A test that needs the simulator uses ``sim_*`` instead.
On the real port a drive or controller is first checked to be of its fixture's family
(``verify_identity``): one that answers as another family fails the test's setup with
:class:`benchbus.WrongDevice`, nothing written to it.

On the real port the ``bench_*`` devices of one test share one :class:`benchbus.Bus`, as
the devices of one RS485 line do. Options:

- ``--benchbus-port PATH``: the line (``/dev/ttyUSB0``, or anything :class:`benchbus.Bus`
  opens). Without it every ``bench_*`` device is simulated.
- ``--benchbus-unit [KIND=]N``: the unit address, for every kind or for one (``drive``,
  ``pbl``, ``j2``, ``instrument``); repeatable, e.g. ``--benchbus-unit j2=2``; default 1.
- ``--benchbus-baudrate N`` and ``--benchbus-parity N|E|O``: the line format. By default
  each family's own (drive 19200 8N1, PBL 115200 8E1, J2 and instrument 9600 8N1); a test
  whose devices' defaults differ needs them given, or its setup fails saying so.
- ``--benchbus-no-identity-check``: no family check, for a device whose identity
  registers differ from its manual's.

Each device gets its family's timeout (drive 0.25 s, J2 0.3 s, PBL and instrument 0.1 s)
and the Bus 2 retries. The unit and line options only apply to the real port; the
``sim_*`` fixtures stay simulated with it too. The fixture ``benchbus_port`` gives the port,
or None: a test that uses no ``bench_*`` device may open its own Bus on it (a port opens
once at a time).

**Marker.** Tests marked ``hardware`` are skipped ("needs a real device: run with
--benchbus-port PATH") unless ``--benchbus-port`` is given; they are for what only means
something on a real device (a real oven's heating time, a real motor's current).

**Header.** pytest's header says which: ``benchbus: simulated devices ...`` or
``benchbus: devices on /dev/ttyUSB0 ...``.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import os
from collections.abc import Callable, Iterator, Mapping
from typing import TYPE_CHECKING, Any, Generic, TypeVar, Union

import pytest

from benchbus._core import Bus, Profile
from benchbus._device import BusDevice, MotorDevice
from benchbus._extras import sim_missing
from benchbus._families import FAMILIES, Family, family
from benchbus.exceptions import FrameError, ResponseTimeout

if TYPE_CHECKING:
    from benchbus._profile import Device
    from benchbus.sim import (
        ProfileDevice,
        SimDevice,
        Simulator,
    )

__all__ = [
    "INSTRUMENT_SPEEDUP",
    "J2_SPEEDUP",
    "KINDS",
    "SIM_UNIT",
    "ProfileBench",
    "SimBench",
    "SimProfile",
]

#: The device kinds, as ``--benchbus-unit`` names them: the families with a benchbus class.
KINDS = tuple(f.key for f in FAMILIES if f.device is not None)
#: The unit address of every simulated device.
SIM_UNIT = 1
#: How many times faster than real time the simulated J2 controller's process runs.
J2_SPEEDUP = float(family("j2").bench_model["speedup"])
#: How many times faster than real time the simulated instrument's measured value moves.
INSTRUMENT_SPEEDUP = float(family("instrument").bench_model["speedup"])

_DEFAULT_UNIT = 1  # on the real port
_SKIP_REASON = "needs a real device: run with --benchbus-port PATH"
_PARITIES = ("N", "E", "O")

DevT = TypeVar("DevT", bound=BusDevice)
ModelT = TypeVar("ModelT", bound="SimDevice")


@dataclasses.dataclass(frozen=True)
class SimBench(Generic[DevT, ModelT]):
    """A simulated device under test: what the ``sim_*`` fixtures yield.

    Annotate as ``SimBench[bb.Drive, DriveDevice]``; ``device, sim, model = bench`` unpacks.
    """

    #: The benchbus device, connected to the simulator (unit :data:`SIM_UNIT`).
    device: DevT
    #: The Simulator serving it: frame logs and line faults.
    sim: Simulator[ModelT]
    #: The simulated device: its state, and its own faults.
    model: ModelT

    def __iter__(self) -> Iterator[Any]:
        """``device``, ``sim``, ``model``."""
        return iter((self.device, self.sim, self.model))


#: A register's engineering value, as ``values=`` gives it: a number, a bool, an enum
#: member's name (or number) or a string.
ProfileValue = Union[int, float, bool, str]


@dataclasses.dataclass(frozen=True)
class ProfileBench:
    """A device profile served by a simulator: what the ``sim_profile`` factory returns.

    The master side is the test's: :attr:`bus` is a :class:`benchbus.Bus` already open on
    :attr:`port` at the profile's line, to read the device at :attr:`unit` with.
    """

    #: The profile's path, as given.
    path: str
    #: The pseudo-terminal the simulator serves (:attr:`sim`'s port).
    port: str
    #: The unit address the profile's device answers at.
    unit: int
    #: The baud rate: the factory's ``baudrate``, else the profile's ``[line]``, else 9600.
    baudrate: int
    #: The framing: ``"rtu"`` or ``"ascii"`` (the factory's, else the profile's, else RTU).
    framing: str
    #: The Simulator serving it: frame logs and line faults.
    sim: Simulator[ProfileDevice]
    #: The simulated device (:class:`benchbus.sim.ProfileDevice`): its values by name.
    model: ProfileDevice
    #: A Bus open on :attr:`port` at the profile's line (parity, stop bits, timeout, byte
    #: size as its ``[line]`` gives them, 9600 8N1 and 0.2 s where it is silent, as for a
    #: :class:`benchbus.Device` opening its own port), closed after the test.
    bus: Bus
    #: The device on :attr:`bus` (:meth:`benchbus.Device.from_profile`).
    device: Device


#: The ``sim_profile`` fixture: ``sim_profile(path, *, unit=1, values=None, baudrate=None,
#: framing=None)`` serves the profile at ``path`` and returns its :class:`ProfileBench`.
SimProfile = Callable[..., ProfileBench]


# ---- options ---------------------------------------------------------------------------------


def _unit_option(text: str) -> tuple[str, int]:
    """``N`` or ``KIND=N`` -> (kind or "", unit)."""
    kind, _, number = text.rpartition("=")
    if kind and kind not in KINDS:
        raise argparse.ArgumentTypeError(f"{kind!r} is not one of {', '.join(KINDS)}")
    try:
        unit = int(number, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{number!r} is not a unit address") from None
    if not 1 <= unit <= 255:
        raise argparse.ArgumentTypeError(f"a unit address is 1 to 255, not {unit}")
    return kind, unit


def _baudrate_option(text: str) -> int:
    """A positive int."""
    try:
        baudrate = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a baud rate") from None
    if baudrate <= 0:
        raise argparse.ArgumentTypeError(f"a baud rate is > 0, not {baudrate}")
    return baudrate


@dataclasses.dataclass(frozen=True)
class _Settings:
    """The benchbus options of a pytest run."""

    port: str | None
    units: dict[str, int]  # kind -> unit; "" for every kind
    baudrate: int | None
    parity: str | None
    #: Whether a real device checks that its unit is of its family (see ``bench_*``).
    check_identity: bool = True

    def unit(self, kind: str) -> int:
        """The unit address of ``kind`` on the real port."""
        return self.units.get(kind, self.units.get("", _DEFAULT_UNIT))

    def line_format(self, kind: str) -> tuple[int, str]:
        """(baudrate, parity) to open the real port at for ``kind``."""
        line = family(kind).line
        return (self.baudrate or line.baudrate, self.parity or line.parity)


_SETTINGS = pytest.StashKey[_Settings]()


def pytest_addoption(parser: pytest.Parser) -> None:
    """The ``--benchbus-*`` options."""
    group = parser.getgroup("benchbus", "benchbus devices (bench_* fixtures, hardware marker)")
    group.addoption(
        "--benchbus-port",
        metavar="PATH",
        default=None,
        help="serial port of the real devices for the bench_* fixtures and the tests marked"
        " hardware (default: simulated devices, hardware tests skipped)",
    )
    group.addoption(
        "--benchbus-unit",
        metavar="[KIND=]N",
        action="append",
        type=_unit_option,
        default=[],
        help=f"unit address on that port, for every kind or one of {', '.join(KINDS)};"
        " repeatable (default 1)",
    )
    group.addoption(
        "--benchbus-baudrate",
        metavar="N",
        type=_baudrate_option,
        default=None,
        help="baud rate of that port (default: each device family's)",
    )
    group.addoption(
        "--benchbus-parity",
        choices=_PARITIES,
        default=None,
        help="parity of that port (default: each device family's, 8E1 for PBL, else 8N1)",
    )
    group.addoption(
        "--benchbus-no-identity-check",
        action="store_false",
        dest="benchbus_check_identity",
        help="do not check that each real device is of its fixture's family (for a device"
        " whose identity registers differ from its manual's)",
    )


def pytest_configure(config: pytest.Config) -> None:
    """Register the ``hardware`` marker and keep the options."""
    config.addinivalue_line("markers", f"hardware: the test {_SKIP_REASON} (else skipped)")
    config.stash[_SETTINGS] = _Settings(
        port=config.getoption("benchbus_port"),
        units=dict(config.getoption("benchbus_unit")),
        baudrate=config.getoption("benchbus_baudrate"),
        parity=config.getoption("benchbus_parity"),
        check_identity=config.getoption("benchbus_check_identity"),
    )


def pytest_report_header(config: pytest.Config) -> list[str]:
    """``benchbus: devices on PORT ...`` or ``benchbus: simulated devices ...``."""
    settings = config.stash[_SETTINGS]
    if settings.port is None:
        return ["benchbus: simulated devices (tests marked hardware skipped: no --benchbus-port)"]
    units = ", ".join(f"{kind} {settings.unit(kind)}" for kind in KINDS)
    if settings.baudrate is None and settings.parity is None:
        line = "each family's line format"
    else:
        line = f"{settings.baudrate or 'family'} baud, parity {settings.parity or 'of the family'}"
    return [f"benchbus: devices on {settings.port} (units: {units}; {line})"]


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Skip the tests marked ``hardware`` when there is no real port."""
    if config.stash[_SETTINGS].port is not None:
        return
    skip = pytest.mark.skip(reason=_SKIP_REASON)
    for item in items:
        if item.get_closest_marker("hardware") is not None:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def benchbus_port(pytestconfig: pytest.Config) -> str | None:
    """The port given with ``--benchbus-port``, or None (simulated devices)."""
    return pytestconfig.stash[_SETTINGS].port


# ---- simulated devices -------------------------------------------------------------------------


def _require_sim() -> None:
    """Fail the test with a clear message if the simulators cannot be imported."""
    try:
        import benchbus.sim  # noqa: F401
    except ImportError as exc:
        pytest.fail(str(sim_missing(exc) or exc), pytrace=False)


@contextlib.contextmanager
def _simulated(of: Family, model: ModelT) -> Iterator[SimBench[Any, ModelT]]:
    """``model`` at :data:`SIM_UNIT` on a running Simulator, the device of the family ``of``
    opened on it as the family opens a simulated unit; afterwards the device closed and the
    simulator stopped."""
    _require_sim()
    from benchbus.sim import Simulator

    with Simulator({SIM_UNIT: model}, baudrate=of.line.baudrate) as sim:
        device = of.open(sim.port, SIM_UNIT, **of.opened_with(model))
        try:
            yield SimBench(device, sim, model)
        finally:
            device.close()


def _serve_profile(
    stack: contextlib.ExitStack,
    path: str | os.PathLike[str],
    unit: int,
    values: Mapping[str, ProfileValue] | None,
    baudrate: int | None,
    framing: str | None,
) -> ProfileBench:
    """The profile at ``path`` served at ``unit`` on a Simulator of its own, with a Bus
    open on it; both closed by ``stack``. A broken profile raises the core's ProfileError
    before anything starts."""
    profile = Profile(path)  # ProfileError: file, line, key
    _require_sim()
    from benchbus._profile import Device, profile_line
    from benchbus.sim import ProfileDevice, Simulator

    # The line a Device of the profile opens its own port at (its [line], else 9600 8N1);
    # its character format is for its own framing, so another framing takes the Bus's.
    line = profile_line(profile)
    options: dict[str, Any] = {
        "parity": line.parity,
        "stopbits": line.stopbits,
        "timeout": line.timeout,
        "bytesize": line.bytesize,
    }
    if framing is not None and framing != line.framing:
        options = {"timeout": line.timeout}
    served: dict[str, Any] = {
        "baudrate": baudrate or line.baudrate,
        "framing": framing or line.framing,
    }
    model = ProfileDevice(profile.path, values)  # the file the name was found at
    sim = stack.enter_context(Simulator({unit: model}, **served))
    bus = stack.enter_context(Bus(sim.port, **served, **options))
    return ProfileBench(
        path=os.fspath(path),
        port=sim.port,
        unit=unit,
        baudrate=served["baudrate"],
        framing=served["framing"],
        sim=sim,
        model=model,
        bus=bus,
        device=Device(profile, bus, unit),
    )


@pytest.fixture
def sim_profile() -> Iterator[SimProfile]:
    """A factory: ``sim_profile(path, *, unit=1, values=None, baudrate=None, framing=None)``
    serves the device profile at ``path`` (a file, or a profile's name: ``"sdm630"``) on a
    simulator of its own and returns a
    :class:`ProfileBench` (``.port``, ``.unit``, ``.bus``, ``.model``, ``.sim``). Every
    simulator it started is stopped after the test, and its Bus closed, also when the test
    fails."""
    with contextlib.ExitStack() as stack:

        def serve(
            path: str | os.PathLike[str],
            *,
            unit: int = SIM_UNIT,
            values: Mapping[str, ProfileValue] | None = None,
            baudrate: int | None = None,
            framing: str | None = None,
        ) -> ProfileBench:
            return _serve_profile(stack, path, unit, values, baudrate, framing)

        yield serve


# ---- real or simulated -------------------------------------------------------------------------


class _Line:
    """The real port of one test: one Bus, opened by the first ``bench_*`` device."""

    def __init__(self, settings: _Settings, port: str) -> None:
        self._settings = settings
        self._port = port
        self._bus: Bus | None = None
        self._first = ""

    def open(self, kind: str) -> tuple[Bus, int, float]:
        """The Bus, the unit and the timeout for a device of ``kind``."""
        baudrate, parity = self._settings.line_format(kind)
        if self._bus is None:
            self._bus = Bus(self._port, baudrate=baudrate, parity=parity, stopbits=1, retries=2)
            self._first = kind
        elif (self._bus.baudrate, self._bus.parity) != (baudrate, parity):
            first = self._settings.line_format(self._first)
            pytest.fail(
                f"bench_{self._first} and bench_{kind} share {self._port}, but their line"
                f" formats differ ({first[0]} 8{first[1]}1 and {baudrate} 8{parity}1): give"
                " the line's with --benchbus-baudrate and --benchbus-parity",
                pytrace=False,
            )
        return self._bus, self._settings.unit(kind), family(kind).line.timeout

    def close(self) -> None:
        """Close the Bus if it was opened."""
        if self._bus is not None:
            self._bus.close()


@pytest.fixture
def _benchbus_line(pytestconfig: pytest.Config) -> Iterator[_Line]:
    """The real port, shared by the ``bench_*`` devices of a test (only with a port)."""
    settings = pytestconfig.stash[_SETTINGS]
    assert settings.port is not None
    line = _Line(settings, settings.port)
    try:
        yield line
    finally:
        line.close()


def _real_line(request: pytest.FixtureRequest) -> _Line | None:
    """The test's real port, or None to simulate."""
    if request.config.stash[_SETTINGS].port is None:
        return None
    line: _Line = request.getfixturevalue("_benchbus_line")
    return line


@contextlib.contextmanager
def _in_use(device: DevT) -> Iterator[DevT]:
    """``device``; afterwards a motor stopped (unless its Bus was closed), then closed."""
    try:
        yield device
    finally:
        if isinstance(device, MotorDevice) and not device.bus.closed:
            device.__exit__(None, None, None)  # stops, then closes, as leaving `with` does
        else:
            device.close()


def _bench(request: pytest.FixtureRequest, of: Family) -> Iterator[Any]:
    """The device of the family ``of`` under test: on ``--benchbus-port`` with the family's
    timeout, else on the simulated ``sim_<key>_model``; in use until the test ends (see
    :func:`_in_use`)."""
    line = _real_line(request)
    if line is None:
        model = request.getfixturevalue(f"sim_{of.key}_model")
        with _simulated(of, model) as bench, _in_use(bench.device):
            yield bench.device
    else:
        bus, unit, timeout = line.open(of.key)
        options = {}
        if of.device is not None and of.device.IDENTITY is not None:
            options["check_identity"] = request.config.stash[_SETTINGS].check_identity
        with _in_use(of.open(bus, unit, timeout=timeout, **options)) as device:
            # A wrong device fails the test's setup; an absent one is checked when it answers.
            with contextlib.suppress(ResponseTimeout, FrameError):
                device.verify_identity()
            yield device


# ---- each family's fixtures ----------------------------------------------------------------------


def _add_fixtures(of: Family) -> None:
    """Add the fixtures of the family ``of`` to this module, where pytest finds them:
    ``sim_<key>_model`` (its simulated unit, made as its registry row says),
    ``sim_<key>`` (that unit on a simulator, with the device on it) and ``bench_<key>`` (the
    device under test, real or simulated)."""
    kind, cls = of.key, f":class:`benchbus.{getattr(of.device, '__name__', '')}`"
    noun = of.name.split(" ", 1)[-1]  # "a BLD drive": "BLD drive"
    keywords = ", ".join(f"{key}={value!r}" for key, value in of.bench_model.items())

    def model() -> SimDevice:
        _require_sim()
        return of.simulate(**of.bench_model)

    def simulated(request: pytest.FixtureRequest) -> Iterator[SimBench[Any, Any]]:
        with _simulated(of, request.getfixturevalue(f"sim_{kind}_model")) as bench:
            yield bench

    def bench(request: pytest.FixtureRequest) -> Iterator[BusDevice]:
        yield from _bench(request, of)

    docs: dict[str, tuple[Callable[..., object], str]] = {
        f"sim_{kind}_model": (
            model,
            f"The simulated {noun} for ``sim_{kind}`` / ``bench_{kind}``: "
            f"``benchbus.sim.{of.simulator}({keywords})``. Override to change.",
        ),
        f"sim_{kind}": (
            simulated,
            f"The {noun} of ``sim_{kind}_model`` on a simulator, as a :class:`SimBench`: "
            f"``.device`` ({cls}), ``.sim``, ``.model``. Closed and stopped after.",
        ),
        f"bench_{kind}": (
            bench,
            f"The {noun} under test ({cls}): on ``--benchbus-port``, or the simulated "
            f"``sim_{kind}_model``. Stopped (a motor) and closed after.",
        ),
    }
    for name, (function, doc) in docs.items():
        function.__name__ = function.__qualname__ = name
        function.__doc__ = doc
        globals()[name] = pytest.fixture(function)


for _family in FAMILIES:
    if _family.device is not None:
        _add_fixtures(_family)
