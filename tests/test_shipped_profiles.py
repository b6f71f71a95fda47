"""The profiles benchbus ships (``benchbus/profiles/``), opened by name.

Each is read by the core and round-trips through ``to_toml``; each is served by its
simulator (``ProfileDevice``, which reads the file itself) and read back through
``bb.Device.from_profile(name, ...)``. The values worked by hand from each vendor's map
(``tests/vectors/profiles/NAME.toml``: raw words and what they mean) are put on a
third-party server, pymodbus's, and read through the profile: a wrong address, word
order, scale or sign cannot agree with itself there. Then the search path: a lab's
``BENCHBUS_PROFILES`` wins over the shipped library, a file that exists wins over a name,
and an unknown name names the close ones, wherever a profile is taken.
"""

from __future__ import annotations

import importlib
import math
import os
import signal
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from pymodbus_peer import pymodbus_server
from test_cli import ok, one_line_error, readline, run, start, stop

import benchbus as bb
from benchbus import _library
from benchbus.epics import PV_NAME_MAX, pvs
from benchbus.pytest_plugin import ProfileBench, SimProfile
from benchbus.sim import ProfileDevice, Simulator
from conftest import hook

# The standard library's TOML reader from Python 3.11, its original (tomli) before.
_toml = importlib.import_module("tomllib" if sys.version_info >= (3, 11) else "tomli")
VECTORS = Path(__file__).resolve().parent / "vectors" / "profiles"
SHIPPED = sorted(p.stem for p in _library.SHIPPED.glob("*.toml"))
#: What a shipped profile's ``kind`` may be: the docs have a page of each.
KINDS = hook("profile_library").KINDS
SIGNED = {"i16", "i32", "i64", "f32", "f64"}
WIDE = {"u32", "i32", "u64", "i64", "f32", "f64"}
FLOATS = {"f32", "f64"}


def cases(name: str) -> list[dict[str, Any]]:
    """The worked values of profile ``name``."""
    with open(VECTORS / f"{name}.toml", "rb") as f:
        found: list[dict[str, Any]] = _toml.load(f)["case"]
    return found


def same(read: Any, want: Any, register: bb.ProfileRegister) -> bool:
    """Whether ``read`` (what the device object gave) is the worked value ``want``: an enum
    member by its name, a bool as a bool, a number within the float's precision."""
    if isinstance(want, str) and register.enum:
        return bool(getattr(read, "name", None) == want)
    if isinstance(want, bool) or isinstance(read, bool):
        return read is want
    if isinstance(want, str):
        return bool(read == want)
    return math.isclose(float(read), float(want), rel_tol=1e-6, abs_tol=1e-9)


def test_the_library_holds_the_devices_labs_have() -> None:
    assert len(SHIPPED) >= 10
    for name in ("sdm630", "sdm120", "xy-md02", "pzem-016", "delta-dtb"):
        assert name in SHIPPED
    assert sorted(VECTORS.glob("*.toml")) == [VECTORS / f"{n}.toml" for n in SHIPPED]
    # Every shipped profile is found by name, at its file in the package.
    found = _library.profiles()
    assert {n: found[n] for n in SHIPPED} == {
        n: str(_library.SHIPPED / f"{n}.toml") for n in SHIPPED
    }


@pytest.mark.parametrize("name", SHIPPED)
def test_each_reads_says_where_it_comes_from_and_round_trips(name: str) -> None:
    profile = bb.Profile(name)
    assert profile.path == str(_library.SHIPPED / f"{name}.toml")
    assert profile.maker and profile.model and profile.source, name
    assert profile.kind in KINDS
    assert len(profile) >= 2
    for r in profile.registers:
        assert r.description, f"{name}: {r.name}"
        if r.access != "r" and r.type not in ("bool", "string") and not r.enum:
            assert r.min is not None and r.max is not None
    again = bb.Profile.parse(profile.to_toml(), path=name)
    assert (again.name, again.description, again.maker, again.model, again.kind) == (
        profile.name,
        profile.description,
        profile.maker,
        profile.model,
        profile.kind,
    )
    assert (again.source, again.line, again.limits) == (
        profile.source,
        profile.line,
        profile.limits,
    )
    assert [r._replace(line=0) for r in again.registers] == [
        r._replace(line=0) for r in profile.registers
    ]
    # Served over EPICS as it is: every record's name fits, under a prefix of 12.
    records, _ = pvs("LAB:BENCH01:", profile)
    assert records and all(len(pv.name) <= PV_NAME_MAX for pv in records)
    for pv in records:  # a value whose places change: the most of them, no display limits
        row = profile[pv.register] if pv.register else None
        if row is not None and row.decimals is not None:
            places = profile[row.decimals]
            most = max(places.enum) if places.enum else places.max
            assert pv.fields["PREC"] == most and "LOPR" not in pv.fields, pv


@pytest.mark.parametrize("name", SHIPPED)
def test_each_has_worked_values_of_every_kind_it_holds(name: str) -> None:
    """A negative value, a value over several registers, a float, where the device has
    them; each case on a register of the profile, at the table and address it says."""
    profile = bb.Profile(name)
    worked = cases(name)
    assert len(worked) >= 4
    rows = [profile[c["register"]] for c in worked]
    for case, row in zip(worked, rows):
        assert (case["table"], case["address"]) == (row.table, row.address), case
        width = row.length or {"u32": 2, "i32": 2, "f32": 2, "u64": 4, "i64": 4, "f64": 4}.get(
            row.type, 1
        )
        assert len(case["words"]) == (1 if row.table in ("coil", "discrete") else width), case
        assert case["why"]
        # A register with decimals is worked at the places its decimals register gives.
        assert ("decimals_words" in case) == (row.decimals is not None), case
        # Words that a wrong order or a missed register would read the same cannot judge.
        assert any(case["words"]), case
        if len(case["words"]) > 1:
            assert case["words"] != case["words"][::-1], case
    types = {r.type for r in profile.registers if r.access != "w"}
    negative = [
        c
        for c, r in zip(worked, rows)
        if isinstance(c["value"], (int, float))
        and not isinstance(c["value"], bool)
        and c["value"] < 0
    ]
    if types & SIGNED:
        assert negative, f"{name}: no negative value worked"
    if types & WIDE:
        assert any(r.type in WIDE for r in rows), f"{name}: no value over two registers"
    if types & FLOATS:
        assert any(r.type in FLOATS for r in rows), f"{name}: no float worked"


def held(case: dict[str, Any], profile: bb.Profile) -> dict[tuple[str, int], int]:
    """The words a case puts on the server, by (table, address): its register's, and for a
    register with ``decimals`` the words of the register giving its places."""
    words = {(case["table"], case["address"] + i): w for i, w in enumerate(case["words"])}
    row = profile[case["register"]]
    if row.decimals is not None:
        places = profile[row.decimals]
        for i, w in enumerate(case["decimals_words"]):
            words[(places.table, places.address + i)] = w
    return words


def rounds(worked: list[dict[str, Any]], profile: bb.Profile) -> list[list[dict[str, Any]]]:
    """``worked`` in rounds whose cases hold no address twice (two cases may work one
    register's two values)."""
    found: list[tuple[set[tuple[str, int]], list[dict[str, Any]]]] = []
    for case in worked:
        its = set(held(case, profile))
        free = next((r for r in found if not r[0] & its), None)
        if free is None:
            free = (set(), [])
            found.append(free)
        free[0].update(its)
        free[1].append(case)
    return [r[1] for r in found]


def tables(worked: list[dict[str, Any]], profile: bb.Profile) -> dict[str, list[int]]:
    """A unit's four tables holding the worked words (0 elsewhere)."""
    made = {t: [0] * 65536 for t in ("coil", "discrete", "holding", "input")}
    for case in worked:
        for (table, address), word in held(case, profile).items():
            made[table][address] = word
    return made


@pytest.mark.parametrize("name", SHIPPED)
def test_the_worked_values_read_from_a_third_party_server(name: str) -> None:
    profile = bb.Profile(name)
    ascii = profile.line.framing == "ascii"
    for worked in rounds(cases(name), profile):
        with (
            pymodbus_server(True, ascii=ascii, tables=tables(worked, profile)) as url,
            bb.Device.from_profile(name, url, unit=1, retries=0) as device,
        ):
            for case in worked:
                row = profile[case["register"]]
                read = device.read(row.name)
                assert same(read, case["value"], row), f"{name}.{row.name}: {read!r}, {case}"
            # All of them together, in the fewest requests the profile allows.
            together = device.read_many([c["register"] for c in worked])
            for case in worked:
                row = profile[case["register"]]
                assert same(together[row.name], case["value"], row), case


@pytest.mark.parametrize("name", SHIPPED)
def test_each_serves_its_simulator_and_reads_back_by_name(
    name: str, sim_profile: SimProfile
) -> None:
    bench: ProfileBench = sim_profile(name)
    assert bench.model.path == str(_library.SHIPPED / f"{name}.toml")
    device = bb.Device.from_profile(name, bench.bus, unit=bench.unit)
    sample = device.sample()
    assert list(sample) == list(device.SAMPLE_FIELDS or ())
    for field, value in sample.items():
        truth = bench.model.value(field)
        row = device.profile[field]
        if row.enum and isinstance(truth, str):
            assert value.name == truth, field
        else:
            assert same(value, truth, row), f"{field}: {value!r} against {truth!r}"
    assert bench.sim.errors == []


# ---- the search path ---------------------------------------------------------------------


LAB_SDM630 = """
[device]
name = "Lab SDM630"
maker = "Eastron"
kind = "energy-meter"
source = "the lab's own"

[[register]]
name = "voltage"
address = 0
table = "input"
type = "f32"
unit = "V"
"""


@pytest.fixture
def lab(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A lab's folder of profiles in ``BENCHBUS_PROFILES`` (after a folder that is not
    there), with its own ``sdm630`` and a profile of its own."""
    folder = tmp_path / "profiles"
    folder.mkdir()
    (folder / "sdm630.toml").write_text(LAB_SDM630)
    (folder / "oven.toml").write_text(LAB_SDM630.replace("Lab SDM630", "Oven"))
    monkeypatch.setenv(_library.ENV, os.pathsep.join([str(tmp_path / "gone"), str(folder)]))
    monkeypatch.chdir(tmp_path)
    yield folder


def test_a_labs_folder_wins_over_the_shipped_library(lab: Path) -> None:
    assert bb.Profile("sdm630").name == "Lab SDM630"
    assert bb.Profile("oven").path == str(lab / "oven.toml")
    assert bb.Profile("sdm120").path == str(_library.SHIPPED / "sdm120.toml")
    assert ProfileDevice("sdm630").name == "Lab SDM630"
    assert _library.profiles()["sdm630"] == str(lab / "sdm630.toml")


def test_the_labs_folders_are_searched_in_their_order(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    first, second = tmp_path / "first", tmp_path / "second"
    for folder in (first, second):
        folder.mkdir()
        (folder / "oven.toml").write_text(LAB_SDM630.replace("Lab SDM630", folder.name))
    (second / "kiln.toml").write_text(LAB_SDM630.replace("Lab SDM630", "kiln"))
    home = tmp_path / "home"
    monkeypatch.setenv("HOME", str(home))
    (home / "p").mkdir(parents=True)
    (home / "p" / "dryer.toml").write_text(LAB_SDM630.replace("Lab SDM630", "dryer"))
    a_file = tmp_path / "not-a-folder"
    a_file.write_text("")
    monkeypatch.setenv(
        _library.ENV, os.pathsep.join([f" {first} ", str(second), "~/p", str(a_file), ""])
    )
    assert bb.Profile("oven").name == "first"
    assert bb.Profile("kiln").name == "kiln"
    assert bb.Profile("dryer").name == "dryer"  # ~ is the home folder
    with pytest.raises(bb.ProfileError, match=f"{a_file}: not a folder"):
        bb.Profile("ovne")


def test_a_file_that_exists_wins_over_a_name(lab: Path) -> None:
    (lab.parent / "sdm120").write_text(LAB_SDM630.replace("Lab SDM630", "Here"))
    assert bb.Profile("sdm120").name == "Here"
    (lab.parent / "pzem-016").mkdir()  # a folder is no profile: the name holds
    assert bb.Profile("pzem-016").path == str(_library.SHIPPED / "pzem-016.toml")


@pytest.mark.parametrize(
    ("name", "said"),
    [
        ("sdm63", "did you mean 'sdm630'"),
        ("SDM-120", "'sdm120'"),
        ("ovne", "'oven'"),
        ("drive", "a built-in family, used through bb.Drive"),
        ("pbll", "'pbl'"),
    ],
)
def test_an_unknown_name_names_the_close_ones(lab: Path, name: str, said: str) -> None:
    with pytest.raises(bb.ProfileError) as refused:
        bb.Profile(name)
    assert said in str(refused.value)
    assert refused.value.path == name
    if name != "drive":
        assert "no such folder" in str(refused.value)  # the lab's missing folder, said
    with pytest.raises(bb.ProfileError, match=said):
        ProfileDevice(name)


def test_a_path_that_is_not_there_stays_a_path() -> None:
    with pytest.raises(bb.ProfileError, match="cannot read the file"):
        bb.Profile("nowhere/sdm630.toml")
    for path in ("sdm630.toml", "./sdm630", "sdm630/", ""):  # not names: not looked up
        with pytest.raises(bb.ProfileError, match="cannot read the file"):
            bb.Profile(path)
    with pytest.raises(FileNotFoundError):
        ProfileDevice("./sdm630")


def test_a_bench_file_takes_a_name_and_a_file_beside_it_wins(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from benchbus._bench import read_bench

    bench_dir = tmp_path / "bench"
    bench_dir.mkdir()
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sdm630").write_text("not a profile")  # in the current folder: not the bench's
    (bench_dir / "sdm120").write_text(LAB_SDM630.replace("Lab SDM630", "Beside"))
    bench = bench_dir / "bench.toml"
    bench.write_text(
        '[[line]]\nname = "a"\nport = "/dev/ttyNONE0"\n\n'
        '[[device]]\nline = "a"\nunit = 1\nprefix = "M:"\nprofile = "sdm630"\n\n'
        '[[device]]\nline = "a"\nunit = 2\nprefix = "N:"\nprofile = "sdm120"\n'
    )
    first, second = read_bench(bench).devices
    assert first.profile is not None and second.profile is not None
    assert first.profile.path == str(_library.SHIPPED / "sdm630.toml")
    assert second.profile.name == "Beside"


# ---- the command line --------------------------------------------------------------------


def test_profile_list_shows_the_library_the_lab_and_the_families(lab: Path) -> None:
    env = {_library.ENV: str(lab)}
    lines = ok(run("profile", "list", env=env))
    header, rows = lines[0].split(), {line.split()[0]: line for line in lines[1:]}
    assert header == ["name", "maker", "model", "kind", "source", "from"]
    for name in SHIPPED:
        assert name in rows
        if name != "sdm630":
            assert rows[name].endswith("shipped")
            assert bb.Profile(name).kind in rows[name]
    assert rows["sdm630"].endswith(str(lab)) and "the lab's own" in rows["sdm630"]
    assert rows["oven"].endswith(str(lab))
    assert rows["pbl"].endswith("bb.PblDrive") and "motor-driver" in rows["pbl"]
    assert rows["j2"].endswith("bb.J2Controller")
    # A lab file that does not read is listed, and said.
    (lab / "broken.toml").write_text("[device]\n")
    broken = run("profile", "list", env=env)
    assert broken.returncode == 1
    assert "broken" in broken.stdout and "broken.toml" in broken.stderr


def test_profile_show_prints_the_source_and_the_table() -> None:
    profile = bb.Profile("pzem-016")
    lines = ok(run("profile", "show", "pzem-016"))
    assert lines[0].startswith(f"{profile.name}: ")
    assert f"source: {profile.source}" in lines
    assert f"kind: {profile.kind}" in lines
    names = [
        line.split()[0]
        for line in lines[lines.index(next(x for x in lines if x.startswith("name "))) + 1 :]
    ]
    assert names == [r.name for r in profile.registers]
    family = ok(run("profile", "show", "j2"))
    assert "PV" in [line.split()[0] for line in family]
    said = one_line_error(run("profile", "show", "pzem016"), 2)
    assert "did you mean 'pzem-016'" in said


def test_profile_show_takes_a_labs_file_named_like_a_family_as_profile_does(lab: Path) -> None:
    (lab / "drive.toml").write_text(LAB_SDM630.replace("Lab SDM630", "Lab drive"))
    env = {_library.ENV: str(lab)}
    assert ok(run("profile", "show", "drive", env=env))[0].startswith("Lab drive")
    assert bb.Profile("drive").name == "Lab drive"
    family = run("profile", "show", "drive", env={_library.ENV: ""})
    assert ok(family)[0].startswith("drive: ")  # the family's


def test_write_and_monitor_take_a_name() -> None:
    model = ProfileDevice("sdm630", values={"frequency": 50.02, "voltage_l1": 229.5})
    with Simulator({1: model}) as sim:
        line = ["--profile", "sdm630", "--port", sim.port]
        before = len(sim.requests)
        ok(run("write", *line, "demand_period", "15"))
        assert model.value("demand_period") == 15.0
        ok(run("write", *line, "reset_demand", "0"))  # one register: still 0x10
        assert [bytes(r)[1] for r in sim.requests[before:]] == [0x10, 0x10]
        lines = ok(run("monitor", *line, "--count", "1", "--interval", "0.1"))
        assert sim.errors == []
    assert "50.02" in "\n".join(lines) and "229.5" in "\n".join(lines)


def test_sim_and_read_take_a_name() -> None:
    model = ProfileDevice("xy-md02", values={"temperature": -7.5, "humidity": 61.2})
    with Simulator({3: model}) as sim:
        lines = ok(
            run(
                "read",
                "--profile",
                "xy-md02",
                "--port",
                sim.port,
                "--unit",
                3,
                "temperature",
                "humidity",
            )
        )
        assert sim.errors == []
    shown = {line.split()[0]: line.split()[1] for line in lines}
    assert float(shown["temperature"]) == -7.5 and float(shown["humidity"]) == 61.2


def test_benchbus_sim_serves_a_shipped_profile_by_name() -> None:
    proc = start("sim", "--profile", "sdm120", "--value", "voltage=231.5")
    try:
        port = readline(proc.stdout).strip()
        assert readline(proc.stderr).startswith("simulating SDM120 from sdm120.toml (unit 1,")
        with bb.Device.from_profile("sdm120", port, unit=1) as meter:
            assert meter.voltage == 231.5
            assert meter.profile.path == str(_library.SHIPPED / "sdm120.toml")
    finally:
        status, _, err = stop(proc, signal.SIGTERM)
    assert status == 0 and "Traceback" not in err


async def _aio_read(port: str) -> float:
    async with bb.aio.AsyncBus(port, timeout=0.5) as bus:
        meter = bb.aio.Device.from_profile("sdm120", bus, unit=4)
        value: float = await meter.read("frequency")
        return value


def test_the_async_device_takes_a_name() -> None:
    import asyncio

    model = ProfileDevice("sdm120", values={"frequency": 49.97})
    with Simulator({4: model}) as sim:
        assert asyncio.run(_aio_read(sim.port)) == pytest.approx(49.97, rel=1e-6)
        assert sim.errors == []


def test_a_file_or_family_given_for_a_profiles_name_says_the_name() -> None:
    said = one_line_error(run("read", "--profile", "sdm630.toml", "--port", "/dev/null"), 2)
    assert said.endswith("; the profile called 'sdm630' is --profile sdm630")
    said = one_line_error(run("ioc", "pzem-016"), 2)
    assert "no device family 'pzem-016'" in said
    assert said.endswith("; the profile called 'pzem-016' is --profile pzem-016")
    assert "--profile" not in one_line_error(run("ioc", "toaster"), 2)
