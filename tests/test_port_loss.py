"""A port that vanishes mid-run (an unplugged USB adapter), reopen, reconnect, exclusive open.

The simulator's pseudo-terminal stands in for the adapter: stopping the simulator closes the
master side, which hangs up the Bus's end exactly as unplugging an adapter does. A
``/dev/pts/N`` cannot be made again at the same number, so the Bus opens a symlink in a tmp
dir instead (as a user opens ``/dev/serial/by-id/...``): removing the link makes the path
vanish, and pointing it at the restarted simulator's new pty brings it back.
"""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

import benchbus as bb
from benchbus.sim import DriveDevice, RegisterDevice, SimDevice, Simulator

#: How soon a lost port must be reported: far below any timeout x attempts used here.
AT_ONCE = 0.25


class Adapter:
    """A simulated line behind a stable path that can be unplugged and plugged in again."""

    def __init__(self, sim: Simulator[SimDevice], path: Path) -> None:
        self.sim = sim
        self.path = path
        self.plug()

    def plug(self) -> None:
        """Start the simulator (on a fresh pty) and point the path at it."""
        self.sim.start()
        self.path.unlink(missing_ok=True)
        self.path.symlink_to(self.sim.port)

    def unplug(self) -> None:
        """Hang up the line and remove the path."""
        self.sim.stop()
        self.path.unlink(missing_ok=True)

    @property
    def port(self) -> str:
        """The stable path a Bus opens."""
        return str(self.path)


@pytest.fixture
def adapter(tmp_path: Path) -> Iterator[Adapter]:
    sim: Simulator[SimDevice] = Simulator({1: RegisterDevice({0x3006: 1450})})
    a = Adapter(sim, tmp_path / "ttyUSB0")
    yield a
    sim.stop()


def timed(call: Callable[[], object]) -> tuple[Exception | None, float]:
    """Run ``call()``; the exception it raised (None if none) and the seconds it took."""
    start = time.monotonic()
    try:
        call()
    except Exception as exc:
        return exc, time.monotonic() - start
    return None, time.monotonic() - start


def test_a_vanished_port_raises_port_error_at_once(adapter: Adapter) -> None:
    with bb.Bus(adapter.port, timeout=1.0, retries=2) as bus:
        assert bus.read_holding_registers(1, 0x3006, 1) == [1450]
        adapter.unplug()
        for call in (
            lambda: bus.read_holding_registers(1, 0x3006, 1),
            lambda: bus.write_register(1, 0x3006, 1),
            lambda: bus.broadcast_write_register(0x3006, 1),
            lambda: bus.scan([1, 2]),
        ):
            exc, took = timed(call)
            assert isinstance(exc, bb.PortError), exc
            assert isinstance(exc, OSError)
            assert took < AT_ONCE, took
            assert "lost" in str(exc) and "reopen()" in str(exc)
        assert not bus.closed
        assert "lost" in repr(bus)
        assert bus.stats.timeouts == 0


def test_a_port_vanishing_during_a_call_ends_it_at_once(adapter: Adapter) -> None:
    adapter.sim.set_silent(1)
    with bb.Bus(adapter.port, timeout=2.0, retries=2) as bus:
        threading.Timer(0.2, adapter.unplug).start()
        exc, took = timed(lambda: bus.read_holding_registers(1, 0x3006, 1))
        assert isinstance(exc, bb.PortError), exc
        assert 0.15 < took < 0.2 + AT_ONCE, took
        assert "hung up" in str(exc)


def test_reopen_brings_the_port_back_and_keeps_the_stats(adapter: Adapter) -> None:
    with bb.Bus(adapter.port, baudrate=9600, parity="E", timeout=0.5) as bus:
        assert bus.read_holding_registers(1, 0x3006, 1) == [1450]
        adapter.unplug()
        with pytest.raises(bb.PortError):
            bus.read_holding_registers(1, 0x3006, 1)
        # Not back yet: reopen says so, and the bus stays without a port.
        with pytest.raises(bb.PortError, match="cannot open"):
            bus.reopen()
        exc, took = timed(lambda: bus.read_holding_registers(1, 0x3006, 1))
        assert isinstance(exc, bb.PortError) and took < AT_ONCE
        adapter.plug()
        bus.reopen()
        assert bus.read_holding_registers(1, 0x3006, 1) == [1450]
        bus.write_register(1, 0x3006, 1500)
        assert bus.read_holding_registers(1, 0x3006, 1) == [1500]
        assert (bus.port, bus.baudrate, bus.parity) == (adapter.port, 9600, "E")
        stats = bus.stats
        assert (stats.transactions, stats.reopens, stats.timeouts) == (4, 1, 0)


def test_reopen_opens_a_closed_bus_and_an_open_one_afresh(adapter: Adapter) -> None:
    bus = bb.Bus(adapter.port)
    bus.reopen()  # an open port: closed and opened again (its own lock does not stop it)
    assert bus.read_holding_registers(1, 0x3006, 1) == [1450]
    bus.close()
    bus.reopen()
    assert not bus.closed
    assert bus.read_holding_registers(1, 0x3006, 1) == [1450]
    bus.close()
    adapter.unplug()
    with pytest.raises(bb.PortError):
        bus.reopen()
    assert bus.closed  # a failed reopen leaves a closed bus closed
    assert bus.stats.reopens == 2


def test_reconnect_reopens_a_port_that_came_back_between_calls(adapter: Adapter) -> None:
    with bb.Bus(adapter.port, reconnect=True) as bus:
        assert bus.reconnect and "reconnect=True" in repr(bus)
        assert bus.read_holding_registers(1, 0x3006, 1) == [1450]
        adapter.unplug()
        adapter.plug()
        # The old handle is found hung up before anything is sent: reopened, no error.
        assert bus.read_holding_registers(1, 0x3006, 1) == [1450]
        assert bus.stats.reopens == 1


def test_reconnect_tries_once_per_call_while_the_port_is_gone(adapter: Adapter) -> None:
    with bb.Bus(adapter.port, timeout=1.0, retries=2, reconnect=True) as bus:
        adapter.unplug()
        for _ in range(3):
            exc, took = timed(lambda: bus.read_holding_registers(1, 0x3006, 1))
            assert isinstance(exc, bb.PortError), exc
            assert took < AT_ONCE, took
            assert "tried to reopen it" in str(exc) and "cannot open" in str(exc)
        adapter.plug()
        assert bus.read_holding_registers(1, 0x3006, 1) == [1450]
        assert bus.stats.reopens == 1


def test_reconnect_fails_the_call_whose_request_was_lost(adapter: Adapter) -> None:
    adapter.sim.set_silent(1)
    with bb.Bus(adapter.port, timeout=2.0, retries=2, reconnect=True) as bus:
        threading.Timer(0.1, adapter.unplug).start()
        exc, took = timed(lambda: bus.write_register(1, 0x3006, 7))
        assert isinstance(exc, bb.PortError), exc
        assert took < 0.1 + AT_ONCE, took
        assert "the next call tries to reopen it" in str(exc)
        adapter.sim.set_silent(1, False)
        adapter.plug()
        bus.write_register(1, 0x3006, 7)
        assert bus.read_holding_registers(1, 0x3006, 1) == [7]


def test_reconnect_never_reopens_a_closed_bus(adapter: Adapter) -> None:
    bus = bb.Bus(adapter.port, reconnect=True)
    bus.close()
    with pytest.raises(bb.PortError, match="closed"):
        bus.read_holding_registers(1, 0x3006, 1)
    assert bus.closed and bus.stats.reopens == 0


@pytest.mark.parametrize("value", [1, "yes", 1.0])
def test_reconnect_must_be_a_bool(adapter: Adapter, value: object) -> None:
    with pytest.raises(TypeError, match="reconnect"):
        bb.Bus(adapter.port, reconnect=value)  # type: ignore[arg-type]
    with bb.Bus(adapter.port, reconnect=None) as bus:  # type: ignore[arg-type]
        assert not bus.reconnect


@pytest.mark.parametrize("reconnect", [False, True])
def test_a_drive_keeps_working_after_the_port_comes_back(tmp_path: Path, reconnect: bool) -> None:
    device = DriveDevice("BLD2")
    sim: Simulator[SimDevice] = Simulator({1: device})
    adapter = Adapter(sim, tmp_path / "ttyUSB0")
    try:
        bus = bb.Bus(adapter.port, timeout=0.25, reconnect=reconnect)
        drive = bb.Drive(bus, unit=1)
        drive.speed_setpoint = 1200
        adapter.unplug()
        exc, took = timed(lambda: drive.speed_setpoint)
        assert isinstance(exc, bb.PortError) and took < AT_ONCE, (exc, took)
        adapter.plug()
        if not reconnect:
            bus.reopen()
        # The same Drive object, on the same Bus: nothing rebuilt.
        assert drive.bus is bus
        assert drive.speed_setpoint == 1200
        drive.speed_setpoint = 900
        assert drive.speed_setpoint == 900
        assert bus.stats.reopens == 1
        bus.close()
    finally:
        sim.stop()


# ---- exclusive open ---------------------------------------------------------------------

IN_USE = "in use by another Bus or program"


def test_a_port_another_bus_holds_is_refused(adapter: Adapter) -> None:
    with bb.Bus(adapter.port) as first:
        for path in (adapter.port, adapter.sim.port):  # by the link and by the pty itself
            with pytest.raises(bb.PortError, match=IN_USE):
                bb.Bus(path)
        # The refused opener changed nothing: the holder goes on.
        assert first.read_holding_registers(1, 0x3006, 1) == [1450]
    # Released on close: another Bus takes it, and the first cannot reopen it meanwhile.
    with bb.Bus(adapter.port) as again:
        assert again.read_holding_registers(1, 0x3006, 1) == [1450]
        with pytest.raises(bb.PortError, match=IN_USE):
            first.reopen()
        assert first.closed


HOLDER = """
import sys
import benchbus as bb
bus = bb.Bus(sys.argv[1])
print("holding", flush=True)
sys.stdin.read()
bus.close()
"""


def test_a_port_another_process_holds_is_refused(adapter: Adapter) -> None:
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, adapter.port],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "holding"
        with pytest.raises(bb.PortError, match=IN_USE) as e:
            bb.Bus(adapter.port)
        assert adapter.port in str(e.value)
    finally:
        holder.communicate("", timeout=10)
    assert holder.returncode == 0
    with bb.Bus(adapter.port) as bus:
        assert bus.read_holding_registers(1, 0x3006, 1) == [1450]
