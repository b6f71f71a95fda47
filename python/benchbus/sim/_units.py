"""What the serial line and the network gateway share about the simulated units.

The router of both the line's forwarder (``benchbus.sim._line``) and the gateway
(``benchbus.sim._network``), ``benchbus.sim._router``, turns each request for a unit into a
:class:`Job`, answers itself the requests the server cannot take (:func:`refusal`), and asks
the unit's callbacks (:class:`UnitHooks`) how its reply goes out. A callback that fails or
gives nonsense is logged and its default holds, so that a faulty device does not stop the
line. Pure Python, no pymodbus.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import threading
from collections.abc import Callable, Collection
from typing import TypeVar

from benchbus.sim._device import BASIC_FUNCTIONS, STANDARD_FUNCTIONS

__all__ = ["SERVER_FUNCTIONS", "WRITE_FUNCTIONS", "Job", "UnitHooks", "refusal"]

log = logging.getLogger("benchbus.sim")

_T = TypeVar("_T")

#: Functions the server can take; any other is answered exception 1 by the forwarder.
SERVER_FUNCTIONS = STANDARD_FUNCTIONS
#: The write functions, whose replies a unit may keep off the line (``answers_writes``).
WRITE_FUNCTIONS = frozenset({0x05, 0x06, 0x0F, 0x10, 0x16})


def refusal(pdu: bytes, functions: Collection[int] = BASIC_FUNCTIONS) -> int | None:
    """The exception code answered for a request the server cannot take, or the unit does
    not serve (its ``functions``); None if it can."""
    function = pdu[0] if pdu else 0
    if function not in SERVER_FUNCTIONS or function not in functions:
        return 0x01
    if function == 0x03 and (len(pdu) != 5 or not 1 <= int.from_bytes(pdu[3:5], "big") <= 125):
        # pymodbus cannot decode such a request and would answer function 0x80.
        return 0x03
    return None


@dataclasses.dataclass
class Job:
    """One request for the server, or an already-made reply, waiting for its turn."""

    frame: bytes  # in the line's or network's framing, addressed to one unit
    deliver: bool  # send the reply on to the library
    made_reply: bytes | None = None  # answered by the forwarder or gateway, not the server
    delay: float = 0.0  # the unit's own reply delay, read when the job is dispatched
    done: threading.Event | None = None  # the line's internal probe: set when answered
    reply: bytes | None = None  # the probe's reply
    broadcast: bool = False  # a broadcast's request, readdressed to one unit


class UnitHooks:
    """The units' callbacks, asked safely: one that fails is logged and its default holds."""

    def __init__(
        self,
        who: str,
        *,
        answers_broadcast: Callable[[int], bool],
        answers_writes: Callable[[int], bool] | None = None,
        reply_delay: Callable[[int], float] | None = None,
        shape_reply: Callable[[int, bytes, bytes], bytes] | None = None,
        functions: Callable[[int], Collection[int]] | None = None,
        took: Callable[[int, bytes, bytes | None, bool, bool], None] | None = None,
    ) -> None:
        """``who`` names the caller in the log (``"simulator"``, ``"simulator gateway"``).

        ``answers_writes(unit)`` defaults to True, ``reply_delay(unit)`` to 0,
        ``shape_reply(unit, request, reply)``, on RTU frames, to the reply as is, and
        ``functions(unit)``, the function codes the unit serves, to the basic ones (0x03,
        0x06, 0x10, 0x2B). ``took(unit, pdu, reply_pdu, broadcast, listen_only)`` is told
        of each request a unit took, once handled (``reply_pdu`` None: kept in the listen
        only mode), for its comm event counters.
        """
        self.who = who
        self._took = took
        self._functions = functions
        self._answers_broadcast = answers_broadcast
        self._answers_writes = answers_writes
        self._reply_delay = reply_delay
        self._shape_reply = shape_reply

    def _ask(self, name: str, unit: int, ask: Callable[[], _T], fallback: _T, means: str) -> _T:
        """``ask()``, the callback ``name`` asked about ``unit``; if it fails, logged and
        ``fallback`` (``means``: what that is, for the log)."""
        try:
            return ask()
        except Exception:
            log.exception("%s: unit %d: %s failed; %s", self.who, unit, name, means)
            return fallback

    def answers_broadcast(self, unit: int) -> bool:
        """Whether ``unit`` replies to a broadcast (False if the callback fails)."""
        hook = self._answers_broadcast
        return self._ask(
            "answers_broadcast", unit, lambda: bool(hook(unit)), False, "not answering"
        )

    def answers_writes(self, unit: int) -> bool:
        """Whether ``unit`` replies to a write (True if the callback fails)."""
        hook = self._answers_writes
        if hook is None:
            return True
        return self._ask("answers_writes", unit, lambda: bool(hook(unit)), True, "answering")

    def reply_delay(self, unit: int) -> float:
        """How long ``unit`` holds its replies back (0 if the callback fails)."""
        hook = self._reply_delay
        if hook is None:
            return 0.0
        delay = self._ask("reply_delay", unit, lambda: float(hook(unit)), 0.0, "no delay")
        if not (math.isfinite(delay) and delay >= 0.0):
            log.error("%s: unit %d: reply_delay %r is not >= 0; no delay", self.who, unit, delay)
            return 0.0
        return delay

    def functions(self, unit: int) -> Collection[int]:
        """The function codes ``unit`` serves (the basic ones if the callback fails)."""
        hook = self._functions
        if hook is None:
            return BASIC_FUNCTIONS
        return self._ask(
            "functions",
            unit,
            lambda: frozenset(int(f) for f in hook(unit)),
            BASIC_FUNCTIONS,
            "the basic ones",
        )

    def shape(self, unit: int, request: bytes, reply: bytes) -> bytes:
        """``unit``'s own form of the server's RTU ``reply`` to ``request`` (``reply`` if the
        callback fails)."""
        hook = self._shape_reply
        if hook is None:
            return reply
        shaped = self._ask(
            "shape_reply", unit, lambda: hook(unit, request, reply), reply, "reply unchanged"
        )
        if not isinstance(shaped, (bytes, bytearray)) or len(shaped) < 4:
            log.error("%s: unit %d: shape_reply gave %r; reply unchanged", self.who, unit, shaped)
            return reply
        return bytes(shaped)

    def took(
        self, unit: int, pdu: bytes, reply: bytes | None, *, broadcast: bool, listen_only: bool
    ) -> None:
        """Tell ``unit`` it took the request ``pdu`` (and answered ``reply``, a PDU; None if
        it took no action, in the listen only mode)."""
        hook = self._took
        if hook is not None:
            self._ask(
                "counting",
                unit,
                lambda: hook(unit, pdu, reply, broadcast, listen_only),
                None,
                "not counted",
            )

    def settle(self, job: Job, unit: int, pdu: bytes) -> None:
        """Ask ``unit``, just before it handles ``job`` (its ``pdu``), how its reply goes out."""
        job.delay = self.reply_delay(unit)
        # A reply made without the server for a write is a forced exception: it stays.
        if job.deliver and job.made_reply is None and pdu and pdu[0] in WRITE_FUNCTIONS:
            job.deliver = self.answers_writes(unit)
