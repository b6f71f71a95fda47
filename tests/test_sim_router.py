"""The one request router of the simulated line and network (``benchbus.sim._router``), without
I/O: bytes in as the library and the server send them, bytes out as they would be written."""

from __future__ import annotations

import time

import pytest

from benchbus import _mbap
from benchbus.sim._line import SimState
from benchbus.sim._network import NetworkState
from benchbus.sim._router import SERVER_REPLY_TIMEOUT, Router, framing
from benchbus.sim._rtu import with_crc
from benchbus.sim._units import UnitHooks

READ = bytes.fromhex("03 3006 0001")  # read one register
WRITE = bytes.fromhex("06 2001 05DC")  # write one register
NETWORKS = [None, "rtu+tcp", "tcp"]


def wrap(network: str | None, unit: int, pdu: bytes, transaction: int = 0x1234) -> bytes:
    if network == "tcp":
        return _mbap.frame(transaction, unit, pdu)
    return with_crc(bytes([unit]) + pdu)


def make_router(
    network: str | None, *, answers_writes: bool = True, answers_broadcast: bool = False
) -> tuple[Router, SimState]:
    state = SimState() if network is None else NetworkState()
    hooks = UnitHooks(
        "test",
        answers_broadcast=lambda unit: answers_broadcast,
        answers_writes=lambda unit: answers_writes,
    )
    router = Router(
        state,
        framing(network),
        units=frozenset({1, 2}),
        broadcast=True,
        hooks=hooks,
        end_of_frame_silence=0.005,
        cut_partial=network is None,
    )
    return router, state


def run(router: Router, library: bytes = b"", server: bytes = b"") -> None:
    now = time.monotonic()
    if library:
        router.rx_req.feed(library, now)
    if server:
        router.rx_rep.feed(server, now)
    assert router.step(now)
    assert router.step(time.monotonic())  # releases the replies held since (no delay)


def take(buf: bytearray) -> bytes:
    out = bytes(buf)
    del buf[:]
    return out


@pytest.mark.parametrize("network", NETWORKS)
def test_a_request_goes_to_the_server_and_its_reply_back(network: str | None) -> None:
    router, state = make_router(network)
    request = wrap(network, 1, READ)
    run(router, library=request)
    assert take(router.to_server) == request
    reply = wrap(network, 1, bytes.fromhex("03 02 05AA"))
    run(router, server=reply)
    assert take(router.to_library) == reply
    assert list(state.requests) == [request]
    assert list(state.replies) == [reply]


@pytest.mark.parametrize("network", NETWORKS)
def test_requests_wait_their_turn(network: str | None) -> None:
    router, _ = make_router(network)
    first, second = wrap(network, 1, READ, 1), wrap(network, 2, READ, 2)
    run(router, library=first + second)
    assert take(router.to_server) == first  # one at a time, as on a half-duplex line
    run(router, server=wrap(network, 1, bytes.fromhex("03 02 0001"), 1))
    assert take(router.to_server) == second


@pytest.mark.parametrize("network", NETWORKS)
def test_a_unit_that_is_not_there(network: str | None) -> None:
    router, _ = make_router(network)
    run(router, library=wrap(network, 9, READ))
    assert not router.to_server
    # Silence on a serial line; a Modbus TCP gateway says its target failed to respond.
    expected = wrap(network, 9, bytes([0x83, 0x0B])) if network == "tcp" else b""
    assert bytes(router.to_library) == expected


@pytest.mark.parametrize("network", NETWORKS)
def test_forced_exception_and_refused_function_are_answered_without_the_server(
    network: str | None,
) -> None:
    router, state = make_router(network)
    state.add_exception_rule(0x06, 1, 1)
    run(router, library=wrap(network, 1, READ))
    assert take(router.to_library) == wrap(network, 1, bytes([0x83, 0x06]))
    run(router, library=wrap(network, 1, bytes.fromhex("01 0000 0001")))
    assert take(router.to_library) == wrap(network, 1, bytes([0x81, 0x01]))
    assert not router.to_server


@pytest.mark.parametrize("network", NETWORKS)
def test_a_broadcast_goes_to_each_unit_unanswered(network: str | None) -> None:
    router, _ = make_router(network)
    run(router, library=wrap(network, 0, WRITE))
    for unit in (1, 2):
        assert take(router.to_server) == wrap(network, unit, WRITE)
        run(router, server=wrap(network, unit, WRITE))
    assert not router.to_library


@pytest.mark.parametrize("network", NETWORKS)
def test_a_unit_that_does_not_answer_writes_acts_silently(network: str | None) -> None:
    router, _ = make_router(network, answers_writes=False)
    request = wrap(network, 1, WRITE)
    run(router, library=request)
    assert take(router.to_server) == request
    run(router, server=request)
    assert not router.to_library


@pytest.mark.parametrize("network", [None, "rtu+tcp"])
def test_rtu_requests_with_a_bad_crc_are_ignored(network: str | None) -> None:
    router, state = make_router(network)
    request = wrap(network, 1, READ)
    run(router, library=request[:-1] + bytes([request[-1] ^ 1]))
    assert not router.to_server and not router.to_library
    assert state.request_count == 1


@pytest.mark.parametrize("network", NETWORKS)
def test_a_server_that_does_not_answer_is_given_up(network: str | None) -> None:
    router, _ = make_router(network)
    run(router, library=wrap(network, 1, READ) + wrap(network, 2, READ))
    take(router.to_server)
    deadline = router.deadline()
    assert deadline is not None
    assert deadline - time.monotonic() > SERVER_REPLY_TIMEOUT - 0.5  # the server's time
    assert router.step(deadline)
    assert take(router.to_server) == wrap(network, 2, READ)  # the next one's turn
    expected = wrap(network, 1, bytes([0x83, 0x0B])) if network == "tcp" else b""
    # A held reply is released by a later step (its release time is the real clock's now).
    router.step(time.monotonic())
    assert bytes(router.to_library) == expected


def test_not_an_mbap_frame_loses_the_stream() -> None:
    router, state = make_router("tcp")
    router.rx_req.feed(bytes.fromhex("0001 0007 0006 01 03 0000 0001"), time.monotonic())
    assert not router.step(time.monotonic())
    assert state.request_count == 1
