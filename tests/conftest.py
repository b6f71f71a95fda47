"""Shared fixtures: a scripted raw slave on a pseudo-terminal, for golden-frame tests, and
the ``benchbus gateway`` command run as a child process."""

from __future__ import annotations

import contextlib
import importlib.util
import os
import select
import subprocess
import sys
import termios
import threading
import time
import tty
import types
from collections.abc import Iterator
from pathlib import Path

import pytest

# pytester runs pytest inside tests/test_plugin.py, with the benchbus plugin loaded.
pytest_plugins = ("pytester",)
# The wheel smoke suite runs against an installed wheel, from a copy outside the checkout
# (.ci/wheel-smoke.sh), not in this run.
collect_ignore = ["wheel_smoke"]
# QCoDeS (the qcodes extra) and ophyd-async (the bluesky extra) need Python 3.11.
if sys.version_info < (3, 11):
    collect_ignore += ["test_qcodes.py", "test_ophyd.py"]


@pytest.fixture(autouse=True)
def _no_labs_profiles(monkeypatch: pytest.MonkeyPatch) -> None:
    """Profiles by name are the shipped ones in every test, whatever folders of its own the
    machine's ``BENCHBUS_PROFILES`` names (a test that wants some sets it)."""
    monkeypatch.delenv("BENCHBUS_PROFILES", raising=False)


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


@contextlib.contextmanager
def gateway_command(port: str, *options: str) -> Iterator[tuple[str, subprocess.Popen[str]]]:
    """``benchbus gateway --port PORT --listen 127.0.0.1:0 OPTIONS`` as a child process: its
    URL (the first line it prints) and the process, stopped with SIGTERM on leaving (its
    ``returncode`` and ``stderr_text`` are then set)."""
    proc = subprocess.Popen(
        [
            *(sys.executable, "-m", "benchbus", "gateway", "--port", port),
            *("--listen", "127.0.0.1:0", "--seconds", "120", *options),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        url = proc.stdout.readline().strip()
        assert url.startswith("tcp://127.0.0.1:"), url
        yield url, proc
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=10)
        proc.stderr_text = err  # type: ignore[attr-defined]


def crc(data: bytes) -> bytes:
    """CRC-16/MODBUS, bit by bit, low byte first: independent of the library's own."""
    value = 0xFFFF
    for byte in data:
        value ^= byte
        for _ in range(8):
            value = (value >> 1) ^ 0xA001 if value & 1 else value >> 1
    return value.to_bytes(2, "little")


def rtu(hexstr: str) -> bytes:
    """The bytes of ``hexstr`` followed by their CRC: an RTU frame."""
    data = bytes.fromhex(hexstr)
    return data + crc(data)


#: The site's build hooks (MkDocs hooks and the griffe extension).
HOOKS = Path(__file__).resolve().parent.parent / "docs_hooks"


def hook(name: str) -> types.ModuleType:
    """The module ``docs_hooks/<name>.py``, loaded from its file as MkDocs loads it."""
    spec = importlib.util.spec_from_file_location(name, HOOKS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


#: The files whose tests hold the library to a line's time (a simulated slave keeping the
#: wire's timing, upper bounds on how long a call takes), marked ``timing`` (a test of
#: another file may carry the marker itself): ``make test`` runs the other tests on
#: pytest-xdist's workers, then these by themselves, three workers for two cores (a machine
#: loaded by builds, browsers or more of them delays a simulated slave's bytes past what a
#: line allows).
TIMING_FILES = frozenset(
    {
        "test_bench.py",
        "test_concurrency.py",
        "test_fair_line.py",
        "test_faults.py",
        "test_line_in_step.py",
        "test_live_timing.py",
        "test_poll.py",
        "test_safety.py",
        "test_ticks.py",
    }
)


#: The files whose tests serve EPICS from an IOC process of their own each, marked
#: ``epics``: ``make test`` runs them last, by themselves (each process loads the machine,
#: and an IOC is held to time bounds of its own: a stop within 2 s, an alarm within a
#: period and a timeout).
EPICS_FILES = frozenset({"test_epics.py"})


def pytest_itemcollected(item: pytest.Item) -> None:
    """Mark the tests of :data:`TIMING_FILES` ``timing`` and those of :data:`EPICS_FILES`
    ``epics``."""
    if item.path.name in TIMING_FILES:
        item.add_marker(pytest.mark.timing)
    if item.path.name in EPICS_FILES:
        item.add_marker(pytest.mark.epics)


#: The site's builds (tests/test_site.py's fixtures), each made once for the run while the
#: workers that need it wait (some 15 s of a core each).
BUILDS = ("site", "broken")

#: The longest single tests (the quick benchmark, a timing test: some 35 s of a busy core),
#: which start first so that the others fill the workers around them.
LONGEST = ("test_bench.py::test_quick_benchmark_runs_every_scenario_for_every_library",)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Run :data:`LONGEST` and the first test of each of :data:`BUILDS` first, and the
    builds' other tests last.

    pytest-xdist hands the first tests out one to each worker in turn: so the builds and
    the longest tests start at once, side by side on workers of their own, the builds are
    made by the time the other tests that read them come (instead of holding the workers
    that wait for them idle), and no long test starts near the end."""

    def needs(item: pytest.Item) -> str | None:
        if item.path.name != "test_site.py":
            return None
        return next((b for b in BUILDS if b in getattr(item, "fixturenames", ())), None)

    first: dict[str, pytest.Item] = {}
    for item in items:
        build = needs(item)
        if build is not None:
            first.setdefault(build, item)
    starters = [i for i in items if i.nodeid.endswith(LONGEST)] + list(first.values())
    rest = [i for i in items if i not in starters]
    items[:] = starters + sorted(rest, key=lambda i: needs(i) is not None)
