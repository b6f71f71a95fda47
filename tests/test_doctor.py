"""``bb.doctor`` and ``benchbus doctor``: a port's check-up as data and as lines, on
pseudo-terminals served by the simulator (with and without a local echo), on a sysfs tree
built in a tmp dir (an FTDI adapter at 16 ms and at 1 ms), and on a port another process
holds; and the kernel RS485 mode a Bus asks for (``rs485=True``), refused by a pty."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from test_cli import one_line_error, run
from test_ports import _board_uart, _ftdi

import benchbus as bb
from benchbus.sim import RegisterDevice, Simulator

UDEV_RULE = 'ACTION=="add", SUBSYSTEM=="usb-serial", DRIVER=="ftdi_sio", ATTR{latency_timer}="1"'


def by_name(findings: list[bb.Finding]) -> dict[str, bb.Finding]:
    return {f.name: f for f in findings}


@pytest.fixture
def pty() -> Iterator[str]:
    """A pseudo-terminal's slave path, not held open by this process; nothing serves the
    master side."""
    master, slave = os.openpty()
    path = os.ttyname(slave)
    os.close(slave)
    yield path
    os.close(master)


def test_a_simulator_on_a_pty_has_no_echo_and_nothing_fails() -> None:
    with Simulator(RegisterDevice({0: 7})) as sim:
        findings = bb.doctor(sim.port, timeout=0.2)
        assert len(sim.requests) == 1  # the echo test's one read, answered
    assert [f.name for f in findings] == [
        "platform",
        "port",
        "permissions",
        "open",
        "usb",
        "low-latency",
        "rs485",
        "echo",
    ]
    found = by_name(findings)
    assert found["platform"].message.startswith(("Linux", "macOS"))
    assert (found["open"].verdict, found["open"].message) == (
        "ok",
        "opens, exclusively, at 19200 8N1",
    )
    assert found["echo"].verdict == "ok"
    assert (
        found["echo"].message
        == "no echo: a reply came back first to a read of register 0 from unit 1"
    )
    # A pty has no low-latency mode: recorded as "not supported", never an error.
    assert found["low-latency"].verdict == "info"
    assert found["low-latency"].message.startswith("not supported")
    assert found["rs485"].message.startswith("no kernel RS485 mode")
    assert all(f.verdict != "fail" for f in findings)


def test_an_echoing_adapter_is_told_to_open_the_bus_with_echo() -> None:
    with Simulator(RegisterDevice({0: 7}), echo=True) as sim:
        echo = by_name(bb.doctor(sim.port, unit=5, timeout=0.2))["echo"]
        assert echo.verdict == "warn"
        assert echo.message.startswith("local echo: a read of register 0 from unit 5 came back")
        assert echo.fix == "open the Bus with echo=True: bb.Bus(port, echo=True)"
        with bb.Bus(sim.port, echo=True) as bus:  # and the fix works
            assert bus.read_holding_registers(1, 0, 1) == [7]


def test_a_finding_is_frozen_data_with_a_one_line_form() -> None:
    f = bb.Finding("latency-timer", "warn", "FTDI latency timer 16 ms", "write 1")
    with pytest.raises(dataclasses.FrozenInstanceError):
        f.verdict = "ok"  # type: ignore[misc]
    assert str(f) == "warn  latency-timer  FTDI latency timer 16 ms  fix: write 1"
    assert str(bb.Finding("open", "ok", "opens")) == "ok    open           opens"
    assert "doctor" in bb.__all__ and "Finding" in bb.__all__


@pytest.mark.parametrize(
    ("kwargs", "error"),
    [
        ({"unit": 0}, ValueError),
        ({"unit": "1"}, TypeError),
        ({"timeout": -1}, ValueError),
        ({"parity": "X"}, ValueError),
        ({"baudrate": 1.5}, TypeError),
    ],
)
def test_bad_arguments_are_refused(pty: str, kwargs: dict[str, object], error: type) -> None:
    with pytest.raises(error):
        bb.doctor(pty, **kwargs)  # type: ignore[arg-type]


def test_a_network_port_is_not_a_serial_port() -> None:
    with pytest.raises(ValueError, match="doctor checks a serial port"):
        bb.doctor("tcp://127.0.0.1:502")


def test_a_missing_port_fails_and_says_where_to_look(tmp_path: Path) -> None:
    found = by_name(bb.doctor(tmp_path / "ttyUSB9"))
    assert found["port"].verdict == "fail"
    assert found["port"].fix is not None and "benchbus ports" in found["port"].fix
    assert "open" not in found


def test_a_macos_tty_path_suggests_its_cu_twin() -> None:
    cu = by_name(bb.doctor("/dev/tty.usbserial-A50285BI"))["tty-vs-cu"]
    assert cu.verdict == "warn"
    assert cu.fix == "open /dev/cu.usbserial-A50285BI instead"


def _ftdi_tree(tmp_path: Path, pty: str, latency_ms: int) -> tuple[Path, Path]:
    """A sysfs tree with an FTDI adapter at ttyUSB0 whose latency timer is ``latency_ms``,
    and a ``ttyUSB0`` link to the pty, so the port opens: (sysfs root, port path)."""
    root = tmp_path / "sys"
    _ftdi(root)
    timer = root / "bus/usb-serial/devices/ttyUSB0"
    timer.mkdir(parents=True)
    (timer / "latency_timer").write_text(f"{latency_ms}\n")
    port = tmp_path / "dev" / "ttyUSB0"
    port.parent.mkdir()
    port.symlink_to(pty)
    return root, port


def test_an_ftdi_at_16_ms_is_a_warning_with_the_fix_and_the_udev_rule(
    tmp_path: Path, pty: str
) -> None:
    sysfs, port = _ftdi_tree(tmp_path, pty, 16)
    found = by_name(bb.doctor(port, sysfs_root=sysfs))
    assert found["port"].message == f"{port} exists, a link to {pty}"
    assert found["usb"].verdict == "ok"
    assert found["usb"].message == (
        "FTDI adapter (0403:6001 FTDI FT232R USB UART, serial A50285BI, driver ftdi_sio)"
    )
    timer = found["latency-timer"]
    assert timer.verdict == "warn"
    assert timer.message == "FTDI latency timer 16 ms: it adds up to 16 ms to every reply"
    assert timer.fix is not None
    assert "write 1 to /sys/bus/usb-serial/devices/ttyUSB0/latency_timer" in timer.fix
    assert UDEV_RULE in timer.fix
    lines = run("doctor", "--port", port, "--sysfs-root", sysfs).stdout.splitlines()
    assert any(
        line.startswith("warn  latency-timer  FTDI latency timer 16 ms") and UDEV_RULE in line
        for line in lines
    ), lines


def test_an_ftdi_at_1_ms_is_ok(tmp_path: Path, pty: str) -> None:
    sysfs, port = _ftdi_tree(tmp_path, pty, 1)
    timer = by_name(bb.doctor(port, sysfs_root=sysfs))["latency-timer"]
    assert (timer.verdict, timer.message, timer.fix) == ("ok", "FTDI latency timer 1 ms", None)


def test_a_board_uart_is_no_usb_adapter_and_has_no_latency_timer(tmp_path: Path, pty: str) -> None:
    root = tmp_path / "sys"
    _board_uart(root)
    port = tmp_path / "ttyAMA0"
    port.symlink_to(pty)
    found = by_name(bb.doctor(port, sysfs_root=root))
    assert found["usb"].message == "not a USB adapter: the board's own UART, driver uart-pl011"
    assert "latency-timer" not in found


def _holder(port: str, how: str) -> subprocess.Popen[str]:
    """A child process that holds ``port`` open (``how``: "plain" with os.open, "bus" with a
    benchbus Bus, which takes it exclusively), once it has printed "ready"."""
    opener = {
        "plain": f"os.open({port!r}, os.O_RDWR | os.O_NOCTTY)",
        "bus": f"benchbus.Bus({port!r})",
    }[how]
    child = subprocess.Popen(
        [
            sys.executable,
            "-c",
            f"import os, sys, time, benchbus\nheld = {opener}\nprint('ready', flush=True)\n"
            "sys.stdin.read()",
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert child.stdout is not None and child.stdout.readline().strip() == "ready"
    return child


def _release(child: subprocess.Popen[str]) -> None:
    child.communicate(timeout=10)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="holders are read from /proc")
def test_a_port_another_process_holds_says_who(pty: str) -> None:
    child = _holder(pty, "bus")
    try:
        found = by_name(bb.doctor(pty))
        opened = found["open"]
        assert opened.verdict == "fail"
        assert opened.message.startswith("cannot open: in use by another Bus or program")
        assert f"held by pid {child.pid} (python" in opened.message
        assert opened.fix == "close the program or Bus that holds it, then try again"
        assert "echo" not in found  # nothing was sent
        done = run("doctor", "--port", pty)
        assert done.returncode == 1 and "Traceback" not in done.stderr
        assert any(
            line.startswith("fail  open") and f"pid {child.pid}" in line
            for line in done.stdout.splitlines()
        ), done.stdout
    finally:
        _release(child)
    assert by_name(bb.doctor(pty))["open"].verdict == "ok"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="holders are read from /proc")
def test_a_port_also_open_elsewhere_is_a_warning(pty: str) -> None:
    child = _holder(pty, "plain")
    try:
        found = by_name(bb.doctor(pty))
        assert found["open"].verdict == "ok"
        holders = found["holders"]
        assert holders.verdict == "warn"
        assert holders.message.startswith(f"also open in pid {child.pid} (python")
        assert holders.fix is not None and "minicom" in holders.fix
    finally:
        _release(child)
    own = os.open(pty, os.O_RDWR | os.O_NOCTTY)
    try:
        assert "holders" not in by_name(bb.doctor(pty))  # this process's own fd is not counted
    finally:
        os.close(own)


def test_benchbus_doctor_prints_a_line_per_finding_and_exits_0(pty: str) -> None:
    done = run("doctor", "--port", pty, "--unit", "3", "--timeout", "0.05")
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert [line.split()[:2] for line in lines] == [
        ["info", "platform"],
        ["ok", "port"],
        ["ok", "permissions"],
        ["ok", "open"],
        ["info", "usb"],
        ["info", "low-latency"],
        ["info", "rs485"],
        ["ok", "echo"],
    ]
    assert lines[-1].endswith(
        "no echo: nothing came back within 50 ms of a read of register 0 from unit 3"
    )


def test_benchbus_doctor_on_a_missing_port_exits_1_with_the_fix(tmp_path: Path) -> None:
    done = run("doctor", "--port", tmp_path / "nope")
    assert done.returncode == 1 and done.stderr == ""
    assert "fail  port" in done.stdout and "fix: run 'benchbus ports'" in done.stdout
    done = run("doctor", "--port", "tcp://127.0.0.1")
    assert done.returncode == 1
    assert done.stderr.startswith("benchbus: doctor checks a serial port")
    assert len(done.stderr.splitlines()) == 1


# ---- rs485=True ---------------------------------------------------------------------------------


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the kernel RS485 mode is Linux's")
def test_rs485_on_a_pty_is_refused_and_leaves_nothing_open(pty: str) -> None:
    start = time.monotonic()
    with pytest.raises(bb.PortError) as raised:
        bb.Bus(pty, rs485=True, rts_delay=(0.001, 0.002))
    assert str(raised.value) == (
        f"port {pty}: cannot open: this port has no kernel RS485 mode (a USB RS485 adapter "
        "switches direction by itself: leave rs485 off)"
    )
    with bb.Bus(pty) as bus:  # opens again at once: the refused open closed the port
        assert bus.rs485 is False
    assert time.monotonic() - start < 1


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"rts_delay": (0.0, 0.0)}, ValueError, "give rs485=True"),
        ({"rs485": False, "rts_delay": (0.001, 0.0)}, ValueError, "give rs485=True"),
        (
            {"rs485": True, "rts_delay": (-0.001, 0.0)},
            ValueError,
            "before sending must be 0 or more",
        ),
        ({"rs485": True, "rts_delay": (0.0, float("nan"))}, ValueError, "after sending"),
        ({"rs485": True, "rts_delay": (float("inf"), 0.0)}, ValueError, "before sending"),
        ({"rs485": True, "rts_delay": (0.0, 0.2)}, ValueError, r"0 to 0\.1 seconds"),
        ({"rs485": True, "rts_delay": (0.001,)}, TypeError, "pair of seconds"),
        ({"rs485": True, "rts_delay": 0.001}, TypeError, "pair of seconds"),
        ({"rs485": True, "rts_delay": "00"}, TypeError, "pair of seconds"),
        ({"rs485": True, "rts_delay": [0.0, 0.0, 0.0]}, TypeError, "pair of seconds"),
        ({"rs485": True, "rts_delay": [0.0, -1]}, ValueError, "after sending must be 0 or more"),
        ({"rs485": True, "rts_delay": ("1", 0)}, TypeError, "number of seconds"),
        ({"rs485": True, "rts_delay": (True, 0)}, TypeError, "number of seconds"),
        ({"rs485": 1}, TypeError, "rs485 must be True or False"),
    ],
)
def test_rs485_arguments_are_checked_before_the_port_opens(
    tmp_path: Path, kwargs: dict[str, object], error: type, match: str
) -> None:
    # The port does not exist: a PortError would mean the port was tried first.
    with pytest.raises(error, match=match):
        bb.Bus(tmp_path / "ttyS9", **kwargs)  # type: ignore[arg-type]


def test_rs485_over_the_network_is_refused() -> None:
    with pytest.raises(ValueError, match="rs485=True is for a local serial port"):
        bb.Bus("tcp://127.0.0.1:1", rs485=True)


def test_line_options_the_bus_refuses_together_are_a_usage_error() -> None:
    # Refused before anything is sent or any port opens: exit 2, as the guide says, with the
    # command named and the options worded as the command line's.
    line = one_line_error(run("read", "0", "--port", "tcp://127.0.0.1:1", "--echo"), 2)
    assert line.startswith("benchbus: read: --echo is for a serial line"), line
    line = one_line_error(run("scan", "--port", "tcp://127.0.0.1:1", "--rs485", "--units", "1"), 2)
    assert line.startswith("benchbus: scan: --rs485 is for a local serial port"), line


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the kernel RS485 mode is Linux's")
def test_the_command_line_asks_for_rs485_mode_with_a_flag(pty: str) -> None:
    line = one_line_error(run("read", "0", "--port", pty, "--rs485", "--rts-delay", "0.001,0"), 1)
    assert line == (
        f"benchbus: port {pty}: cannot open: this port has no kernel RS485 mode (a USB RS485 "
        "adapter switches direction by itself: leave out --rs485)"
    )
    line = one_line_error(run("read", "0", "--port", pty, "--rts-delay", "0.001,0"), 2)
    assert line == "benchbus: read: --rts-delay goes with --rs485"
    done = run("read", "0", "--port", pty, "--rs485", "--rts-delay", "1ms")
    assert done.returncode == 2 and "--rts-delay takes BEFORE,AFTER in seconds" in done.stderr
    line = one_line_error(run("scan", "--port", pty, "--rs485", "--units", "1"), 1)
    assert "no kernel RS485 mode" in line
