"""Shared fixtures: a scripted raw slave on a pseudo-terminal, for golden-frame tests."""

from __future__ import annotations

import os
import select
import termios
import threading
import time
import tty
from collections.abc import Iterator

import pytest

# pytester runs pytest inside tests/test_plugin.py, with the benchbus plugin loaded.
pytest_plugins = ("pytester",)


def read_up_to(fd: int, n: int, timeout: float) -> bytes:
    """Up to ``n`` bytes from ``fd``: whatever has come within ``timeout`` seconds."""
    data = b""
    deadline = time.monotonic() + timeout
    while len(data) < n:
        left = deadline - time.monotonic()
        if left <= 0 or not select.select([fd], [], [], left)[0]:
            break
        data += os.read(fd, n - len(data))
    return data


class FakeClock:
    """A clock a test moves by hand (``clock.now += 1.5``), for simulated motor ramps."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


class ScriptedSlave:
    """The far end of a pty pair that answers each request with scripted bytes.

    The library opens ``port``; each call of :meth:`expect` queues one exchange: read a
    request of a given length, record it, then write the reply (or stay silent).
    """

    def __init__(self) -> None:
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)
        attrs = termios.tcgetattr(self._slave)
        attrs[3] &= ~termios.ECHO
        termios.tcsetattr(self._slave, termios.TCSANOW, attrs)
        self.port = os.ttyname(self._slave)
        self.received: list[bytes] = []
        self._thread: threading.Thread | None = None

    def expect(self, request_len: int, reply: bytes | None, timeout: float = 2.0) -> None:
        """In the background: read ``request_len`` bytes, then write ``reply`` (None: silent)."""

        def run() -> None:
            self.received.append(read_up_to(self.master, request_len, timeout))
            if reply is not None:
                os.write(self.master, reply)

        self._thread = threading.Thread(target=run, daemon=True)
        self._thread.start()

    def join(self) -> None:
        """Wait for the queued exchange to finish."""
        if self._thread is not None:
            self._thread.join(5)

    def close(self) -> None:
        """Close both ends of the pty pair."""
        self.join()
        for fd in (self.master, self._slave):
            os.close(fd)


@pytest.fixture
def slave() -> Iterator[ScriptedSlave]:
    """A scripted slave on a fresh pseudo-terminal pair."""
    s = ScriptedSlave()
    yield s
    s.close()
