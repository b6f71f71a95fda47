"""The communication watchdog (issue 9, item 6): F08.04 through ``Drive.comm_loss_timeout``,
the simulated drive tripping when no request reaches it, and ``Drive.keepalive()``.

Real time on the simulator's clock: F08.04 = 0.5 s, and ~1 s of silence (or of keepalive).
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Iterator

import pytest

import benchbus as bb
from benchbus.sim import DriveDevice, Simulator
from benchbus.sim._drive import COMM_LOSS_FAULT

Rig = tuple[bb.Drive, Simulator[DriveDevice], DriveDevice]
F08_04 = 0x0804


@contextlib.contextmanager
def open_drive(
    model: str = "BLD2", timeout: float | None = None, retries: int | None = None
) -> Iterator[Rig]:
    """A simulated drive and a Drive on its line, with the Drive's timeout and retries."""
    device = DriveDevice(model)
    family = "C20" if model == "C20" else "BLD"
    with (
        Simulator(device) as sim,
        bb.Drive(sim.port, family=family, timeout=timeout, retries=retries) as drive,
    ):
        yield drive, sim, device


@pytest.fixture
def bld() -> Iterator[Rig]:
    with open_drive() as line:
        yield line


def running_with_watchdog(line: Rig) -> None:
    """F08.04 = 0.5 s, then the motor forward at 1000 rpm."""
    drive, _sim, device = line
    drive.comm_loss_timeout = 0.5
    assert device.params[F08_04] == 5
    drive.speed_setpoint = 1000
    drive.forward()
    assert device.state == DriveDevice.FORWARD


def keepalive_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith("benchbus keepalive")]


# ---- F08.04 through the property --------------------------------------------------------------


def test_comm_loss_timeout_lands_in_f08_04(bld: Rig) -> None:
    drive, _sim, device = bld
    assert drive.comm_loss_timeout == 0.0
    for seconds, raw in ((0.5, 5), (60, 600), (0.1, 1), (12.34, 123), (0, 0)):
        drive.comm_loss_timeout = seconds
        assert device.params[F08_04] == raw
        assert drive.comm_loss_timeout == raw / 10
    device.set_param(F08_04, 25)
    assert drive.comm_loss_timeout == 2.5


@pytest.mark.parametrize(
    ("value", "exc"),
    [
        (-0.1, ValueError),
        (0.05, ValueError),
        (60.1, ValueError),
        (float("nan"), ValueError),
        (float("inf"), ValueError),
        (2**70, ValueError),
        (2**1100, ValueError),
        ("1", TypeError),
        (None, TypeError),
        (True, TypeError),
    ],
)
def test_bad_comm_loss_timeout_sends_nothing(bld: Rig, value: object, exc: type) -> None:
    drive, sim, device = bld
    sent = len(sim.requests)
    with pytest.raises(exc, match="comm_loss_timeout"):
        drive.comm_loss_timeout = value  # type: ignore[assignment]
    assert sim.requests[sent:] == []
    assert device.params[F08_04] == 0


def test_c20_has_no_f08_04() -> None:
    with open_drive("C20") as (drive, sim, _device):
        with pytest.raises(ValueError, match=r"C20.*F08\.04"):
            drive.comm_loss_timeout = 1.0
        with pytest.raises(ValueError, match=r"F08\.04"):
            _ = drive.comm_loss_timeout
        assert sim.requests == []


# ---- the simulated drive trips ----------------------------------------------------------------


def test_silence_trips_the_drive(bld: Rig) -> None:
    running_with_watchdog(bld)
    drive, _sim, device = bld
    time.sleep(1.0)
    assert device.state == DriveDevice.FAULT
    assert device.speed == 0.0
    assert device.fault == COMM_LOSS_FAULT
    status = drive.status()
    assert status.state == bb.DriveState.FAULT
    assert status.fault is not None and status.fault.code == COMM_LOSS_FAULT
    with pytest.raises(bb.ModbusException):
        drive.forward()  # no run command in fault
    drive.reset_fault()
    assert device.state == DriveDevice.STOPPED


def test_no_trip_while_stopped_or_when_off(bld: Rig) -> None:
    drive, _sim, device = bld
    drive.comm_loss_timeout = 0.1
    device.advance(1.0)
    assert device.state == DriveDevice.STOPPED  # stopped: nothing to stop
    drive.comm_loss_timeout = 0
    drive.forward()
    device.advance(100.0)
    assert device.state == DriveDevice.FORWARD  # F08.04 = 0: off


def test_keepalive_keeps_the_drive_running_and_stop_lets_it_trip(bld: Rig) -> None:
    running_with_watchdog(bld)
    drive, _sim, device = bld
    with drive.keepalive(0.1) as keepalive:
        assert keepalive.running
        time.sleep(1.0)
        assert device.state == DriveDevice.FORWARD
        assert keepalive.reads >= 5
        assert keepalive.errors == 0
    assert not keepalive.running
    assert keepalive_threads() == []
    time.sleep(1.0)
    assert device.state == DriveDevice.FAULT
    assert device.fault == COMM_LOSS_FAULT


def test_one_keepalive_per_drive(bld: Rig) -> None:
    drive, _sim, _device = bld
    first = drive.keepalive(0.2)
    with pytest.raises(RuntimeError, match="already running"):
        drive.keepalive(0.1)
    first.stop()
    first.stop()  # twice is fine
    second = drive.keepalive(0.1)
    assert second is not first and second.running
    second.stop()


def test_close_stops_the_keepalive() -> None:
    with open_drive() as (drive, _sim, _device):
        keepalive = drive.keepalive(0.05)
        assert len(keepalive_threads()) == 1
    assert not keepalive.running
    assert keepalive_threads() == []


def test_failed_reads_are_counted_and_the_thread_goes_on(
    caplog: pytest.LogCaptureFixture,
) -> None:
    with open_drive(timeout=0.1, retries=0) as (drive, sim, _device):
        caplog.set_level(logging.WARNING, logger="benchbus.device")
        keepalive = drive.keepalive(0.1)
        sim.set_silent(1)
        deadline = time.monotonic() + 3.0
        while keepalive.errors < 2 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert keepalive.errors >= 2
        assert keepalive.running
        sim.set_silent(1, False)
        reads = keepalive.reads
        deadline = time.monotonic() + 3.0
        while keepalive.reads < reads + 3 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert keepalive.reads >= reads + 3
        keepalive.stop()
    assert any("keepalive read failed" in r.getMessage() for r in caplog.records)


@pytest.mark.parametrize(
    ("interval", "exc"),
    [
        (0, ValueError),
        (0.001, ValueError),
        (61, ValueError),
        (float("nan"), ValueError),
        ("1", TypeError),
        (None, TypeError),
        (True, TypeError),
    ],
)
def test_bad_interval_starts_nothing(bld: Rig, interval: object, exc: type) -> None:
    drive, sim, _device = bld
    sent = len(sim.requests)
    with pytest.raises(exc, match="interval"):
        drive.keepalive(interval)  # type: ignore[arg-type]
    assert keepalive_threads() == []
    assert sim.requests[sent:] == []
