"""CONTRIBUTING.md names files and code; this holds it to the tree, so the map cannot drift."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
TEXT = (ROOT / "CONTRIBUTING.md").read_text(encoding="utf-8")

#: Paths in backquotes (``src/bus.rs``), but the recipes' placeholders (``xy``, ``<family>``).
PATHS = sorted(
    {
        p
        for p in re.findall(r"`((?:src|python|tests|bench)/[\w./<>{},-]+)`", TEXT)
        if "<" not in p and "{" not in p and not re.search(r"\bxy\b|_xy|/xy", p)
    }
)


def test_the_map_names_files() -> None:
    assert len(PATHS) >= 20


@pytest.mark.parametrize("path", PATHS)
def test_every_file_the_map_names_exists(path: str) -> None:
    assert (ROOT / path.rstrip("/")).exists(), path


@pytest.mark.parametrize(
    ("term", "code", "where"),
    [
        ("device_methods!", "macro_rules! device_methods", "src/python/mod.rs"),
        ("on_station!", "macro_rules! on_station", "src/device/mod.rs"),
        ("Attached::attach", "fn attach(", "src/python/mod.rs"),
        ("public()", "fn public<", "src/python/mod.rs"),
        ("member()", "fn member<", "src/python/mod.rs"),
        ("_Station", 'name = "_Station"', "src/python/mod.rs"),
        ("_on_line", "def _on_line(", "python/benchbus/_device.py"),
        ("drive_commands!", "macro_rules! drive_commands", "src/device/drive.rs"),
        ("COMMANDS", "COMMANDS: tuple[types.ModuleType", "python/benchbus/cli/__init__.py"),
        ("OWNERS", "OWNERS: dict[str, type] = {", "tests/test_bad_input.py"),
        ("Station", "pub struct Station {", "src/device/mod.rs"),
        ("Framing", "pub enum Framing {", "src/codec/mod.rs"),
        ("TableDevice", "class TableDevice(SimDevice):", "python/benchbus/sim/_device.py"),
    ],
)
def test_the_mechanisms_the_map_describes_are_where_it_says(
    term: str, code: str, where: str
) -> None:
    assert term in TEXT, term
    assert code in (ROOT / where).read_text(encoding="utf-8"), (code, where)
