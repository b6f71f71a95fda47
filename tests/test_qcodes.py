"""benchbus.qcodes: devices described by the example profiles as QCoDeS instruments, each
against its simulator (benchbus.sim.ProfileDevice, which reads the profile itself): the
parameters' unit, label and validators, get and set against the simulator's values, values
refused before anything is sent, and a QCoDeS Measurement whose dataset holds what the
simulator held. (Python 3.11 and later: QCoDeS needs it; conftest.py leaves this file out
before.)"""

from __future__ import annotations

import enum
import math
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import qcodes
from qcodes import validators as vals
from qcodes.dataset import (
    Measurement,
    initialise_or_create_database_at,
    load_by_id,
    load_or_create_experiment,
)
from qcodes.instrument import Instrument

import benchbus as bb
from benchbus.qcodes import DeviceInstrument, Members, instrument
from benchbus.sim import DriveDevice, J2Device, PblDevice, ProfileDevice, SimDevice, Simulator
from conftest import crc

PROFILES = Path(__file__).resolve().parent.parent / "examples" / "profiles"
SENSOR = PROFILES / "xy_md02.toml"
RELAYS = PROFILES / "relay_board.toml"
CONTROLLER = PROFILES / "flow_controller.toml"

Rig = tuple[Simulator[ProfileDevice], DeviceInstrument, ProfileDevice]


@pytest.fixture(autouse=True)
def close_instruments() -> Iterator[None]:
    """Every test leaves QCoDeS without an open instrument, so that names are free."""
    yield
    Instrument.close_all()
    assert list(Instrument._all_instruments) == []


def rig(path: Path, name: str, **values: object) -> Iterator[Rig]:
    model = ProfileDevice(path, values=values)
    with Simulator({1: model}) as sim, bb.Bus(sim.port, timeout=0.5) as bus:
        yield sim, instrument(bb.Device.from_profile(path, bus), name), model
        assert sim.errors == []


@pytest.fixture
def sensor() -> Iterator[Rig]:
    yield from rig(SENSOR, "sensor", temperature=-12.3)


@pytest.fixture
def relays() -> Iterator[Rig]:
    yield from rig(RELAYS, "relays")


@pytest.fixture
def controller() -> Iterator[Rig]:
    yield from rig(CONTROLLER, "fc")


def frame(*pdu: int) -> bytes:
    body = bytes([1, *pdu])
    return body + crc(body)


def same(got: object, held: object) -> bool:
    """A value read through QCoDeS is what the simulator holds (an enum member by name)."""
    if isinstance(got, float):
        return isinstance(held, (int, float)) and math.isclose(got, held, rel_tol=1e-6)
    if isinstance(got, enum.IntEnum):
        return got.name == held
    return type(got) is type(held) and got == held


# ---- one parameter per register, as the profile describes it -----------------------------


@pytest.mark.parametrize("path", [SENSOR, RELAYS, CONTROLLER], ids=lambda p: p.stem)
def test_every_register_is_a_parameter_with_its_unit_label_and_access(path: Path) -> None:
    profile = bb.Profile(path)
    with Simulator({1: ProfileDevice(path)}) as sim, bb.Bus(sim.port) as bus:
        inst = instrument(bb.Device.from_profile(path, bus), "dev")
        assert list(inst.parameters) == ["IDN", *(r.name for r in profile.registers)]
        for register in profile.registers:
            param = inst.parameters[register.name]
            assert param.full_name == f"dev_{register.name}"
            assert param.unit == register.unit
            assert param.label == (register.description or register.name)
            assert param.gettable is (register.access != "w")
            assert param.settable is (register.access != "r")
            assert param.metadata == {
                "table": register.table,
                "address": register.address,
                "type": register.type,
                "access": register.access,
            }
        assert inst.label == profile.name
        assert inst.metadata["benchbus"] == {
            "profile": profile.name,
            "description": profile.description,
            "unit": 1,
        }
        assert inst.IDN() == {
            "vendor": None,
            "model": profile.name,
            "serial": None,
            "firmware": None,
        }
        assert sim.requests == []  # made from the profile: nothing was read


def test_validators_follow_each_registers_kind_and_range(
    sensor: Rig, relays: Rig, controller: Rig
) -> None:
    s, r, c = sensor[1], relays[1], controller[1]

    def numbers(param: object) -> tuple[float, float]:
        validator = param.vals  # type: ignore[attr-defined]
        assert type(validator) is vals.Numbers
        return validator.min_value, validator.max_value

    def ints(param: object) -> tuple[int, int]:
        validator = param.vals  # type: ignore[attr-defined]
        assert type(validator) is vals.Ints
        return validator.min_value, validator.max_value

    assert numbers(s.temperature) == (-40.0, 125.0)
    assert numbers(s.humidity) == (0.0, 100.0)
    assert numbers(s.temperature_correction) == (-10.0, 10.0)
    assert ints(s.unit_address) == (1, 247)
    assert isinstance(s.baud.vals, Members)
    assert s.baud.vals.members == {0: "b9600", 1: "b14400", 2: "b19200"}
    assert s.baud.vals.values == {0, 1, 2, "b9600", "b14400", "b19200"}
    assert type(r.relay1.vals) is vals.Bool and type(r.all_off.vals) is vals.Bool
    assert ints(r.board_address) == (0, 0xFFFF)  # the type's range where the file gives none
    assert numbers(c.setpoint) == (0.0, 200.0)
    assert numbers(c.gain) == (0.5, 2.0)
    assert numbers(c.total) == (0.0, pytest.approx(0xFFFF_FFFF / 100))  # scaled: a float
    assert numbers(c.gas_temperature) == pytest.approx((-(2**31) / 100 - 273.15, 21474563.32))
    assert ints(c.zero_offset) == (-1_000_000, 1_000_000)
    assert ints(c.runtime) == (0, 2**64 - 1)  # exactly, though the profile's float is 2**64
    assert ints(c.reset_total) == (0, 1)
    assert type(c.device_name.vals) is vals.Strings
    assert c.device_name.vals.max_length == 16  # two characters a register


# ---- get and set against the simulator ---------------------------------------------------


def test_a_shipped_profile_by_name_gives_its_maker_and_model_as_the_idn() -> None:
    model = ProfileDevice("pzem-016", values={"voltage": 231.4})
    with Simulator({1: model}) as sim, bb.Bus(sim.port, timeout=0.5) as bus:
        inst = instrument(bb.Device.from_profile("pzem-016", bus), "mains")
        profile = bb.Profile("pzem-016")
        assert inst.IDN() == {
            "vendor": "Peacefair",
            "model": profile.model,
            "serial": None,
            "firmware": None,
        }
        assert inst.voltage() == pytest.approx(231.4) and inst.voltage.unit == "V"
        assert sim.errors == []


@pytest.mark.parametrize("path", [SENSOR, RELAYS, CONTROLLER], ids=lambda p: p.stem)
def test_every_readable_register_reads_what_the_simulator_holds(path: Path) -> None:
    model = ProfileDevice(path)
    with Simulator({1: model}) as sim, bb.Bus(sim.port, timeout=0.5) as bus:
        inst = instrument(bb.Device.from_profile(path, bus), "dev")
        readable = [r.name for r in bb.Profile(path).registers if r.access != "w"]
        for name in readable:
            got = inst.parameters[name]()
            assert same(got, model.value(name)), (name, got, model.value(name))
            assert inst.parameters[name].cache.get(get_if_invalid=False) == got
        assert sim.errors == []


def test_get_follows_the_simulator(sensor: Rig, relays: Rig) -> None:
    _, s, model = sensor
    assert s.temperature() == pytest.approx(-12.3)
    model.set_value("humidity", 61.7)
    assert s.humidity() == pytest.approx(61.7)
    baud = s.baud()
    assert baud is s.device.enums["baud"].b9600  # type: ignore[attr-defined]
    _, r, board = relays
    board.set_value("input3", True)
    assert r.input3() is True and r.input4() is False


def test_set_writes_to_the_simulator(sensor: Rig, relays: Rig, controller: Rig) -> None:
    sim, s, model = sensor
    before = len(sim.requests)
    s.temperature_correction(-1.5)
    assert list(sim.requests[before:]) == [frame(0x06, 0x01, 0x03, 0xFF, 0xF1)]  # -15 tenths
    assert model.value("temperature_correction") == pytest.approx(-1.5)
    s.baud("b19200")
    assert model.value("baud") == "b19200"
    s.baud(0)
    assert model.value("baud") == "b9600"
    s.baud(s.device.enums["baud"].b14400)  # type: ignore[attr-defined]
    assert model.value("baud") == "b14400"
    s.unit_address(np.int64(17))  # a sweep's numpy scalar goes as the number it holds
    assert model.value("unit_address") == 17

    _, r, board = relays
    r.relay2(True)
    r.relay8(True)  # write-only
    r.all_on(np.bool_(True))
    assert board.value("relay2") is True and board.value("relay8") is True
    assert board.value("all_on") is True and board.value("all_off") is False

    _, c, flow = controller
    c.setpoint(np.float64(120.5))
    c.zero_offset(-1000)
    c.device_name("line 3")
    c.mode("purge")
    assert flow.value("setpoint") == pytest.approx(120.5)
    assert flow.value("zero_offset") == -1000
    assert flow.value("device_name") == "line 3"
    assert flow.value("mode") == "purge"
    assert c.setpoint.cache.get(get_if_invalid=False) == 120.5


def test_validators_refuse_before_anything_is_sent(
    sensor: Rig, relays: Rig, controller: Rig
) -> None:
    sims = [rig_[0] for rig_ in (sensor, relays, controller)]
    before = [len(sim.requests) for sim in sims]
    s, r, c = sensor[1], relays[1], controller[1]
    refused: list[tuple[type[Exception], str, object, object]] = [
        (ValueError, "between 1 and 247", s.unit_address, 248),
        (TypeError, "is not an int", s.unit_address, 5.0),
        (ValueError, "between -10.0 and 10.0", s.temperature_correction, 10.5),
        (ValueError, "is not in", s.baud, "b115200"),
        (ValueError, "is not in", s.baud, 3),
        (TypeError, "not a member's name or number", s.baud, True),
        (TypeError, "not a member's name or number", s.baud, 1.0),
        (TypeError, "is not Boolean", r.relay3, 1),
        (TypeError, "is not Boolean", r.relay8, "on"),
        (ValueError, "between 0.5 and 2.0", c.gain, 2.5),
        (ValueError, "between 0.0 and 200.0", c.setpoint, -1.0),
        (ValueError, "between -1000000 and 1000000", c.zero_offset, 1_000_001),
        (ValueError, "length must be between 0 and 16", c.device_name, "x" * 17),
        (TypeError, "is not a string", c.device_name, 7),
        (ValueError, "between 0 and 1", c.reset_total, 2),
    ]
    for error, message, param, value in refused:
        with pytest.raises(error, match=message):
            param(value)  # type: ignore[operator]
    # The device's own checks stand behind the validators: a step off the scale.
    with pytest.raises(ValueError, match=r"steps of 0\.1 degC"):
        s.temperature_correction(0.25)
    assert [len(sim.requests) for sim in sims] == before
    assert sensor[2].value("unit_address") == 1 and sensor[2].value("baud") == "b9600"
    assert controller[2].value("gain") == 1.0


def test_read_only_has_no_set_and_write_only_no_get(sensor: Rig, relays: Rig) -> None:
    sim, s, model = sensor
    before = len(sim.requests)
    assert not s.temperature.settable and not hasattr(s.temperature, "set")
    with pytest.raises(NotImplementedError, match="no set cmd"):
        s.temperature(20.0)
    assert sim.requests[before:] == [] and model.value("temperature") == pytest.approx(-12.3)
    board_sim, r, _ = relays
    before = len(board_sim.requests)
    assert not r.relay8.gettable and r.relay8.settable
    with pytest.raises(NotImplementedError, match="no get cmd"):
        r.relay8()
    assert board_sim.requests[before:] == []


class Registers:
    """Not a ``bb.Device``: only what :func:`instrument` asks of a device (``profile``, ``get``
    and ``set``), as every benchbus device has them, here passed on to a device on the
    simulator."""

    def __init__(self, dev: bb.Device) -> None:
        self.profile = dev.profile
        self._dev = dev

    def get(self, name: str) -> object:
        return self._dev.get(name)

    def set(self, name: str, value: object) -> None:
        self._dev.set(name, value)


def test_any_device_with_a_profile_get_and_set_is_wrapped(controller: Rig) -> None:
    sim, fc, model = controller
    inst = instrument(Registers(fc.device), "registers", close_device=True)  # type: ignore[arg-type]
    assert list(inst.parameters) == list(fc.parameters)
    assert inst.metadata["benchbus"]["unit"] is None  # it has no unit to say
    assert inst.gain.vals.min_value == 0.5  # type: ignore[union-attr]
    inst.gain(1.25)
    assert model.value("gain") == 1.25
    assert inst.flow() == pytest.approx(49.75)
    inst.close()  # handed over, but it has no close(): nothing more to do
    assert not Instrument.exist("registers") and not fc.device.bus.closed  # type: ignore[attr-defined]
    assert sim.errors == []


# ---- a QCoDeS measurement -------------------------------------------------------------


@pytest.fixture
def database(tmp_path: Path) -> Iterator[Path]:
    """A QCoDeS database of the test's own; QCoDeS's default one is given back afterwards."""
    previous = qcodes.config.core.db_location
    path = tmp_path / "bench.db"
    initialise_or_create_database_at(path)
    yield path
    qcodes.config.core.db_location = previous


def test_a_measurement_sweeps_a_register_and_saves_what_the_simulator_held(
    controller: Rig, database: Path
) -> None:
    sim, fc, model = controller
    experiment = load_or_create_experiment("flow sweep", sample_name="FC-200")
    meas = Measurement(exp=experiment, name="setpoint sweep")
    meas.register_parameter(fc.setpoint)
    for measured in (fc.flow, fc.total, fc.mode):
        meas.register_parameter(measured, setpoints=(fc.setpoint,))
    setpoints = np.linspace(0.0, 200.0, 5)  # numpy floats, as a sweep has them
    held: dict[str, list[float]] = {"setpoint": [], "flow": [], "total": [], "mode": []}
    modes = ["control", "purge", "close", "control", "off"]
    numbers = {name: n for n, name in bb.Profile(CONTROLLER)["mode"].enum.items()}
    with meas.run() as saver:
        for i, value in enumerate(setpoints):
            fc.setpoint(value)
            # The simulated controller: its flow follows the setpoint, its totaliser counts.
            model.set_value("flow", 0.98 * float(value))
            model.set_value("total", 1234.56 + 10 * i)
            model.set_value("mode", modes[i])
            saver.add_result(
                (fc.setpoint, value),
                (fc.flow, fc.flow()),
                (fc.total, fc.total()),
                (fc.mode, fc.mode()),
            )
            held["setpoint"].append(model.value("setpoint"))
            held["flow"].append(model.value("flow"))
            held["total"].append(model.value("total"))
            held["mode"].append(numbers[model.value("mode")])
        run_id = saver.run_id
    dataset = load_by_id(run_id)  # read back from the database file
    assert Path(dataset.path_to_db) == database
    data = dataset.get_parameter_data()
    assert set(data) == {"fc_flow", "fc_total", "fc_mode"}
    for name in ("flow", "total", "mode"):
        column = data[f"fc_{name}"]
        assert column["fc_setpoint"] == pytest.approx(setpoints)
        assert column[f"fc_{name}"] == pytest.approx(np.array(held[name], dtype=float))
    assert held["setpoint"] == pytest.approx(setpoints)  # each value reached the simulator
    specs = {spec.name: spec for spec in dataset.get_parameters()}
    assert (specs["fc_flow"].unit, specs["fc_flow"].label) == (
        "sccm",
        "measured flow (process value)",
    )
    assert specs["fc_setpoint"].unit == "sccm" and specs["fc_mode"].type == "numeric"
    assert sim.errors == []


# ---- names, closing, what is refused ------------------------------------------------------


def test_a_name_is_open_once_and_close_frees_it_leaving_a_shared_bus_open(sensor: Rig) -> None:
    _, inst, model = sensor
    dev = inst.device
    with pytest.raises(KeyError, match="Another instrument has the name: sensor"):
        instrument(dev, "sensor")
    assert Instrument.find_instrument("sensor") is inst
    inst.close()
    assert not Instrument.exist("sensor")
    assert not dev.bus.closed  # type: ignore[attr-defined]
    model.set_value("humidity", 50.5)
    assert dev.get("humidity") == pytest.approx(50.5)
    again = instrument(dev, "sensor")
    assert again.humidity() == pytest.approx(50.5)


@pytest.mark.parametrize(
    ("own_port", "close_device", "bus_closed"),
    [(True, True, True), (True, False, False), (False, True, False)],
    ids=["own port, handed over", "own port, kept", "shared bus, handed over"],
)
def test_close_device_closes_only_a_bus_the_device_opened(
    own_port: bool, close_device: bool, bus_closed: bool
) -> None:
    with Simulator({1: ProfileDevice(SENSOR)}) as sim:
        shared = None if own_port else bb.Bus(sim.port)
        dev = bb.Device.from_profile(SENSOR, shared or sim.port)
        inst = instrument(dev, "sensor", close_device=close_device)
        assert inst.humidity() == pytest.approx(45.0)
        inst.close()
        assert dev.bus.closed is bus_closed
        dev.close()
        if shared is not None:
            assert not shared.closed  # the device never closes a Bus it was given
            shared.close()


def test_what_is_not_a_device_or_not_a_name_is_refused(sensor: Rig) -> None:
    with pytest.raises(TypeError, match=r"benchbus device \(with \.profile, \.get and \.set\)"):
        instrument(object(), "thing")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="invalid instrument identifier"):
        instrument(sensor[1].device, "two words")
    text = '[device]\nname = "x"\n[[register]]\nname = "IDN"\naddress = 0\n'
    dev = bb.Device.from_profile(bb.Profile.parse(text), sensor[1].device.bus)  # type: ignore[attr-defined]
    with pytest.raises(ValueError, match="may not be called 'IDN'"):
        instrument(dev, "thing")
    assert not Instrument.exist("thing")


def test_a_register_named_like_an_instrument_attribute_is_in_parameters(sensor: Rig) -> None:
    text = '[device]\nname = "x"\n[[register]]\nname = "label"\naddress = 0x0101\n'
    inst = sensor[1]
    dev = bb.Device.from_profile(bb.Profile.parse(text), inst.device.bus)  # type: ignore[attr-defined]
    other = instrument(dev, "other")
    assert other.label == "x"  # the instrument's own
    assert other.parameters["label"]() == 1  # the register: the sensor's unit_address


def test_without_qcodes_the_module_imports_and_says_what_to_install() -> None:
    script = (
        "import sys\n"
        "sys.modules['qcodes'] = None\n"  # as if it were not installed
        "import benchbus.qcodes as q\n"
        "for attempt in (lambda: q.instrument(object(), 'x'), lambda: q.DeviceInstrument):\n"
        "    try:\n"
        "        attempt()\n"
        "    except ImportError as exc:\n"
        "        print(exc)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True, timeout=60
    ).stdout.splitlines()
    assert len(out) == 2
    assert all("pip install 'benchbus[qcodes]'" in line for line in out)


# ---- the built-in devices, from their family's profile -----------------------------------------


@pytest.fixture(scope="module")
def families() -> Iterator[tuple[Simulator[Any], bb.Bus]]:
    frozen = lambda: 0.0  # noqa: E731 (no motor or process moves between two reads)
    devices: dict[int, SimDevice] = {
        1: DriveDevice(single_register_reads=False, clock=frozen),
        3: J2Device(clock=frozen),
        0x11: PblDevice(clock=frozen),
    }
    with Simulator(devices) as sim, bb.Bus(sim.port, timeout=0.5) as bus:
        yield sim, bus
        assert not sim.errors


@pytest.mark.parametrize(
    ("make", "setting", "value", "above"),
    [
        (lambda bus: bb.Drive(bus, 1), "speed_setpoint", 1500, 10**6),
        (lambda bus: bb.PblDrive(bus, 0x11), "max_speed", 2500, 10**6),
        (lambda bus: bb.J2Controller(bus, 3), "SV", 120.5, 10**6),
    ],
    ids=["drive", "pbl", "j2"],
)
def test_the_built_in_devices_are_wrapped_the_same_way(
    families: tuple[Simulator[Any], bb.Bus], make: Any, setting: str, value: float, above: float
) -> None:
    sim, bus = families
    dev = make(bus)
    inst = instrument(dev, f"builtin_{dev.unit}")
    rows = dev.profile.registers
    assert [p for p in inst.parameters if p != "IDN"] == [r.name for r in rows]
    for row in rows:
        parameter = inst.parameters[row.name]
        assert parameter.unit == row.unit, row.name
        assert parameter.settable == (row.access != "r"), row.name
        if row.access != "w":
            got = parameter()
            want = dev.get(row.name)
            assert math.isclose(got, want, abs_tol=1e-9) if isinstance(got, float) else got == want
    inst.parameters[setting](value)
    assert dev.get(setting) == pytest.approx(value)  # through the family's own rules
    sent = len(sim.requests)
    with pytest.raises(ValueError):
        inst.parameters[setting](above)
    assert sim.requests[sent:] == []
    read_only = next(r.name for r in rows if r.access == "r")
    with pytest.raises(NotImplementedError):
        inst.parameters[read_only](0)
