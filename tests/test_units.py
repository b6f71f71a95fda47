"""Units from the register tables, wherever a recording shows numbers: ``to_pandas()``'s
``attrs["units"]`` and ``plot()``'s labels, for each device family, on the simulators."""

from __future__ import annotations

from collections.abc import Callable

import pytest

import benchbus as bb
from benchbus._core import J2Core
from benchbus.sim import DriveDevice, J2Device, PblDevice, Simulator

FAMILIES: dict[str, Callable[[bb.Bus], bb.Drive | bb.PblDrive | bb.J2Controller]] = {
    "drive": lambda bus: bb.Drive(bus, 1),
    "pbl": lambda bus: bb.PblDrive(bus, 2),
    "j2": lambda bus: bb.J2Controller(bus, 3),
}


def _recording(family: str, columns: list[str] | None = None) -> bb.Recording:
    units = {1: DriveDevice("BLD2"), 2: PblDevice(), 3: J2Device()}
    with Simulator(units) as sim, bb.Bus(sim.port) as bus:
        return FAMILIES[family](bus).record(0.25, 0.1, columns=columns)


def test_pandas_attrs_carry_each_columns_unit_and_the_names_stay() -> None:
    frame = _recording("drive").to_pandas()
    units = frame.attrs["units"]
    assert list(units) == list(frame.columns)
    assert units["speed"] == "rpm" and units["output_current"] == "A"
    assert units["temperature"] == "°C" and units["hall_state"] == ""
    assert frame["speed"].dtype == float  # the names stay as they were


@pytest.mark.parametrize(
    ("family", "expected"),
    [
        ("pbl", {"speed": "rpm", "bus_voltage": "V", "current": "A", "power": "W"}),
        ("j2", {"pv": "°C", "sv": "°C", "mv": "%"}),
    ],
)
def test_every_family_records_its_units(family: str, expected: dict[str, str]) -> None:
    rec = _recording(family)
    assert expected.items() <= rec.units.items()
    assert rec.to_pandas().attrs["units"] == rec.units


def test_the_units_are_the_tables() -> None:
    """One declaration: what a recording shows is what the register tables hold."""
    with Simulator({1: DriveDevice("BLD2")}) as sim, bb.Bus(sim.port) as bus:
        drive = bb.Drive(bus, 1)
        table = {row[0]: row[3] for row in drive.registers()}
        assert all(drive.sample_units()[k] == table[k] for k in table if k in drive.SAMPLE_FIELDS)
    j2_table = J2Core.units()
    assert j2_table["MV"] == "%" and j2_table["PV"] == "°C"
    assert j2_table == {name: j2_table[name] for name, *_ in bb.J2Controller.table()}


def test_plot_labels_carry_units() -> None:
    rec = _recording("drive", ["speed", "output_current"])
    ax = rec.plot()
    # One Axes per unit, stacked, each labelled with its unit and its column.
    axes = ax.figure.axes
    assert axes[0] is ax
    assert [a.get_ylabel() for a in axes] == ["rpm", "A"]
    assert [[t.get_text() for t in a.get_legend().get_texts()] for a in axes] == [
        ["speed (rpm)"],
        ["output_current (A)"],
    ]
    one = rec.plot(["speed"])
    assert one.get_ylabel() == "rpm"
