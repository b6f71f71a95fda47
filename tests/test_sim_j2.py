"""The simulated J2 temperature controller, driven by the raw pseudo-terminal client.

Requests are bytes with a CRC computed bit by bit in test_sim.py, and the manual's example
frames are written out literally, so the tests do not lean on the package's own framing.
The process runs on a clock that stands still unless a test moves it; ``advance`` moves it
in process seconds. Most tests turn the write pacing off (``write_interval=0``); the tests
about pacing, and the manual's write examples, keep the manual's 150 ms and sleep.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest
from test_sim import Client, crc_valid, frame

from benchbus.sim import J2Device, SimException, Simulator

UNIT = 0x01

# Parameter addresses used below.
MV, PV, SV, AL1, AL2, PROP, INTEG, DERIV, LSP, USP = 0, 2, 6, 8, 10, 14, 16, 18, 20, 22
HY1, HYS, OUL, OUH, GAP, RAP, RTM, P1 = 24, 30, 32, 34, 36, 38, 40, 42
TRL, PVOS, DIE = 48, 52, 62
AM, RAPNF, AT, CYT, INP, FST = 128, 130, 132, 134, 152, 156
NC = (4, 12, 28, 140)

#: The manual's pause between two writes, with a margin.
PACE = 0.17
#: A write interval long enough that no scheduling delay reaches it.
SLOW = 0.5


def x10(value: float) -> int:
    """``value`` as a signed x10 register word."""
    return round(value * 10) & 0xFFFF


class Rig:
    """One simulated J2 controller and a raw client that sends it 0x03, 0x06 and 0x10."""

    def __init__(self, sim: Simulator[J2Device], client: Client, j2: J2Device) -> None:
        self.sim, self.client, self.j2 = sim, client, j2

    def exchange(self, request: bytes, reply_len: int) -> bytes:
        self.client.send(request)
        return self.client.recv(reply_len)

    def read(self, address: int, count: int = 1) -> list[int]:
        reply = self.exchange(frame(f"01 03 {address:04X} {count:04X}"), 5 + 2 * count)
        assert crc_valid(reply) and reply[:3] == bytes([UNIT, 3, 2 * count]), reply.hex(" ")
        data = reply[3:-2]
        return [int.from_bytes(data[i : i + 2], "big") for i in range(0, len(data), 2)]

    def read_x10(self, address: int) -> float:
        """A signed x10 parameter, decoded."""
        word = self.read(address)[0]
        return (word - 0x10000 if word & 0x8000 else word) / 10

    def read_fails(self, address: int, count: int = 1) -> int:
        reply = self.exchange(frame(f"01 03 {address:04X} {count:04X}"), 5)
        assert crc_valid(reply) and reply[:2] == b"\x01\x83", reply.hex(" ")
        return reply[2]

    def write(self, address: int, word: int) -> None:
        """0x06, answered with the echo."""
        request = frame(f"01 06 {address:04X} {word:04X}")
        reply = self.exchange(request, 8)
        assert reply == request, reply.hex(" ")

    def write_fails(self, address: int, word: int) -> int:
        reply = self.exchange(frame(f"01 06 {address:04X} {word:04X}"), 5)
        assert crc_valid(reply) and reply[:2] == b"\x01\x86", reply.hex(" ")
        return reply[2]

    def _many(self, address: int, words: list[int]) -> bytes:
        data = "".join(f"{w:04X}" for w in words)
        return frame(f"01 10 {address:04X} {len(words):04X} {2 * len(words):02X} {data}")

    def write_many(self, address: int, words: list[int]) -> None:
        reply = self.exchange(self._many(address, words), 8)
        assert reply == frame(f"01 10 {address:04X} {len(words):04X}"), reply.hex(" ")

    def write_many_fails(self, address: int, words: list[int]) -> int:
        reply = self.exchange(self._many(address, words), 5)
        assert crc_valid(reply) and reply[:2] == b"\x01\x90", reply.hex(" ")
        return reply[2]


@contextmanager
def open_rig(unit: int = UNIT, baudrate: int = 9600, **options: Any) -> Iterator[Rig]:
    options.setdefault("clock", lambda: 0.0)  # time moves only by advance()
    options.setdefault("write_interval", 0.0)
    j2 = J2Device(**options)
    with Simulator({unit: j2}, baudrate=baudrate) as sim:
        client = Client(sim.port)
        try:
            yield Rig(sim, client, j2)
            assert sim.errors == []
        finally:
            client.close()


@pytest.fixture
def j2() -> Iterator[Rig]:
    with open_rig() as rig:
        yield rig


def manual(request: str, reply: str) -> tuple[bytes, bytes]:
    """A request / reply pair as printed; both carry the CRC the manual prints."""
    pair = bytes.fromhex(request), bytes.fromhex(reply)
    assert all(crc_valid(f) for f in pair)
    return pair


# ---- the manual's three examples, byte for byte -------------------------------------------------


def test_manual_read_example(j2: Rig) -> None:
    # 0x03: SV = 100.0 (the default) reads 03 E8.
    sent, expected = manual("01 03 00 06 00 01 64 0B", "01 03 02 03 E8 B8 FA")
    assert j2.client.transact(sent, len(expected)) == expected


def test_manual_write_examples_at_the_manual_pace() -> None:
    with open_rig(write_interval=0.150) as rig:
        j2 = rig.j2
        j2.set_value("SV", 50.0)
        # 0x06: SV = 100.0, answered with the echo.
        sent, expected = manual("01 06 00 06 03 E8 69 75", "01 06 00 06 03 E8 69 75")
        assert rig.client.transact(sent, len(expected)) == expected
        assert j2.value("SV") == 100.0
        j2.set_value("SV", 50.0)  # the keys: no pacing
        time.sleep(PACE)
        # 0x10: SV = 100.0, answered with the address and the count.
        sent, expected = manual("01 10 00 06 00 01 02 03 E8 A6 88", "01 10 00 06 00 01 E1 C8")
        assert rig.client.transact(sent, len(expected)) == expected
        assert j2.value("SV") == 100.0 and rig.read(SV) == [1000]
        assert j2.write_violations == [] and len(j2.write_times) == 2
        assert j2.write_times[1] - j2.write_times[0] >= 0.150
        writes = [t for f, t in zip(rig.sim.requests, rig.sim.request_times) if f[1] != 3]
        assert len(writes) == 2 and writes[1] - writes[0] >= 0.150


# ---- values and ranges --------------------------------------------------------------------------


def test_negative_values_round_trip(j2: Rig) -> None:
    # AL1 = -50.0 is -500, FE 0C in two's complement.
    sent = bytes.fromhex("01 06 00 08 FE 0C") + frame("01 06 00 08 FE 0C")[-2:]
    assert j2.client.transact(sent, 8) == sent
    assert j2.client.transact(frame("01 03 00 08 00 01"), 7) == frame("01 03 02 FE 0C")
    assert j2.j2.value("AL1") == -50.0
    j2.write_many(AL2, [0xFF85])  # -12.3
    assert j2.read_x10(AL2) == -12.3 and j2.j2.value("AL2") == -12.3
    j2.j2.set_value("AL1", -1999.0)
    assert j2.read(AL1) == [0xB1EA]  # -19990
    j2.write(LSP, 0xB1EA)  # LSP = -1999.0, its lowest
    assert j2.j2.value("LSP") == -1999.0
    assert j2.write_fails(LSP, 0xB1E9) == 3  # -1999.1
    j2.write(SV, x10(-1500.0))  # now within LSP..USP
    assert j2.read_x10(SV) == -1500.0
    j2.write(GAP, x10(-50.0))
    assert j2.read(GAP) == [0xFE0C]


@pytest.mark.parametrize(
    ("address", "bad", "good"),
    [
        (SV, x10(400.1), x10(400.0)),  # LSP..USP = 0..400 by default
        (SV, x10(-0.1), 0),
        (AL1, x10(-1999.1), 0x7FFF),  # 9999 cannot be sent: 3276.7 is the most
        (AL2, x10(-1999.1), x10(-1999.0)),
        (PROP, 0, 1),  # 0.1..3600
        (PROP, 0xFFFF, 0x7FFF),
        (INTEG, 0xFFFF, 0x7FFF),  # 0..3600
        (DERIV, x10(-0.1), 0),
        (HY1, x10(400.1), x10(400.0)),
        (HYS, x10(-0.1), x10(0.5)),
        (OUL, x10(100.1), x10(100.0)),
        (OUH, x10(-0.1), x10(100.0)),
        (GAP, x10(50.1), x10(-50.0)),
        (RAP, x10(-1.0), x10(10.0)),
        (RTM, x10(-0.1), 0x7FFF),
        (P1, 0, 1),
        (TRL, x10(400.1), x10(0.0)),
        (PVOS, x10(-50.1), x10(50.0)),
        (54, x10(-0.1), x10(400.0)),  # SRT
        (56, x10(100.1), x10(100.0)),  # LMO
        (58, x10(400.1), x10(0.0)),  # TOP
        (60, x10(100.1), x10(0.0)),  # U0
        (DIE, x10(0.4), x10(0.5)),
        (DIE, x10(5.1), x10(5.0)),
        (AM, 2, 0),
        (RAPNF, 2, 0),
        (AT, 2, 0),
        (CYT, 251, 250),
        (136, 10, 9),  # AD1
        (138, 10, 0),  # AD2
        (142, 251, 250),  # CYT1
        (144, 2, 1),  # MAN
        (146, 100, 99),  # SFT
        (148, 4, 3),  # DP
        (150, 3, 2),  # TH
        (INP, 10, 9),
        (154, 2, 1),  # OUD
        (FST, 19, 20),
        (FST, 121, 120),
        (FST, 0xFFFF, 50),  # unsigned: 65535, not -1
    ],
)
def test_out_of_range_answers_3(j2: Rig, address: int, bad: int, good: int) -> None:
    before = j2.read(address)
    assert j2.write_fails(address, bad) == 3
    assert j2.write_many_fails(address, [bad]) == 3
    assert j2.read(address) == before
    j2.write(address, good)
    assert j2.read(address) == [good]


def test_lsp_and_usp_bound_each_other_and_the_setpoints(j2: Rig) -> None:
    assert j2.write_fails(LSP, x10(400.1)) == 3  # above USP = 400
    j2.write(LSP, x10(400.0))  # LSP = USP is allowed
    j2.write(SV, x10(400.0))
    assert j2.write_fails(SV, x10(399.9)) == 3
    assert j2.write_fails(USP, x10(399.9)) == 3  # below LSP
    j2.write(LSP, x10(50.0))
    j2.write(USP, x10(60.0))  # SV = 400 stays stored; the loop works to 60.0
    assert j2.read_x10(SV) == 400.0 and j2.j2.setpoint == 60.0
    assert j2.write_fails(SV, x10(49.9)) == 3
    assert j2.write_fails(HY1, 0) == 3  # HY1 is LSP~USP too
    j2.write(HY1, x10(55.0))
    assert [j2.read_x10(a) for a in (LSP, USP, HY1)] == [50.0, 60.0, 55.0]


# ---- addresses and counts -----------------------------------------------------------------------


def test_unimplemented_addresses_read_0(j2: Rig) -> None:
    assert j2.read(0, 16) == [0, 0, 250, 0, 0, 0, 1000, 0, 0, 0, 0, 0, 0, 0, 400, 0]
    assert j2.read(16, 16) == [1200, 0, 0, 0, 0, 0, 4000, 0, 0, 0, 0, 0, 0, 0, 0, 0]
    assert j2.read(32, 16) == [0, 0, 1000, 0, 0, 0, 100, 0, 0, 0, 400, 0, 1200, 0, 0, 0]
    assert j2.read(48, 16) == [0] * 14 + [10, 0]  # ... DIE = 1.0 at 62
    assert j2.read(64, 16) == [0] * 16
    assert j2.read(128, 16) == [1, 0, 0, 0, 0, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0]
    assert j2.read(144, 16) == [0, 0, 0, 0, 1, 0, 0, 0, 6, 0, 0, 0, 50, 0, 0, 0]
    assert j2.read(5, 3) == [0, 1000, 0]  # a block starting on an odd address
    for address in (*NC, 7, 63, 127, 157, 0x1000):
        assert j2.read(address) == [0]
    assert j2.read(0xFFF0, 16) == [0] * 16
    assert j2.read(0xFFFF) == [0]


def test_the_16_register_limit(j2: Rig) -> None:
    assert len(j2.read(0, 16)) == 16
    assert j2.read_fails(0, 17) == 3
    assert j2.read_fails(0x80, 125) == 3
    assert j2.read_fails(0, 0) == 3
    assert j2.write_many_fails(SV, [x10(50.0)] * 17) == 3
    assert j2.read(SV) == [1000]


def test_past_0xffff_answers_2(j2: Rig) -> None:
    assert j2.read_fails(0xFFFF, 2) == 2
    assert j2.read_fails(0xFFF1, 16) == 2
    assert j2.write_many_fails(0xFFFF, [0, 0]) == 2


def test_writes_to_no_parameter_answer_2(j2: Rig) -> None:
    for address in (PV, *NC, 7, 63, 64, 127, 158, 0x1000, 0xFFFF):
        assert j2.write_fails(address, 0) == 2, address
        assert j2.write_many_fails(address, [0]) == 2, address
    assert j2.read(0, 16) == [0, 0, 250, 0, 0, 0, 1000, 0, 0, 0, 0, 0, 0, 0, 400, 0]


def test_a_write_of_several_registers_meets_an_odd_address(j2: Rig) -> None:
    # Parameters sit at even addresses only: a block of two covers an address with none.
    assert j2.write_many_fails(SV, [x10(50.0), 0]) == 2
    assert j2.write_many_fails(PROP, [x10(10.0), 0, x10(60.0)]) == 2
    assert j2.write_many_fails(0, [0] * 16) == 2
    assert j2.read(SV) == [1000] and j2.read(PROP, 3) == [400, 0, 1200]  # all or nothing
    assert j2.write_many_fails(PV, [0]) == 2
    j2.write_many(PROP, [x10(10.0)])
    assert j2.read(PROP) == [100]


# ---- the manual's rules: answered with exception 4 ----------------------------------------------


def test_mv_is_written_in_manual_mode_only(j2: Rig) -> None:
    device = j2.j2
    device.advance(30.0)
    auto_mv = j2.read(MV)[0]
    assert auto_mv > 0 and j2.read(AM) == [1]
    assert j2.write_fails(MV, x10(50.0)) == 4
    assert j2.write_many_fails(MV, [x10(50.0)]) == 4
    assert j2.read(MV) == [auto_mv]
    j2.write(AM, 0)  # manual: MV keeps its last automatic value (bumpless)
    assert j2.read(MV) == [auto_mv] and not device.auto
    device.advance(5.0)
    assert j2.read(MV) == [auto_mv]
    j2.write(MV, x10(50.0))
    assert j2.read(MV) == [500] and device.mv == 50.0
    assert j2.write_fails(MV, x10(100.1)) == 3
    device.advance(2000.0)  # the output holds; the process settles at 25 + 400 x 50 %
    assert j2.read(MV) == [500]
    assert abs(device.temperature - 225.0) < 0.1 and j2.read(PV) == [2250]
    j2.write(AM, 1)  # back to auto, far above SV: the output shuts off
    device.advance(device.STEP)
    assert device.mv == 0.0
    device.advance(2000.0)
    assert abs(device.pv - 100.0) < 0.2


def test_switching_near_the_setpoint_is_bumpless(j2: Rig) -> None:
    device = j2.j2
    device.advance(2000.0)
    settled = device.mv
    assert abs(settled - 18.75) < 0.01
    j2.write(AM, 0)
    device.advance(1.0)
    assert device.mv == settled and j2.read(MV) == [round(settled * 10)]
    j2.write(MV, x10(25.0))
    device.advance(10.0)  # warming a little
    assert device.mv == 25.0 and device.pv > 100.5
    j2.write(AM, 1)
    device.advance(device.STEP)
    assert abs(device.mv - 25.0) < 0.2  # it goes on from the manual output
    device.advance(2000.0)
    assert abs(device.pv - 100.0) < 0.2


def test_ramp_parameters_are_locked_while_a_ramp_runs(j2: Rig) -> None:
    j2.write(RAP, x10(10.0))
    j2.write(RTM, x10(5.0))
    j2.write(RAPNF, 1)
    assert j2.read(RAPNF) == [1]
    assert j2.write_fails(RAP, x10(20.0)) == 4
    assert j2.write_fails(RTM, x10(6.0)) == 4
    assert j2.write_many_fails(RAP, [x10(20.0)]) == 4
    assert j2.read(RAP, 3) == [100, 0, 50]
    j2.write(RAPNF, 0)  # as the manual says: end the ramp first
    assert j2.read(RAPNF) == [0]
    j2.write(RAP, x10(20.0))
    j2.write(RTM, x10(6.0))
    assert j2.read(RAP, 3) == [200, 0, 60]


def test_autotune_in_manual_mode_takes_the_output_and_gives_it_back(j2: Rig) -> None:
    device = j2.j2
    j2.write(AT, 0)  # stopping a tune that does not run is harmless
    j2.write(AM, 0)
    j2.write(MV, x10(20.0))
    j2.write(AT, 1)
    assert j2.read(AT) == [1]
    device.advance(1.0)
    assert device.mv == 100.0  # the relay: PV below SV
    j2.write(MV, x10(30.0))  # kept for after the test
    device.advance(1.0)
    assert device.mv == 100.0 and j2.read(AM) == [0]
    device.advance(60.0)
    assert j2.read(AT) == [0] and j2.read(PROP) == [200]
    assert device.mv == 30.0 and j2.read(MV) == [300]
    device.advance(100.0)
    assert j2.read(MV) == [300]  # manual: it holds


# ---- write pacing -------------------------------------------------------------------------------


def test_writes_closer_than_the_interval_answer_6() -> None:
    # A long interval (the manual's is 150 ms), so a loaded machine cannot stretch the quick
    # exchanges below past it.
    with open_rig(write_interval=SLOW) as rig:
        j2 = rig.j2
        rig.write(SV, x10(80.0))
        # Straight after it (exchange does not wait for stray bytes after the reply).
        assert rig.exchange(frame("01 06 00 06 02 BC"), 5) == frame("01 86 06")
        assert rig.exchange(frame("01 10 00 06 00 01 02 02 BC"), 5) == frame("01 90 06")
        assert rig.exchange(frame("01 06 00 08 00 01"), 5) == frame("01 86 06")
        assert rig.read(SV) == [800] and rig.read(AL1) == [0]  # reads are not paced
        assert len(j2.write_times) == 4 and len(j2.write_violations) == 3
        gaps = [b - a for a, b in zip(j2.write_times, j2.write_times[1:])]
        assert j2.write_violations == gaps  # each measured from the request before it
        assert all(0 < gap < SLOW for gap in gaps)
        time.sleep(SLOW + 0.02)
        rig.write(SV, x10(70.0))  # after the pause: accepted
        assert j2.value("SV") == 70.0 and len(j2.write_violations) == 3
        assert j2.write_times[-1] - j2.write_times[-2] >= SLOW
        # A refused request counts too: a quick retry after it is refused again.
        assert rig.write_fails(SV, x10(60.0)) == 6
        time.sleep(0.05)
        assert rig.write_fails(SV, x10(60.0)) == 6
        assert len(j2.write_violations) == 5 and j2.value("SV") == 70.0
        # The line's own times show the same spacing, a little earlier.
        writes = [t for f, t in zip(rig.sim.requests, rig.sim.request_times) if f[1] != 3]
        assert len(writes) == len(j2.write_times) == 7
        assert all(a <= b for a, b in zip(writes, j2.write_times))
        j2.write_interval = 0.0  # a plain attribute
        rig.write(SV, x10(60.0))
        rig.write(SV, x10(65.0))
        assert j2.value("SV") == 65.0 and len(j2.write_violations) == 5


def test_pacing_uses_real_time_not_the_process_clock() -> None:
    now = [0.0]
    with open_rig(write_interval=0.150, speedup=1000.0, clock=lambda: now[0]) as rig:
        rig.write(SV, x10(90.0))
        now[0] += 10.0  # ten seconds on the process clock (10000 process seconds)
        assert rig.write_fails(SV, x10(80.0)) == 6
        assert rig.j2.value("SV") == 90.0


def test_set_value_is_not_paced() -> None:
    j2 = J2Device(clock=lambda: 0.0)
    for value in (50.0, 60.0, 70.0):
        j2.set_value("SV", value)
    assert j2.value("SV") == 70.0
    assert j2.write_times == [] and j2.write_violations == []


# ---- the process --------------------------------------------------------------------------------


def test_pv_approaches_sv_in_auto_with_a_fast_clock() -> None:
    now = [1000.0]
    with open_rig(speedup=100.0, clock=lambda: now[0]) as rig:
        assert rig.read(PV, 5) == [250, 0, 0, 0, 1000]  # PV 25.0, SV 100.0
        seen = []
        for _ in range(30):  # three seconds of real time, 300 s of process time
            now[0] += 0.1
            seen.append(rig.read_x10(PV))
        assert seen[0] > 25.0 and rig.read(MV) != [0]
        assert all(a <= b for a, b in zip(seen[:8], seen[1:9]))  # heating
        assert max(seen) < 105.0  # a modest overshoot
        assert abs(seen[-1] - 100.0) < 3.0
        now[0] += 20.0
        assert abs(rig.read_x10(PV) - 100.0) < 0.2
        mv = rig.read_x10(MV)  # what holds 75 degrees over ambient: 75 / 400
        assert abs(mv - 18.75) < 0.2


@pytest.mark.parametrize(("sv", "by"), [(50.0, 260), (80.0, 260), (100.0, 320)])
def test_pv_settles_at_sv_without_a_lasting_overshoot(sv: float, by: int) -> None:
    """From ambient, at the power-up PID: PV reaches SV, overshoots by less than half a
    degree, and is within 0.3 degrees of it ``by`` process seconds on (at 80, the demo's:
    its 13 s at 20 times real time) and from then on."""
    device = J2Device(clock=lambda: 0.0)
    device.set_value("SV", sv)
    trace = []
    for _ in range(600):
        device.advance(1.0)
        trace.append(device.pv)
    assert max(trace) < sv + 0.5
    assert all(abs(pv - sv) <= 0.3 for pv in trace[by - 1 :]), trace[by - 1]


def test_the_clock_times_speedup_is_process_time() -> None:
    now = [50.0]
    fast = J2Device(speedup=100.0, clock=lambda: now[0])
    slow = J2Device(clock=lambda: 0.0)
    now[0] += 1.5
    slow.advance(150.0)
    assert fast.temperature == slow.temperature > 25.0
    fast.advance(10.0)  # process seconds on top
    slow.advance(10.0)
    assert fast.temperature == slow.temperature


def test_a_setpoint_change_is_followed(j2: Rig) -> None:
    device = j2.j2
    device.advance(1000.0)
    assert abs(device.pv - 100.0) < 0.2
    j2.write(SV, x10(50.0))  # down: the output shuts off while it cools
    device.advance(5.0)
    assert device.mv == 0.0
    device.advance(1000.0)
    assert abs(device.pv - 50.0) < 0.2
    assert abs(device.mv - 25.0 / 400.0 * 100.0) < 0.2


def test_output_limits(j2: Rig) -> None:
    device = j2.j2
    j2.write(OUH, x10(10.0))  # 10 % holds 25 + 40 = 65 degrees at most
    for _ in range(10):
        device.advance(30.0)
        assert j2.read(MV) == [100]
    device.advance(2000.0)
    assert abs(device.pv - 65.0) < 0.2
    j2.write(OUH, x10(100.0))
    device.advance(1000.0)
    assert abs(device.pv - 100.0) < 0.2
    j2.write(OUL, x10(30.0))  # 30 % is more than 100 degrees needs
    device.advance(2000.0)
    assert j2.read(MV) == [300] and abs(device.pv - 145.0) < 0.2


def test_pvos_offsets_the_pv(j2: Rig) -> None:
    device = j2.j2
    device.hold_temperature(80.0)
    assert j2.read(PV) == [800]
    j2.write(PVOS, x10(5.0))
    assert j2.read(PV) == [850] and device.pv == 85.0 and device.temperature == 80.0
    j2.write(PVOS, x10(-50.0))
    assert j2.read(PV) == [300]
    assert j2.write_fails(PVOS, x10(50.1)) == 3
    # The loop works on the PV: the process settles 5 degrees below SV.
    j2.write(PVOS, x10(5.0))
    device.hold_temperature(None)
    device.advance(2000.0)
    assert abs(device.pv - 100.0) < 0.2 and abs(device.temperature - 95.0) < 0.2


def test_pv_register_limits(j2: Rig) -> None:
    device = j2.j2
    device.hold_temperature(5000.0)
    assert j2.read(PV) == [0x7FFF] and device.pv == 3276.7
    device.hold_temperature(-4000.0)
    assert j2.read(PV) == [0x8000] and device.pv == -3276.8
    device.hold_temperature(-12.34)
    assert j2.read(PV) == [x10(-12.3)]
    device.advance(100.0)
    assert device.temperature == -12.34  # held


def test_holding_a_temperature_does_not_kick_the_derivative(j2: Rig) -> None:
    device = j2.j2
    j2.write(DERIV, x10(30.0))
    device.hold_temperature(60.0)  # a jump of 35 degrees, at once
    device.advance(device.STEP)
    assert device.mv == 100.0  # 40 degrees below SV with P = 40: full output
    device.hold_temperature(90.0)
    device.advance(device.STEP)
    assert abs(device.mv - 25.0) < 0.5  # 10 degrees below: a quarter of the band


def test_a_held_temperature_does_not_wind_the_integral_up(j2: Rig) -> None:
    device = j2.j2
    device.hold_temperature(90.0)  # below SV for an hour: the output saturates
    device.advance(3600.0)
    assert device.mv == pytest.approx(100.0, abs=0.05) and device.temperature == 90.0
    device.hold_temperature(None)  # the integral stopped at saturation: a limited overshoot
    peak = 0.0
    for _ in range(150):
        device.advance(10.0)
        peak = max(peak, device.pv)
    assert 100.0 < peak < 120.0 and abs(device.pv - 100.0) < 0.5


# ---- the ramp -----------------------------------------------------------------------------------


def test_ramp_from_pv_to_sv(j2: Rig) -> None:
    device = j2.j2
    j2.write(RAP, x10(10.0))  # degrees per minute
    assert device.setpoint == 100.0 and j2.read(RAPNF) == [0]
    j2.write(RAPNF, 1)
    assert j2.read(RAPNF) == [1] and device.setpoint == 25.0  # from the PV
    device.advance(60.0)
    assert device.setpoint == pytest.approx(35.0)
    assert j2.read(RAPNF) == [1] and 25.0 < device.pv < 35.0  # the process follows
    device.advance(360.0)
    assert device.setpoint == pytest.approx(95.0) and j2.read(RAPNF) == [1]
    device.advance(31.0)  # 75 degrees at 10 per minute: 450 s
    assert device.setpoint == 100.0 and j2.read(RAPNF) == [0]
    # Down from a hot process, following SV as it changes.
    device.hold_temperature(150.0)
    j2.write(RAPNF, 1)
    assert device.setpoint == 150.0
    device.advance(120.0)
    assert device.setpoint == pytest.approx(130.0)
    j2.write(SV, x10(140.0))  # back up from 130
    device.advance(61.0)
    assert device.setpoint == 140.0 and j2.read(RAPNF) == [0]


def test_ending_a_ramp_and_a_rate_of_zero(j2: Rig) -> None:
    device = j2.j2
    j2.write(RAP, x10(1.0))
    j2.write(RAPNF, 1)
    device.advance(60.0)
    assert device.setpoint == pytest.approx(26.0)
    j2.write(RAPNF, 0)  # ends it: the working setpoint is SV
    assert j2.read(RAPNF) == [0] and device.setpoint == 100.0
    j2.write(RAP, 0)
    j2.write(RAPNF, 1)  # no rate: SV at once
    assert j2.read(RAPNF) == [0] and device.setpoint == 100.0
    # A ramp starts from the PV, offset included.
    device.hold_temperature(40.0)
    j2.write(PVOS, x10(5.0))
    j2.write(RAP, x10(6.0))
    j2.write(RAPNF, 1)
    assert device.setpoint == 45.0
    device.advance(10.0)
    assert device.setpoint == pytest.approx(46.0)


# ---- autotune -----------------------------------------------------------------------------------


def test_autotune_runs_a_minute_then_sets_pid(j2: Rig) -> None:
    device = j2.j2
    assert j2.read(PROP, 5) == [400, 0, 1200, 0, 0]
    j2.write(AT, 1)
    assert j2.read(AT) == [1]
    outputs = set()
    for _ in range(59):
        device.advance(1.0)
        outputs.add(device.mv)
    assert outputs == {0.0, 100.0}  # a relay test: OUL or OUH
    j2.write(AT, 1)  # a second start does not restart it
    device.advance(0.5)
    assert j2.read(AT) == [1] and j2.read(PROP) == [400]
    device.advance(1.0)
    assert j2.read(AT) == [0]
    assert j2.read(PROP, 5) == [200, 0, 3000, 0, 150]
    assert {k: device.value(k) for k in "PID"} == dict(J2Device.TUNED)
    device.advance(1000.0)
    assert abs(device.pv - 100.0) < 0.2


def test_autotune_is_aborted_by_at_0(j2: Rig) -> None:
    device = j2.j2
    j2.write(AT, 1)
    device.advance(30.0)
    j2.write(AT, 0)
    assert j2.read(AT) == [0]
    device.advance(60.0)
    assert j2.read(PROP, 5) == [400, 0, 1200, 0, 0]
    assert 0.0 < device.mv < 100.0  # the PID again, not the relay
    # A change of mode does not stop it.
    j2.write(AT, 1)
    device.advance(30.0)
    j2.write(AM, 0)
    j2.write(AM, 1)
    assert j2.read(AT) == [1]
    device.advance(31.0)
    assert j2.read(AT) == [0] and j2.read(PROP) == [200]


# ---- the line: station numbers and request times ------------------------------------------------


def test_station_255() -> None:
    with open_rig(unit=255) as rig:
        request = frame("FF 03 00 06 00 01")
        assert rig.client.transact(request, 7) == frame("FF 03 02 03 E8")
        write = frame("FF 06 00 06 01 F4")
        assert rig.client.transact(write, 8) == write
        assert rig.j2.value("SV") == 50.0
        rig.client.send(frame("01 03 00 06 00 01"))  # nobody at 1
        rig.client.assert_quiet()


def test_request_times_are_when_the_last_byte_came() -> None:
    # At 50 baud a silence of 700 ms ends a frame of unknown length: far longer than any
    # scheduling delay between the steps below.
    with open_rig(baudrate=50) as rig:
        sim, client = rig.sim, rig.client
        request = frame("01 03 00 06 00 01")
        start = time.monotonic()
        client.send(request[:3])  # a request in two pieces
        time.sleep(0.05)
        middle = time.monotonic()
        client.send(request[3:])
        assert client.recv(7) == frame("01 03 02 03 E8")
        answered = time.monotonic()
        client.send(b"\x01\x03\x00")  # a fragment, cut by the silence after it
        sent = time.monotonic()
        time.sleep(1.2)
        assert sim.requests == [request, b"\x01\x03\x00"]
        assert len(sim.request_times) == 2
        complete, fragment = sim.request_times
        assert start < middle <= complete <= answered  # the second piece, not the first
        assert answered <= fragment < sent + 0.35  # its last byte, not the silence's end
        sim.clear_log()
        assert sim.request_times == [] and sim.requests == []
        rig.write(SV, x10(90.0))
        assert len(sim.request_times) == 1 and sim.request_times[0] > sent


# ---- the Python side ----------------------------------------------------------------------------


def test_tables() -> None:
    signed, unsigned = J2Device.SIGNED_TABLE, J2Device.UNSIGNED_TABLE
    assert len(signed) == 29 and len(unsigned) == 14
    assert signed["SV"] == (6, -1999.0, 3276.7, 10)
    assert signed["MV"] == (0, 0.0, 100.0, 10)
    assert signed["P"] == (14, 0.1, 3276.7, 10)
    assert signed["AL1"] == (8, -1999.0, 3276.7, 10)
    assert signed["DIE"] == (62, 0.5, 5.0, 10)
    assert signed["PV"] == (2, -3276.8, 3276.7, 10)
    assert unsigned["FST"] == (156, 20.0, 120.0, 1)
    assert unsigned["AM"] == (128, 0.0, 1.0, 1)
    assert list(J2Device.PARAMETERS) == [*signed, *unsigned]
    addresses = [entry[0] for entry in J2Device.PARAMETERS.values()]
    assert addresses == sorted(addresses) and all(a % 2 == 0 for a in addresses)
    assert not set(addresses) & set(NC)
    limited = {"SV", "HY1", "HY2", "HYS", "RAP", "TRL", "TRH", "SRT", "TOP"}
    assert limited == J2Device.BETWEEN_LSP_USP
    assert {"PV"} == J2Device.READ_ONLY
    with pytest.raises(TypeError):
        J2Device.SIGNED_TABLE["SV"] = (6, 0.0, 1.0, 10)  # type: ignore[index]
    with pytest.raises(TypeError):
        J2Device.DEFAULTS["SV"] = 5.0  # type: ignore[index]


def test_defaults() -> None:
    j2 = J2Device(clock=lambda: 0.0)
    assert set(J2Device.DEFAULTS) == set(J2Device.PARAMETERS) - {"PV"}
    for name, default in J2Device.DEFAULTS.items():
        assert j2.value(name) == default, name
        _, low, high, _ = J2Device.PARAMETERS[name]
        if name in J2Device.BETWEEN_LSP_USP:
            low, high = J2Device.DEFAULTS["LSP"], J2Device.DEFAULTS["USP"]
        assert low <= default <= high, name
    expected = {"SV": 100.0, "P": 40.0, "I": 120.0, "D": 0.0, "LSP": 0.0, "USP": 400.0}
    expected |= {"OUL": 0.0, "OUH": 100.0, "AM": 1.0, "INP": 6.0, "DP": 1.0, "CYT": 2.0}
    expected |= {"FST": 50.0, "DIE": 1.0, "AL1": 0.0, "MV": 0.0, "RAP": 10.0}
    assert {k: J2Device.DEFAULTS[k] for k in expected} == expected
    assert j2.pv == 25.0 and j2.temperature == 25.0 and j2.mv == 0.0 and j2.auto
    assert J2Device(ambient=18.5, clock=lambda: 0.0).pv == 18.5


def test_python_access_and_errors() -> None:
    j2 = J2Device(clock=lambda: 0.0)
    assert j2.value("sv") == j2.value("SV") == 100.0  # any case
    assert j2.speedup == 1.0 and j2.ambient == 25.0 and j2.write_interval == 0.150
    assert "auto" in repr(j2) and "PV=25.0" in repr(j2) and "SV=100.0" in repr(j2)
    j2.set_value("SV", 55.56)  # rounded to the register's 0.1
    assert j2.value("SV") == 55.6
    j2.set_value("AL1", -3)  # an int is a number
    assert j2.value("AL1") == -3.0
    for name in ("NC", "PV1", "XX", ""):
        with pytest.raises(KeyError):
            j2.value(name)
    with pytest.raises(KeyError):
        j2.value(6)  # type: ignore[arg-type]
    with pytest.raises(KeyError, match="read-only"):
        j2.set_value("PV", 50.0)
    with pytest.raises(ValueError, match=r"0\.\.400"):
        j2.set_value("SV", 400.1)
    with pytest.raises(ValueError, match="LSP"):
        j2.set_value("LSP", 401.0)
    with pytest.raises(ValueError):
        j2.set_value("AL1", 3276.8)  # beyond the register
    with pytest.raises(ValueError):
        j2.set_value("SV", math.nan)
    for bad in ("1", True, None):
        with pytest.raises(TypeError):
            j2.set_value("SV", bad)  # type: ignore[arg-type]
    with pytest.raises(RuntimeError, match="manual"):
        j2.set_value("MV", 10.0)
    j2.set_value("AM", 0)
    assert not j2.auto and "manual" in repr(j2)
    j2.set_value("MV", 12.5)
    assert j2.mv == 12.5 and j2.value("MV") == 12.5
    j2.set_value("AM", 1)
    j2.set_value("RAP", 5.0)
    j2.set_value("RAPNF", 1)
    assert "ramping" in repr(j2)
    with pytest.raises(RuntimeError, match="ramp"):
        j2.set_value("RTM", 1.0)
    j2.set_value("AT", 1)
    assert "tuning" in repr(j2) and j2.value("AT") == 1.0
    with pytest.raises(ValueError):
        j2.hold_temperature(math.inf)
    with pytest.raises(ValueError):
        j2.advance(-1.0)
    assert j2.value("SV") == 55.6


@pytest.mark.parametrize(
    "options",
    [
        {"speedup": 0},
        {"speedup": -1.0},
        {"speedup": math.nan},
        {"write_interval": -0.1},
        {"write_interval": math.inf},
        {"ambient": math.inf},
    ],
)
def test_bad_constructor_arguments(options: dict[str, float]) -> None:
    with pytest.raises(ValueError):
        J2Device(**options)  # type: ignore[arg-type]


def test_constructor_wants_a_callable_clock() -> None:
    with pytest.raises(TypeError):
        J2Device(clock=5)  # type: ignore[arg-type]


def test_handlers_directly() -> None:
    j2 = J2Device(clock=lambda: 0.0, write_interval=0.0)
    assert j2.read_holding(SV, 1) == [1000]
    j2.write_holding(SV, [x10(42.0)])
    assert j2.read_holding(SV, 1) == [420]
    for address, values, code in [
        (PV, [0], 2),
        (SV, [x10(401.0)], 3),
        (MV, [0], 4),
    ]:
        with pytest.raises(SimException) as caught:
            j2.write_holding(address, values)
        assert caught.value.code == code
    # The 16-register limit is data the simulator applies before the handlers run.
    assert (j2.max_read, j2.max_write, j2.too_many_code) == (16, 16, 3)
    assert j2.read_holding(SV, 1) == [420]
