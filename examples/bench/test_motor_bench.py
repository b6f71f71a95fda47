"""A motor and oven test bench as pytest tests, with the fixtures of the benchbus plugin.

On simulated devices (no hardware needed; the tests marked ``hardware`` are skipped)::

    pytest examples/bench

On the real bench: a BLD2 drive at unit 1 and a J2 controller at unit 2 on one RS485 line,
both set to 19200 8N1::

    pytest examples/bench --benchbus-port /dev/ttyUSB0 --benchbus-unit j2=2 \\
        --benchbus-baudrate 19200

Tests on the ``bench_*`` fixtures run on both. Tests on ``sim_*`` need the simulator (to
inject a fault, or to make time pass faster) and always run simulated. Tests marked
``hardware`` only mean something on the real bench and run only there.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import pytest

import benchbus as bb

if TYPE_CHECKING:
    from benchbus.pytest_plugin import SimBench
    from benchbus.sim import DriveDevice, J2Device

SPEED = 1200  # rpm
SPEED_TOLERANCE = 30  # rpm
SETPOINT = 60.0  # degrees C
SETPOINT_TOLERANCE = 2.0  # degrees C
SUPPLY_VOLTAGE = 311.0  # V on the DC bus: the bench's 220 V AC mains, rectified
RATED_CURRENT = 5.0  # A, the bench motor's


def wait_until(
    condition: Callable[[], bool], what: str, timeout: float, interval: float = 0.05
) -> None:
    """Poll ``condition`` until it holds; fail the test after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"{what}: not within {timeout} s")
        time.sleep(interval)


def spin_up(drive: bb.Drive, rpm: int = SPEED) -> int:
    """Run ``drive`` forward at ``rpm`` with short ramps; the speed it reached."""
    drive.accel_time = 0.5
    drive.decel_time = 0.5
    drive.speed_setpoint = rpm
    drive.forward()
    return drive.wait_for_speed(rpm, tolerance=SPEED_TOLERANCE, timeout=5)


# ---- the drive ---------------------------------------------------------------------------------


def test_drive_spins_up_to_speed_and_stops(bench_drive: bb.Drive) -> None:
    speed = spin_up(bench_drive)
    assert abs(speed - SPEED) <= SPEED_TOLERANCE
    assert bench_drive.state == bb.DriveState.FORWARD
    frequency = bench_drive.telemetry().output_frequency
    assert frequency == pytest.approx(speed * bench_drive.pole_pairs / 60, rel=0.05)

    bench_drive.stop()
    wait_until(lambda: bench_drive.state == bb.DriveState.STOPPED, "stopped", timeout=5)
    assert bench_drive.speed <= SPEED_TOLERANCE


def test_drive_refuses_a_pole_pair_change_while_running(bench_drive: bb.Drive) -> None:
    spin_up(bench_drive, 600)
    with pytest.raises(bb.ModbusException) as refused:
        bench_drive.pole_pairs = 4
    assert refused.value.code == 0x08  # not changeable while running
    # Leaving the test stops the drive (the fixture sends the stop).


def test_drive_trips_on_undervoltage_and_resets(sim_drive: SimBench[bb.Drive, DriveDevice]) -> None:
    drive, sim, model = sim_drive
    spin_up(drive)
    model.inject_fault(0x0A)  # the simulated supply sags

    status = drive.status()
    assert status.state == bb.DriveState.FAULT
    assert status.fault is not None and status.fault.code == 0x0A
    assert drive.speed == 0
    with pytest.raises(bb.ModbusException) as refused:
        drive.forward()
    assert refused.value.code == 0x01  # no run command while in fault

    drive.reset_fault()
    assert (drive.state, drive.fault) == (bb.DriveState.STOPPED, None)
    assert model.commands[-1] == 7  # the fault reset went on the wire
    assert not sim.errors


def test_drive_that_stops_answering_times_out(sim_drive: SimBench[bb.Drive, DriveDevice]) -> None:
    drive, sim, _ = sim_drive
    assert drive.speed == 0
    sim.set_silent(drive.unit)
    sim.clear_log()
    with pytest.raises(bb.ResponseTimeout):
        _ = drive.speed
    assert len(sim.requests) == 1 + drive.bus.retries  # asked, then retried


@pytest.mark.hardware
def test_motor_current_and_supply_are_plausible_at_speed(bench_drive: bb.Drive) -> None:
    spin_up(bench_drive)
    telemetry = bench_drive.telemetry()
    assert 0 < telemetry.output_current < RATED_CURRENT
    assert telemetry.bus_voltage == pytest.approx(SUPPLY_VOLTAGE, rel=0.15)


# ---- the oven's J2 controller ----------------------------------------------------------------


def test_controller_keeps_a_new_setpoint(bench_j2: bb.J2Controller) -> None:
    saved = bench_j2.sv
    try:
        bench_j2.sv = SETPOINT
        assert bench_j2.sv == SETPOINT
        with pytest.raises(ValueError):  # checked against the controller's limits: not sent
            bench_j2.sv = bench_j2.limits.high + 10.0
        assert bench_j2.sv == SETPOINT
    finally:
        bench_j2.sv = saved


def test_oven_heats_to_the_setpoint(sim_j2: SimBench[bb.J2Controller, J2Device]) -> None:
    j2, _, model = sim_j2  # the simulated process runs 100 times faster than real time
    j2.sv = SETPOINT

    def settled() -> bool:
        return bool(abs(j2.pv - SETPOINT) <= SETPOINT_TOLERANCE)

    wait_until(settled, f"PV within {SETPOINT_TOLERANCE} of {SETPOINT}", timeout=10)
    assert 0.0 < j2.mv < 100.0  # holding the temperature, not saturated
    time.sleep(1.0)  # 100 s of process time
    assert settled()
    assert model.auto


@pytest.mark.hardware
def test_real_oven_reaches_the_setpoint_within_a_quarter_hour(
    bench_j2: bb.J2Controller,
) -> None:
    saved = bench_j2.sv
    try:
        bench_j2.sv = SETPOINT
        wait_until(
            lambda: abs(bench_j2.pv - SETPOINT) <= SETPOINT_TOLERANCE,
            f"PV within {SETPOINT_TOLERANCE} of {SETPOINT}",
            timeout=15 * 60,
            interval=1.0,
        )
    finally:
        bench_j2.sv = saved
