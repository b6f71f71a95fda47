"""A Modbus RTU slave on a pseudo-terminal pair that keeps a real line's time, and misbehaves
in time on request: for the tests of a line that falls out of step.

The library opens :attr:`TimedSlave.port`; the slave serves the other end in a process of
its own (this file run as a script), so that it keeps the line's time whatever the test's
process does: a thread would wait for the GIL while the test's thread holds it, and be late
by up to the interpreter's switch interval (5 ms), the size of the gaps it keeps. A pty
carries bytes at once, so the slave reckons the wire itself: a request ends one character
time a byte after its first byte came (as the master reckons it too), and each byte of a
reply leaves one character time after the one before, never two frames at once.

What it can do wrong, each a constructor option:

- ``turnaround`` (and ``jitter``, a random extra of up to that much): the time from the end
  of a request to the start of its reply (a device slower than t3.5 plus the master's own
  turnaround);
- ``copy_every`` / ``copy_gap``: every n-th reply is sent a second time, ``copy_gap`` after
  the end of the first (a repeater, a gateway on the line, a firmware that repeats);
- ``service``: each unit works on one request at a time, each taking ``service`` seconds
  from its end (or from the end of the one before, whichever is later), and answers every
  request it got, in order (a slow device that queues its master's retries);
- ``burst_copies``: each copy is handed over whole when its last byte has crossed the wire,
  as a master slow to read (a loaded machine) or an adapter's latency timer sees it: its
  first byte is on the wire as early as ever, but read only once the copy is over.

Register ``a`` of unit ``u`` holds :func:`value` ``(u, a)``, so a reply taken for another
request's answer shows as a wrong value. Reads (0x03, 0x04) and single writes (0x06, the
echo) are answered; other units stay silent.
"""

from __future__ import annotations

import contextlib
import json
import os
import random
import select
import subprocess
import sys
import termios
import time
import tty
from collections import deque
from pathlib import Path
from types import TracebackType
from typing import Any

from conftest import crc


def value(unit: int, address: int) -> int:
    """What register ``address`` of ``unit`` holds: different for every address."""
    return (address * 7 + unit * 1000 + 1) & 0xFFFF


def request_length(buf: bytes | bytearray) -> int | None:
    """The length of the request at the start of ``buf``, once it can be told."""
    if len(buf) < 2:
        return None
    if buf[1] in (0x03, 0x04, 0x06):
        return 8
    return 0  # anything else: dropped


class TimedSlave:
    """A slave on a pty pair that answers in the line's time (see the module's text), run in
    a process of its own; its options are :class:`Line`'s."""

    def __init__(self, baud: int = 9600, bits: int = 10, **options: Any) -> None:
        config = {"baud": baud, "bits": bits, **options}
        if "units" in config:
            config["units"] = sorted(config["units"])
        self._process = subprocess.Popen(
            [sys.executable, __file__, json.dumps(config)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            cwd=Path(__file__).parent,
        )
        #: The pseudo-terminal the library opens.
        self.port: str = self._ask({"port": None})

    def _ask(self, command: dict[str, Any]) -> Any:
        """Send ``command`` to the slave's process; its answer."""
        assert self._process.stdin is not None and self._process.stdout is not None
        self._process.stdin.write(json.dumps(command) + "\n")
        self._process.stdin.flush()
        answer = self._process.stdout.readline()
        if not answer:
            raise RuntimeError(f"the timed slave ended ({self._process.wait(5)})")
        return json.loads(answer)

    @property
    def turnaround(self) -> float:
        """The turnaround; set it on the fly: the next request's reply takes the new one."""
        value: float = self._ask({"turnaround": None})
        return value

    @turnaround.setter
    def turnaround(self, value: float) -> None:
        self._ask({"turnaround": value})

    @property
    def copies(self) -> int:
        """How many copies of replies were sent."""
        value: int = self._ask({"copies": None})
        return value

    @property
    def copy_lateness(self) -> list[float]:
        """For each copy sent, how much later than due its first byte left, in seconds."""
        value: list[float] = self._ask({"copy_lateness": None})
        return value

    @property
    def requests(self) -> list[tuple[float, bytes]]:
        """Requests as they came: (when the first byte came, the bytes)."""
        got = self._ask({"requests": None})
        return [(first, bytes.fromhex(frame)) for first, frame in got]

    def __enter__(self) -> TimedSlave:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        """Stop serving: the process ends and closes both ends of the pair."""
        with contextlib.suppress(OSError, ValueError):
            assert self._process.stdin is not None
            self._process.stdin.close()  # end of commands: the process ends
        try:
            self._process.wait(5)
        except subprocess.TimeoutExpired:
            self._process.kill()
            self._process.wait()
        if self._process.stdout is not None:
            self._process.stdout.close()


class Line:
    """The slave itself, in the process of its own."""

    def __init__(
        self,
        baud: int = 9600,
        bits: int = 10,
        *,
        turnaround: float = 0.005,
        jitter: float = 0.0,
        units: frozenset[int] = frozenset({1}),
        copy_every: int = 0,
        copy_gap: float = 0.010,
        service: float = 0.0,
        burst_copies: bool = False,
    ) -> None:
        self.char_time = bits / baud
        self.burst_copies = burst_copies
        #: The turnaround (changed on the fly: the next request's reply takes the new one).
        self.turnaround = turnaround
        self.jitter = jitter
        self._random = random.Random(1)
        self.units = frozenset(units)
        self.copy_every = copy_every
        self.copy_gap = copy_gap
        self.service = service
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)
        attrs = termios.tcgetattr(self._slave)
        attrs[3] &= ~termios.ECHO
        termios.tcsetattr(self._slave, termios.TCSANOW, attrs)
        os.set_blocking(self.master, False)
        self.port = os.ttyname(self._slave)
        #: Requests as they came: (when the first byte came, the bytes).
        self.requests: list[tuple[float, bytes]] = []
        #: Frames sent, the copies among them: (when the first byte left, the bytes).
        self.sent: list[tuple[float, bytes]] = []
        self.copies = 0
        #: For each copy, how much later than due its first byte left (the slave's process
        #: may be late on a loaded machine: a copy then comes later than asked; a burst
        #: copy's first byte is due with its last).
        self.copy_lateness: list[float] = []
        self._out: deque[tuple[float, int, bool]] = deque()  # (when due, byte, a copy's first)
        self._free_at = 0.0  # when the last scheduled byte ends on the wire
        self._busy_until: dict[int, float] = {}  # a queuing unit: when it is done with its last
        self._replies = 0

    def _command(self, line: str) -> str:
        """Carry out one command of the test's process: ``{name: value}`` sets ``name`` (a
        value of null reads it); the answer is its value, as JSON."""
        [(name, value)] = json.loads(line).items()
        if name == "turnaround" and value is not None:
            self.turnaround = float(value)
        if name == "requests":
            return json.dumps([(first, frame.hex()) for first, frame in self.requests])
        return json.dumps(getattr(self, name))

    def _answer(self, request: bytes) -> bytes | None:
        if len(request) != 8 or crc(request[:-2]) != request[-2:] or request[0] not in self.units:
            return None
        unit, function = request[0], request[1]
        address = int.from_bytes(request[2:4], "big")
        count = int.from_bytes(request[4:6], "big")
        if function == 0x06:
            return request
        if not 1 <= count <= 125:
            pdu = bytes((unit, function | 0x80, 0x03))
        else:
            data = b"".join(value(unit, address + i).to_bytes(2, "big") for i in range(count))
            pdu = bytes((unit, function, len(data))) + data
        return pdu + crc(pdu)

    def _send(self, frame: bytes, start: float, copy: bool = False) -> float:
        """Schedule ``frame`` (a ``copy`` of a reply, or not) to start at ``start`` (or when
        the line is free); its end."""
        t = max(start, self._free_at)
        self.sent.append((t, frame))
        end = t + len(frame) * self.char_time
        burst = copy and self.burst_copies
        for i, b in enumerate(frame):
            t += self.char_time
            self._out.append((end if burst else t, b, copy and i == 0))
        self._free_at = end
        return end

    def _on_request(self, request: bytes, first: float) -> None:
        self.requests.append((first, request))
        end = first + len(request) * self.char_time
        reply = self._answer(request)
        if reply is None:
            return
        if self.service:
            start = max(end, self._busy_until.get(request[0], 0.0)) + self.service
            self._busy_until[request[0]] = start
        else:
            start = end + self.turnaround + self._random.uniform(0.0, self.jitter)
        reply_end = self._send(reply, start)
        self._replies += 1
        if self.copy_every and self._replies % self.copy_every == 0:
            self.copies += 1
            self._send(reply, reply_end + self.copy_gap, copy=True)

    def run(self, commands: Any, answers: Any) -> None:
        """Serve the line, and the test's ``commands`` (one JSON object a line, each answered
        on ``answers``), until ``commands`` ends."""
        buf = bytearray()
        first = 0.0
        while True:
            now = time.monotonic()
            wait = 0.05
            if self._out:
                wait = min(wait, max(0.0, self._out[0][0] - now))
            try:
                readable = select.select([self.master, commands], [], [], wait)[0]
            except (OSError, ValueError):
                return
            now = time.monotonic()
            if commands in readable:
                command = commands.readline()
                if not command:
                    return
                answers.write(self._command(command) + "\n")
                answers.flush()
            if self.master in readable:
                try:
                    data = os.read(self.master, 4096)
                except BlockingIOError:
                    data = b""
                except OSError:
                    return
                if data and not buf:
                    first = now
                buf += data
                while (n := request_length(buf)) is not None:
                    if n == 0 or len(buf) < n:
                        if n == 0:
                            buf.clear()
                        break
                    request, buf = bytes(buf[:n]), buf[n:]
                    self._on_request(request, first)
                    first = now
            due = bytearray()
            while self._out and self._out[0][0] <= now:
                at, byte, copy = self._out.popleft()
                due.append(byte)
                if copy:
                    self.copy_lateness.append(now - at)
            if due:
                try:
                    os.write(self.master, bytes(due))
                except OSError:
                    return


if __name__ == "__main__":
    Line(**json.loads(sys.argv[1])).run(sys.stdin, sys.stdout)
