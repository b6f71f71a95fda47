"""The simulators' table-driven unit (``benchbus.sim._device.TableDevice``): one set of
checks, with each family's manual kept as data and its rules as hooks.

Where the families differ in the order of their refusals within one write, the manual
decides: a drive applies a 0x10 write register by register (a refusal there is the first
register's own, and what came before it is put back), the PBL, J2 and profile simulators
look at every address of the write before any value.
"""

from __future__ import annotations

from pathlib import Path
from types import MappingProxyType

import pytest
from test_sim_tables import answer

from benchbus.sim import DriveDevice, J2Device, PblDevice, ProfileDevice

DRIVE_SETPOINT, POSITION_REFERENCE = 0x2001, 0x2010
SV = 6


def still() -> float:
    return 0.0


def test_a_drive_write_is_checked_register_by_register() -> None:
    drive = DriveDevice("BLD2", clock=still)
    # 0x2011 (hall count clear) 0..1, 0x2012 stop mode, 0x2013 has no register: the value
    # of the first is refused before the address of the third is looked at.
    assert answer(lambda: drive.write_holding(0x2011, [2, 0, 0])) == 3
    assert answer(lambda: drive.write_holding(0x2011, [0, 0, 0])) == 2
    # What the write had stored before its refusal is put back.
    assert answer(lambda: drive.write_holding(POSITION_REFERENCE, [77, 0, 1, 5])) == 2
    assert drive.peek(POSITION_REFERENCE) == 0 and drive.peek(0x2012) == 0


def test_a_j2_write_looks_at_every_address_first() -> None:
    j2 = J2Device(clock=still, write_interval=0.0)
    # SV out of LSP..USP, then an odd address: the address is answered, not the value.
    assert answer(lambda: j2.write_holding(SV, [5000, 0])) == 2
    assert answer(lambda: j2.write_holding(SV, [5000])) == 3
    # Every address outside the tables reads 0, also past their ends.
    assert j2.read_holding(0xFFF0, 16) == [0] * 16
    assert answer(lambda: j2.read_holding(0xFFF1, 16)) == 2  # past 0xFFFF


def test_a_pbl_write_takes_a_live_value_and_ignores_it() -> None:
    pbl = PblDevice(clock=still)
    # 99 is a live value (read-only in the manual's table): taken, ignored, with the
    # setting after it; a bad setting refuses the whole write, past 222 the address.
    assert answer(lambda: pbl.write_holding(99, [0x1234, 2])) == 0  # 100 is 0..2
    assert pbl.read_holding(99, 2) == [0, 2]
    assert answer(lambda: pbl.write_holding(99, [0x1234, 0, 5])) == 3  # 101 is 0..1
    assert pbl.read_holding(100, 2) == [2, 1]
    assert answer(lambda: pbl.write_holding(203, [2])) == 3
    assert answer(lambda: pbl.write_holding(222, [0, 0])) == 2
    assert answer(lambda: pbl.read_holding(222, 2)) == 2


PROFILE = """
[device]
name = "unit"

[[register]]
name = "level"
address = 0
max = 10

[[register]]
name = "total"
address = 1
type = "u32"

[[register]]
name = "serial"
address = 4
access = "r"
"""


@pytest.fixture
def profile(tmp_path: Path) -> ProfileDevice:
    path = tmp_path / "unit.toml"
    path.write_text(PROFILE, encoding="utf-8")
    return ProfileDevice(path)


def test_a_profile_write_looks_at_every_address_first(profile: ProfileDevice) -> None:
    # level out of range, then total's first word without its second; 4 is read-only.
    assert answer(lambda: profile.write_holding(0, [11, 0])) == 2
    assert answer(lambda: profile.write_holding(4, [1])) == 2
    assert answer(lambda: profile.write_holding(0, [11])) == 3
    assert answer(lambda: profile.write_holding(0, [10, 0, 7])) == 0
    assert profile.value("total") == 7 and profile.value("level") == 10
    assert answer(lambda: profile.read_holding(2, 2)) == 2  # 3 is no register


def test_a_subclass_changes_the_words_at_power_up_through_defaults() -> None:
    """``DEFAULTS`` is the class's: a subclass's values are what the unit starts with."""

    class Pbl(PblDevice):
        DEFAULTS = MappingProxyType({**PblDevice.DEFAULTS, 205: 7})

    class J2(J2Device):
        DEFAULTS = MappingProxyType({**J2Device.DEFAULTS, "SV": 42.5})

    assert Pbl(clock=still).read_holding(205, 1) == [7]
    assert PblDevice(clock=still).read_holding(205, 1) != [7]
    assert J2(clock=still, write_interval=0.0).read_holding(SV, 1) == [425]
    assert J2(clock=still, write_interval=0.0).value("SV") == 42.5
