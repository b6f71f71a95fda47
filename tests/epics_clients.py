"""EPICS clients for the tests: ``benchbus ioc`` run in a process of its own (on loopback, on
ports of a test's own: ``benchbus.epics.loopback_env``), and reads and puts with caproto
(Channel Access)."""

from __future__ import annotations

import contextlib
import dataclasses
import os
import select
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any

import caproto.threading.client as caproto_client
import pytest

from benchbus.sim import Simulator

#: Function codes that write.
WRITES = {0x05, 0x06, 0x0F, 0x10, 0x16, 0x17}


@dataclasses.dataclass
class Epics:
    """The EPICS environment of one test: its own ports, loopback only."""

    env: dict[str, str]

    def client(self) -> Any:
        """A caproto Channel Access client context searching this test's IOCs."""
        return caproto_client.Context()


def wait_for(what: str, check: Callable[[], Any], timeout: float = 10.0) -> Any:
    """``check()``'s first true result within ``timeout`` s; fails naming ``what``."""
    deadline = time.monotonic() + timeout
    last: Any = None
    while time.monotonic() < deadline:
        try:
            last = check()
        except Exception as exc:  # a PV not yet connected, a read timed out
            last = exc
        else:
            if last:
                return last
        time.sleep(0.05)
    pytest.fail(f"{what}: not within {timeout} s (last: {last!r})")


def spawn(command: list[str], env: dict[str, str], stdin: int = subprocess.DEVNULL) -> Any:
    """``command`` started in a process of its own with ``env`` (Python's output unbuffered:
    its lines come as they are said), its output and errors piped, as text."""
    return subprocess.Popen(
        command,
        env={**os.environ, **env, "PYTHONUNBUFFERED": "1"},
        stdin=stdin,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@contextlib.contextmanager
def served(
    args: list[str],
    env: dict[str, str],
    ready: str,
    context: Any,
    command: list[str] | None = None,
    stop: signal.Signals = signal.SIGTERM,
    ready_value: int = 1,
    serving: tuple[str, str] = ("stderr", "benchbus: ioc: serving"),
) -> Iterator[subprocess.Popen[str]]:
    """``benchbus ioc ARGS`` (or ``command``) in a process of its own, with no standard
    input (as a service runs), until the block ends, once ``ready`` (a PV) reads
    ``ready_value``; then ``stop`` (SIGTERM), which must end it cleanly within 2 s.
    ``serving``: the stream and the start of the line the process says it serves with
    (``benchbus ioc``'s, on standard error)."""
    process = spawn(command or [sys.executable, "-m", "benchbus", "ioc", *args], env)
    said = ""
    stream, line = serving
    try:
        # Searching for a PV once the IOC serves finds it at once (a search that misses is
        # repeated later and later).
        said = until(process, stream, line, 20)
        (pv,) = context.get_pvs(ready, timeout=2)
        wait_for(
            f"{ready} = {ready_value}",
            lambda: pv.read(timeout=1).data[0] == ready_value,
            timeout=20,
        )
        yield process
    except BaseException:
        process.kill()
        _, err = process.communicate(timeout=10)
        print(said, err)
        raise
    process.send_signal(stop)
    started = time.monotonic()
    out, err = process.communicate(timeout=10)
    if stream == "stdout":
        out = said + out
    else:
        err = said + err
    took = time.monotonic() - started
    assert process.returncode == 0, err
    assert took < 2.0, f"{stop.name} took {took:.1f} s"
    process.stdout_text, process.stderr_text = out, err  # type: ignore[attr-defined]


def until(process: subprocess.Popen[str], stream: str, line: str, timeout: float) -> str:
    """What ``process`` writes to ``stream`` (``"stdout"``, ``"stderr"``) up to and with a
    line that starts with ``line``; fails if it ends or ``timeout`` s pass first."""
    pipe = process.stdout if stream == "stdout" else process.stderr
    assert pipe is not None
    deadline = time.monotonic() + timeout
    said: list[str] = []
    fd = pipe.fileno()
    os.set_blocking(fd, False)
    pending = b""
    try:
        while time.monotonic() < deadline:
            ready, _, _ = select.select([fd], [], [], 0.05)
            if not ready:
                if process.poll() is not None:
                    break
                continue
            chunk = os.read(fd, 65536)
            if not chunk:
                break
            pending += chunk
            *lines, pending = pending.split(b"\n")
            said += [n.decode(errors="replace") + "\n" for n in lines]
            if any(n.startswith(line) for n in said):
                return "".join(said) + pending.decode(errors="replace")
    finally:
        os.set_blocking(fd, True)
    pytest.fail(f"the IOC never said {line!r}: {''.join(said)}")


def read(context: Any, name: str, kind: str = "control") -> Any:
    """One read of the PV ``name`` with its ``kind`` of metadata."""
    (pv,) = context.get_pvs(name, timeout=2)
    return pv.read(data_type=kind, timeout=3)


def put(context: Any, name: str, value: Any) -> None:
    """A put that waits for the IOC to have processed it (put-callback)."""
    (pv,) = context.get_pvs(name, timeout=2)
    pv.write(value if isinstance(value, list) else [value], wait=True, timeout=5)


def writes(sim: Simulator[Any]) -> list[bytes]:
    """The write requests the simulator has received."""
    return [f for f in sim.requests if len(f) > 1 and f[1] in WRITES]
