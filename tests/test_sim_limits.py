"""Each simulator refuses a request for more registers than its manual allows, with the
exception a real device is likely to give, and takes a request right at the limit; the
limits are data (``max_read`` / ``max_write`` on the device class), applied in one place."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import pytest

import benchbus as bb
from benchbus.sim import (
    Atv31Device,
    DriveDevice,
    J2Device,
    PblDevice,
    RegisterDevice,
    SimDevice,
    Simulator,
    TaisongDevice,
)


@dataclass
class Limits:
    make: Callable[[], SimDevice]
    read_at: int  # where a read of max_read registers is answered
    max_read: int
    write_at: int | None  # where a write of max_write registers is taken (None: none is)
    max_write: int


CASES = {
    # BLD / C20: the manuals' 0x03 reads one register; 0x10 takes N (the protocol's 123).
    "BLD2": Limits(lambda: DriveDevice("BLD2"), 0x2103, 1, None, 123),
    "C20": Limits(lambda: DriveDevice("C20"), 0x2103, 1, None, 123),
    # PBL: a frame carries 1..123 data bytes: 61 registers a reply, 59 a 0x10 request.
    "PBL": Limits(PblDevice, 100, 61, 100, 59),
    # J2: 16 registers a read or write.
    "J2": Limits(J2Device, 0, 16, None, 16),
    # Taisong: 37 a read, 20 a write.
    "Taisong": Limits(TaisongDevice, 0x0100, 37, 0x0100, 20),
    # ATV31 section of the Taisong manual: 29 words a read or write.
    "ATV31": Limits(Atv31Device, 0x3000, 29, 0x3000, 29),
}


@pytest.fixture(params=list(CASES))
def rig(request: pytest.FixtureRequest) -> Iterator[tuple[Limits, SimDevice, bb.Bus]]:
    case = CASES[request.param]
    device = case.make()
    with Simulator({1: device}) as sim, bb.Bus(sim.port, timeout=0.5, retries=0) as bus:
        yield case, device, bus


def refused(call: Callable[[], object]) -> int:
    with pytest.raises(bb.ModbusException) as caught:
        call()
    return caught.value.code


def test_limits_are_declared(rig: tuple[Limits, SimDevice, bb.Bus]) -> None:
    case, device, _ = rig
    assert (device.max_read, device.max_write) == (case.max_read, case.max_write)
    assert device.too_many_code == 3  # illegal data value


def test_a_read_at_the_limit_is_answered_and_one_over_refused(
    rig: tuple[Limits, SimDevice, bb.Bus],
) -> None:
    case, _, bus = rig
    assert len(bus.read_holding_registers(1, case.read_at, case.max_read)) == case.max_read
    assert refused(lambda: bus.read_holding_registers(1, case.read_at, case.max_read + 1)) == 3


# BLD and C20 take the protocol's 123 registers a write: the Bus refuses more itself.
@pytest.mark.parametrize("name", [name for name, c in CASES.items() if c.max_write < 123])
def test_a_write_at_the_limit_is_taken_and_one_over_refused(name: str) -> None:
    case = CASES[name]
    device = case.make()
    with Simulator({1: device}) as sim, bb.Bus(sim.port, timeout=0.5, retries=0) as bus:
        write_at_the_limit(case, device, bus)


def write_at_the_limit(case: Limits, device: SimDevice, bus: bb.Bus) -> None:
    at = case.read_at if case.write_at is None else case.write_at
    before = device.read_holding(at, case.max_write + 1)
    over = [(v + 1) & 0xFFFF for v in before]
    assert refused(lambda: bus.write_registers(1, at, over)) == 3
    assert device.read_holding(at, case.max_write + 1) == before  # nothing written
    if case.write_at is not None:
        bus.write_registers(1, at, before[: case.max_write])  # the limit itself is taken


def test_the_limit_is_applied_before_the_device_sees_the_request() -> None:
    seen: list[tuple[int, int]] = []

    class Small(RegisterDevice):
        max_read = 4

        def read_holding(self, address: int, count: int) -> list[int]:
            seen.append((address, count))
            return super().read_holding(address, count)

    with Simulator({1: Small()}) as sim, bb.Bus(sim.port, retries=0) as bus:
        seen.clear()
        assert refused(lambda: bus.read_holding_registers(1, 0, 5)) == 3
        assert bus.read_holding_registers(1, 0, 4) == [0] * 4
    assert seen == [(0, 4)]
