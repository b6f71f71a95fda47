"""The built-in families exported as profiles: each export reads back as its family's own
table (the rows the Python classes give), and its addresses, scales and signedness are right
on the wire: a profile device reads the family's simulator as the family's class does, and
the family's class reads a ProfileDevice serving the export as that device holds it."""

from __future__ import annotations

import math
from collections.abc import Iterator
from importlib import resources
from pathlib import Path
from typing import Any

import pytest

import benchbus as bb
from benchbus.sim import DriveDevice, J2Device, PblDevice, ProfileDevice, SimDevice, Simulator

DRIVE, C20, PBL, J2 = 1, 2, 3, 4


def exported(key: str) -> bb.Profile:
    """The family ``key`` exported and read back, as a user's file would be."""
    return bb.Profile.parse(bb.Profile.family(key).to_toml(), f"{key}.toml")


def word_range(signed: bool, scale: float) -> tuple[float, float]:
    """What a register's word holds in engineering units."""
    low, high = (-32768, 32767) if signed else (0, 65535)
    return low * scale, high * scale


def check_row(row: bb.ProfileRegister, want: dict[str, Any]) -> None:
    """The exported ``row`` is the table's row ``want``; a read-only row's range is its
    word's, or its field's (the table says only that it takes no write)."""
    got = {
        "name": row.name,
        "address": row.address,
        "scale": row.scale,
        "unit": row.unit,
        "access": row.access,
        "signed": row.type == "i16",
    }
    assert got == {k: want[k] for k in got}, row.name
    assert (row.table, row.offset, row.enum) == ("holding", 0.0, {})
    if row.type == "bool":  # a flag of a status word: no range
        assert (row.min, row.max, want["access"]) == (None, None, "r"), row.name
        return
    low, high = (
        word_range(want["signed"], want["scale"])
        if want["access"] == "r"
        else (want["low"], want["high"])
    )
    if row.bits is not None:  # a field of a status word: what its bits hold
        low, high = 0, (1 << row.bits[1] - row.bits[0] + 1) - 1
    assert row.min == pytest.approx(low) and row.max == pytest.approx(high), row.name


ACCESS = {"R": "r", "W/R": "rw", "W/R*": "rw-stopped"}


@pytest.fixture(scope="module")
def bench() -> Iterator[tuple[Simulator[Any], bb.Bus]]:
    frozen = lambda: 0.0  # noqa: E731 (no motor or process moves between two reads)
    devices: dict[int, SimDevice] = {
        DRIVE: DriveDevice(single_register_reads=False, clock=frozen),
        C20: DriveDevice("C20", single_register_reads=False, clock=frozen),
        PBL: PblDevice(clock=frozen),
        J2: J2Device(clock=frozen),
    }
    with Simulator(devices) as sim, bb.Bus(sim.port, timeout=0.5) as bus:
        yield sim, bus
        assert not sim.errors


@pytest.mark.parametrize(
    ("key", "family", "unit"), [("drive", "BLD", DRIVE), ("drive-c20", "C20", C20)]
)
def test_the_drive_export_is_the_drive_table(
    bench: tuple[Simulator[Any], bb.Bus], key: str, family: str, unit: int
) -> None:
    drive = bb.Drive(bench[1], unit, family=family)
    table = drive.registers()
    profile = exported(key)
    assert [r.name for r in profile.registers] == [r.name for r in table]
    for row, want in zip(profile.registers, table):
        check_row(
            row,
            {
                **want._asdict(),
                "access": ACCESS[want.access],
                "signed": row.name == "temperature",
            },
        )
    assert drive.profile.to_toml() == bb.Profile.family(key).to_toml()
    line = profile.line
    assert (line.baudrate, line.parity, line.timeout) == tuple(bb.Drive.LINE_DEFAULTS[:3])


def test_the_pbl_export_is_the_pbl_table() -> None:
    table = bb.PblDrive.table()
    profile = exported("pbl")
    assert len(profile) == len(table) == 223
    for row, want in zip(profile.registers, table):
        check_row(
            row,
            {
                **want._asdict(),
                "address": want.number,
                "scale": 1.0,
                "access": ACCESS[want.access],
                "signed": False,
            },
        )
    assert profile.limits.max_read == 61
    assert tuple(profile.line[:2]) == tuple(bb.PblDrive.LINE_DEFAULTS[:2])


def test_the_j2_export_is_the_j2_table() -> None:
    table = bb.J2Controller.table()
    units = bb.J2Controller.units()
    profile = exported("j2")
    assert [r.name for r in profile.registers] == [r.name for r in table]
    for row, want in zip(profile.registers, table):
        check_row(
            row,
            {
                **want._asdict(),
                "scale": 0.1 if want.signed else 1.0,
                "unit": units[want.name],
                "access": "rw" if want.writable else "r",
            },
        )
    limits = profile.limits
    assert (limits.max_read, limits.max_write, limits.min_write_interval) == (16, 16, 0.15)
    assert "LSP..USP" in profile["SV"].description
    assert profile.line.baudrate == bb.J2Controller.LINE_DEFAULTS.baudrate


def test_family_refuses_an_unknown_key_and_notes_what_stays_code() -> None:
    with pytest.raises(ValueError, match=r"drive, drive-c20, pbl, j2"):
        bb.Profile.family("atv31")
    with pytest.raises(TypeError):
        bb.Profile.family(1)  # type: ignore[arg-type]
    text = bb.Profile.family("drive").to_toml()
    assert text.startswith("# ") and "Fgg.nn" in text and "parameter_write_enable" in text
    assert "RAPNF" in bb.Profile.family("j2").to_toml().split("[device]")[0]
    # A profile read from a file is written back without a note, and reads back the same.
    again = exported("pbl").to_toml()
    assert not again.startswith("#")
    lineless = [r._replace(line=0) for r in exported("pbl").registers]
    assert [r._replace(line=0) for r in bb.Profile.parse(again).registers] == lineless


FAMILY_FILES = sorted(
    f.name
    for f in resources.files("benchbus").joinpath("families").iterdir()
    if f.name.endswith(".toml")
)


def test_the_package_ships_the_family_files() -> None:
    assert FAMILY_FILES == ["drive.toml", "j2.toml", "pbl.toml"]


@pytest.mark.parametrize("name", FAMILY_FILES)
def test_a_family_with_a_file_exports_the_file_itself(name: str) -> None:
    """The family's register map is the file the package ships: the export is that file,
    byte for byte (its comments included), and the class's line defaults are its [line]."""
    text = resources.files("benchbus").joinpath("families", name).read_text("utf-8")
    key = name.removesuffix(".toml")
    assert bb.Profile.family(key).to_toml() == text
    assert text.startswith("# ")
    family = bb.Profile.parse(text, name)
    assert [r._replace(line=0) for r in family.registers] == [
        r._replace(line=0) for r in bb.Profile.family(key).registers
    ]
    classes = {"drive": bb.Drive, "pbl": bb.PblDrive, "j2": bb.J2Controller}
    line = family.line
    assert tuple(classes[key].LINE_DEFAULTS[:5]) == (
        line.baudrate,
        line.parity,
        line.timeout,
        line.stopbits,
        line.framing,
    )


def same(a: Any, b: Any) -> bool:
    return math.isclose(a, b, abs_tol=1e-9) if isinstance(a, float) else a == b


@pytest.mark.parametrize(
    ("key", "unit", "make"),
    [
        ("drive", DRIVE, lambda bus: bb.Drive(bus, DRIVE)),
        ("drive-c20", C20, lambda bus: bb.Drive(bus, C20, family="C20")),
        ("pbl", PBL, lambda bus: bb.PblDrive(bus, PBL)),
        ("j2", J2, lambda bus: bb.J2Controller(bus, J2)),
    ],
)
def test_a_profile_device_reads_the_family_simulator_as_its_class_does(
    bench: tuple[Simulator[Any], bb.Bus], key: str, unit: int, make: Any
) -> None:
    bus = bench[1]
    dev = bb.Device.from_profile(exported(key), bus, unit)
    native = make(bus)
    values = dev.sample()
    assert len(values) == len(native.profile)
    for name, value in values.items():
        assert same(value, native.get(name)), name
    # Not all zero: the comparison sees the addresses.
    assert sum(1 for v in values.values() if v) > 5


@pytest.mark.parametrize(
    ("key", "make"),
    [
        ("drive", lambda bus: bb.Drive(bus, 9)),
        ("pbl", lambda bus: bb.PblDrive(bus, 9)),
        ("j2", lambda bus: bb.J2Controller(bus, 9)),
    ],
)
def test_the_family_class_reads_a_profile_device_serving_the_export(
    tmp_path: Path, key: str, make: Any
) -> None:
    path = tmp_path / f"{key}.toml"
    path.write_text(bb.Profile.family(key).to_toml(), encoding="utf-8")
    profile = bb.Profile(path)
    values: dict[str, float] = {}
    for i, row in enumerate(profile.registers):
        if row.type == "bool" or row.bits is not None:
            continue  # a flag or a field of a status word: its bits of the word's value
        assert row.min is not None and row.max is not None
        step = row.scale * (i + 1)
        low = 0.0 if row.min <= 0.0 <= row.max and row.min < 0 else row.min
        # Distinct values, negative ones where the word is signed, each in range.
        value = -step if row.type == "i16" and row.min < 0 else low + step
        values[row.name] = round(min(value, row.max), 1)
    words = {r.address: int(values[r.name]) for r in profile.registers if r.name in values}
    expected = dict(values)
    for row in profile.registers:
        first, last = (row.bit, row.bit) if row.bit is not None else row.bits or (0, 15)
        if row.name not in values:
            expected[row.name] = words[row.address] >> first & (1 << last - first + 1) - 1
    sim_dev = ProfileDevice(path, values=values)
    with Simulator({9: sim_dev}) as sim, bb.Bus(sim.port, timeout=0.5) as bus:
        native = make(bus)
        for name, value in expected.items():
            assert same(float(native.get(name)), value), name
        assert any(v < 0 for v in values.values()) is (key != "pbl")
        assert not sim.errors
