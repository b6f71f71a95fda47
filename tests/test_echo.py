"""Local echo (issue 9, item 7): an RS485 adapter whose receiver stays on while it transmits
hears every request it sends. With ``echo=True`` the Bus reads each echo back and checks it;
a garbled echo is a collision and is retried; the wrong setting says so. Checked against the
simulator's line, which echoes (``Simulator(echo=True)``) and garbles (``collide_next``).
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

import benchbus as bb
from benchbus.sim import DriveDevice, RegisterDevice, Simulator

TIMEOUT = 0.05
REGISTERS = {10: 0x1234, 11: 0xABCD}


@pytest.fixture
def sim() -> Iterator[Simulator[RegisterDevice | DriveDevice]]:
    devices: dict[int, RegisterDevice | DriveDevice] = {
        1: RegisterDevice(dict(REGISTERS)),
        2: DriveDevice("BLD2"),
    }
    with Simulator(devices, echo=True) as s:
        yield s


def echo_bus(sim: Simulator[RegisterDevice | DriveDevice], retries: int = 2) -> bb.Bus:
    return bb.Bus(sim.port, timeout=TIMEOUT, retries=retries, echo=True)


def test_an_echoing_adapter_works_with_echo_true(
    sim: Simulator[RegisterDevice | DriveDevice],
) -> None:
    with echo_bus(sim) as bus:
        assert bus.echo is True
        assert "echo=True" in repr(bus)
        for _ in range(20):
            assert bus.read_holding_registers(1, 10, 2) == sim.peek(1, 10, 2)
        bus.write_registers(1, 10, [7, 8])
        assert sim.peek(1, 10, 2) == [7, 8]
        bus.write_register(1, 11, 9)
        assert sim.peek(1, 11) == [9]
        stats = bus.stats
        # Every echo was taken as an echo, never left behind as stale input or a bad reply.
        assert (stats.transactions, stats.frame_errors, stats.crc_errors) == (22, 0, 0)
        assert (stats.stale_bytes, stats.timeouts, stats.retries) == (0, 0, 0)
    assert len(sim.requests) == len(sim.replies) == 22


def test_a_drive_behind_an_echoing_adapter(sim: Simulator[RegisterDevice | DriveDevice]) -> None:
    with echo_bus(sim) as bus:
        drive = bb.Drive(bus, unit=2)
        drive.speed_setpoint = 1500
        drive.accel_time = 2.5
        assert sim.devices[2].peek(0x2001) == 1500
        assert drive.speed_setpoint == 1500
        assert drive.accel_time == pytest.approx(2.5)
        assert bus.stats.frame_errors == 0


def test_a_broadcast_behind_an_echoing_adapter(
    sim: Simulator[RegisterDevice | DriveDevice],
) -> None:
    with bb.Bus(sim.port, timeout=TIMEOUT, turnaround=0.02, echo=True) as bus:
        bus.broadcast_write_register(10, 0x0042)
        assert sim.peek(1, 10) == [0x0042]
        assert bus.read_holding_registers(1, 10, 1) == [0x0042]
        assert bus.stats.stale_bytes == 0


def test_a_collision_garbles_the_echo_and_is_retried(
    sim: Simulator[RegisterDevice | DriveDevice],
) -> None:
    with echo_bus(sim, retries=2) as bus:
        sim.collide_next(2)
        assert bus.read_holding_registers(1, 10, 2) == list(REGISTERS.values())
        stats = bus.stats
        assert (stats.frame_errors, stats.retries, stats.transactions) == (2, 2, 1)
    sent = list(sim.requests)
    assert len(sent) == 3
    crc_ok = [bb.crc16(f[:-2]).to_bytes(2, "little") == f[-2:] for f in sent]
    assert crc_ok == [False, False, True], "the units saw two garbled requests, then the retry"


def test_collisions_beyond_the_retries_raise_frame_error_and_write_nothing(
    sim: Simulator[RegisterDevice | DriveDevice],
) -> None:
    with echo_bus(sim, retries=1) as bus:
        sim.collide_next(2)
        with pytest.raises(bb.FrameError, match="collision") as info:
            bus.write_register(1, 10, 0x0777)
        assert not isinstance(info.value, bb.CrcError)
        assert (info.value.unit, info.value.function) == (1, 0x06)
        assert sim.peek(1, 10) == [REGISTERS[10]]
        assert len(sim.requests) == 2
        # The line is clean again: the next call goes through at once.
        bus.write_register(1, 10, 0x0777)
        assert sim.peek(1, 10) == [0x0777]


def test_an_echo_on_a_bus_not_told_of_it_says_so(
    sim: Simulator[RegisterDevice | DriveDevice],
) -> None:
    with (
        bb.Bus(sim.port, timeout=TIMEOUT, retries=0) as bus,
        pytest.raises(bb.FrameError, match="echo=True"),
    ):
        bus.read_holding_registers(1, 10, 2)


def test_echo_true_on_an_adapter_that_does_not_echo_is_a_port_error(
    sim: Simulator[RegisterDevice | DriveDevice],
) -> None:
    sim.echo = False
    with echo_bus(sim, retries=2) as bus:
        with pytest.raises(bb.PortError, match="does not echo"):
            bus.read_holding_registers(1, 10, 2)
        assert len(sim.requests) == 1, "not retried"
        sim.set_silent(1)
        with pytest.raises(bb.PortError, match="no local echo"):
            bus.read_holding_registers(1, 10, 2)
        # Not a lost port: the Bus goes on once the adapter echoes.
        sim.set_silent(1, False)
        sim.echo = True
        assert bus.read_holding_registers(1, 10, 2) == list(REGISTERS.values())


def test_echo_must_be_a_bool(sim: Simulator[RegisterDevice | DriveDevice]) -> None:
    with pytest.raises(TypeError, match="echo must be True or False"):
        bb.Bus(sim.port, echo=1)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="echo must be True or False"):
        sim.echo = 1  # type: ignore[assignment]
    with pytest.raises(ValueError, match="n must be"):
        sim.collide_next(-1)
    assert sim.requests == []


def test_a_collision_on_a_broadcast_is_reported_not_repeated(
    sim: Simulator[RegisterDevice | DriveDevice],
) -> None:
    with bb.Bus(sim.port, timeout=TIMEOUT, turnaround=0.02, echo=True) as bus:
        sim.collide_next(1)
        with pytest.raises(bb.FrameError, match="local echo"):
            bus.broadcast_write_register(10, 0x0042)
        assert len(sim.requests) == 1
        assert sim.peek(1, 10) == [REGISTERS[10]]
        assert (bus.stats.broadcasts, bus.stats.frame_errors) == (1, 1)


def test_an_echo_lost_after_one_was_seen_is_a_retried_frame_error(
    sim: Simulator[RegisterDevice | DriveDevice],
) -> None:
    with echo_bus(sim, retries=1) as bus:
        assert bus.read_holding_registers(1, 10, 2) == sim.peek(1, 10, 2)
        sim.echo = False
        with pytest.raises(bb.FrameError, match="local echo"):
            bus.read_holding_registers(1, 10, 2)
        assert len(sim.requests) == 3, "the attempt was repeated"
