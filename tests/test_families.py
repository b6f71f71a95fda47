"""The family registry (benchbus._families): each kind of device declared once, read by the
command line, the pytest plugin, the demo and scan; model identification from the core's
table, tried on the simulators."""

from __future__ import annotations

import pytest

import benchbus as bb
from benchbus import pytest_plugin
from benchbus._core import DriveCore
from benchbus._device import LineDefaults
from benchbus._families import FAMILIES, command_families, family, mismatch
from benchbus.cli import BUS_OPTIONS, SIM_DEVICES, guess_model
from benchbus.sim import (
    Atv31Device,
    DriveDevice,
    J2Device,
    PblDevice,
    Simulator,
    TaisongDevice,
)


def test_each_kind_is_declared_once_with_its_class_and_simulator() -> None:
    assert [(f.key, f.device, f.simulator) for f in FAMILIES] == [
        ("drive", bb.Drive, "DriveDevice"),
        ("pbl", bb.PblDrive, "PblDevice"),
        ("j2", bb.J2Controller, "J2Device"),
        ("instrument", bb.Instrument, "TaisongDevice"),
        ("atv31", None, "Atv31Device"),
    ]
    assert [f.key for f in command_families()] == ["drive", "pbl", "j2"]


def test_line_defaults_are_the_classes() -> None:
    for f in FAMILIES:
        if f.device is not None:
            assert f.line is f.device.LINE_DEFAULTS, f.key
    assert family("atv31").line == LineDefaults(19200, "N", 0.1)  # the generic device's


def test_the_command_line_and_the_plugin_read_the_registry() -> None:
    assert {k: SIM_DEVICES[k] for k in ("drive", "pbl", "j2", "instrument", "atv31")} == {
        "drive": 19200,
        "pbl": 115200,
        "j2": 9600,
        "instrument": 9600,
        "atv31": 19200,
    }
    for f in command_families():
        options = BUS_OPTIONS[f.key]
        assert (options.baudrate, options.parity, options.timeout, options.retries) == (
            f.line.baudrate,
            f.line.parity,
            f.line.timeout,
            2,
        )
    assert pytest_plugin.KINDS == ("drive", "pbl", "j2", "instrument")


def test_simulate_makes_the_family_simulator_with_its_options() -> None:
    made = {f.key: f.simulate() for f in FAMILIES}
    assert [type(m) for m in made.values()] == [
        DriveDevice,
        PblDevice,
        J2Device,
        TaisongDevice,
        Atv31Device,
    ]
    drive = family("drive").simulate(model="C20")
    assert isinstance(drive, DriveDevice) and drive.model == "C20"
    assert family("drive").sim_options == ("model",)
    assert family("j2").sim_options == family("instrument").sim_options == ("speedup",)


def test_an_unknown_kind_or_a_device_without_class_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="no device family 'oven'"):
        family("oven")
    with pytest.raises(ValueError, match="no benchbus class"):
        family("atv31").open("/dev/null", 1)


def test_model_from_id_is_the_core_table() -> None:
    assert DriveCore.model_from_id("BLD", 0x20) == "BLD2"
    assert DriveCore.model_from_id("C20", 0x20) == "C20"
    assert DriveCore.model_from_id("BLD", 0x30) == DriveCore.model_from_id("C20", 0x30) == "BLD3H"
    assert DriveCore.model_from_id("BLD", 0x40) is None
    with pytest.raises(ValueError, match="family must be"):
        DriveCore.model_from_id("ABC", 0x20)
    with pytest.raises(ValueError, match="id must be 0 to 65535"):
        DriveCore.model_from_id("BLD", 0x10000)
    with pytest.raises(TypeError, match="id must be an int"):
        DriveCore.model_from_id("BLD", "0x20")  # type: ignore[arg-type]


def test_scan_names_each_model_and_family_from_its_probe() -> None:
    devices = {
        1: DriveDevice("BLD2"),
        2: DriveDevice("BLD3H"),
        3: DriveDevice("C20"),
        4: PblDevice(),
        5: J2Device(),
        6: TaisongDevice(),
        7: Atv31Device(),
    }
    with Simulator(devices) as sim, bb.Bus(sim.port, timeout=0.2) as bus:
        names = {u: guess_model(bus, u, identify=False) for u in devices}
        assert names == {
            1: "Drive BLD2",
            2: "Drive BLD3H",
            3: "Drive C20",
            4: "PBL",
            5: "J2",
            6: "Taisong",
            7: "?",
        }
        # status and monitor refuse a unit of another family with a command, naming it.
        assert mismatch(bus, 4, "j2") is family("pbl")
        assert mismatch(bus, 5, "j2") is None
        assert mismatch(bus, 1, "pbl") is family("drive")
