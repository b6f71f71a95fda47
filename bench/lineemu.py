"""A serial line on pseudo-terminals that takes as long as a real one, and a fast fake slave.

Run as a child process by the benchmark (``python bench/lineemu.py --baud 19200 --bits 10``).
For each line it makes two pseudo-terminal pairs::

    master under test -> pts A | forwarder | pts B -> fake slave

The forwarder releases each byte only after its time on the wire (``bits / baud``), one after
the other in each direction, so the master sees a reply arrive byte by byte and end when a real
one would. ``--plain`` skips the forwarder: the fake slave answers on pair A at once (the pure
software cost of a master).

The fake slave finds the end of a request by its length (0x01 to 0x06: 8 bytes, 0x10: 9 +
byte count) and answers at once: a read of register ``a`` (0x03, 0x04) returns
``value(unit, a)``, a read of coil or discrete input ``a`` (0x01, 0x02) its lowest bit;
reads at ``0x8000`` and above get exception 2; units not in ``--units`` stay silent.

It prints one JSON line ``{"ports": [...]}`` and then answers commands on stdin, one per line:
``stats`` prints (and clears) what it measured since the last ``stats``: per line the time the
first byte of each request arrived and its unit, when each reply's last byte reached the
master, the gap on the wire between the end of each reply and the
next request, how many requests came less than t3.5 after a reply, the slave's own
turnaround, and how late the last byte of each frame left the forwarder (its own error);
``quit`` (or end of input) stops it.
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import json
import os
import select
import sys
import termios
import time
import tty
from collections import deque
from collections.abc import Iterator

EXCEPTION_ADDRESS = 0x8000


def silence(baud: int, char_time: float) -> float:
    """t3.5: 3.5 character times, or 1.75 ms above 19200 baud (serial line spec 2.5.1.1)."""
    return 3.5 * char_time if baud <= 19200 else 0.00175


def value(unit: int, address: int) -> int:
    """What the fake slave holds in register ``address`` of ``unit``."""
    return (address * 3 + unit) & 0xFFFF


def crc16(data: bytes) -> bytes:
    """The Modbus CRC, low byte first."""
    crc = 0xFFFF
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return bytes((crc & 0xFF, crc >> 8))


def request_length(buf: bytes | bytearray) -> int | None:
    """Length of the request at the start of ``buf``, once enough of it is there to tell."""
    if len(buf) < 2:
        return None
    function = buf[1]
    if function in (0x01, 0x02, 0x03, 0x04, 0x06):
        return 8
    if function == 0x10:
        return 9 + buf[6] if len(buf) >= 7 else None
    return None  # unknown: dropped when the next request starts


def answer(request: bytes, units: set[int]) -> bytes | None:
    """The fake slave's reply to one complete request, or None (silent)."""
    if len(request) < 4 or crc16(request[:-2]) != request[-2:]:
        return None
    unit, function = request[0], request[1]
    if unit not in units:
        return None
    if function in (0x03, 0x04):
        address = int.from_bytes(request[2:4], "big")
        count = int.from_bytes(request[4:6], "big")
        if address >= EXCEPTION_ADDRESS or not 1 <= count <= 125:
            pdu = bytes((unit, function | 0x80, 0x02))
        else:
            words = b"".join(value(unit, address + i).to_bytes(2, "big") for i in range(count))
            pdu = bytes((unit, function, 2 * count)) + words
    elif function in (0x01, 0x02):
        address = int.from_bytes(request[2:4], "big")
        count = int.from_bytes(request[4:6], "big")
        if address >= EXCEPTION_ADDRESS or not 1 <= count <= 2000:
            pdu = bytes((unit, function | 0x80, 0x02))
        else:
            bits = sum((value(unit, address + i) & 1) << i for i in range(count))
            packed = bits.to_bytes((count + 7) // 8, "little")
            pdu = bytes((unit, function, len(packed))) + packed
    elif function in (0x06, 0x10):
        pdu = request[:6]  # the echo of a write
    else:
        pdu = bytes((unit, function | 0x80, 0x01))
    return pdu + crc16(pdu)


@contextlib.contextmanager
def fine_slack() -> Iterator[None]:
    """Within the block, the calling thread wakes from sleeps within a microsecond (Linux's
    default timer slack is 50 us); the slack is put back after."""
    try:
        prctl = ctypes.CDLL(None).prctl
    except (OSError, AttributeError):
        yield
        return
    previous = prctl(30, 0, 0, 0, 0)  # PR_GET_TIMERSLACK
    prctl(29, 1, 0, 0, 0)  # PR_SET_TIMERSLACK
    try:
        yield
    finally:
        prctl(29, previous, 0, 0, 0)


def raw_pty() -> tuple[int, int, str]:
    """A pseudo-terminal pair in raw mode: (master fd, slave fd, slave path)."""
    master, slave = os.openpty()
    tty.setraw(slave, termios.TCSANOW)
    os.set_blocking(master, False)
    return master, slave, os.ttyname(slave)


class Direction:
    """Bytes on their way one way along a line, each released after its wire time."""

    def __init__(self, out_fd: int, char_time: float) -> None:
        self.out_fd = out_fd
        self.char_time = char_time
        self.queue: deque[tuple[float, int]] = deque()
        self.free_at = 0.0  # when the last scheduled character ends on the wire
        self.written = 0.0  # when the last write of released bytes began

    def push(self, data: bytes, now: float) -> None:
        """Schedule ``data``, written by the sender at ``now``."""
        t = max(now, self.free_at)
        for b in data:
            t += self.char_time
            self.queue.append((t, b))
        self.free_at = t

    def due(self) -> float | None:
        """When the next byte is due, or None."""
        return self.queue[0][0] if self.queue else None

    def release(self, now: float) -> float | None:
        """Write the bytes that are due. When that ends a frame, return how late its last
        byte left (the emulator's own error), else None. ``written`` is when the last write
        began: the receiver cannot have the bytes before then, so a quiet time counted from
        it is never too long, however late this process runs after the write."""
        out = bytearray()
        due = 0.0
        while self.queue and self.queue[0][0] <= now:
            due, b = self.queue.popleft()
            out.append(b)
        if not out:
            return None
        self.written = time.monotonic()
        os.write(self.out_fd, bytes(out))
        return self.written - due if not self.queue else None


class Slave:
    """The fake slave on one fd: frames by length, answers at once."""

    def __init__(self, fd: int, units: set[int]) -> None:
        self.fd = fd
        self.units = units
        self.buf = bytearray()
        self.turnarounds: list[float] = []
        self.wrote_at = 0.0  # when the last reply was written

    def feed(self, data: bytes, now: float) -> bool:
        """Take bytes read at ``now``; answer every complete request. True if it answered."""
        self.buf += data
        answered = False
        while (n := request_length(self.buf)) is not None and len(self.buf) >= n:
            request, self.buf = bytes(self.buf[:n]), self.buf[n:]
            reply = answer(request, self.units)
            if reply is not None:
                self.wrote_at = time.monotonic()
                os.write(self.fd, reply)
                self.turnarounds.append(time.monotonic() - now)
                answered = True
        return answered


class EmulatedLine:
    """One emulated (or plain) line with its fake slave and what was measured on it."""

    def __init__(self, baud: int, bits: int, units: set[int], plain: bool) -> None:
        self.char_time = bits / baud
        self.t35 = silence(baud, self.char_time)
        self.a_master, self.a_slave, self.port = raw_pty()
        self.plain = plain
        if plain:
            self.slave = Slave(self.a_master, units)
            self.b_master = self.slave_fd = -1
            self.up = self.down = None
        else:
            self.b_master, b_slave, b_path = raw_pty()
            # The fake slave opens its end by path, as a program on a real port would.
            self.slave_fd = os.open(b_path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
            tty.setraw(self.slave_fd, termios.TCSANOW)
            os.close(b_slave)
            self.slave = Slave(self.slave_fd, units)
            self.up = Direction(self.b_master, self.char_time)  # master -> slave
            self.down = Direction(self.a_master, self.char_time)  # slave -> master
        self.requests: list[float] = []
        self.units: list[int] = []  # the unit each request is addressed to
        self.replies: list[float] = []  # when each reply's last byte reached the master
        self.gaps: list[float] = []
        self.late: list[float] = []
        self.early = 0  # requests less than t3.5 after a reply's last byte
        self.last_request_byte = -1.0
        self.reply_end: float | None = None

    def fds(self) -> list[int]:
        """The fds to watch for input."""
        if self.plain:
            return [self.a_master]
        return [self.a_master, self.b_master, self.slave_fd]

    def from_master(self, data: bytes, now: float) -> None:
        """Bytes the master under test wrote."""
        if self.reply_end is not None or now - self.last_request_byte > self.t35:
            # The first byte of a request: how long the line was quiet after the last reply.
            # Whatever the slave holds of an earlier frame is abandoned (resynchronised).
            self.slave.buf.clear()
            self.requests.append(now)
            self.units.append(data[0])
            if self.reply_end is not None:
                self.gaps.append(now - self.reply_end)
                # 20 us of grace for the clocks' reading: the reply's end is stamped just before
                # the write that delivers its last byte, so the master never sees it earlier.
                self.early += now - self.reply_end < self.t35 - 20e-6
                self.reply_end = None
        self.last_request_byte = now
        if self.plain:
            if self.slave.feed(data, now):
                self.reply_end = self.slave.wrote_at
        else:
            assert self.up is not None
            self.up.push(data, now)

    def on_input(self, fd: int, now: float) -> None:
        """Read what is waiting on ``fd`` and pass it on."""
        try:
            data = os.read(fd, 4096)
        except (BlockingIOError, OSError):
            return  # EIO: the master side is not open at the moment
        if not data:
            return
        if fd == self.a_master:
            self.from_master(data, now)
        elif fd == self.b_master:
            assert self.down is not None
            # The reply starts on the wire when the slave wrote it, as from a UART; the hop
            # through pair B (tens of microseconds) is the emulator's, not the line's.
            self.down.push(data, min(now, max(self.slave.wrote_at, now - self.char_time)))
        elif fd == self.slave_fd:
            self.slave.feed(data, now)

    def due(self) -> float | None:
        """The next instant a byte is due on this line."""
        times = [d.due() for d in (self.up, self.down) if d is not None]
        pending = [t for t in times if t is not None]
        return min(pending) if pending else None

    def release(self, now: float) -> None:
        """Release what is due in both directions; note when a reply has fully arrived."""
        if self.up is not None and (late := self.up.release(now)) is not None:
            self.late.append(late)
        if self.down is not None and (late := self.down.release(now)) is not None:
            self.late.append(late)
            self.reply_end = self.down.written
            self.replies.append(self.down.written)

    def take_stats(self) -> dict[str, object]:
        """What was measured since the last call, and clear it."""
        stats = {
            "port": self.port,
            "requests": self.requests,
            "units": self.units,
            "replies": self.replies,
            "gaps": self.gaps,
            "turnarounds": self.slave.turnarounds,
            "late": self.late,
            "early": self.early,
        }
        self.requests, self.gaps, self.slave.turnarounds, self.late = [], [], [], []
        self.units, self.replies = [], []
        self.early = 0
        return stats


def serve(lines: list[EmulatedLine], spin: bool) -> None:
    """The event loop: forward, answer, and obey commands until told to quit. With ``spin``
    it never sleeps, so it never pays the time a CPU takes to wake from idle (tens of
    microseconds on a virtual machine): bytes leave on time, as from a UART."""
    owner = {fd: line for line in lines for fd in line.fds()}
    stdin = sys.stdin.fileno()
    watched = [stdin, *owner]
    commands = b""
    while True:
        now = time.monotonic()
        dues = [t for t in (line.due() for line in lines) if t is not None]
        timeout = 0.0 if spin else max(0.0, min(dues) - now) if dues else None
        readable, _, _ = select.select(watched, [], [], timeout)
        now = time.monotonic()
        for fd in readable:
            if fd == stdin:
                chunk = os.read(stdin, 1024)
                if not chunk:
                    return
                commands += chunk
                while b"\n" in commands:
                    command, commands = commands.split(b"\n", 1)
                    if command.strip() == b"quit":
                        return
                    if command.strip() == b"stats":
                        print(json.dumps([line.take_stats() for line in lines]), flush=True)
            else:
                owner[fd].on_input(fd, now)
        now = time.monotonic()
        for line in lines:
            line.release(now)


def main() -> None:
    """Parse the options, make the lines, print their ports, serve."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baud", type=int, default=19200)
    parser.add_argument("--bits", type=int, default=10, help="bits per character (8N1: 10)")
    parser.add_argument("--lines", type=int, default=1)
    parser.add_argument("--units", default="1", help="comma-separated units that answer")
    parser.add_argument("--plain", action="store_true", help="no wire time: answer at once")
    parser.add_argument("--spin", action="store_true", help="poll without sleeping (one core)")
    args = parser.parse_args()
    units = {int(u) for u in args.units.split(",")}
    lines = [EmulatedLine(args.baud, args.bits, units, args.plain) for _ in range(args.lines)]
    print(json.dumps({"ports": [line.port for line in lines]}), flush=True)
    with fine_slack():
        serve(lines, args.spin)


if __name__ == "__main__":
    main()
