"""A live Bus's ``timeout`` and ``retries`` are settable (a slow command, a long flash
write): the calls that start afterwards use them, a call in flight keeps its own, and a bad
value is refused as the constructor refuses it, leaving the old one."""

from __future__ import annotations

import asyncio
import math
import threading
import time
from typing import Any

import pytest

import benchbus as bb
from benchbus import aio
from benchbus.sim import RegisterDevice, Simulator

ABSENT = 9


def asked(sim: Simulator[Any], unit: int = ABSENT) -> int:
    """How many requests to ``unit`` the simulator has seen."""
    return sum(1 for r in sim.requests if r[0] == unit)


def test_a_timeout_and_retries_set_on_a_live_bus_are_those_the_next_call_uses() -> None:
    with (
        Simulator({1: RegisterDevice({0: 7})}) as sim,
        bb.Bus(sim.port, timeout=3, retries=2) as bus,
    ):
        bus.timeout = 0.2
        bus.retries = 1
        assert (bus.timeout, bus.retries) == (0.2, 1)
        assert "timeout=0.2, retries=1" in repr(bus)
        start = time.monotonic()
        with pytest.raises(bb.ResponseTimeout) as err:
            bus.read_holding_registers(ABSENT, 0, 1)
        took = time.monotonic() - start
        # Two attempts of 0.2 s, not three of 3 s.
        assert asked(sim) == 2
        assert "200ms" in str(err.value) and "2 attempts" in str(err.value)
        assert 0.35 < took < 2.0, took
        bus.retries = 0
        with pytest.raises(bb.ResponseTimeout):
            bus.read_holding_registers(ABSENT, 0, 1)
        assert asked(sim) == 3
        # A device without its own timing follows the Bus's.
        drive = bb.Drive(bus, unit=1)
        assert (drive.timeout, drive.retries) == (0.2, 0)
        bus.timeout = 1.5
        assert drive.timeout == 1.5
        assert bus.read_holding_registers(1, 0, 1) == [7]


def test_a_call_in_flight_keeps_the_timeout_it_started_with() -> None:
    with (
        Simulator({1: RegisterDevice({0: 7})}) as sim,
        bb.Bus(sim.port, timeout=1.0, retries=0) as bus,
    ):
        outcome: list[BaseException] = []

        def call() -> None:
            try:
                bus.read_holding_registers(ABSENT, 0, 1)
            except bb.ResponseTimeout as e:
                outcome.append(e)

        worker = threading.Thread(target=call)
        start = time.monotonic()
        worker.start()
        while asked(sim) == 0 and time.monotonic() - start < 5:
            time.sleep(0.005)
        bus.timeout = 0.1
        worker.join(10)
        took = time.monotonic() - start
        assert len(outcome) == 1 and "1s" in str(outcome[0])
        assert took > 0.8, took
        assert bus.timeout == 0.1


BAD_TIMEOUTS: list[tuple[Any, type[Exception]]] = [
    (0, ValueError),
    (-1, ValueError),
    (math.nan, ValueError),
    (math.inf, ValueError),
    (3601, ValueError),
    ("1", TypeError),
    (True, TypeError),
    (None, TypeError),
    ([1], TypeError),
]
BAD_RETRIES: list[tuple[Any, type[Exception]]] = [
    (-1, ValueError),
    (101, ValueError),
    (2**70, ValueError),
    (1.0, TypeError),
    (True, TypeError),
    (None, TypeError),
    ("2", TypeError),
]


def test_bad_values_are_refused_as_the_constructor_refuses_them_and_change_nothing() -> None:
    with (
        Simulator({1: RegisterDevice({0: 7})}) as sim,
        bb.Bus(sim.port, timeout=0.5, retries=3) as bus,
    ):
        for value, error in BAD_TIMEOUTS:
            with pytest.raises(error, match="timeout"):
                bus.timeout = value
            if value is not None:  # the constructor's default
                with pytest.raises(error, match="timeout"):
                    bb.Bus(sim.port + "-none", timeout=value)
            assert bus.timeout == 0.5
        for value, error in BAD_RETRIES:
            with pytest.raises(error, match="retries"):
                bus.retries = value
            if value is not None:
                with pytest.raises(error, match="retries"):
                    bb.Bus(sim.port + "-none", retries=value)
            assert bus.retries == 3
        with pytest.raises(AttributeError):
            del bus.timeout
        with pytest.raises(AttributeError):
            del bus.retries
        # The limits themselves are taken.
        bus.timeout = 3600
        bus.retries = 0
        bus.retries = 100
        assert (bus.timeout, bus.retries) == (3600.0, 100)
        assert sim.requests == []


def test_an_async_bus_sets_them_on_its_bus() -> None:
    with Simulator({1: RegisterDevice({0: 7})}) as sim:

        async def main() -> None:
            async with aio.AsyncBus(sim.port, timeout=3, retries=2) as abus:
                abus.timeout = 0.2
                abus.retries = 0
                assert (abus.timeout, abus.retries) == (0.2, 0)
                assert (abus.bus.timeout, abus.bus.retries) == (0.2, 0)
                start = time.monotonic()
                with pytest.raises(bb.ResponseTimeout):
                    await abus.read_holding_registers(ABSENT, 0, 1)
                assert time.monotonic() - start < 2.0
                assert asked(sim) == 1
                with pytest.raises(ValueError, match="timeout"):
                    abus.timeout = -1
                with pytest.raises(TypeError, match="retries"):
                    abus.retries = "3"
                assert (abus.timeout, abus.retries) == (0.2, 0)
                assert await abus.read_holding_registers(1, 0, 1) == [7]

        asyncio.run(asyncio.wait_for(main(), 20))


def test_the_calls_that_take_options_take_their_own_timeout_and_retries() -> None:
    with (
        Simulator({1: RegisterDevice({0: 7})}) as sim,
        bb.Bus(sim.port, timeout=3, retries=3) as bus,
    ):
        calls = [
            lambda: bus.write_register(ABSENT, 0, 1, timeout=0.2, retries=1),
            lambda: bus.write_registers(ABSENT, 0, [1, 2], timeout=0.2, retries=1),
            lambda: bus.request(ABSENT, 3, b"\0\0\0\1", reply_length=3, timeout=0.2, retries=1),
        ]
        for n, call in enumerate(calls, start=1):
            start = time.monotonic()
            with pytest.raises(bb.ResponseTimeout) as err:
                call()
            assert time.monotonic() - start < 2.5
            assert "200ms" in str(err.value) and "2 attempts" in str(err.value)
            assert asked(sim) == 2 * n
        # The Bus's own are left as they were.
        assert (bus.timeout, bus.retries) == (3.0, 3)
        bus.write_register(1, 0, 9, timeout=0.5, retries=0)
        assert bus.read_holding_registers(1, 0, 1) == [9]
