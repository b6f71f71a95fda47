"""Every device with a register table reads and writes by name with the same verbs: ``get``,
``set``, ``get_many`` and ``set_many`` (and ``profile``, ``units``, ``sample``). Checked on
each family's simulator and on a profile's, the words read back by address with the Bus's
raw reads (the manuals' addresses), not through the names."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import benchbus as bb
from benchbus._families import family
from benchbus.sim import ProfileDevice, Simulator

#: For each family: two writable registers, each (value, its address, the word written).
WRITES: dict[str, dict[str, tuple[float, int, int]]] = {
    "drive": {"speed_setpoint": (1200, 0x2001, 1200), "accel_time": (2.5, 0x2003, 25)},
    "pbl": {"pole_pairs": (4, 205, 4), "acceleration": (500, 209, 500)},
    "j2": {"AL1": (12.5, 0x0008, 125), "AL2": (-3.0, 0x000A, 0x10000 - 30)},
    "profile": {"setpoint": (350, 0x0010, 350), "gain": (2.5, 0x0011, 5)},
}

PROFILE = """\
[device]
name = "verbs"
[[register]]
name = "setpoint"
address = 0x0010
max = 1000
[[register]]
name = "gain"
address = 0x0011
scale = 0.5
max = 100
[[register]]
name = "temperature"
address = 0x0012
type = "i16"
scale = 0.1
access = "r"
"""


@contextlib.contextmanager
def device_of(kind: str, tmp_path: Path, **options: Any) -> Iterator[Any]:
    """The device of ``kind`` at unit 1 on its simulator (given ``options``)."""
    if kind == "profile":
        path = tmp_path / "verbs.toml"
        path.write_text(PROFILE, encoding="utf-8")
        with (
            Simulator({1: ProfileDevice(path)}) as sim,
            bb.Device.from_profile(path, sim.port, unit=1) as device,
        ):
            yield device
        return
    of = family(kind)
    model = of.simulate(**{**of.bench_model, **options})
    with Simulator({1: model}, baudrate=of.line.baudrate) as sim:
        device = of.open(sim.port, 1, **of.opened_with(model))
        try:
            yield device
        finally:
            device.close()


@pytest.mark.parametrize("kind", WRITES)
def test_set_many_writes_each_value_and_get_many_reads_them_back(kind: str, tmp_path: Path) -> None:
    writes = WRITES[kind]
    with device_of(kind, tmp_path) as device:
        device.set_many({name: value for name, (value, _, _) in writes.items()})
        for value, address, word in writes.values():
            assert device.bus.read_holding_registers(1, address, 1) == [word], (address, value)
        names = list(writes)
        got = device.get_many(reversed(names))
        assert list(got) == names[::-1]  # in the order asked
        assert got == {name: value for name, (value, _, _) in writes.items()}
        assert got == {name: device.get(name) for name in names}
        # Pairs too, and one value each: the same as set.
        (first, (value, address, _)), *_ = writes.items()
        device.set_many([(first, 0)])
        assert device.bus.read_holding_registers(1, address, 1) == [0]
        device.set(first, value)
        assert device.get_many([first]) == {first: value}


@pytest.mark.parametrize("kind", WRITES)
def test_a_refused_value_in_set_many_leaves_every_register_as_it_was(
    kind: str, tmp_path: Path
) -> None:
    writes = WRITES[kind]
    with device_of(kind, tmp_path) as device:
        before = {a: device.bus.read_holding_registers(1, a, 1) for _, a, _ in writes.values()}
        first, last = list(writes)
        with pytest.raises(ValueError, match=last):
            device.set_many({first: writes[first][0], last: 10**6})  # beyond its range
        after = {a: device.bus.read_holding_registers(1, a, 1) for _, a, _ in writes.values()}
        assert after == before


@pytest.mark.parametrize("kind", WRITES)
def test_every_device_with_a_table_has_the_same_verbs(kind: str, tmp_path: Path) -> None:
    with device_of(kind, tmp_path) as device:
        for verb in ("get", "set", "get_many", "set_many", "sample", "units"):
            assert callable(getattr(device, verb)), verb
        assert isinstance(device.profile, bb.Profile)
        # The profile's rows are the names get and set take, with their units.
        assert set(device.units()) == {r.name for r in device.profile.registers}


#: For each family: registers at neighbouring addresses (the J2's tables hold a parameter
#: every other address, and its file reads across the empty ones), which ``get_many`` reads
#: in one request, and one far from them, which takes a request of its own. (A drive that
#: refuses block reads is read one register a request: ``tests/drive_logic.rs``.)
NEIGHBOURS: dict[str, tuple[list[str], str]] = {
    "drive": (["pole_pairs", "speed_setpoint", "accel_time"], "state"),
    "pbl": (["speed_gain", "pole_pairs", "p2_group_switch"], "status"),
    "j2": (["AL2", "AL1"], "AM"),
    "profile": (["gain", "setpoint", "temperature"], ""),
}


@pytest.mark.parametrize("kind", NEIGHBOURS)
def test_get_many_reads_neighbouring_registers_in_one_request(kind: str, tmp_path: Path) -> None:
    near, far = NEIGHBOURS[kind]
    options = {"single_register_reads": False} if kind == "drive" else {}
    with device_of(kind, tmp_path, **options) as device:
        alone = {name: device.get(name) for name in near}
        before = device.bus.stats.transactions
        assert device.get_many(near) == alone
        assert device.bus.stats.transactions - before == 1
        if far:
            before = device.bus.stats.transactions
            got = device.get_many([*near, far])
            assert got == {**alone, far: device.get(far)}
            assert device.bus.stats.transactions - before == 2 + 1  # two plans, one get
