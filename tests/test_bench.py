"""The benchmark's line emulator keeps wire time, its fake slave speaks Modbus, and the whole
benchmark runs (its figures are not judged here: CI machines differ)."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import time
import tty
from pathlib import Path

import pytest

import benchbus as bb

BENCH = Path(__file__).resolve().parent.parent / "bench"
sys.path.insert(0, str(BENCH))

import lineemu  # noqa: E402
import run as bench_run  # noqa: E402


def crc(data: bytes) -> bytes:
    """benchbus's CRC of ``data`` as it goes on the wire (low byte first)."""
    return bb.crc16(data).to_bytes(2, "little")


def test_fake_slave_answers_the_golden_read_and_checks_crc() -> None:
    # Modbus over Serial Line, 6.3: read one register at 0 of unit 1.
    request = bytes.fromhex("01 03 00 00 00 01 84 0A")
    reply = lineemu.answer(request, {1})
    assert reply is not None
    assert reply[:3] == bytes.fromhex("01 03 02")
    assert int.from_bytes(reply[3:5], "big") == lineemu.value(1, 0)
    assert crc(reply[:-2]) == reply[-2:]
    assert lineemu.answer(request[:-1] + b"\x00", {1}) is None  # bad CRC: silent
    assert lineemu.answer(request, {2}) is None  # another unit: silent
    exception = lineemu.answer(
        bytes.fromhex("01 03 80 00 00 01") + crc(b"\x01\x03\x80\x00\x00\x01"), {1}
    )
    assert exception is not None and exception[:3] == bytes.fromhex("01 83 02")


def test_request_length_is_known_from_the_header() -> None:
    assert lineemu.request_length(b"\x01") is None
    assert lineemu.request_length(b"\x01\x03") == 8
    assert lineemu.request_length(b"\x01\x10\x00\x00\x00\x02") is None
    assert lineemu.request_length(b"\x01\x10\x00\x00\x00\x02\x04") == 13
    assert lineemu.request_length(b"\x01\x2b\x0e") is None  # not served


def test_emulated_line_takes_the_wire_time_of_both_frames() -> None:
    line = bench_run.LineSpec(9600, "N")
    with bench_run.Emulator(line) as emu, bb.Bus(emu.ports[0], 9600, timeout=0.5) as bus:
        t0 = time.perf_counter()
        assert bus.read_holding_registers(1, 0x3000, 10) == [
            lineemu.value(1, 0x3000 + i) for i in range(10)
        ]
        elapsed = time.perf_counter() - t0
        # 8 request + 25 reply characters at 1.042 ms each: a pty alone would take ~0.1 ms.
        assert elapsed >= 33 * line.char_time * 0.98
        assert elapsed < 33 * line.char_time + 0.05
        stats = emu.stats()[0]
        assert len(stats["requests"]) == 1
        assert 0 < stats["turnarounds"][0] < 0.05


def test_emulator_flags_a_request_sent_less_than_t35_after_a_reply() -> None:
    # At 1200 baud t3.5 is 29 ms: this process and the emulator's both reach the second
    # request well within it, even on a loaded machine.
    line = bench_run.LineSpec(1200, "N")
    request = bytes.fromhex("01 03 00 05 00 01")
    request += crc(request)
    with bench_run.Emulator(line) as emu:
        fd = os.open(emu.ports[0], os.O_RDWR | os.O_NOCTTY)
        try:
            tty.setraw(fd)
            for _ in range(2):  # the second goes out as soon as the first reply is in
                os.write(fd, request)
                got = b""
                while len(got) < 7:
                    got += os.read(fd, 7 - len(got))
            assert got[3:5] == lineemu.value(1, 5).to_bytes(2, "big")
        finally:
            os.close(fd)
        time.sleep(0.05)
        assert emu.stats()[0]["early"] == 1


def test_benchbus_keeps_t35_seen_from_the_emulated_line() -> None:
    # An observer outside the library: every request starts at least t3.5 after the reply.
    line = bench_run.LineSpec(19200, "N")
    with bench_run.Emulator(line) as emu, bb.Bus(emu.ports[0], 19200, timeout=0.2) as bus:
        for address in range(30):
            assert bus.read_holding_registers(1, address, 1) == [lineemu.value(1, address)]
        stats = emu.stats()[0]
    assert len(stats["gaps"]) == 29
    assert stats["early"] == 0
    assert min(stats["gaps"]) >= line.t35 - 20e-6


@pytest.mark.timeout(300)
def test_quick_benchmark_runs_every_scenario_for_every_library(tmp_path: Path) -> None:
    out = tmp_path / "bench.json"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    proc = subprocess.run(
        [sys.executable, str(BENCH / "run.py"), "--quick", "--json", str(out)],
        capture_output=True,
        text=True,
        timeout=280,
        env=env,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(out.read_text())
    assert report["mode"] == "quick"
    assert report["machine"]["cores"] == os.cpu_count()
    limits = report["wire limits (tx/s, one-register reads)"]
    assert limits["19200 8N1"] == pytest.approx(103.8, abs=0.05)
    assert limits["115200 8E1"] == pytest.approx(314.2, abs=0.05)
    figures = report["figures"]
    scenarios = {f["scenario"][0] for f in figures}
    assert scenarios == set("abcdefghijklm")
    # modbus-rs where its wheel installed (CPython 3.11 on x86-64 Linux).
    rust_peer = {"modbus-rs"} if importlib.util.find_spec("modbus_rs") else set()
    assert tuple(report["libraries"]) == bench_run.LIBRARIES
    assert set(bench_run.LIBRARIES) == {"benchbus", "minimalmodbus", "pymodbus"} | rust_peer
    for letter in "abcdefghijk":
        libraries = {f["library"] for f in figures if f["scenario"][0] == letter}
        # minimalmodbus has no asyncio client for (j) and (k).
        everyone = {"benchbus", "pymodbus"} | ({"minimalmodbus"} if letter < "j" else set())
        # modbus-rs's answers do not fit the scans' 50 ms timeout: it is left out of them.
        assert libraries == everyone | (rust_peer if letter not in "dh" else set()), letter
    # (l) loads profiles, which only benchbus reads: every step, timed and its memory.
    loads = {f["metric"] for f in figures if f["scenario"][0] == "l"}
    assert loads == {m for step in bench_run.PROFILE_STEPS for m in (step, f"{step}: peak memory")}
    assert {f["library"] for f in figures if f["scenario"][0] == "l"} == {"benchbus"}
    # (m) an EPICS IOC polling 10 devices, which only benchbus serves: the line's use and
    # the latency of a monitor update, a read to its update taking more than nothing.
    served = {f["metric"]: f for f in figures if f["scenario"][0] == "m"}
    assert {f["library"] for f in served.values()} == {"benchbus"}
    assert {"ratio to wire limit", "read to monitor p50", "read to monitor p99"} <= set(served)
    assert 0 < served["read to monitor p50"]["median"] <= served["read to monitor p99"]["median"]
    early_by = {
        (f["scenario"], f["library"]): f["max"]
        for f in figures
        if f["metric"] == "requests < t3.5 after a reply"
    }
    for f in figures:
        assert f["min"] <= f["median"] <= f["max"], f
        if f["metric"] == "ratio to wire limit":
            # The emulator holds every library that keeps t3.5 to the wire: none of them
            # can beat the limit. (pymodbus's asyncio client sends inside t3.5, and so can.)
            # modbus-rs waits some 35 ms after each reply: a fifth of the limit at 19200.
            assert f["max"] > (0.3 if f["library"] == "benchbus" else 0.05), f
            if early_by.get((f["scenario"], f["library"])) == 0 or f["library"] == "benchbus":
                assert f["max"] <= 1.02, f
    # Every target of the issue is judged (met or not: figures are the machine's).
    judged = {t["target"].split(")")[0] + ")" for t in report["targets"]}
    early = [f for f in figures if f["metric"] == "requests < t3.5 after a reply"]
    assert {f["library"] for f in early} == {"benchbus", "minimalmodbus", "pymodbus"} | rust_peer
    assert judged == {f"({x})" for x in "abcdeghijklm"}
    assert all(v == 0 for (scenario, lib), v in early_by.items() if lib == "benchbus")
    assert all(isinstance(t["met"], bool) for t in report["targets"])
    assert "benchbus" in proc.stdout and "ratio to wire limit" in proc.stdout
