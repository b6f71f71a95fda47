"""Many threads on one Bus, and several Buses at once (issue 9, item 4, the in-process part).

Eight threads share one Bus to four simulated units for :data:`DURATION` seconds, mixing
single writes, block writes and reads. Each thread writes registers no other thread touches,
with values that carry its own number, and checks every value it reads back; so a reply
delivered to the wrong caller, or a frame cut into by another thread's, shows as a wrong value
here and as a broken frame at the simulator, which logs every request as it arrives on the line.
A thread that never comes back is a deadlock: threads are joined with a timeout.

Several Buses on their own lines, one thread each, wait for their devices at the same time:
the GIL is released while a call waits, so four buses take about as long as one.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator

import pytest

import benchbus as bb
from benchbus.sim import RegisterDevice, Simulator

#: Seconds of traffic from the eight threads (the issue asks for 10 s).
DURATION = 10.0
THREADS = 8
UNITS = (1, 2, 3, 4)
#: How long a thread may take to finish after the traffic stops before it counts as stuck.
JOIN_TIMEOUT = 15.0


def frame(*fields: int, words: tuple[int, ...] = ()) -> bytes:
    """A request as it should go on the wire: bytes, then big-endian words, then the CRC."""
    body = bytes(fields) + b"".join(w.to_bytes(2, "big") for w in words)
    return body + bb.crc16(body).to_bytes(2, "little")


def whole(request: bytes) -> bool:
    """Whether ``request`` is one whole, valid request to one of :data:`UNITS`."""
    if len(request) < 8 or request[0] not in UNITS:
        return False
    if bb.crc16(request[:-2]).to_bytes(2, "little") != request[-2:]:
        return False
    function = request[1]
    if function in (0x03, 0x06):
        return len(request) == 8
    if function == 0x10:
        count = int.from_bytes(request[4:6], "big")
        return request[6] == 2 * count and len(request) == 9 + 2 * count
    return False


class Worker:
    """Thread ``index``: unit ``UNITS[index % 4]``, registers ``base .. base + 4`` its own."""

    def __init__(self, bus: bb.Bus, index: int, stop_at: float) -> None:
        self.bus, self.index, self.stop_at = bus, index, stop_at
        self.unit = UNITS[index % len(UNITS)]
        self.base = 0x1000 + 0x100 * index
        self.tag = (index + 1) << 12  # the top nibble of every value it writes
        self.shadow = [self.tag] * 5  # what its registers hold, as far as it knows
        self.sent: list[bytes] = []  # the frames it asked for, in order
        self.error: BaseException | None = None

    def value(self, n: int) -> int:
        return self.tag | (n & 0x0FFF)

    def run(self) -> None:
        unit, base = self.unit, self.base
        try:
            # Start from a known state: its five registers hold its tag.
            self.bus.write_registers(unit, base, self.shadow)
            self.sent.append(frame(unit, 0x10, *divmod(base, 256), 0, 5, 10, words=(self.tag,) * 5))
            n = 0
            while time.monotonic() < self.stop_at:
                step = n % 4
                if step == 0:  # one register, 0x06
                    value = self.value(n)
                    self.bus.write_register(unit, base, value)
                    self.sent.append(frame(unit, 0x06, *divmod(base, 256), *divmod(value, 256)))
                    self.shadow[0] = value
                elif step == 1:  # four registers, 0x10
                    values = [self.value(n + k) for k in range(4)]
                    self.bus.write_registers(unit, base + 1, values)
                    start = divmod(base + 1, 256)
                    self.sent.append(frame(unit, 0x10, *start, 0, 4, 8, words=tuple(values)))
                    self.shadow[1:] = values
                elif step == 2:  # its own registers back
                    got = self.bus.read_holding_registers(unit, base, 5)
                    self.sent.append(frame(unit, 0x03, *divmod(base, 256), 0, 5))
                    assert got == self.shadow, f"thread {self.index}: {got} != {self.shadow}"
                else:  # a register nobody writes, at an address only this thread reads
                    got = self.bus.read_holding_registers(unit, self.index, 1)
                    self.sent.append(frame(unit, 0x03, 0, self.index, 0, 1))
                    expected = [unit * 100 + self.index]
                    assert got == expected, f"thread {self.index}: {got} != {expected}"
                n += 1
        except BaseException as exc:
            self.error = exc

    def owns(self, request: bytes) -> bool:
        """Whether ``request`` is to this thread's unit at an address only it uses."""
        address = int.from_bytes(request[2:4], "big")
        mine = self.base <= address < self.base + 5 or address == self.index
        return request[0] == self.unit and mine


@pytest.fixture
def four_units() -> Iterator[Simulator[RegisterDevice]]:
    # Registers 0..THREADS-1 of unit u hold u * 100 + k, and nobody writes them.
    devices = {u: RegisterDevice({k: u * 100 + k for k in range(THREADS)}) for u in UNITS}
    with Simulator(devices) as sim:
        yield sim


def test_eight_threads_share_one_bus(four_units: Simulator[RegisterDevice]) -> None:
    sim = four_units
    with bb.Bus(sim.port, timeout=1.0, retries=0) as bus:
        stop_at = time.monotonic() + DURATION
        workers = [Worker(bus, i, stop_at) for i in range(THREADS)]
        threads = [threading.Thread(target=w.run, name=f"worker-{w.index}") for w in workers]
        started = time.monotonic()
        for t in threads:
            t.start()
        for t in threads:
            t.join(max(0.0, stop_at + JOIN_TIMEOUT - time.monotonic()))
        took = time.monotonic() - started
        stuck = [t.name for t in threads if t.is_alive()]
        assert not stuck, f"deadlock: {stuck} still running {took:.1f} s after the start"
        errors = [(w.index, w.error) for w in workers if w.error is not None]
        assert not errors, errors
        stats = bus.stats

    requests, replies = list(sim.requests), list(sim.replies)
    sent = sum(len(w.sent) for w in workers)
    # No interleaving: every request the simulator saw is one whole, valid frame...
    broken = [r.hex(" ") for r in requests if not whole(r)]
    assert broken == [], f"{len(broken)} broken frames, e.g. {broken[:3]}"
    # ...each thread's requests reached the line whole, once and in its own order...
    for w in workers:
        assert [r for r in requests if w.owns(r)] == w.sent, f"thread {w.index}"
    # ...and nothing else did; every request got its reply, with nothing retried.
    assert len(requests) == len(replies) == sent == stats.transactions
    assert all(bb.crc16(r[:-2]).to_bytes(2, "little") == r[-2:] for r in replies)
    assert (stats.retries, stats.timeouts, stats.crc_errors, stats.frame_errors) == (0, 0, 0, 0)
    assert sim.request_times == sorted(sim.request_times)
    # Every write landed on the unit it was meant for, where its thread last left it.
    for w in workers:
        assert sim.devices[w.unit].registers[w.base : w.base + 5] == w.shadow
    assert not sim.errors
    assert all(len(w.sent) > 50 for w in workers), [len(w.sent) for w in workers]
    print(
        f"\n{sent} transactions from {THREADS} threads on one Bus to {len(UNITS)} units in "
        f"{took:.1f} s ({sent / took:.0f}/s): 0 interleaved frames, 0 wrong values"
    )


# ---- several buses at once ---------------------------------------------------------------------

BUSES = 4
READS = 20
#: Each simulated device holds every reply this long: the calls spend it waiting.
REPLY_DELAY = 0.03


def timed(jobs: list[Callable[[], None]]) -> float:
    """Seconds for ``jobs`` run in a thread each, all at once."""
    errors: list[BaseException] = []

    def guarded(job: Callable[[], None]) -> None:
        try:
            job()
        except BaseException as exc:
            errors.append(exc)

    threads = [threading.Thread(target=guarded, args=(job,)) for job in jobs]
    start = time.monotonic()
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    took = time.monotonic() - start
    assert not any(t.is_alive() for t in threads), "a bus thread is stuck"
    assert not errors, errors
    return took


def test_buses_in_threads_wait_in_parallel() -> None:
    sims = [Simulator({1: RegisterDevice({0x3006: 1000 + i})}) for i in range(BUSES)]
    try:
        for sim in sims:
            sim.start()
            sim.reply_delay = REPLY_DELAY
        buses = [bb.Bus(sim.port, timeout=1.0, retries=0) for sim in sims]
        try:

            def reads(i: int) -> Callable[[], None]:
                def job() -> None:
                    for _ in range(READS):
                        assert buses[i].read_holding_registers(1, 0x3006, 1) == [1000 + i]

                return job

            timed([reads(i) for i in range(BUSES)])  # warm up every line
            one = timed([reads(0)])
            together = timed([reads(i) for i in range(BUSES)])
        finally:
            for bus in buses:
                bus.close()
    finally:
        for sim in sims:
            sim.stop()
    # One bus alone waits READS x REPLY_DELAY; four in turn would wait four times that.
    assert one >= READS * REPLY_DELAY
    assert together < 2.5 * one, f"{BUSES} buses took {together:.2f} s, one {one:.2f} s"
    print(f"\n{BUSES} buses x {READS} reads in {together:.2f} s, 1 bus x {READS} in {one:.2f} s")
    for i, sim in enumerate(sims):
        assert len(sim.requests) == (3 if i == 0 else 2) * READS
