"""A simulator's frame logs are bounded: they keep the most recent ``log_size`` frames, so a
simulator served for days does not grow, and ``request_count`` still counts every request."""

from __future__ import annotations

import pytest

import benchbus as bb
from benchbus.sim import RegisterDevice, Simulator


def address_of(request: bytes, network: str | None) -> int:
    pdu = request[7:] if network == "tcp" else request[1:-2]
    return int.from_bytes(pdu[1:3], "big")


@pytest.mark.parametrize("network", [None, "tcp", "rtu+tcp"])
def test_the_logs_keep_the_newest_frames(network: str | None) -> None:
    device = RegisterDevice({a: a + 1 for a in range(300)})
    with Simulator({1: device}, network=network, log_size=50) as sim:
        sim.clear_log()  # the start-up probe is not ours
        with bb.Bus(sim.port, timeout=1.0) as bus:
            for address in range(200):
                assert bus.read_holding_registers(1, address, 1) == [address + 1]
        assert sim.log_size == 50
        requests, times, replies = sim.requests, sim.request_times, sim.replies
        assert len(requests) == len(times) == len(replies) == 50
        assert [address_of(r, network) for r in requests] == list(range(150, 200))
        assert [
            int.from_bytes(r[-4:-2] if network != "tcp" else r[-2:], "big") for r in replies
        ] == [a + 1 for a in range(150, 200)]
        assert times == sorted(times)
        assert sim.request_count == 200
        sim.clear_log()
        assert (sim.requests, sim.replies, sim.request_times, sim.request_count) == ([], [], [], 0)


def test_the_default_bound() -> None:
    sim = Simulator({1: RegisterDevice()})
    assert sim.log_size == 10_000


def test_a_log_is_a_snapshot() -> None:
    with Simulator({1: RegisterDevice()}) as sim, bb.Bus(sim.port) as bus:
        before = sim.requests
        bus.read_holding_registers(1, 0, 1)
        assert len(sim.requests) == len(before) + 1  # the earlier list did not change
        before.clear()
        assert sim.requests  # clearing a snapshot leaves the log alone


@pytest.mark.parametrize(
    ("size", "error"), [(0, ValueError), (-1, ValueError), (1.5, TypeError), (True, TypeError)]
)
def test_a_bad_log_size_is_refused(size: object, error: type[Exception]) -> None:
    with pytest.raises(error, match="log_size"):
        Simulator({1: RegisterDevice()}, log_size=size)  # type: ignore[arg-type]
