"""t3.5 on each side of the wire, pinned to the spec (Modbus over Serial Line V1.02, 2.5.1.1).

The library (``Bus.t3_5``, from ``src/timing.rs``), the simulators
(``benchbus.sim._rtu.t3_5``) and the benchmark's line emulator (``bench/lineemu.py``) each
count the silence between frames their own way, so that each judges the others. This holds
all three to the spec's figures: 3.5 characters of the line format (start + 8 data + parity +
stop bits), fixed 1.75 ms above 19200 baud.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

import benchbus as bb
from benchbus.sim._rtu import end_of_frame_silence, t3_5

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))

import lineemu

#: (baud, parity, stop bits, bits a character, t3.5 in seconds) as the spec gives them.
SPEC = [
    (2400, "N", 1, 10, 3.5 * 10 / 2400),
    (9600, "N", 1, 10, 3.5 * 10 / 9600),
    (9600, "E", 1, 11, 3.5 * 11 / 9600),
    (9600, "N", 2, 11, 3.5 * 11 / 9600),
    (19200, "N", 1, 10, 3.5 * 10 / 19200),
    (19200, "E", 1, 11, 3.5 * 11 / 19200),
    (38400, "N", 1, 10, 0.00175),
    (57600, "E", 1, 11, 0.00175),
    (115200, "N", 1, 10, 0.00175),
    (115200, "E", 1, 11, 0.00175),
]
IDS = [f"{baud}-8{parity}{stop}" for baud, parity, stop, _, _ in SPEC]


@pytest.mark.parametrize(("baud", "parity", "stop", "bits", "expected"), SPEC, ids=IDS)
def test_library_t35_is_the_spec(baud: int, parity: str, stop: int, bits: int, expected: float):
    master, slave = os.openpty()
    try:
        with bb.Bus(os.ttyname(slave), baudrate=baud, parity=parity, stopbits=stop) as bus:
            assert bus.char_time == pytest.approx(bits / baud, abs=1e-9)
            assert bus.t3_5 == pytest.approx(expected, abs=1e-9)
    finally:
        os.close(master)
        os.close(slave)


@pytest.mark.parametrize(("baud", "parity", "stop", "bits", "expected"), SPEC, ids=IDS)
def test_simulator_t35_is_the_spec(baud: int, parity: str, stop: int, bits: int, expected: float):
    assert t3_5(baud, bits) == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize(("baud", "parity", "stop", "bits", "expected"), SPEC, ids=IDS)
def test_bench_t35_is_the_spec(baud: int, parity: str, stop: int, bits: int, expected: float):
    assert lineemu.silence(baud, bits / baud) == pytest.approx(expected, abs=1e-12)


def test_simulator_frame_gap_is_t35_of_the_longest_character_with_a_floor() -> None:
    # The simulator does not know the library's parity: it waits t3.5 of 11-bit characters,
    # and never less than 5 ms (a pseudo-terminal's writer may pause between pieces).
    assert end_of_frame_silence(2400) == pytest.approx(3.5 * 11 / 2400)
    assert end_of_frame_silence(9600) == pytest.approx(0.005)
    assert end_of_frame_silence(115200) == pytest.approx(0.005)
