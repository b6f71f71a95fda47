"""A typo in an attribute name is an error: every device class refuses to take a new
attribute once it is made, names the closest ones, and sends nothing; subclasses that set
their own attributes in ``__init__`` (or declare them on the class) keep working, and the
simulated devices are not affected."""

from __future__ import annotations

import asyncio
from collections.abc import Iterator

import pytest

import benchbus as bb
from benchbus.sim import (
    Atv31Device,
    DriveDevice,
    J2Device,
    PblDevice,
    RegisterDevice,
    Simulator,
    TaisongDevice,
)

DRIVE, PBL, J2, METER = 1, 2, 3, 4


@pytest.fixture(scope="module")
def bench() -> Iterator[tuple[Simulator, bb.Bus]]:
    devices = {DRIVE: DriveDevice(), PBL: PblDevice(), J2: J2Device(), METER: TaisongDevice()}
    with Simulator(devices) as sim, bb.Bus(sim.port, timeout=0.5) as bus:
        yield sim, bus


def make(kind: str, bus: bb.Bus) -> bb.Drive | bb.PblDrive | bb.J2Controller | bb.Instrument:
    if kind == "Drive":
        return bb.Drive(bus, DRIVE)
    if kind == "PblDrive":
        return bb.PblDrive(bus, PBL)
    if kind == "J2Controller":
        return bb.J2Controller(bus, J2)
    return bb.Instrument(bus, METER)


@pytest.mark.parametrize(
    ("kind", "typo", "meant"),
    [
        ("Drive", "spped_setpoint", "speed_setpoint"),
        ("Drive", "Accel_Time", "accel_time"),
        ("PblDrive", "speed_setpiont", "speed_setpoint"),
        ("PblDrive", "DIRECTION_SETTING", "direction_setting"),
        ("J2Controller", "SV", "sv"),
        ("J2Controller", "pv_ofset", "pv_offset"),
        ("Instrument", "min_write_intervall", "min_write_interval"),
    ],
)
def test_a_typo_is_refused_with_the_closest_name(
    bench: tuple[Simulator, bb.Bus], kind: str, typo: str, meant: str
) -> None:
    sim, bus = bench
    device = make(kind, bus)
    sent = len(sim.requests)
    with pytest.raises(AttributeError, match=f"did you mean '{meant}'") as caught:
        setattr(device, typo, 150)
    message = str(caught.value)
    assert f"'{kind}' object has no attribute '{typo}'" in message
    assert caught.value.name == typo
    assert typo not in vars(device)
    assert len(sim.requests) == sent  # and nothing was sent


def test_the_controller_keeps_its_setpoint(bench: tuple[Simulator, bb.Bus]) -> None:
    sim, bus = bench
    j2 = bb.J2Controller(bus, J2)
    j2.sv = 120.0
    with pytest.raises(AttributeError, match="did you mean 'sv'"):
        j2.SV = 150  # type: ignore[attr-defined]
    assert j2.sv == 120.0
    assert sim.peek(J2, 6) == [1200]  # SV at address 6, tenths
    drive = bb.Drive(bus, DRIVE)
    drive.speed_setpoint = 900
    with pytest.raises(AttributeError, match="did you mean 'speed_setpoint'"):
        drive.spped_setpoint = 1  # type: ignore[attr-defined]
    assert sim.peek(DRIVE, 0x2001) == [900]


def test_no_close_name_says_no_guess(bench: tuple[Simulator, bb.Bus]) -> None:
    _, bus = bench
    with pytest.raises(AttributeError) as caught:
        bb.Instrument(bus, METER).zzzz = 1  # type: ignore[attr-defined]
    assert str(caught.value) == "'Instrument' object has no attribute 'zzzz' to set"


def test_read_only_and_measured_names_keep_their_own_errors(
    bench: tuple[Simulator, bb.Bus],
) -> None:
    _, bus = bench
    j2 = bb.J2Controller(bus, J2)
    with pytest.raises(AttributeError, match="PV is a measurement"):
        j2.pv = 1.0  # type: ignore[misc]
    with pytest.raises(AttributeError, match="unit"):
        j2.unit = 2  # type: ignore[misc]


@pytest.mark.parametrize(
    ("kind", "typo", "meant"),
    [
        ("Drive", "sped", "speed"),
        ("Drive", "spped_setpoint", "speed_setpoint"),
        ("PblDrive", "pole_pair", "pole_pairs"),
        ("J2Controller", "pvv", "pv"),
        ("Instrument", "max_reed", "max_read"),
    ],
)
def test_reading_a_typo_names_the_closest_name(
    bench: tuple[Simulator, bb.Bus], kind: str, typo: str, meant: str
) -> None:
    sim, bus = bench
    device = make(kind, bus)
    sent = len(sim.requests)
    with pytest.raises(AttributeError, match=f"did you mean '{meant}'") as caught:
        getattr(device, typo)
    assert str(caught.value).startswith(f"'{kind}' object has no attribute '{typo}';")
    assert (caught.value.name, caught.value.obj) == (typo, device)
    assert len(sim.requests) == sent  # and nothing was sent


def test_asking_for_a_missing_name_stays_cheap_and_plain(bench: tuple[Simulator, bb.Bus]) -> None:
    _, bus = bench
    drive = bb.Drive(bus, DRIVE)
    assert not hasattr(drive, "zzzz")
    assert getattr(drive, "sped", None) is None
    with pytest.raises(AttributeError) as caught:
        drive._privat  # type: ignore[attr-defined]  # noqa: B018
    assert str(caught.value) == "'Drive' object has no attribute '_privat'"  # no search
    with pytest.raises(AttributeError) as caught:
        drive.__getstate_x__  # type: ignore[attr-defined]  # noqa: B018
    assert "did you mean" not in str(caught.value)
    with pytest.raises(AttributeError) as caught:
        drive.zzzz  # type: ignore[attr-defined]  # noqa: B018
    assert str(caught.value) == "'Drive' object has no attribute 'zzzz'"


@pytest.mark.parametrize(
    ("kind", "typo", "meant"),
    [
        ("Drive", "speed_setpont", "speed_setpoint"),
        ("PblDrive", "internal_sped", "internal_speed"),
        ("J2Controller", "SVV", "SV"),
        ("J2Controller", "pv_ofset", "PVOS"),
    ],
)
def test_get_and_set_of_an_unknown_register_name_the_closest(
    bench: tuple[Simulator, bb.Bus], kind: str, typo: str, meant: str
) -> None:
    sim, bus = bench
    device = make(kind, bus)
    assert not isinstance(device, bb.Instrument)
    sent = len(sim.requests)
    with pytest.raises(
        ValueError, match=f"no (register|parameter) \"{typo}\"; did you mean '{meant}'"
    ):
        device.get(typo)
    with pytest.raises(ValueError, match=f"did you mean '{meant}'"):
        device.set(typo, 1)
    assert len(sim.requests) == sent


def test_an_unknown_register_with_no_close_name_lists_or_says_nothing(
    bench: tuple[Simulator, bb.Bus],
) -> None:
    _, bus = bench
    with pytest.raises(ValueError) as caught:
        bb.Drive(bus, DRIVE).get("zzzz")
    assert str(caught.value).endswith('no register "zzzz"')
    with pytest.raises(ValueError, match="it has MV, PV, SV"):
        bb.J2Controller(bus, J2).get("zzzz")


def test_async_devices_name_the_closest_too() -> None:
    async def main(port: str) -> None:
        async with bb.aio.AsyncBus(port, timeout=0.5) as bus, bb.aio.Drive(bus, DRIVE) as drive:
            with pytest.raises(AttributeError, match="did you mean 'speed'"):
                drive.sped  # noqa: B018
            with pytest.raises(ValueError, match="did you mean 'speed_setpoint'"):
                await drive.get("speed_setpont")

    with Simulator({DRIVE: DriveDevice()}) as sim:
        asyncio.run(main(sim.port))


class LabelledDrive(bb.Drive):
    """A user's subclass: attributes of its own, set in ``__init__`` and later."""

    #: Declared on the class: may be set at any time.
    note: str

    def __init__(self, bus: bb.Bus, unit: int, label: str) -> None:
        super().__init__(bus, unit)
        self.label = label
        self.history: list[int] = []

    def run_at(self, rpm: int) -> None:
        self.speed_setpoint = rpm
        self.history.append(rpm)
        self.note = f"ran at {rpm}"


class Plain(bb.J2Controller):
    """A subclass without an ``__init__`` of its own."""

    default_sv = 50.0


def test_subclasses_set_their_own_attributes(bench: tuple[Simulator, bb.Bus]) -> None:
    sim, bus = bench
    drive = LabelledDrive(bus, DRIVE, "left wheel")
    assert drive.label == "left wheel"
    drive.label = "right wheel"  # set in __init__: may be set again
    drive.run_at(1200)
    assert (drive.history, drive.note, sim.peek(DRIVE, 0x2001)) == ([1200], "ran at 1200", [1200])
    with pytest.raises(AttributeError, match="did you mean 'label'"):
        drive.lable = "x"  # type: ignore[attr-defined]
    with pytest.raises(AttributeError, match="did you mean 'history'"):
        drive.histroy = []  # type: ignore[attr-defined]
    j2 = Plain(bus, J2)
    j2.default_sv = 60.0  # defined on the class
    with pytest.raises(AttributeError, match="did you mean 'default_sv'"):
        j2.default_SV = 1.0  # type: ignore[attr-defined]


def test_a_device_opened_on_a_port_is_guarded_too() -> None:
    with (
        Simulator({1: J2Device()}) as sim,
        bb.J2Controller(sim.port, 1) as j2,
        pytest.raises(AttributeError, match="did you mean 'sv'"),
    ):
        j2.Sv = 1.0  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    "device",
    [DriveDevice(), PblDevice(), J2Device(), TaisongDevice(), Atv31Device(), RegisterDevice()],
    ids=lambda d: type(d).__name__,
)
def test_simulated_devices_take_new_attributes(device: object) -> None:
    device.scratch = 5  # type: ignore[attr-defined]  # tests hang their own state on them
    assert device.scratch == 5  # type: ignore[attr-defined]
