"""Soak: benchbus on a noisy simulated line, every result checked against the simulator.

    python bench/soak.py                     # 10,000 transactions at a 5 % fault rate
    python bench/soak.py --transactions 2000 --rate 0.1 --seed 3 --retries 3 --timeout 0.05

Two simulated units (``benchbus.sim.RegisterDevice``) sit behind a line that spoils a share
of the replies (``benchbus.sim.Faults``: bit flips, dropped bytes, truncation, garbage before
and after, late, duplicated and wrong-unit replies). A seeded mix of reads of 1..125
registers, single and block writes, and writes the unit refuses (read-only registers, an
exception reply) goes through one ``benchbus.Bus``. Each result is checked against what the
unit holds (``Simulator.peek``), and after a failed write the unit must hold either the old
or the new values. The run passes when no wrong value came back, every failure is a
``ResponseTimeout`` or a ``FrameError`` (``CrcError`` is one), no call took longer than its
bound, and at least 99.5 % of the transactions succeeded. Exit status 0 on a pass, 1 if not.

A call's bound is ``attempts x (timeout + silence + wire) + margin``: per attempt the
timeout, six t3.5 of silence (before the request, restarted by stale bytes, and to see the
end of a bad frame), the request's and the longest possible reply's time on the wire at
the line's baud rate, and a scheduling margin for the whole call (0.25 s).

The line is a pseudo-terminal, which carries bytes at once: wire times count in the bound
only, as the library counts them in its deadlines. tests/test_faults.py runs a short soak
through :func:`run_soak`.
"""

from __future__ import annotations

import argparse
import collections
import dataclasses
import random
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import benchbus as bb
from benchbus.sim import FAULT_KINDS, Faults, RegisterDevice, Simulator

sys.path.insert(0, str(Path(__file__).resolve().parent))

from lineemu import silence  # the bench's own t3.5

#: Registers each unit holds in the soak (addresses 0 .. SPAN-1), and the read-only ones.
SPAN = 600
READONLY = frozenset({SPAN - 1, SPAN - 2})
#: The failures a noisy line may cause (CrcError is a FrameError).
EXPECTED_FAILURES = (bb.ResponseTimeout, bb.FrameError)
#: Longest RTU frame, and how many t3.5 of silence an attempt may spend.
MAX_ADU = 256
SILENCES = 6


@dataclasses.dataclass(frozen=True)
class SoakConfig:
    """What to run: how many transactions, how noisy, and the bus's settings."""

    transactions: int = 10_000
    rate: float = 0.05
    seed: int = 1
    retries: int = 3
    timeout: float = 0.05
    baudrate: int = 115_200
    #: How late a ``delay`` fault makes its reply (None: 1.6 x timeout, so it lands in the
    #: master's next attempt).
    delay: float | None = None
    kinds: tuple[str, ...] = FAULT_KINDS
    #: Scheduling allowance on top of each call's computed bound.
    margin: float = 0.25
    units: tuple[int, ...] = (1, 2)

    @property
    def fault_delay(self) -> float:
        """Seconds a ``delay`` fault holds its reply."""
        return self.delay if self.delay is not None else 1.6 * self.timeout

    def char_time(self) -> float:
        """Seconds per character at 8N1."""
        return 10.0 / self.baudrate

    def t3_5(self) -> float:
        """The inter-frame silence (the bench's own reading of the spec)."""
        return silence(self.baudrate, self.char_time())

    def bound(self, request_len: int) -> float:
        """Longest a call whose request is ``request_len`` bytes may take."""
        wire = (request_len + MAX_ADU) * self.char_time()
        per_attempt = self.timeout + SILENCES * self.t3_5() + wire
        return (self.retries + 1) * per_attempt + self.margin


@dataclasses.dataclass
class SoakResult:
    """What happened: outcomes, faults, timings and the bus's counters."""

    config: SoakConfig
    ok: int = 0
    refused: int = 0  # exception replies expected (writes to read-only registers)
    ops: collections.Counter[str] = dataclasses.field(default_factory=collections.Counter)
    failures: collections.Counter[str] = dataclasses.field(default_factory=collections.Counter)
    unexpected: list[str] = dataclasses.field(default_factory=list)
    wrong: list[str] = dataclasses.field(default_factory=list)
    ambiguous_writes: int = 0  # failed writes (the unit held the new values after all of them)
    times: list[float] = dataclasses.field(default_factory=list)
    over_bound: list[str] = dataclasses.field(default_factory=list)
    worst: tuple[float, float] = (0.0, 0.0)  # (took, bound) of the call closest to its bound
    faults: dict[str, int] = dataclasses.field(default_factory=dict)
    requests: int = 0  # requests on the line (retries too), each answered by one reply
    stats: dict[str, int] = dataclasses.field(default_factory=dict)
    sim_errors: list[str] = dataclasses.field(default_factory=list)
    elapsed: float = 0.0

    @property
    def transactions(self) -> int:
        """Calls made."""
        return sum(self.ops.values())

    @property
    def recovered(self) -> float:
        """Share of the calls that gave their right result (a value, or the refusal)."""
        return (self.ok + self.refused) / self.transactions if self.transactions else 0.0

    def problems(self) -> list[str]:
        """The pass criteria that failed (empty: the soak passes)."""
        out = []
        if self.wrong:
            out.append(f"{len(self.wrong)} wrong values, first: {self.wrong[0]}")
        if self.unexpected:
            out.append(f"{len(self.unexpected)} unexpected failures, first: {self.unexpected[0]}")
        if self.over_bound:
            out.append(
                f"{len(self.over_bound)} calls over their bound, first: {self.over_bound[0]}"
            )
        if self.recovered < 0.995:
            out.append(f"recovered {100 * self.recovered:.2f} % < 99.5 %")
        if self.sim_errors:
            out.append(f"simulator errors: {self.sim_errors}")
        return out

    def report(self) -> str:
        """The figures, as printed by the script."""
        c = self.config
        n = self.transactions
        total_faults = sum(self.faults.values())
        times = sorted(self.times)
        p50 = statistics.median(times) if times else 0.0
        p99 = times[min(len(times) - 1, int(0.99 * len(times)))] if times else 0.0
        took, bound = self.worst
        failures = ", ".join(f"{k} {v}" for k, v in sorted(self.failures.items())) or "none"
        kinds = "  ".join(f"{k} {self.faults.get(k, 0)}" for k in FAULT_KINDS)
        stats = ", ".join(
            f"{k}={self.stats.get(k, 0)}"
            for k in (
                "transactions",
                "retries",
                "timeouts",
                "crc_errors",
                "frame_errors",
                "exceptions",
                "stale_bytes",
            )
        )
        lines = [
            f"benchbus soak: {n} transactions, {100 * c.rate:g} % of replies spoiled"
            f" (seed {c.seed}), retries={c.retries}, timeout={c.timeout * 1000:g} ms,"
            f" {c.baudrate} 8N1, delay fault {c.fault_delay * 1000:g} ms",
            f"  operations     reads {self.ops['read']}, write_register"
            f" {self.ops['write_register']}, write_registers {self.ops['write_registers']},"
            f" refused writes {self.ops['refused_write']}",
            f"  faults         {total_faults} injected in {self.requests} replies"
            f" ({100 * total_faults / max(1, self.requests):.2f} %)",
            f"                 {kinds}",
            f"  recovered      {self.ok + self.refused} / {n} ({100 * self.recovered:.2f} %)",
            f"  failures       {failures}; unexpected classes {len(self.unexpected)}",
            f"  wrong values   {len(self.wrong)}"
            f" (failed writes that had been applied: {self.ambiguous_writes})",
            f"  call time      p50 {p50 * 1000:.1f} ms, p99 {p99 * 1000:.1f} ms,"
            f" max {max(times, default=0.0) * 1000:.1f} ms;"
            f" closest to its bound: {took * 1000:.1f} of {bound * 1000:.0f} ms;"
            f" over bound {len(self.over_bound)}",
            f"  bus.stats      {stats}",
            f"  elapsed        {self.elapsed:.1f} s",
            f"  result         {'PASS' if not self.problems() else 'FAIL'}",
        ]
        lines += [f"  problem        {p}" for p in self.problems()]
        return "\n".join(lines)


def _initial(rng: random.Random) -> dict[int, int]:
    return {a: rng.randrange(0x10000) for a in range(SPAN)}


def run_soak(
    config: SoakConfig, progress: Callable[[int, SoakResult], None] | None = None
) -> SoakResult:
    """Run the soak of ``config``; ``progress(i, result)`` is called every 1000 calls."""
    c = config
    rng = random.Random(c.seed ^ 0x50A4)  # the workload; the faults draw from c.seed
    devices = {
        unit: RegisterDevice(_initial(rng), readonly=READONLY, max_read=125, max_write=123)
        for unit in c.units
    }
    model = {unit: list(dev.registers[:SPAN]) for unit, dev in devices.items()}
    result = SoakResult(config=c)
    faults = Faults(rate=c.rate, seed=c.seed, kinds=c.kinds, delay=c.fault_delay)
    start = time.monotonic()
    with (
        Simulator(devices, baudrate=c.baudrate, faults=faults) as sim,
        bb.Bus(sim.port, baudrate=c.baudrate, timeout=c.timeout, retries=c.retries) as bus,
    ):
        for i in range(c.transactions):
            _one(rng, sim, bus, model, result)
            if progress is not None and (i + 1) % 1000 == 0:
                progress(i + 1, result)
        sim.faults = None
        result.faults = sim.fault_counts
        result.requests = sim.request_count  # each answered once, so the replies seen
        result.stats = bus.stats.as_dict()
        # On a clean line now, everything the units hold reads back as the model says.
        for unit in c.units:
            for address in range(0, SPAN, 125):
                count = min(125, SPAN - address)
                got = bus.read_holding_registers(unit, address, count)
                if got != model[unit][address : address + count]:
                    result.wrong.append(f"final read-back of unit {unit} at {address} differs")
        result.sim_errors = [repr(e) for e in sim.errors]
    result.elapsed = time.monotonic() - start
    return result


def _one(
    rng: random.Random,
    sim: Simulator[RegisterDevice],
    bus: bb.Bus,
    model: dict[int, list[int]],
    result: SoakResult,
) -> None:
    c = result.config
    unit = rng.choice(c.units)
    roll = rng.random()
    call: Callable[[], object]
    if roll < 0.5:
        op = "read"
        count = rng.choice((rng.randint(1, 8), rng.randint(9, 40), rng.randint(41, 125)))
        address = rng.randrange(SPAN - count + 1)
        request_len = 8
        call = lambda: bus.read_holding_registers(unit, address, count)  # noqa: E731
        new: list[int] = []
    elif roll < 0.98:
        if roll < 0.74:
            op = "write_register"
            count = 1
        else:
            op = "write_registers"
            count = rng.choice((rng.randint(1, 8), rng.randint(9, 60)))
        address = rng.randrange(SPAN - 2 - count + 1)  # clear of the read-only registers
        new = [rng.randrange(0x10000) for _ in range(count)]
        if op == "write_register":
            request_len = 8
            call = lambda: bus.write_register(unit, address, new[0])  # noqa: E731
        else:
            request_len = 9 + 2 * count
            call = lambda: bus.write_registers(unit, address, new)  # noqa: E731
    else:
        op = "refused_write"
        count = 1
        address = rng.choice(sorted(READONLY))
        new = [rng.randrange(0x10000)]
        request_len = 8
        call = lambda: bus.write_register(unit, address, new[0])  # noqa: E731
    result.ops[op] += 1
    what = f"{op} unit {unit} at {address} x{count}"
    old = model[unit][address : address + count]

    t0 = time.perf_counter()
    try:
        got = call()
        error: BaseException | None = None
    except bb.BenchbusError as e:
        got, error = None, e
    took = time.perf_counter() - t0

    result.times.append(took)
    bound = c.bound(request_len)
    if took / bound > result.worst[0] / max(result.worst[1], 1e-9):
        result.worst = (took, bound)
    if took > bound:
        result.over_bound.append(f"{what}: {took:.3f} s > {bound:.3f} s")

    truth = sim.peek(unit, address, count)
    if op == "refused_write":
        if isinstance(error, bb.ModbusException) and error.code == 2:
            result.refused += 1
        elif error is None:
            result.wrong.append(f"{what}: a refused write reported done")
        else:
            _failed(result, what, error)
        if truth != old:
            result.wrong.append(f"{what}: a read-only register changed to {truth}")
        return
    if error is not None:
        _failed(result, what, error)
        if op != "read":
            if truth not in (old, new):
                result.wrong.append(f"{what}: failed write left {truth}, not {old} or {new}")
            elif truth == new:
                result.ambiguous_writes += 1
            model[unit][address : address + count] = truth
        return
    if op == "read":
        if got != truth:
            result.wrong.append(f"{what}: got {got}, the unit holds {truth}")
    elif truth != new:
        result.wrong.append(f"{what}: write reported done, the unit holds {truth} not {new}")
    else:
        model[unit][address : address + count] = new
    if truth != model[unit][address : address + count]:
        result.wrong.append(f"{what}: the unit holds {truth}, nobody wrote that")
        model[unit][address : address + count] = truth
    result.ok += 1


def _failed(result: SoakResult, what: str, error: BaseException) -> None:
    name = type(error).__name__
    result.failures[name] += 1
    if not isinstance(error, EXPECTED_FAILURES):
        result.unexpected.append(f"{what}: {name}: {error}")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the soak from the command line; print the figures; 0 on a pass."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    d = SoakConfig()
    parser.add_argument("--transactions", type=int, default=d.transactions)
    parser.add_argument("--rate", type=float, default=d.rate, help="faults per reply, 0..1")
    parser.add_argument("--seed", type=int, default=d.seed)
    parser.add_argument("--retries", type=int, default=d.retries)
    parser.add_argument("--timeout", type=float, default=d.timeout, help="seconds per attempt")
    parser.add_argument("--baudrate", type=int, default=d.baudrate)
    parser.add_argument(
        "--delay", type=float, default=None, help="seconds a delay fault adds (1.6 x timeout)"
    )
    parser.add_argument(
        "--kinds", default=",".join(FAULT_KINDS), help="comma-separated fault kinds (all)"
    )
    args = parser.parse_args(argv)
    config = SoakConfig(
        transactions=args.transactions,
        rate=args.rate,
        seed=args.seed,
        retries=args.retries,
        timeout=args.timeout,
        baudrate=args.baudrate,
        delay=args.delay,
        kinds=tuple(k.strip() for k in args.kinds.split(",") if k.strip()),
    )

    def progress(i: int, r: SoakResult) -> None:
        print(
            f"  ... {i} calls, {r.ok + r.refused} right, {sum(r.failures.values())} failed,"
            f" {len(r.wrong)} wrong",
            file=sys.stderr,
            flush=True,
        )

    result = run_soak(config, progress)
    print(result.report())
    return 0 if not result.problems() else 1


if __name__ == "__main__":
    sys.exit(main())
