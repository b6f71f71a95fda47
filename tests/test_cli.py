"""The ``benchbus`` command line, run as a user runs it: a subprocess against simulators.

Each test starts its simulators in this process and runs ``python -m benchbus ...`` (or the
``benchbus`` console script installed next to this Python) on their pseudo-terminal.

A pseudo-terminal carries every line format (simulators open it at 8N1 and only time frames
by their baud rate), so ``scan --auto`` finds a unit at the first format it tries: the tests
check what that can show (a PBL is found and named once, every format is tried before
giving up), not which format a real line would need.
"""

from __future__ import annotations

import contextlib
import csv
import os
import select
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import IO

import pytest

import benchbus as bb
from benchbus import cli
from benchbus.sim import (
    Atv31Device,
    DriveDevice,
    J2Device,
    PblDevice,
    RegisterDevice,
    SimDevice,
    Simulator,
    TaisongDevice,
)

MODULE = [sys.executable, "-m", "benchbus"]
SCRIPT = Path(sys.executable).with_name("benchbus")


def _env(extra: dict[str, str] | None = None) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != cli.PORT_ENV}
    env.update(extra or {})
    return env


def run(
    *args: object, script: bool = False, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    """``benchbus ARGS`` to completion, output captured."""
    if script:
        assert SCRIPT.exists(), f"no console script at {SCRIPT}: pip install -e ."
    command = [str(SCRIPT)] if script else MODULE
    return subprocess.run(
        [*command, *map(str, args)],
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
        env=_env(env),
    )


def start(*args: object) -> subprocess.Popen[str]:
    """``benchbus ARGS`` in the background, stdout and stderr piped."""
    return subprocess.Popen(
        [*MODULE, *map(str, args)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=_env(),
    )


def readline(stream: IO[str] | None, timeout: float = 10.0) -> str:
    """One line from a child's pipe, failing the test rather than hanging."""
    assert stream is not None
    ready, _, _ = select.select([stream], [], [], timeout)
    assert ready, f"no output within {timeout} s"
    return stream.readline()


def stop(proc: subprocess.Popen[str], sig: int) -> tuple[int, str, str]:
    """Send ``sig``, then wait: the exit status and what is left of stdout and stderr."""
    try:
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=10)
        return proc.returncode, out, err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def ok(done: subprocess.CompletedProcess[str]) -> list[str]:
    """The stdout lines of a run that must have succeeded."""
    assert done.returncode == 0, f"exit {done.returncode}: {done.stderr}"
    assert "Traceback" not in done.stderr
    return done.stdout.splitlines()


def one_line_error(done: subprocess.CompletedProcess[str], status: int) -> str:
    """The single ``benchbus: ...`` line of a run that must have failed with ``status``."""
    assert done.returncode == status, f"exit {done.returncode}: {done.stdout} {done.stderr}"
    assert "Traceback" not in done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith("benchbus: "), lines[0]
    return lines[0]


def table(lines: Sequence[str]) -> dict[str, str]:
    """A two-column status table as ``{name: value}`` (names may hold single spaces)."""
    rows = {}
    for line in lines:
        name, _, value = line.partition("  ")
        rows[name] = value.strip()
    return rows


@pytest.fixture
def drive() -> Iterator[tuple[Simulator[DriveDevice], DriveDevice]]:
    device = DriveDevice("BLD2")
    with Simulator({1: device}) as sim:
        yield sim, device


# ---- the command itself --------------------------------------------------------------------------


def test_the_console_script_and_python_m_are_the_same_command() -> None:
    by_script = ok(run("--help", script=True))
    by_module = ok(run("--help"))
    assert by_script == by_module
    text = "\n".join(by_script)
    for command in ("scan", "read", "write", "drive", "pbl", "j2", "monitor", "sim", "demo"):
        assert command in text
    assert ok(run("--version", script=True)) == [f"benchbus {bb.__version__}"]
    demo = "\n".join(ok(run("demo", "--help")))  # wired; the demo itself is tested elsewhere
    assert "--port" in demo and "--out" in demo


def test_numbers_are_decimal_or_hex_and_unit_lists_take_ranges() -> None:
    assert [cli.parse_int(t) for t in ("100", "0x64", "0X64", "-5", "007")] == [
        100,
        100,
        100,
        -5,
        7,
    ]
    for bad in ("", "0x", "ten", "0b11"):
        with pytest.raises(ValueError, match="not a number"):
            cli.parse_int(bad)
    for bad in ("1.5", "1e3"):
        with pytest.raises(ValueError, match="not a whole number"):
            cli.parse_int(bad)
    assert cli.parse_units("1-3,0x10,5,2") == [1, 2, 3, 5, 16]
    for bad in ("5-2", "0", "1-", "1--3", "256", "a-b", ""):
        with pytest.raises(ValueError):
            cli.parse_units(bad)


# ---- errors: one line, never a traceback ---------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "status", "says"),
    [
        (["read", "0"], 2, "--port is required"),
        (["read", "--port", "/dev/no-such-benchbus-port", "0"], 1, "cannot open"),
        (["read", "--port", "/dev/null", "zz"], 2, "'zz' is not a number"),
        (["read", "--port", "/dev/null", "0x10000"], 2, "ADDRESS must be 0 to 65535"),
        (["write", "--port", "/dev/null", "0", "70000"], 2, "does not fit"),
        (["read", "--port", "/dev/null", "0", "--hex", "--signed"], 2, "--hex"),
        (["frobnicate"], 2, "invalid choice: 'frobnicate'"),
        ([], 2, "required: COMMAND"),
        (["drive", "--port", "/dev/null"], 2, "required: ACTION"),
        (["scan", "--port", "/dev/null", "--units", "9-2"], 2, "increasing"),
        (["scan", "--port", "/dev/null", "--auto", "--baudrate", "9600"], 2, "--auto"),
        (["monitor", "j2", "--count", "2", "--duration", "1"], 2, "not allowed with"),
        (["read", "--port", "/dev/null", "0", "--parity", "X"], 2, "parity is N, E or O"),
    ],
)
def test_an_error_is_one_line_and_a_nonzero_exit(args: list[str], status: int, says: str) -> None:
    assert says in one_line_error(run(*args), status)


def test_a_silent_unit_times_out_after_the_retries_asked_for(
    drive: tuple[Simulator[DriveDevice], DriveDevice],
) -> None:
    sim, _ = drive
    sim.set_silent(1)
    line = one_line_error(
        run("read", "--port", sim.port, "0x2100", "--timeout", "0.05", "--retries", "1"), 1
    )
    assert "unit 1" in line and "no complete reply" in line
    assert len(sim.requests) == 2  # one try and one retry
    sim.set_silent(1, False)
    assert "illegal data address" in one_line_error(run("read", "--port", sim.port, "0x1234"), 1)


def test_the_simulators_need_pymodbus_and_say_so(tmp_path: Path) -> None:
    (tmp_path / "pymodbus").mkdir()
    (tmp_path / "pymodbus" / "__init__.py").write_text("")  # a pymodbus without its modules
    done = run("sim", "drive", "--seconds", "1", env={"PYTHONPATH": str(tmp_path)})
    assert "pip install 'benchbus[sim]'" in one_line_error(done, 1)
    assert done.stdout == ""


def test_ctrl_c_during_a_scan_shows_what_it_found_and_exits_130() -> None:
    with Simulator({1: RegisterDevice()}) as sim:  # unit 1 answers, 2..247 time out
        proc = start("scan", "--port", sim.port, "--timeout", "0.2", "--progress")
        try:
            assert proc.stderr is not None
            seen, deadline = "", time.monotonic() + 10
            while "1 found" not in seen and time.monotonic() < deadline:
                if select.select([proc.stderr], [], [], 1)[0]:
                    seen += proc.stderr.read(1)
            assert "1 found" in seen  # past unit 1, still scanning
        finally:
            status, out, err = stop(proc, signal.SIGINT)
    assert status == 130
    assert out.splitlines() == ["unit  hex   line       model", "1     0x01  19200 8N1  ?"]
    assert "Traceback" not in err and err.splitlines()[-1] == "benchbus: interrupted"


# ---- scan ----------------------------------------------------------------------------------------


def test_scan_finds_the_units_and_guesses_their_models() -> None:
    units: dict[int, SimDevice] = {
        1: DriveDevice("BLD2"),
        2: DriveDevice("C20"),
        3: J2Device(),
        4: TaisongDevice(),
        5: Atv31Device(),
        0x11: PblDevice(),
    }
    with Simulator(units) as sim:
        done = run("scan", "--port", sim.port, "--units", "1-6,0x11", "--progress", script=True)
    lines = ok(done)
    assert lines[0].split() == ["unit", "hex", "line", "model"]
    found = {int(line.split()[0]): line.split(None, 4)[1:] for line in lines[1:]}
    assert found == {
        1: ["0x01", "19200", "8N1", "Drive BLD2"],
        2: ["0x02", "19200", "8N1", "Drive C20"],
        3: ["0x03", "19200", "8N1", "J2"],
        4: ["0x04", "19200", "8N1", "Taisong"],
        5: ["0x05", "19200", "8N1", "TELEMECANIQUE ATV31HU09M3S232"],
        17: ["0x11", "19200", "8N1", "PBL"],
    }
    # The progress bar went to stderr (asked for: stderr is not a terminal here), not stdout.
    assert "#" not in done.stdout
    assert "[########################] 7/7" in done.stderr
    assert done.stderr.rstrip().endswith("7/7 6 found")


def test_scan_auto_finds_a_pbl_once_and_shows_no_bar_off_a_terminal() -> None:
    with Simulator({0x11: PblDevice()}, baudrate=115200) as sim:
        done = run("scan", "--port", sim.port, "--auto", "--units", "0x10-0x12")
    # On a pty the first format already reaches it (see the module docstring); a unit found
    # at one format is not asked again at the next.
    assert ok(done)[1:] == ["17    0x11  19200 8N1  PBL"]
    assert done.stderr == ""


def test_scan_auto_tries_every_format_before_it_gives_up() -> None:
    with Simulator({1: DriveDevice()}) as sim:
        done = run(
            "scan", "--port", sim.port, "--auto", "--units", "2", "--timeout", "0.02", "--progress"
        )
        assert all(frame[0] == 2 for frame in sim.requests)
        assert len(sim.requests) == 5  # unit 2 asked once at each format
    assert done.returncode == 1 and done.stdout == ""
    for line_format in ("19200 8N1", "115200 8E1", "9600 8N1", "4800 8N1", "2400 8N1"):
        assert f"unit 2 at {line_format}" in done.stderr
    assert done.stderr.splitlines()[-1].startswith("benchbus: no unit answered on ")


class AnyUnitServer:
    """A Modbus TCP server on loopback that answers every unit id, as libmodbus and many
    devices that speak Modbus TCP themselves do: 0x03 with each register's address as its
    value; any other function, as libmodbus 3.1.6 does, only after 0.5 s, dropping what
    arrived meanwhile, with exception 1."""

    STALL = 0.5

    def __init__(self) -> None:
        self._server = socket.create_server(("127.0.0.1", 0))
        self._server.settimeout(0.1)
        self.url = f"tcp://127.0.0.1:{self._server.getsockname()[1]}"
        #: Every request PDU, in order.
        self.requests: list[bytes] = []
        self._stop = threading.Event()
        self._threads = [threading.Thread(target=self._accept)]
        self._threads[0].start()

    def __enter__(self) -> AnyUnitServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        for thread in self._threads:
            thread.join(5)
        self._server.close()

    def _accept(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._server.accept()
            except TimeoutError:
                continue
            thread = threading.Thread(target=self._serve, args=(conn,))
            self._threads.append(thread)
            thread.start()

    def _serve(self, conn: socket.socket) -> None:
        buf = b""
        with conn:
            conn.settimeout(0.1)
            while not self._stop.is_set():
                try:
                    chunk = conn.recv(512)
                except TimeoutError:
                    continue
                except OSError:
                    return
                if not chunk:
                    return
                buf += chunk
                while len(buf) >= 7 and len(buf) >= 6 + int.from_bytes(buf[4:6], "big"):
                    length = int.from_bytes(buf[4:6], "big")
                    header, pdu, buf = buf[:7], buf[7 : 6 + length], buf[6 + length :]
                    self.requests.append(pdu)
                    if pdu[0] == 0x03 and len(pdu) == 5:
                        address, count = struct.unpack(">HH", pdu[1:])
                        values = [(address + i) & 0xFFFF for i in range(count)]
                        reply = struct.pack(f">BB{count}H", 3, 2 * count, *values)
                    else:
                        time.sleep(self.STALL)
                        buf = b""
                        with contextlib.suppress(TimeoutError):
                            while conn.recv(512):
                                pass
                        reply = bytes([pdu[0] | 0x80, 0x01])
                    conn.sendall(
                        header[:4] + struct.pack(">H", len(reply) + 1) + header[6:] + reply
                    )


def test_scan_over_tcp_of_a_server_that_answers_every_unit_id_is_quick() -> None:
    with AnyUnitServer() as server:
        started = time.monotonic()
        done = run("scan", "--port", server.url, "--units", "1-247")
        elapsed = time.monotonic() - started
        # Read Device Identification stalls this server: asked of the first unit only.
        assert [pdu[0] for pdu in server.requests].count(0x2B) == 1
    lines = ok(done)
    # 0.5 s for each unit's identification took over 2 minutes.
    assert elapsed < 10, elapsed
    assert lines[0].split() == ["unit", "hex", "line", "model"]
    rows = [line.split() for line in lines[1:-1]]
    assert [int(row[0]) for row in rows] == list(range(1, 248))
    assert {row[2] for row in rows} == {"tcp"}
    assert lines[-1].startswith(f"every unit id tried answered: the server at {server.url}")


def test_scan_over_tcp_shows_the_transport_and_identifies_units() -> None:
    with Simulator({1: Atv31Device(), 3: DriveDevice("BLD2")}, network="tcp") as sim:
        done = run("scan", "--port", sim.port, "--units", "1-4", "--auto")
    assert ok(done)[1:] == [
        "1     0x01  tcp   TELEMECANIQUE ATV31HU09M3S232",
        "3     0x03  tcp   Drive BLD2",
    ]


def test_scan_auto_over_a_serial_converter_tries_one_line_format() -> None:
    # rtu+tcp:// reaches a converter whose serial side keeps its own line format: no format
    # the scan could set is tried, only the one it was given (default or not).
    with Simulator({1: DriveDevice("BLD2")}, network="rtu+tcp") as sim:
        done = run("scan", "--port", sim.port, "--units", "2-3", "--auto", "--timeout", "0.05")
    assert done.returncode == 1
    tried = done.stderr.strip().rpartition("(at ")[2].rstrip(")")
    assert tried.count(",") == 0 and tried, done.stderr


# ---- read / write --------------------------------------------------------------------------------


def test_read_prints_registers_raw_hex_signed_and_scaled() -> None:
    device = RegisterDevice({0x10: 0xFFFB, 0x11: 1234})
    with Simulator({7: device}) as sim:
        port = ["--port", sim.port, "--unit", "7"]
        assert ok(run("read", *port, "0x10", "2")) == ["0x0010 (16) = 65531", "0x0011 (17) = 1234"]
        assert ok(run("read", *port, "16", "2", "--hex")) == [
            "0x0010 (16) = 0xFFFB",
            "0x0011 (17) = 0x04D2",
        ]
        signed = run("read", *port, "0x10", "2", "--signed", "--decimals", "1")
        assert [line.split()[-1] for line in ok(signed)] == ["-0.5", "123.4"]
        # $BENCHBUS_PORT stands in for --port; 130 registers take two requests (125 + 5).
        sim.clear_log()
        many = ok(run("read", "--unit", "7", "0", "130", env={cli.PORT_ENV: sim.port}))
        assert len(many) == 130 and many[-1] == "0x0081 (129) = 0"
        assert [(f[1], f[4] << 8 | f[5]) for f in sim.requests] == [(3, 125), (3, 5)]


def test_read_and_write_typed_values_in_each_layout() -> None:
    device = RegisterDevice()
    with Simulator({7: device}) as sim:
        port = ["--port", sim.port, "--unit", "7"]
        # Two floats, low word first (CDAB): 21.5 is 0x41AC0000, -0.5 is 0xBF000000.
        device.registers[0x10:0x14] = [0x0000, 0x41AC, 0x0000, 0xBF00]
        lines = ok(run("read", *port, "0x10", "2", "--type", "f32", "--order", "cdab"))
        assert lines == ["0x0010 (16) = 21.5", "0x0012 (18) = -0.5"]
        assert [(f[1], f[4] << 8 | f[5]) for f in sim.requests] == [(3, 4)]
        # Written as it is read: a 64-bit integer over four registers, byte-swapped.
        done = ok(run("write", *port, "0x20", "-2", "--type", "i64", "--order", "BADC"))
        assert done == ["unit 7: wrote 65535 65535 65535 65279 at 0x0020 (0x10)"]
        assert sim.peek(7, 0x20, 4) == [0xFFFF, 0xFFFF, 0xFFFF, 0xFEFF]
        back = ok(run("read", *port, "0x20", "--type", "i64", "--order", "BADC"))
        assert back == ["0x0020 (32) = -2"]
        # One u16 still goes as 0x06; a hex integer is taken for an integer type.
        ok(run("write", *port, "0x30", "0x1234", "--type", "u16"))
        assert sim.requests[-1][1] == 0x06 and sim.peek(7, 0x30) == [0x1234]


def test_read_and_write_every_table() -> None:
    device = RegisterDevice(coils=[1, 3], discrete_inputs=[0, 2])
    device.input_registers[5:7] = [0x41AC, 0x0000]
    with Simulator({4: device}) as sim:
        port = ["--port", sim.port, "--unit", "4"]
        assert ok(run("read", *port, "0", "4", "--table", "coils")) == [
            "0x0000 (0) = 0",
            "0x0001 (1) = 1",
            "0x0002 (2) = 0",
            "0x0003 (3) = 1",
        ]
        assert [
            line.split()[-1] for line in ok(run("read", *port, "0", "3", "--table", "discrete"))
        ] == ["1", "0", "1"]
        assert ok(run("read", *port, "5", "--table", "input", "--type", "f32")) == [
            "0x0005 (5) = 21.5"
        ]
        assert [f[1] for f in sim.requests] == [0x01, 0x02, 0x04]
        # 2500 coils: a read of 2000, then 500.
        sim.clear_log()
        assert len(ok(run("read", *port, "0", "2500", "--table", "coils"))) == 2500
        assert [(f[1], f[4] << 8 | f[5]) for f in sim.requests] == [(1, 2000), (1, 500)]
        assert ok(run("write", *port, "10", "on", "--table", "coils")) == [
            "unit 4: wrote coils 1 at 0x000A (0x05)"
        ]
        assert ok(run("write", *port, "20", "1", "0", "true", "--table", "coils")) == [
            "unit 4: wrote coils 1 0 1 at 0x0014 (0x0F)"
        ]
        assert sim.peek(4, 10, 1, table="coils") == [1]
        assert sim.peek(4, 20, 3, table="coils") == [1, 0, 1]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["read", "0", "--order", "CDAB"], "give --type with it"),
        (["read", "0", "--type", "f32", "--hex"], "leave out --hex"),
        (["read", "0xFFFF", "--type", "u32"], "2 registers from 0xffff run past 0xFFFF"),
        (["write", "0", "1.5", "--type", "i32"], "'1.5' is not a whole number"),
        (["write", "0", "x", "--type", "f32"], "'x' is not a number"),
        (["write", "0", "70000", "--type", "u16"], "u16 value must be 0 to 65535"),
        (["write", "0", "1", "--type", "f32", "--decimals", "1"], "leave out --decimals"),
        (["read", "0", "--table", "coils", "--hex"], "--table coils reads bits"),
        (["read", "0", "--table", "discrete", "--type", "u32"], "reads bits"),
        (["read", "0xFFFF", "2", "--table", "coils"], "2 coils from 0xffff run past"),
        (["write", "0", "2", "--table", "coils"], "'2' is not a coil value"),
        (["write", "0", "1", "--table", "coils", "--type", "u16"], "writes bits"),
    ],
)
def test_typed_values_refused_before_the_port_opens(args: list[str], message: str) -> None:
    assert message in one_line_error(run(*args, "--port", "/dev/null"), 2)


def test_write_uses_0x06_for_one_value_and_0x10_for_several(
    drive: tuple[Simulator[DriveDevice], DriveDevice],
) -> None:
    sim, device = drive
    assert ok(run("write", "--port", sim.port, "0x2001", "1500")) == [
        "unit 1: wrote 1500 at 0x2001 (0x06)"
    ]
    assert device.peek(0x2001) == 1500 and sim.requests[-1][1] == 0x06
    ok(run("write", "--port", sim.port, "0x2003", "0x19", "30"))
    assert (device.peek(0x2003), device.peek(0x2004)) == (25, 30)
    assert sim.requests[-1][1] == 0x10
    ok(run("write", "--port", sim.port, "0x2001", "900", "--multiple"))
    assert device.peek(0x2001) == 900 and sim.requests[-1][1] == 0x10


def test_write_takes_negative_and_scaled_values() -> None:
    device = RegisterDevice()
    with Simulator({1: device}) as sim:
        ok(run("write", "--port", sim.port, "0x10", "-0.5", "12.3", "--decimals", "1"))
        ok(run("write", "--port", sim.port, "0x20", "-2"))
        assert device.registers[0x10:0x12] == [0xFFFB, 123] and device.registers[0x20] == 0xFFFE
        line = one_line_error(run("write", "--port", sim.port, "0", "1.25", "--decimals", "1"), 2)
        assert "more than 1 decimals" in line
        assert device.registers[0] == 0


# ---- drive / pbl / j2 ----------------------------------------------------------------------------


def test_drive_start_makes_the_simulated_drive_run(
    drive: tuple[Simulator[DriveDevice], DriveDevice],
) -> None:
    sim, device = drive
    port = ["--port", sim.port]
    assert ok(run("drive", *port, "start", "--speed", "1200")) == [
        "unit 1: running forward at 1200 rpm"
    ]
    assert device.state == DriveDevice.FORWARD and device.peek(0x2001) == 1200
    deadline = time.monotonic() + 5
    while device.speed <= 0 and time.monotonic() < deadline:
        time.sleep(0.02)
    assert device.speed > 0
    status = table(ok(run("drive", "status", *port)))
    assert status["model"] == "BLD2" and status["state"] == "FORWARD"
    assert status["speed setpoint"] == "1200 rpm" and status["fault"] == "none"
    ok(run("drive", *port, "stop"))
    assert device.commands[-1] == 5
    device.inject_fault(0x0A)
    assert "exception" in one_line_error(run("drive", *port, "start"), 1)
    assert device.state == DriveDevice.FAULT
    ok(run("drive", *port, "reset-fault"))
    assert device.fault == 0


def test_pbl_start_reverse_and_the_start_stop_source() -> None:
    device = PblDevice()
    with Simulator({0x11: device}) as sim:
        pbl = ["--port", sim.port, "--unit", "0x11"]
        device.set_param(204, 0)  # start/stop from the keys: a start would be ignored
        line = one_line_error(run("pbl", *pbl, "start", "--speed", "900"), 2)
        assert "--take-control" in line and device.peek(0) == 0
        ok(run("pbl", *pbl, "start", "--speed", "900", "--take-control"))
        assert device.peek(204) == 2 and device.peek(201) == 900
        assert device.peek(0) == 0b01 and device.running
        ok(run("pbl", "reverse", *pbl))
        assert device.peek(0) == 0b11
        status = table(ok(run("pbl", "status", *pbl)))
        assert status["running"].startswith("yes, ") and status["direction asked"] == "REVERSE"
        assert status["speed setpoint"] == "900 rpm" and status["alarms"] == "none"
        ok(run("pbl", "stop", *pbl))
        assert device.peek(0) == 0b10


def test_j2_setpoint_modes_and_output() -> None:
    device = J2Device()
    with Simulator({3: device}) as sim:
        j2 = ["--port", sim.port, "--unit", "3"]
        assert ok(run("j2", *j2, "set-sv", "150.5")) == ["unit 3: SV 150.5"]
        assert device.value("SV") == 150.5
        assert "--manual" in one_line_error(run("j2", *j2, "set-output", "30"), 2)
        assert device.auto
        ok(run("j2", *j2, "set-output", "30", "--manual"))
        assert not device.auto and device.value("MV") == 30.0
        status = table(ok(run("j2", "status", *j2)))
        assert status["sv"] == "150.5 °C" and status["mv"] == "30 %" and status["mode"] == "MANUAL"
        ok(run("j2", *j2, "auto"))
        assert device.auto
        assert "LSP to USP" in one_line_error(run("j2", *j2, "set-sv", "500"), 2)
        assert device.value("SV") == 150.5


# ---- monitor -------------------------------------------------------------------------------------


def test_monitor_count_appends_rows_to_a_csv_file(tmp_path: Path) -> None:
    log = tmp_path / "j2.csv"
    units: dict[int, SimDevice] = {1: J2Device(), 2: PblDevice()}
    with Simulator(units) as sim:
        args = ["monitor", "j2", "--port", sim.port, "--interval", "0.1", "--csv", log]
        lines = ok(run(*args, "--count", "3"))
        assert lines[0].split() == ["t", "(s)", "pv", "(°C)", "sv", "(°C)", "mv", "(%)"]
        assert len(lines) == 4
        t = [round(float(line.split()[0]) * 10) for line in lines[1:]]  # in intervals
        assert t[0] == 0 and t[0] < t[1] < t[2]  # on the ticks (one may be skipped if late)
        with log.open() as f:
            rows = list(csv.reader(f))
        assert rows[0] == ["time", "t (s)", "pv (°C)", "sv (°C)", "mv (%)"] and len(rows) == 4
        assert all(float(r[3]) == 100.0 for r in rows[1:])  # SV at power-up
        ok(run(*args, "--count", "2"))  # appends, without a second header
        with log.open() as f:
            rows = list(csv.reader(f))
        assert len(rows) == 6 and rows[4][0] != "time"
        other = run(
            "monitor", "pbl", "--port", sim.port, "--unit", "2", "--count", "1", "--csv", log
        )
        assert "other columns" in one_line_error(other, 1)


def test_monitor_duration_and_fields(drive: tuple[Simulator[DriveDevice], DriveDevice]) -> None:
    sim, _ = drive
    done = run(
        "monitor", "drive", "--port", sim.port, "--duration", "0.3", "--interval", "0.1",
        "--fields", "speed,bus_voltage",
    )  # fmt: skip
    lines = ok(done)
    assert lines[0].split() == ["t", "(s)", "speed", "(rpm)", "bus_voltage", "(V)"]
    assert 1 <= len(lines) - 1 <= 3
    assert all(line.split()[1:] == ["0", "311"] for line in lines[1:])
    bad = run("monitor", "drive", "--port", sim.port, "--count", "1", "--fields", "rpm")
    assert "choose from" in one_line_error(bad, 2)


def test_monitor_ends_at_ctrl_c_with_status_0() -> None:
    with Simulator({1: PblDevice()}) as sim:
        proc = start("monitor", "pbl", "--port", sim.port, "--interval", "0.05")
        try:
            assert readline(proc.stdout).split()[:4] == ["t", "(s)", "speed", "(rpm)"]
            assert readline(proc.stdout).split()[0] == "0.000"
        finally:
            status, _, err = stop(proc, signal.SIGINT)
    assert status == 0, err
    assert "Traceback" not in err and " samples" in err


# ---- sim -----------------------------------------------------------------------------------------


def test_sim_prints_its_port_serves_it_and_ends_at_sigterm() -> None:
    proc = start("sim", "drive", "--unit", "3", "--model", "C20")
    try:
        port = readline(proc.stdout).strip()
        assert port.startswith("/dev/")
        assert ok(run("read", "--port", port, "--unit", "3", "0x2103", "--hex")) == [
            "0x2103 (8451) = 0x0020"
        ]
        with bb.Drive(port, unit=3, family="C20") as drive:
            assert drive.model == bb.Model.C20
    finally:
        status, out, err = stop(proc, signal.SIGTERM)
    assert status == 0, err
    assert out == "" and "Traceback" not in err
    assert "simulating C20 drive (unit 3" in err


def test_sim_ends_after_its_seconds_and_at_ctrl_c() -> None:
    began = time.monotonic()
    lines = ok(run("sim", "j2", "--seconds", "0.3", "--speedup", "10"))
    assert len(lines) == 1 and lines[0].startswith("/dev/")
    assert time.monotonic() - began < 10
    proc = start("sim", "pbl", "--unit", "1-2")
    try:
        port = readline(proc.stdout).strip()
        with bb.Bus(port, baudrate=115200, parity="E") as bus:
            assert bus.scan(range(1, 4)) == [1, 2]
    finally:
        status, _, err = stop(proc, signal.SIGINT)
    assert status == 0, err


def test_profile_check_prints_the_table_and_refuses_a_mistake_with_its_line(
    tmp_path: Path,
) -> None:
    example = Path(__file__).resolve().parent.parent / "examples" / "profiles" / "xy_md02.toml"
    lines = ok(run("profile", "check", example))
    assert lines[0].startswith("XY-MD02")
    assert lines[1].startswith("line 9600 8N1 rtu")
    rows = {line.split()[0]: line.split() for line in lines[3:]}
    assert rows["temperature"][1:5] == ["input", "0x0001", "i16", "0.1"]
    assert rows["baud"][-1].startswith("0=b9600")
    bad = tmp_path / "bad.toml"
    bad.write_text('[device]\nname = "x"\n\n[[register]]\nname = "sample"\naddress = 1\n')
    message = one_line_error(run("profile", "check", bad), 2)
    assert f"{bad}:5: register[0].name" in message and "shadow" in message
    assert "No such file" in one_line_error(run("profile", "check", tmp_path / "none.toml"), 2)


def test_profile_check_shows_a_flag_and_a_field_of_a_status_word(tmp_path: Path) -> None:
    path = tmp_path / "status.toml"
    path.write_text(
        '[device]\nname = "x"\n[[register]]\nname = "status"\naddress = 1\naccess = "r"\n'
        '[[register]]\nname = "ready"\naddress = 1\ntype = "bool"\nbit = 0\naccess = "r"\n'
        '[[register]]\nname = "mode"\naddress = 1\nbits = [5, 6]\naccess = "r"\n'
    )
    rows = {line.split()[0]: line for line in ok(run("profile", "check", path))[3:]}
    assert "bool bit 0" in rows["ready"]
    assert "u16 bits 5..6" in rows["mode"] and rows["mode"].rstrip().endswith("0..3")


def test_profile_check_refuses_an_enum_member_python_keeps_for_itself(tmp_path: Path) -> None:
    bad = tmp_path / "enum.toml"
    bad.write_text(
        '[device]\nname = "x"\n[[register]]\nname = "mode"\naddress = 1\n'
        'enum = { 0 = "off", 1 = "_missing_" }\n'
    )
    message = one_line_error(run("profile", "check", bad), 2)
    assert f'{bad}:6: register[0].enum.1: "_missing_" is a _sunder_ name' in message


def test_profile_export_writes_a_family_as_a_profile_that_reads_back(tmp_path: Path) -> None:
    text = run("profile", "export", "j2")
    lines = ok(text)
    assert lines[0].startswith("# ") and "RAPNF" in text.stdout
    profile = bb.Profile.parse(text.stdout, "j2.toml")
    table = bb.J2Controller.table()
    assert [(r.name, r.address) for r in profile.registers] == [(t.name, t.address) for t in table]
    assert profile["PV"].type == "i16" and profile["PV"].scale == 0.1
    out = tmp_path / "pbl.toml"
    assert ok(run("profile", "export", "pbl", "-o", out)) == []
    assert out.read_text(encoding="utf-8") == bb.Profile.family("pbl").to_toml()
    assert ok(run("profile", "check", out))[0].startswith("PBL")
    message = one_line_error(run("profile", "export", "atv31"), 2)
    assert "drive, drive-c20, pbl, j2" in message
    message = one_line_error(run("profile", "export", "drive", "-o", tmp_path / "no" / "x"), 2)
    assert "cannot write" in message
