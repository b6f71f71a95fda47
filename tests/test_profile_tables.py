"""The example profiles read two ways, held together: by the core's parser
(``bb.Profile``) and by the simulator's own reader (``sim.ProfileDevice``, the
oracle). For every readable register, the raw words the simulator holds at the core's
address, in the core's table, decoded by the core's type, order, scale and offset, are the
value the simulator gives for it; names, units, the line and the limits agree too."""

from __future__ import annotations

from pathlib import Path

import pytest

import benchbus as bb
from benchbus.sim import ProfileDevice

PROFILES = sorted((Path(__file__).resolve().parent.parent / "examples" / "profiles").glob("*.toml"))
WIDTH = {"u16": 1, "i16": 1, "u32": 2, "i32": 2, "u64": 4, "i64": 4, "f32": 2, "f64": 4}


def words(sim: ProfileDevice, row: bb.ProfileRegister, count: int) -> list[int]:
    table = sim.registers if row.table == "holding" else sim.input_registers
    return list(table[row.address : row.address + count])


def raw_value(sim: ProfileDevice, row: bb.ProfileRegister) -> object:
    """What the simulator holds for ``row``, decoded as the core declares it."""
    if row.table in ("coil", "discrete"):
        bits = sim.coils if row.table == "coil" else sim.discrete_inputs
        return bool(bits[row.address])
    if row.type == "bool":
        word = words(sim, row, 1)[0]
        return bool(word >> row.bit & 1) if row.bit is not None else word != 0
    if row.type == "string":
        data = b"".join(w.to_bytes(2, "big") for w in words(sim, row, row.length))
        return data.rstrip(b"\0").decode("latin-1")
    (number,) = bb.from_registers(words(sim, row, WIDTH[row.type]), row.type, row.order)
    if row.enum:
        return row.enum[number]
    return number * row.scale + row.offset


@pytest.mark.parametrize("path", PROFILES, ids=[p.stem for p in PROFILES])
def test_the_core_and_the_simulator_read_a_profile_alike(path: Path) -> None:
    profile = bb.Profile(path)
    sim = ProfileDevice(path)
    rows = profile.registers
    assert tuple(r.name for r in rows) == tuple(sim.names)
    assert profile.name == sim.name and profile.description == sim.description
    assert {k: profile.line._asdict()[k] for k in sim.line} == sim.line
    assert {k: profile.limits._asdict()[k] for k in sim.limits} == sim.limits
    checked = 0
    for row in rows:
        assert sim.unit_of(row.name) == row.unit, row.name
        if row.access == "w":
            continue
        held = sim.value(row.name)
        ours = raw_value(sim, row)
        if isinstance(held, float):
            assert ours == pytest.approx(held, rel=1e-6, abs=1e-9), row.name
        else:
            assert ours == held, row.name
        checked += 1
    assert checked >= len(rows) - 2


def test_every_example_profile_is_checked() -> None:
    assert {p.stem for p in PROFILES} == {"xy_md02", "relay_board", "flow_controller"}
