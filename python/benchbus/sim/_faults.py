"""A noisy line: random, seeded faults applied to the replies on their way to the library.

The forwarder between the library and the simulated units (``benchbus.sim._line``) hands
every reply it is about to put on the line to a :class:`FaultInjector`, which draws from its
own ``random.Random(seed)`` whether to spoil it and how. Pure Python, no pymodbus.
"""

from __future__ import annotations

import dataclasses
import math
import random
from collections.abc import Collection

from benchbus.sim._rtu import with_crc

__all__ = ["FAULT_KINDS", "FaultInjector", "Faults", "Injection"]

#: Every kind of fault the line can inject, in the order :class:`Faults` keeps them.
FAULT_KINDS: tuple[str, ...] = (
    "bitflip",
    "drop_byte",
    "truncate",
    "garbage_before",
    "garbage_after",
    "delay",
    "duplicate",
    "wrong_unit",
)

#: Most bytes of noise the garbage kinds add.
MAX_GARBAGE = 8


@dataclasses.dataclass(frozen=True)
class Faults:
    """How noisy the simulated line is: which faults, how often, from which seed.

    ::

        sim = Simulator(devices, faults=Faults(rate=0.05, seed=7))
        sim.faults = Faults(rate=1.0, kinds={"truncate"}, limit=1)  # the next reply only
        sim.faults = None                                           # a clean line again

    Each reply on its way to the library is spoiled with probability :attr:`rate`, by one
    fault of a kind drawn evenly from :attr:`kinds`:

    ``bitflip``
        one bit of one byte (anywhere, CRC included) is inverted.
    ``drop_byte``
        one byte (anywhere) is left out.
    ``truncate``
        the reply stops early: only its first 1 .. n-1 bytes are sent.
    ``garbage_before`` / ``garbage_after``
        1 .. 8 random bytes go on the line just before / just after the reply.
    ``delay``
        the reply is held :attr:`delay` more seconds (set it past the master's timeout: the
        reply then arrives during the master's next attempt or request). Replies after it
        wait their turn behind it, as a slow unit's would.
    ``duplicate``
        the reply is sent twice, back to back.
    ``wrong_unit``
        the reply carries another unit address (1..247) and a correct CRC for it.

    Requests are never touched: a write whose reply is spoiled has been applied. All the
    choices come from one ``random.Random(seed)`` drawn once per reply, so a run that sees
    the same replies in the same order is spoiled the same way. A reply also spoiled by
    ``Simulator.corrupt_next`` gets no random fault and does not draw.
    """

    #: Probability (0..1) that a reply is spoiled.
    rate: float = 0.05
    #: Seed of the random sequence.
    seed: int = 0
    #: The kinds to draw from (a subset of :data:`FAULT_KINDS`, at least one); kept as a
    #: tuple in :data:`FAULT_KINDS` order whatever collection was given.
    kinds: Collection[str] = FAULT_KINDS
    #: Extra seconds a ``delay`` fault holds its reply.
    delay: float = 0.15
    #: Most faults injected in all (None: no limit); then the line is clean.
    limit: int | None = None

    def __post_init__(self) -> None:
        """Check every field; ValueError / TypeError on a bad one."""
        if isinstance(self.rate, bool) or not isinstance(self.rate, (int, float)):
            raise TypeError(f"rate must be a number, not {type(self.rate).__name__}")
        if not 0.0 <= self.rate <= 1.0:
            raise ValueError(f"rate must be 0..1, not {self.rate!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int):
            raise TypeError(f"seed must be an int, not {type(self.seed).__name__}")
        if isinstance(self.kinds, str) or not isinstance(self.kinds, Collection):
            raise TypeError(f"kinds must be a collection of kind names, not {self.kinds!r}")
        unknown = sorted(str(k) for k in self.kinds if k not in FAULT_KINDS)
        if unknown:
            raise ValueError(f"unknown fault kinds {unknown}; the kinds are {list(FAULT_KINDS)}")
        kinds = tuple(k for k in FAULT_KINDS if k in self.kinds)
        if not kinds:
            raise ValueError("kinds must name at least one fault kind")
        object.__setattr__(self, "kinds", kinds)
        if isinstance(self.delay, bool) or not isinstance(self.delay, (int, float)):
            raise TypeError(f"delay must be a number, not {type(self.delay).__name__}")
        if not (math.isfinite(self.delay) and self.delay >= 0.0):
            raise ValueError(f"delay must be >= 0 seconds, not {self.delay!r}")
        if self.limit is not None and (
            isinstance(self.limit, bool) or not isinstance(self.limit, int) or self.limit < 0
        ):
            raise ValueError(f"limit must be None or an int >= 0, not {self.limit!r}")


@dataclasses.dataclass
class Injection:
    """What the line sends for one reply: ``frames`` in order, after ``delay`` more seconds."""

    frames: list[bytes]
    delay: float = 0.0
    kind: str | None = None


class FaultInjector:
    """Draws the faults of one :class:`Faults` run and counts them (not thread-safe)."""

    def __init__(self, faults: Faults, counts: dict[str, int]) -> None:
        """Start ``faults``' random sequence; each injection adds 1 to ``counts[kind]``."""
        self.faults = faults
        self.counts = counts
        for kind in FAULT_KINDS:
            counts.setdefault(kind, 0)
        self._rng = random.Random(faults.seed)
        self._injected = 0

    def apply(self, reply: bytes) -> Injection:
        """The frames that go on the line for ``reply`` (the reply itself when unspoiled)."""
        faults = self.faults
        if faults.limit is not None and self._injected >= faults.limit:
            return Injection([reply])
        rng = self._rng
        if not rng.random() < faults.rate or len(reply) < 2:
            return Injection([reply])
        kind = rng.choice(list(faults.kinds))
        injection = self._spoil(kind, reply)
        self._injected += 1
        self.counts[kind] = self.counts.get(kind, 0) + 1
        return injection

    def _spoil(self, kind: str, reply: bytes) -> Injection:
        rng = self._rng
        n = len(reply)
        if kind == "bitflip":
            at = rng.randrange(n)
            spoiled = bytearray(reply)
            spoiled[at] ^= 1 << rng.randrange(8)
            return Injection([bytes(spoiled)], kind=kind)
        if kind == "drop_byte":
            at = rng.randrange(n)
            return Injection([reply[:at] + reply[at + 1 :]], kind=kind)
        if kind == "truncate":
            return Injection([reply[: rng.randrange(1, n)]], kind=kind)
        if kind == "garbage_before":
            return Injection([_garbage(rng) + reply], kind=kind)
        if kind == "garbage_after":
            return Injection([reply + _garbage(rng)], kind=kind)
        if kind == "delay":
            return Injection([reply], delay=self.faults.delay, kind=kind)
        if kind == "duplicate":
            return Injection([reply, reply], kind=kind)
        if kind == "wrong_unit":
            other = rng.randrange(1, 247)
            if other >= reply[0]:
                other += 1  # 1..247 without the unit itself
            return Injection([with_crc(bytes([other]) + reply[1:-2])], kind=kind)
        raise AssertionError(f"unknown fault kind {kind!r}")  # pragma: no cover


def _garbage(rng: random.Random) -> bytes:
    return bytes(rng.randrange(256) for _ in range(rng.randint(1, MAX_GARBAGE)))
