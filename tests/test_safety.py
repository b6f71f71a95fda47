"""Motor safety (issue 9, item 6, first half): a Drive or PblDrive used as a context manager
stops its motor when the block ends, whether it ends normally, with an exception, or with
Ctrl-C, including a real SIGINT delivered to a process running a script.

The motors are simulated with a clock the test moves (:class:`conftest.FakeClock`), so "the
motor is turning" and "the motor has stopped" are read off the simulated drive, not guessed
from timing. For SIGINT, the simulator runs here and the script in a child process, on the
simulator's port: the simulated drive outlives the script, so its state after the script dies
is what a bench would find.
"""

from __future__ import annotations

import contextlib
import logging
import os
import select
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Union

import pytest

import benchbus as bb
from benchbus import _core
from benchbus.sim import DriveDevice, PblDevice, RegisterDevice, Simulator
from conftest import FakeClock

PBL_UNIT = 0x11
#: Seconds the fake clock moves: long enough for any ramp of these tests to finish.
LONG = 1000.0

Device = Union[DriveDevice, PblDevice]


class Motor:
    """A simulated drive of one family and how to start it and read it from the test."""

    def __init__(self, family: str) -> None:
        self.family = family
        self.clock = FakeClock()
        self.device: Device
        if family == "PBL":
            self.device = PblDevice(clock=self.clock)
            self.unit = PBL_UNIT
        else:
            self.device = DriveDevice("C20" if family == "C20" else "BLD2", clock=self.clock)
            self.unit = 1

    def open(self, port_or_bus: str | bb.Bus) -> bb.Drive | bb.PblDrive:
        """The library's object for this drive, on a port (its own Bus) or a shared Bus."""
        if self.family == "PBL":
            return bb.PblDrive(port_or_bus, unit=self.unit)
        return bb.Drive(
            port_or_bus, unit=self.unit, family="C20" if self.family == "C20" else "BLD"
        )

    @staticmethod
    def start(drive: bb.Drive | bb.PblDrive) -> None:
        drive.speed_setpoint = 1500
        if isinstance(drive, bb.PblDrive):
            drive.start_stop_source = bb.StartStopSource.COMMUNICATION
            drive.start()
        else:
            drive.forward()

    def turning(self) -> bool:
        """Whether the motor turns (after the clock moved on a little)."""
        return abs(self.device.speed) > 0

    def commanded_to_run(self) -> bool:
        """Whether the drive holds a run command: the motor would go on turning."""
        if isinstance(self.device, PblDevice):
            return bool(self.device.peek(0) & 1)
        commands = self.device.commands  # the last one to 0x2000 is what the drive does
        return bool(commands) and commands[-1] in (1, 2, 3, 4)  # forward, reverse, jogs

    def stopped(self) -> bool:
        """Whether the motor has come to rest with no run command, once the ramp is over."""
        self.clock.now += LONG
        if isinstance(self.device, PblDevice):
            return not self.device.running and self.device.speed == 0
        return self.device.state == DriveDevice.STOPPED and self.device.speed == 0


@contextlib.contextmanager
def simulated(family: str) -> Iterator[tuple[Motor, Simulator[Any]]]:
    motor = Motor(family)
    with Simulator({motor.unit: motor.device}) as sim:
        yield motor, sim


FAMILIES = ["BLD2", "C20", "PBL"]


# ---- in this process ---------------------------------------------------------------------------


class BenchFailed(Exception):
    pass


#: How a block can end: normally, with an exception, with Ctrl-C (raised here by hand).
ENDINGS: dict[str, type[BaseException] | None] = {
    "normal": None,
    "exception": BenchFailed,
    "ctrl-c": KeyboardInterrupt,
}


@pytest.mark.parametrize("family", FAMILIES)
@pytest.mark.parametrize("ending", ENDINGS)
def test_leaving_the_block_stops_the_motor(family: str, ending: str) -> None:
    error = ENDINGS[ending]
    with simulated(family) as (motor, sim):
        raised = pytest.raises(error) if error is not None else contextlib.nullcontext()
        with raised, motor.open(sim.port) as drive:
            motor.start(drive)
            motor.clock.now += 1.0
            assert motor.turning() and motor.commanded_to_run()
            if error is not None:
                raise error
        assert not motor.commanded_to_run()
        assert motor.stopped()
        assert drive.bus.closed  # the Bus it opened is closed after the stop


@pytest.mark.parametrize("family", FAMILIES)
def test_a_drive_on_a_shared_bus_stops_and_leaves_the_bus_open(family: str) -> None:
    with simulated(family) as (motor, sim), bb.Bus(sim.port, timeout=0.3) as bus:
        with pytest.raises(BenchFailed), motor.open(bus) as drive:
            motor.start(drive)
            assert motor.commanded_to_run()
            raise BenchFailed
        assert motor.stopped()
        assert not bus.closed
        assert drive.bus is bus


def test_a_jog_is_ended_then_the_motor_stopped() -> None:
    with simulated("BLD2") as (motor, sim):
        assert isinstance(motor.device, DriveDevice)
        with pytest.raises(KeyboardInterrupt), bb.Drive(sim.port) as drive:
            drive.jog_forward()
            motor.clock.now += 1.0
            assert motor.turning()
            raise KeyboardInterrupt
        assert motor.device.commands == [3, 8, 5]  # jog forward, jog stop, stop
        assert motor.stopped()


@pytest.mark.parametrize("family", FAMILIES)
def test_a_failed_stop_does_not_hide_the_exception_that_ended_the_block(
    family: str, caplog: pytest.LogCaptureFixture
) -> None:
    """If the drive stops answering, the exception that ended the block goes on, the failed
    stop is logged, and the Bus is closed all the same; on a normal exit the failure is
    raised (a motor that may still be turning is never silent)."""
    caplog.set_level(logging.ERROR, logger="benchbus.device")
    with simulated(family) as (motor, sim):
        with pytest.raises(BenchFailed), motor.open(sim.port) as drive:
            motor.start(drive)
            sim.set_silent(motor.unit)
            raise BenchFailed
        assert drive.bus.closed
        assert "could not stop the motor" in caplog.text
        assert "ResponseTimeout" in caplog.text
        sim.set_silent(None, False)
        with pytest.raises(bb.ResponseTimeout), motor.open(sim.port) as drive:
            sim.set_silent(motor.unit)
        assert drive.bus.closed


@pytest.mark.parametrize("family", FAMILIES)
def test_leaving_on_an_exception_sends_the_stop_once_at_once(family: str) -> None:
    """A drive gone silent, a Bus with retries: leaving the block on an exception sends one
    request, the stop (a PblDrive: control word 0, not read first), without waiting for the
    answer the drive owes the read that timed out; a normal exit still retries."""
    with simulated(family) as (motor, sim), bb.Bus(sim.port, timeout=0.3, retries=3) as bus:
        with pytest.raises(BenchFailed), motor.open(bus) as drive:
            motor.start(drive)
            sim.set_silent(motor.unit)
            with pytest.raises(bb.ResponseTimeout):
                _ = drive.running if isinstance(drive, bb.PblDrive) else drive.speed
            before = sim.request_count
            start = time.monotonic()
            raise BenchFailed
        took = time.monotonic() - start
        after = sim.requests[-(sim.request_count - before) :] if sim.request_count > before else []
        assert len(after) == 1, after
        assert after[0][1] == 0x06
        assert after[0][2:6] == (bytes(4) if family == "PBL" else bytes.fromhex("20000005"))
        assert took < 0.6 + 0.3, took
        sim.set_silent(None, False)
        with pytest.raises(bb.ResponseTimeout), motor.open(bus):
            sim.set_silent(motor.unit)
            before = sim.request_count
        # Not urgent: the stop is retried (a PblDrive reads the control word first).
        assert sim.request_count - before >= 4


# ---- Ctrl-C as a real SIGINT to a script -------------------------------------------------------

#: The script a bench would run: start the motor, then wait in one of three ways.
SCRIPT = """\
import sys
import time

import benchbus as bb

port, family, wait = sys.argv[1:4]
if family == "PBL":
    drive = bb.PblDrive(port, unit=0x11)
else:
    drive = bb.Drive(port, unit=1, family="C20" if family == "C20" else "BLD")
with drive:
    drive.speed_setpoint = 1500
    if family == "PBL":
        drive.start_stop_source = bb.StartStopSource.COMMUNICATION
        drive.start()
    else:
        drive.forward()
    print("running", flush=True)
    if wait == "record":  # Ctrl-C ends a recording, which returns what it has
        rec = drive.record(3600, 0.05)
        print("recorded", len(rec), "interrupted", rec.interrupted, flush=True)
    while wait != "record":
        if wait == "reading":  # mostly inside a call that waits for the wire
            _ = drive.speed
        else:
            time.sleep(0.05)
print("after the block", flush=True)
"""

#: Seconds the child may take for each step (start-up includes importing benchbus).
STEP_TIMEOUT = 20.0


def read_line(proc: subprocess.Popen[bytes], timeout: float) -> str:
    """The child's next line of output, or AssertionError after ``timeout`` seconds."""
    assert proc.stdout is not None
    fd, line = proc.stdout.fileno(), b""
    deadline = time.monotonic() + timeout
    while not line.endswith(b"\n"):
        left = deadline - time.monotonic()
        assert left > 0 and select.select([fd], [], [], left)[0], (
            f"no line from the child: {line!r}"
        )
        chunk = os.read(fd, 1)
        assert chunk, f"the child closed its output (exit {proc.poll()}) after {line!r}"
        line += chunk
    return line.decode().strip()


@pytest.mark.parametrize(
    ("family", "wait"),
    [
        ("BLD2", "reading"),
        ("BLD2", "sleeping"),
        ("BLD2", "record"),
        ("C20", "reading"),
        ("PBL", "reading"),
        ("PBL", "sleeping"),
    ],
)
def test_sigint_to_a_script_stops_the_motor(family: str, wait: str, tmp_path: Path) -> None:
    script = tmp_path / "bench.py"
    script.write_text(SCRIPT)
    with simulated(family) as (motor, sim):
        proc = subprocess.Popen(
            [sys.executable, str(script), sim.port, family, wait],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            cwd=tmp_path,
        )
        try:
            assert read_line(proc, STEP_TIMEOUT) == "running"
            motor.clock.now += 1.0
            assert motor.turning() and motor.commanded_to_run()
            time.sleep(0.3)  # well inside its loop
            assert proc.poll() is None and motor.commanded_to_run()
            proc.send_signal(signal.SIGINT)
            out, err = proc.communicate(timeout=STEP_TIMEOUT)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        stderr = err.decode(errors="replace")
        if wait == "record":
            assert proc.returncode == 0, stderr
            assert out.decode().splitlines()[-2].endswith("interrupted True")
            assert out.decode().splitlines()[-1] == "after the block"
        else:
            # An uncaught KeyboardInterrupt ends Python as SIGINT would: -2, with its traceback.
            assert proc.returncode == -signal.SIGINT, stderr
            assert stderr.rstrip().endswith("KeyboardInterrupt"), stderr
            assert b"after the block" not in out
        assert "could not stop" not in stderr
        assert not motor.commanded_to_run()
        assert motor.stopped()
        if isinstance(motor.device, DriveDevice):
            # Forward, then the stop on leaving, once: a SIGINT during a read no longer cuts
            # the read short (see test_ctrl_c_during_a_read_leaves_the_stop_its_reply).
            assert motor.device.commands == [1, 5]
        assert not sim.errors


#: A drive that falls silent while a script reads it, on a Bus with a long timeout and retries.
SILENT_SCRIPT = """\
import sys

import benchbus as bb

bus = bb.Bus(sys.argv[1], timeout=float(sys.argv[2]), retries=3)
with bb.Drive(bus, unit=1) as drive:
    drive.forward()
    print("running", flush=True)
    while True:
        _ = drive.speed
"""

#: The silent drive's timeout: long beside the tolerance, short enough for the suite.
SILENT_TIMEOUT = 1.5


@contextlib.contextmanager
def gone_silent(tmp_path: Path, script: str) -> Iterator[tuple[subprocess.Popen[bytes], Any]]:
    """Run ``script`` (:data:`SILENT_SCRIPT` or a variant) on a simulated BLD2 drive, make
    the drive fall silent once the script says "running", and wait until the script's read
    is into its retries (the drive owes answers, as after any timeout): yields the script's
    process and the simulator; the process is killed on the way out if still running."""
    path = tmp_path / "silent.py"
    path.write_text(script)
    with simulated("BLD2") as (motor, sim):
        proc = subprocess.Popen(
            [sys.executable, str(path), sim.port, str(SILENT_TIMEOUT)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            cwd=tmp_path,
        )
        try:
            assert read_line(proc, STEP_TIMEOUT) == "running"
            sim.set_silent(motor.unit)
            silent_from = sim.request_count
            deadline = time.monotonic() + STEP_TIMEOUT
            while sim.request_count < silent_from + 2 and time.monotonic() < deadline:
                time.sleep(0.01)
            yield proc, sim
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()


def test_ctrl_c_on_a_silent_drive_leaves_the_block_within_two_timeouts(tmp_path: Path) -> None:
    """Ctrl-C while the drive has fallen silent: the read in flight ends (one timeout), then
    the stop is sent once, at once (no retries, no wait for the read's owed answer): the
    block is left within two timeouts of the Ctrl-C, not after the owed answer's window and
    four attempts of the stop (about nine timeouts)."""
    with gone_silent(tmp_path, SILENT_SCRIPT) as (proc, sim):
        time.sleep(0.2)
        proc.send_signal(signal.SIGINT)
        sent = time.monotonic()
        _, err = proc.communicate(timeout=STEP_TIMEOUT * 2)
        took = time.monotonic() - sent
        stops = [r for r in sim.requests if r[1] == 0x06 and r[2:6] == bytes.fromhex("20000005")]
    stderr = err.decode(errors="replace")
    assert proc.returncode == -signal.SIGINT, stderr
    # The stop went unanswered: the interrupt goes on, the failure noted on it.
    assert "\nKeyboardInterrupt\nunit 1: could not stop the motor" in stderr, stderr
    assert len(stops) == 1, stops
    assert took < 2 * SILENT_TIMEOUT + 1.0, took


#: The silent drive of SILENT_SCRIPT, jogging.
JOGGING_SCRIPT = SILENT_SCRIPT.replace("drive.forward()", "drive.jog_forward()")


def test_a_second_ctrl_c_during_the_jog_stop_cuts_the_way_out_short(tmp_path: Path) -> None:
    """A jogging drive leaves its block by a jog stop and a stop; a second Ctrl-C while the
    jog stop waits on a silent drive is raised once that request is over, and the stop after
    it is not sent: the block is left within two timeouts of the first Ctrl-C, not three."""
    with gone_silent(tmp_path, JOGGING_SCRIPT) as (proc, sim):
        proc.send_signal(signal.SIGINT)
        sent = time.monotonic()
        jog_stop = bytes.fromhex("20000008")
        deadline = sent + STEP_TIMEOUT
        while time.monotonic() < deadline and not any(
            r[1] == 0x06 and r[2:6] == jog_stop for r in sim.requests
        ):
            time.sleep(0.01)
        time.sleep(0.2)  # the jog stop is on its way: its one attempt waits
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=STEP_TIMEOUT * 2)
        took = time.monotonic() - sent
        commands = [r[5] for r in sim.requests if r[1] == 0x06 and r[2:4] == b"\x20\x00"]
    stderr = err.decode(errors="replace")
    assert proc.returncode == -signal.SIGINT, stderr
    assert commands == [3, 8], commands  # the jog, its stop on leaving, and no stop after
    assert took < 2 * SILENT_TIMEOUT + 1.0, took


# ---- a signal in the middle of a transaction ---------------------------------------------------


@contextlib.contextmanager
def signal_during_the_next_call(signum: int, handler: Any, after: float) -> Iterator[list[int]]:
    """Install ``handler`` for ``signum`` and deliver that signal to this (the main) thread
    ``after`` seconds from now; yields the list of signals the handler saw."""
    seen: list[int] = []

    def handle(number: int, frame: Any) -> None:
        seen.append(number)
        handler()

    previous = signal.signal(signum, handle)
    main = threading.main_thread().ident
    assert main is not None and threading.get_ident() == main
    timer = threading.Timer(after, signal.pthread_kill, args=(main, signum))
    timer.start()
    try:
        yield seen
    finally:
        timer.join()
        signal.signal(signum, previous)


def test_a_signal_during_a_read_changes_no_value() -> None:
    """A signal whose handler returns (a timer, SIGWINCH, a child exiting...) leaves the
    transaction it lands in alone, and the next call gets its own value, never the last one's."""
    device = RegisterDevice({0x10: 111, 0x20: 222})
    with Simulator(device) as sim, bb.Bus(sim.port, timeout=1.0, retries=0) as bus:
        sim.reply_delay = 0.3
        with signal_during_the_next_call(signal.SIGUSR1, lambda: None, 0.05) as seen:
            try:
                first: object = bus.read_holding_registers(1, 0x10, 1)
            except bb.BenchbusError as exc:
                first = exc
        sim.reply_delay = 0.0
        second = bus.read_holding_registers(1, 0x20, 1)
        assert seen == [signal.SIGUSR1]
        assert (first, second) == ([111], [222])


def test_ctrl_c_during_a_read_leaves_the_stop_its_reply(caplog: pytest.LogCaptureFixture) -> None:
    """Ctrl-C that lands while a read waits for its reply: the block ends with
    KeyboardInterrupt and the stop on leaving is sent once and answered by its own reply (not
    by the read's, which would make it fail: "could not stop the motor")."""

    def ctrl_c() -> None:
        raise KeyboardInterrupt

    caplog.set_level(logging.ERROR, logger="benchbus.device")
    with simulated("BLD2") as (motor, sim):
        with (
            pytest.raises(KeyboardInterrupt),
            bb.Drive(sim.port, timeout=1.0, retries=0) as drive,
        ):
            motor.start(drive)
            sim.reply_delay = 0.3
            with signal_during_the_next_call(signal.SIGUSR2, ctrl_c, 0.05):
                while True:
                    _ = drive.speed
        stops = [r for r in sim.requests if r[1] == 0x06 and r[2:6] == bytes.fromhex("20000005")]
        assert isinstance(motor.device, DriveDevice)
        assert motor.device.commands == [1, 5]
        assert len(stops) == 1
        assert "could not stop the motor" not in caplog.text


def ctrl_c() -> None:
    """A SIGINT handler's work, as Python's default one does it."""
    raise KeyboardInterrupt


@pytest.mark.parametrize("raises", [True, False])
def test_ctrl_c_is_honoured_between_attempts(raises: bool) -> None:
    """Unit 9 is absent; the call has 4 attempts of 0.4 s. Ctrl-C in the first attempt lets
    that attempt run out, then raises at once: no further request. A handler that returns
    (a timer) leaves the call alone: all 4 attempts."""
    with (
        Simulator(RegisterDevice({0x10: 111})) as sim,
        bb.Bus(sim.port, timeout=0.4, retries=3) as bus,
    ):
        handler = ctrl_c if raises else (lambda: None)
        started = time.monotonic()
        with signal_during_the_next_call(signal.SIGUSR2, handler, 0.05) as seen:
            if raises:
                with pytest.raises(KeyboardInterrupt):
                    bus.read_holding_registers(9, 0x10, 1)
            else:
                with pytest.raises(bb.ResponseTimeout):
                    bus.read_holding_registers(9, 0x10, 1)
        elapsed = time.monotonic() - started
        asked = [r for r in sim.requests if r[0] == 9]
        assert seen == [signal.SIGUSR2]
        if raises:
            assert len(asked) == 1
            assert elapsed < 2 * 0.4, elapsed  # one attempt; four would take 1.6 s
        else:
            assert len(asked) == 4
        # The line is in step: the next call gets its own unit's value.
        assert bus.read_holding_registers(1, 0x10, 1) == [111]


def test_ctrl_c_stops_a_write_waiting_behind_another_threads_write_to_its_unit() -> None:
    """A write to unit 9 (absent) from another thread has four attempts of 0.4 s; a write to
    the same unit made after it waits for it (the device takes a unit's writes in the order
    they were made). Ctrl-C while it waits raises at once, not once the other write's
    attempts are over, and it was never sent; the other write goes on to its four attempts."""
    with (
        Simulator(RegisterDevice({0x10: 111})) as sim,
        bb.Bus(sim.port, timeout=0.4, retries=3) as bus,
    ):
        token, errors = bb.CancelToken(), []

        def earlier() -> None:
            with token, pytest.raises(bb.ResponseTimeout) as caught:
                bus.write_register(9, 0x10, 1)
            errors.append(caught.value)

        other = threading.Thread(target=earlier)
        other.start()
        while not token.queued:
            time.sleep(0.001)
        started = time.monotonic()
        with (
            signal_during_the_next_call(signal.SIGUSR2, ctrl_c, 0.2) as seen,
            pytest.raises(KeyboardInterrupt),
        ):
            bus.write_register(9, 0x10, 2)
        elapsed = time.monotonic() - started
        other.join(5)
        assert seen == [signal.SIGUSR2] and len(errors) == 1
        assert elapsed < 1.0, elapsed  # the other write's attempts end at 1.6 s
        assert [r[4:6] for r in sim.requests if r[0] == 9] == [b"\x00\x01"] * 4
        assert bus.read_holding_registers(1, 0x10, 1) == [111]


def test_a_handlers_write_is_not_undone_by_the_write_it_interrupted() -> None:
    """Unit 9 is absent; a write to it has three attempts of 0.25 s. A signal handler that
    writes another value to the same unit, run between the first write's attempts, makes
    the later write: its three attempts go out, and the first write's remaining attempts
    are not sent after them (they would leave the device with the value it replaced)."""
    with (
        Simulator(RegisterDevice({0x10: 111})) as sim,
        bb.Bus(sim.port, timeout=0.25, retries=2) as bus,
    ):
        errors: list[Exception] = []

        def handler() -> None:
            try:
                bus.write_register(9, 0x10, 2)
            except bb.ResponseTimeout as exc:
                errors.append(exc)

        with (
            signal_during_the_next_call(signal.SIGUSR2, handler, 0.05) as seen,
            pytest.raises(bb.ResponseTimeout),
        ):
            bus.write_register(9, 0x10, 1)
        values = [r[4:6] for r in sim.requests if r[0] == 9]
        assert seen == [signal.SIGUSR2] and len(errors) == 1
        assert values == [b"\x00\x01"] + [b"\x00\x02"] * 3
        assert bus.read_holding_registers(1, 0x10, 1) == [111]


CLI_READ_SLOW = """
import sys
from benchbus.cli import main
sys.exit(main(["read", "0", "--port", sys.argv[1], "--unit", "9", "--timeout", "2",
               "--retries", "3"]))
"""


def test_ctrl_c_ends_a_cli_read_after_the_attempt_in_flight() -> None:
    """``benchbus read --unit 9 --timeout 2 --retries 3`` to an absent unit: a real SIGINT
    ends it after the attempt in flight (about 2 s), not after all four (8 s)."""
    with Simulator(RegisterDevice({0: 1})) as sim:
        proc = subprocess.Popen(
            [sys.executable, "-c", CLI_READ_SLOW, sim.port],
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            deadline = time.monotonic() + 10
            while not any(r[0] == 9 for r in sim.requests) and time.monotonic() < deadline:
                time.sleep(0.02)
            proc.send_signal(signal.SIGINT)
            sent = time.monotonic()
            _, err = proc.communicate(timeout=15)
            took = time.monotonic() - sent
        finally:
            proc.kill()
        asked = [r for r in sim.requests if r[0] == 9]
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    assert len(asked) == 1
    assert took < 4.0, took


def test_a_panic_in_the_core_comes_out_as_benchbus_error() -> None:
    # The hook panics inside the guard every wire call runs in; without it PyO3 would raise
    # its PanicException, which is a BaseException that ``except Exception`` misses.
    with pytest.raises(bb.BenchbusError, match="internal error in benchbus") as info:
        _core._panic_on_wire()
    assert type(info.value) is bb.BenchbusError
    assert "a deliberate panic" in str(info.value)
