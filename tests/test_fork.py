"""A Bus belongs to the process that opened it: a child made by fork (``os.fork``,
``multiprocessing``'s fork start method) that got a copy of it raises PortError at once on
any use, naming fork and what to do; its ``close()`` and garbage collection send nothing,
raise nothing and leave the parent's port (its exclusive mode, its lock, its connection)
as it was; and the parent's Bus goes on. The same for a device, an AsyncBus and a gateway.

Each child runs its checks and reports them through a pipe; the parent checks them, and the
simulator's request counter says whether the child sent anything. Every child is bounded
in time (killed, and the test failed, if it hangs).
"""

from __future__ import annotations

import asyncio
import errno
import fcntl
import gc
import json
import multiprocessing
import os
import signal
import struct
import termios
import threading
import time
import traceback
from collections.abc import Callable, Iterator
from multiprocessing.connection import Connection
from typing import Any

import pytest

import benchbus as bb
from benchbus import aio
from benchbus.sim import DriveDevice, RegisterDevice, Simulator

# Python 3.12+ warns that forking a process with threads (the simulator's) may deadlock the
# child: that is the point of these tests, and the child never touches those threads.
pytestmark = pytest.mark.filterwarnings("ignore:.*multi-threaded.*fork:DeprecationWarning")

BAUD = 115_200
TIMEOUT = 0.2
REGISTERS = {1: {10: 111, 11: 112}, 2: {10: 222}}
#: Far below any timeout: what "at once" means for a child's call.
AT_ONCE = 0.1
#: ``TIOCGEXCL`` (Linux): whether a tty is in exclusive mode.
TIOCGEXCL = getattr(termios, "TIOCGEXCL", 0x80045440)


@pytest.fixture
def sim() -> Iterator[Simulator[RegisterDevice]]:
    devices = {unit: RegisterDevice(dict(regs)) for unit, regs in REGISTERS.items()}
    devices[3] = RegisterDevice({10: 333})
    with Simulator(devices, baudrate=BAUD) as s:
        s.set_silent(3)
        yield s


def open_bus(port: str, timeout: float = TIMEOUT) -> bb.Bus:
    return bb.Bus(port, baudrate=BAUD, timeout=timeout, retries=0)


def in_child(work: Callable[[], dict[str, Any]], limit: float = 10.0) -> dict[str, Any]:
    """What ``work()`` returns, run in a child made by ``os.fork``. Fails the test if it
    raised, or if the child has not ended within ``limit`` seconds (it is killed then)."""
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: reports, and never returns into pytest
        try:
            os.close(read_end)
            try:
                report: dict[str, Any] = {"result": work()}
            except BaseException:
                report = {"error": traceback.format_exc()}
            os.write(write_end, json.dumps(report).encode())
        finally:
            os._exit(0)
    os.close(write_end)
    deadline = time.monotonic() + limit
    while os.waitpid(pid, os.WNOHANG) == (0, 0):
        if time.monotonic() > deadline:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            os.close(read_end)
            pytest.fail(f"the child hung (killed after {limit} s)")
        time.sleep(0.01)
    with os.fdopen(read_end, "rb") as reader:
        report = json.loads(reader.read() or b'{"error": "the child reported nothing"}')
    assert "error" not in report, report["error"]
    result: dict[str, Any] = report["result"]
    return result


def failure(call: Callable[[], object]) -> list[Any]:
    """``[class name, message, seconds]`` of what ``call()`` raised (``"none"`` and its
    result if it returned)."""
    start = time.monotonic()
    try:
        value = call()
    except Exception as exc:
        return [type(exc).__name__, str(exc), time.monotonic() - start]
    return ["none", repr(value), time.monotonic() - start]


def assert_fork_error(seen: list[Any], parent: int, port: str) -> None:
    """``seen`` (from :func:`failure`) is the PortError of a Bus used in a fork's child."""
    name, message, seconds = seen
    assert name == "PortError", seen
    assert message.startswith(f"port {port}: this Bus was opened by process {parent}; "), seen
    assert "got it by fork() and cannot use it" in message, seen
    assert "open a new Bus once the parent has closed its own" in message, seen
    assert "'spawn' or 'forkserver'" in message, seen
    assert "gateway" in message, seen
    assert seconds < AT_ONCE, seen


def port_fds(port: str) -> int:
    """How many of this process's descriptors are open on ``port``."""
    target = os.stat(port)
    count = 0
    for name in os.listdir("/dev/fd"):
        try:
            st = os.fstat(int(name))
        except OSError:
            continue
        count += (st.st_dev, st.st_ino) == (target.st_dev, target.st_ino)
    return count


def exclusive(port: str) -> bool:
    """Whether the tty ``port`` is in exclusive mode (``TIOCEXCL``): another open is refused
    (EBUSY), or, for root, whom the mode lets in, ``TIOCGEXCL`` says so."""
    try:
        fd = os.open(port, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    except OSError as exc:
        if exc.errno == errno.EBUSY:
            return True
        raise
    try:
        if os.geteuid() != 0:
            return False
        mode = fcntl.ioctl(fd, TIOCGEXCL, struct.pack("i", 0))
        return struct.unpack("i", mode)[0] != 0
    finally:
        os.close(fd)


def assert_parent_goes_on(bus: bb.Bus, sim: Simulator[RegisterDevice]) -> None:
    """The parent's Bus still reads the right values, and holds its port exclusively."""
    for _ in range(20):
        assert bus.read_holding_registers(1, 10, 2) == [111, 112]
        assert bus.read_holding_registers(2, 10, 1) == [222]
    assert exclusive(sim.port)
    with pytest.raises(bb.PortError, match="in use"):
        open_bus(sim.port)


# ---- the Bus and a device ---------------------------------------------------------------


def test_a_child_cannot_use_the_bus_and_its_close_and_gc_leave_the_port_to_the_parent(
    sim: Simulator[RegisterDevice],
) -> None:
    # Held only through `box`, so that the child can drop its last reference.
    box = [open_bus(sim.port)]
    box[0].read_holding_registers(1, 10, 1)
    devices = [bb.Instrument(box[0], unit=1)]
    parent, port = os.getpid(), sim.port
    assert exclusive(port)
    sent = sim.request_count

    def child() -> dict[str, Any]:
        calls: dict[str, Callable[[], object]] = {
            "read": lambda: box[0].read_holding_registers(2, 10, 1),
            "write": lambda: box[0].write_register(1, 11, 999),
            "write_registers": lambda: box[0].write_registers(1, 10, [1, 2]),
            "broadcast": lambda: box[0].broadcast_write_register(11, 999),
            "request": lambda: box[0].request(1, 0x03, b"\x00\x0a\x00\x01"),
            "identification": lambda: box[0].read_device_identification(1),
            "scan": lambda: box[0].scan([1, 2]),
            "poll": lambda: box[0].poll(1, 10, interval=0.01),
            "stats": lambda: box[0].stats,
            "reopen": lambda: box[0].reopen(),
            "device read": lambda: devices[0].read_register(10),
            "device write": lambda: devices[0].write_register(11, 5),
        }
        seen = {name: failure(call) for name, call in calls.items()}
        looks = [box[0].closed, repr(box[0]), box[0].port, box[0].baudrate]
        before = port_fds(port)
        closing = [failure(box[0].close), failure(box[0].close), failure(devices[0].close)]
        after_close = port_fds(port)
        devices.clear()
        box.clear()
        gc.collect()
        return {
            "seen": seen,
            "looks": looks,
            "closing": closing,
            "fds": [before, after_close, port_fds(port)],
            "exclusive": exclusive(port),
        }

    report = in_child(child)
    assert len(report["seen"]) == 12
    for seen in report["seen"].values():
        assert_fork_error(seen, parent, port)
    closed, text, port_name, baudrate = report["looks"]
    assert closed is True
    assert text.endswith(f", of process {parent})"), text
    assert (port_name, baudrate) == (port, BAUD)
    assert [name for name, _, _ in report["closing"]] == ["none"] * 3, report["closing"]
    # close() let go of the child's copy of the port; nothing was left for the GC.
    before, after_close, after_gc = report["fds"]
    assert before - after_close == 1, report["fds"]
    assert after_gc == after_close, report["fds"]
    assert report["exclusive"] is True
    assert sim.request_count == sent, "the child sent requests"
    assert sim.peek(1, 11) == [112]  # the child's writes never reached the unit
    assert_parent_goes_on(box[0], sim)
    assert box[0].stats.transactions >= 41


def test_gc_in_a_child_lets_go_of_its_copy_of_the_port_and_nothing_else(
    sim: Simulator[RegisterDevice],
) -> None:
    box = [open_bus(sim.port)]
    port = sim.port

    def child() -> dict[str, Any]:
        before = port_fds(port)
        box.clear()
        gc.collect()
        return {"fds": [before, port_fds(port)], "exclusive": exclusive(port)}

    report = in_child(child)
    before, after = report["fds"]
    assert before - after == 1, report["fds"]
    assert report["exclusive"] is True
    assert sim.request_count == 0
    assert_parent_goes_on(box[0], sim)


def test_a_child_forked_while_a_thread_is_mid_call_gets_the_error_at_once(
    sim: Simulator[RegisterDevice],
) -> None:
    # Long enough to outlast the child, whose fork and collection take a while in a big
    # process (the whole test run).
    box = [open_bus(sim.port, timeout=4.0)]
    parent, port = os.getpid(), sim.port
    outcome: list[BaseException] = []

    def slow_call() -> None:  # unit 3 is silent: the call holds the line for 4 s
        try:
            box[0].read_holding_registers(3, 10, 1)
        except BaseException as exc:
            outcome.append(exc)

    caller = threading.Thread(target=slow_call, daemon=True)
    caller.start()
    deadline = time.monotonic() + 2.0
    while sim.request_count == 0 and time.monotonic() < deadline:
        time.sleep(0.001)
    assert sim.request_count == 1, "the slow call's request never went out"

    def child() -> dict[str, Any]:
        seen = [
            failure(lambda: box[0].read_holding_registers(1, 10, 1)),
            failure(lambda: box[0].broadcast_write_register(11, 5)),
            failure(lambda: box[0].reopen()),
            failure(lambda: bb.Instrument(box[0], unit=1).read_register(10)),
            failure(lambda: box[0].stats),
        ]
        start = time.monotonic()
        closing = [failure(box[0].close), failure(lambda: (box[0].closed, repr(box[0])))]
        box.clear()
        seconds = time.monotonic() - start
        gc.collect()  # raises nothing (untimed: in a big process a collection takes its time)
        return {"seen": seen, "closing": closing, "seconds": seconds}

    report = in_child(child, limit=5.0)
    assert caller.is_alive(), "the parent's call ended before the child was checked"
    for seen in report["seen"]:
        assert_fork_error(seen, parent, port)
    assert [name for name, _, _ in report["closing"]] == ["none", "none"], report["closing"]
    assert report["seconds"] < AT_ONCE
    caller.join(10.0)
    assert len(outcome) == 1 and isinstance(outcome[0], bb.ResponseTimeout), outcome
    assert sim.request_count == 1, "the child sent requests"
    assert_parent_goes_on(box[0], sim)


def test_a_drive_with_a_keepalive_in_a_child_raises_and_closes_at_once() -> None:
    with Simulator({1: DriveDevice("BLD2")}, baudrate=BAUD) as drive_sim:
        drives = [bb.Drive(open_bus(drive_sim.port), unit=1)]
        keepalive = drives[0].keepalive(0.02)
        parent, port = os.getpid(), drive_sim.port

        def child() -> dict[str, Any]:
            seen = [
                failure(lambda: drives[0].speed),
                failure(lambda: drives[0].forward()),
                failure(lambda: drives[0].__exit__(None, None, None)),  # sends the stop
            ]
            closing = failure(drives[0].close)
            return {"seen": seen, "closing": closing, "running": keepalive.running}

        report = in_child(child)
        for seen in report["seen"]:
            assert_fork_error(seen, parent, port)
        assert report["closing"][0] == "none"
        assert report["closing"][2] < AT_ONCE, report["closing"]
        assert report["running"] is False  # the keepalive thread is the parent's
        # The parent's keepalive goes on reading, and only the parent's requests came.
        reads = keepalive.reads
        deadline = time.monotonic() + 2.0
        while keepalive.reads < reads + 3 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert keepalive.running and keepalive.reads >= reads + 3
        drives[0].close()
        assert not keepalive.running
        assert keepalive.errors == 0
        assert drive_sim.request_count == keepalive.reads + 1  # and the identity check's
        drives[0].bus.close()


def _mp_child(box: list[bb.Bus], results: Connection) -> None:
    """A multiprocessing child (fork start method): uses its copy of the parent's Bus."""
    seen = failure(lambda: box[0].read_holding_registers(1, 10, 1))
    closing = failure(box[0].close)
    box.clear()
    gc.collect()
    results.send([seen, closing])


def test_multiprocessing_fork_children_get_the_error_and_the_parent_goes_on(
    sim: Simulator[RegisterDevice],
) -> None:
    box = [open_bus(sim.port)]
    assert box[0].read_holding_registers(1, 10, 1) == [111]
    sent = sim.request_count
    context = multiprocessing.get_context("fork")
    children = []
    for _ in range(3):
        receiver, sender = context.Pipe(duplex=False)
        process = context.Process(target=_mp_child, args=(box, sender))
        process.start()
        children.append((process, receiver))
    for process, receiver in children:
        assert receiver.poll(10.0), "a child hung"
        seen, closing = receiver.recv()
        process.join(10.0)
        assert process.exitcode == 0
        assert_fork_error(seen, os.getpid(), sim.port)
        assert closing[0] == "none", closing
    assert sim.request_count == sent, "a child sent requests"
    assert_parent_goes_on(box[0], sim)


def test_a_child_opens_its_own_bus_once_the_parent_has_closed_its_own(
    sim: Simulator[RegisterDevice],
) -> None:
    box = [open_bus(sim.port)]
    port = sim.port
    ready_read, ready_write = os.pipe()
    go_read, go_write = os.pipe()

    def child() -> dict[str, Any]:
        os.write(ready_write, b"r")
        os.read(go_read, 1)  # the parent has closed its Bus
        # The child's copy of the port still holds its lock, until the child lets go.
        while_held = failure(lambda: open_bus(port))
        box[0].close()
        with open_bus(port) as own:
            values = own.read_holding_registers(2, 10, 1)
            own.write_register(1, 11, 7)
        return {"while_held": while_held[:2], "values": values}

    def close_then_go() -> None:
        os.read(ready_read, 1)  # the child exists, with its copy of the open port
        box[0].close()
        os.write(go_write, b"g")

    closer = threading.Thread(target=close_then_go, daemon=True)
    closer.start()
    report = in_child(child)
    closer.join(5.0)
    for fd in (ready_read, ready_write, go_read, go_write):
        os.close(fd)
    name, message = report["while_held"]
    assert name == "PortError" and "in use" in message, report
    assert report["values"] == [222]
    assert sim.peek(1, 11) == [7]
    # The child has ended: the parent opens the port again.
    box[0].reopen()
    assert box[0].read_holding_registers(1, 11, 1) == [7]


# ---- asyncio -----------------------------------------------------------------------------


def test_an_async_bus_and_device_in_a_child_raise_at_once_and_close_quietly(
    sim: Simulator[RegisterDevice],
) -> None:
    abus = aio.AsyncBus(sim.port, baudrate=BAUD, timeout=TIMEOUT, retries=0, workers=2)
    device = aio.Instrument(abus, unit=1)

    async def parent_reads() -> list[int]:
        # Several at once: the worker threads exist (idle) when the child is made.
        reads = [abus.read_holding_registers(1, 10, 1) for _ in range(4)]
        values = [v for (v,) in await asyncio.gather(*reads)]
        return [*values, await device.read_register(11)]

    assert asyncio.run(parent_reads()) == [111] * 4 + [112]
    parent, port = os.getpid(), sim.port
    sent = sim.request_count

    def child() -> dict[str, Any]:
        async def main() -> dict[str, Any]:
            async def caught(make: Callable[[], Any]) -> list[Any]:
                start = time.monotonic()
                try:
                    value = await asyncio.wait_for(make(), 2.0)
                except Exception as exc:
                    return [type(exc).__name__, str(exc), time.monotonic() - start]
                return ["none", repr(value), time.monotonic() - start]

            seen = [
                await caught(lambda: abus.read_holding_registers(1, 10, 1)),
                await caught(lambda: abus.write_register(1, 11, 999)),
                await caught(lambda: abus.reopen()),
                await caught(lambda: device.read_register(10)),
                await caught(lambda: device.read_registers(10, 2)),
                failure(lambda: abus.poll(1, 10, interval=0.01)),
                failure(lambda: abus.stats),
            ]
            closing = [
                await caught(device.aclose),
                await caught(abus.aclose),
                await caught(abus.aclose),
            ]
            return {"seen": seen, "closing": closing, "closed": abus.closed}

        return asyncio.run(main())

    report = in_child(child)
    assert len(report["seen"]) == 7
    for seen in report["seen"]:
        assert_fork_error(seen, parent, port)
    assert [name for name, _, _ in report["closing"]] == ["none"] * 3, report["closing"]
    assert report["closed"] is True
    assert sim.request_count == sent, "the child sent requests"
    assert asyncio.run(parent_reads()) == [111] * 4 + [112]
    asyncio.run(abus.aclose())
    assert abus.closed


# ---- the gateway -------------------------------------------------------------------------


def test_the_gateway_in_a_child_raises_and_children_share_the_line_through_it(
    sim: Simulator[RegisterDevice],
) -> None:
    bus = open_bus(sim.port, timeout=0.5)
    with bb.Gateway(bus, "127.0.0.1:0") as gw:
        # The parent's own client, over TCP: its connection must outlive the child.
        clients = [bb.Bus(gw.url, timeout=2.0, retries=0)]
        assert clients[0].read_holding_registers(1, 10, 1) == [111]
        parent, url = os.getpid(), gw.url
        sent = sim.request_count

        def child() -> dict[str, Any]:
            seen = [
                failure(gw.start),
                failure(lambda: gw.handle(1, b"\x03\x00\x0a\x00\x01")),
                failure(lambda: bb.Gateway(bus, "127.0.0.1:0")),
                failure(lambda: clients[0].read_holding_registers(1, 10, 1)),
            ]
            closing = [failure(gw.stop), failure(clients[0].close)]
            clients.clear()
            gc.collect()
            # What to do in a child: a Bus of its own, through the parent's gateway.
            with bb.Bus(url, timeout=2.0, retries=0) as own:
                values = [own.read_holding_registers(1, 10, 2)]
                values.append(own.read_holding_registers(2, 10, 1))
            return {"seen": seen, "closing": closing, "values": values}

        report = in_child(child)
        assert_fork_error(report["seen"][0], parent, bus.port)
        assert_fork_error(report["seen"][1], parent, bus.port)
        assert_fork_error(report["seen"][2], parent, bus.port)
        assert_fork_error(report["seen"][3], parent, url)
        assert [name for name, _, _ in report["closing"]] == ["none", "none"], report
        assert report["values"] == [[111, 112], [222]]
        # Only the child's own client's two reads reached the line.
        assert sim.request_count == sent + 2
        # The parent's client and gateway go on.
        assert clients[0].read_holding_registers(2, 10, 1) == [222]
        assert gw.stats.connections == 2
        clients[0].close()
    assert_parent_goes_on(bus, sim)
    bus.close()
