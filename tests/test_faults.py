"""The noisy line (benchbus.sim.Faults): each fault does what it says, benchbus raises the
right class or recovers with retries, and a short soak never gets a wrong value back."""

from __future__ import annotations

import contextlib
import dataclasses
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

import benchbus as bb
from benchbus.sim import FAULT_KINDS, Faults, RegisterDevice, Simulator

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))

import soak

BAUD = 115_200
TIMEOUT = 0.05
VALUES = [0x1234, 0xABCD]  # registers 10 and 11 of unit 1
OTHER = [0x0F0F, 0x5A5A]  # registers 50 and 51


def crc(data: bytes) -> bytes:
    return bb.crc16(data).to_bytes(2, "little")


# The clean reply to "read 2 registers from 10 of unit 1".
CLEAN = bytes([1, 3, 4, 0x12, 0x34, 0xAB, 0xCD])
CLEAN += crc(CLEAN)


@pytest.fixture
def sim() -> Iterator[Simulator[RegisterDevice]]:
    registers = {10: VALUES[0], 11: VALUES[1], 50: OTHER[0], 51: OTHER[1]}
    with Simulator({1: RegisterDevice(registers)}, baudrate=BAUD) as s:
        yield s


def bus(sim: Simulator[RegisterDevice], retries: int) -> bb.Bus:
    return bb.Bus(sim.port, baudrate=BAUD, timeout=TIMEOUT, retries=retries)


def once(kind: str, seed: int = 0, **kw: float) -> Faults:
    """Exactly one fault of ``kind``, on the next reply."""
    return Faults(rate=1.0, seed=seed, kinds={kind}, limit=1, **kw)  # type: ignore[arg-type]


def read(b: bb.Bus) -> list[int]:
    return b.read_holding_registers(1, 10, 2)


# ---- the configuration ---------------------------------------------------------------------


def test_faults_are_checked_and_kept_in_a_fixed_order() -> None:
    f = Faults(kinds=["wrong_unit", "bitflip"])
    assert f.kinds == ("bitflip", "wrong_unit")
    assert Faults().kinds == FAULT_KINDS
    assert (Faults().rate, Faults().limit) == (0.05, None)
    with pytest.raises(ValueError, match="unknown fault kinds"):
        Faults(kinds={"bitflip", "gremlins"})
    with pytest.raises(ValueError, match="at least one"):
        Faults(kinds=())
    with pytest.raises(TypeError):
        Faults(kinds="bitflip")
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(ValueError, match="rate"):
            Faults(rate=bad)
    with pytest.raises(ValueError, match="delay"):
        Faults(delay=-1)
    with pytest.raises(ValueError, match="limit"):
        Faults(limit=-1)
    with pytest.raises(TypeError):
        Faults(seed=1.5)  # type: ignore[arg-type]
    with pytest.raises(dataclasses.FrozenInstanceError):
        f.rate = 0.5  # type: ignore[misc]


def test_faults_set_on_a_running_simulator_and_counted(sim: Simulator[RegisterDevice]) -> None:
    assert sim.faults is None
    assert sim.fault_counts == dict.fromkeys(FAULT_KINDS, 0)
    with pytest.raises(TypeError):
        sim.faults = "noisy"  # type: ignore[assignment]
    with bus(sim, retries=0) as b:
        sim.faults = Faults(rate=1.0, kinds={"duplicate", "garbage_after"})
        for _ in range(10):
            assert read(b) == VALUES  # both kinds leave the reply itself whole
        counts = sim.fault_counts
        assert sum(counts.values()) == 10
        assert counts["duplicate"] > 0 and counts["garbage_after"] > 0
        sim.faults = None  # a clean line, the counts stay
        assert read(b) == VALUES
        assert sim.replies[-1] == CLEAN
        assert sim.fault_counts == counts
        sim.faults = Faults(rate=0.0)  # a new run restarts them
        assert sum(sim.fault_counts.values()) == 0
        sim.faults = Faults(rate=1.0, kinds={"truncate"})
        sim.clear_faults()
        assert sim.faults is None
        assert read(b) == VALUES


def test_faults_from_the_constructor_and_the_limit() -> None:
    device = RegisterDevice({10: VALUES[0], 11: VALUES[1]})
    with (
        Simulator({1: device}, baudrate=BAUD, faults=Faults(rate=1.0, limit=3)) as sim,
        bus(sim, retries=0) as b,
    ):
        for _ in range(6):
            with contextlib.suppress(bb.ResponseTimeout, bb.FrameError):
                read(b)
        assert sum(sim.fault_counts.values()) == 3
        assert read(b) == VALUES  # the limit is used up: clean from here on


def test_the_same_seed_spoils_the_same_way(sim: Simulator[RegisterDevice]) -> None:
    def run(seed: int) -> list[bytes]:
        sim.clear_log()
        sim.faults = Faults(rate=0.5, seed=seed, kinds={"bitflip", "wrong_unit", "garbage_after"})
        with bus(sim, retries=0) as b:
            for _ in range(30):
                with contextlib.suppress(bb.FrameError, bb.ResponseTimeout):
                    read(b)
        return list(sim.replies)

    first = run(7)
    assert run(7) == first
    assert run(8) != first
    assert 0 < sum(r != CLEAN for r in first) < 30


def test_peek_is_the_truth_past_the_line(sim: Simulator[RegisterDevice]) -> None:
    sim.faults = Faults(rate=1.0, kinds={"truncate"})
    assert sim.peek(1, 10, 2) == VALUES
    assert sim.requests == []  # nothing went on the line
    with pytest.raises(ValueError):
        sim.peek(9, 0)


# ---- each kind --------------------------------------------------------------------------------


def test_bitflip_is_one_bit_and_a_crc_error(sim: Simulator[RegisterDevice]) -> None:
    with bus(sim, retries=0) as b:
        for seed in range(16):
            sim.faults = once("bitflip", seed)
            with pytest.raises(bb.BenchbusError) as e:
                read(b)
            sent = sim.replies[-1]
            diff = [i for i in range(len(CLEAN)) if sent[i] != CLEAN[i]]
            assert len(sent) == len(CLEAN) and len(diff) == 1
            assert bin(sent[diff[0]] ^ CLEAN[diff[0]]).count("1") == 1
            if diff[0] in (1, 2):  # the function or the byte count: the length is off
                assert isinstance(e.value, (bb.FrameError, bb.ResponseTimeout))
            else:
                assert isinstance(e.value, bb.CrcError), e.value
                assert e.value.frame is not None
                assert bytes.fromhex(e.value.frame) == sent
            time.sleep(2 * TIMEOUT)  # let anything left over arrive


def test_bitflip_is_recovered_by_a_retry(sim: Simulator[RegisterDevice]) -> None:
    sim.faults = once("bitflip", seed=3)
    with bus(sim, retries=2) as b:
        assert read(b) == VALUES
        s = b.stats
        assert (s.retries, s.crc_errors, s.transactions) == (1, 1, 1)


def test_drop_byte_leaves_one_byte_out(sim: Simulator[RegisterDevice]) -> None:
    with bus(sim, retries=0) as b:
        for seed in range(12):
            sim.faults = once("drop_byte", seed)
            with pytest.raises((bb.ResponseTimeout, bb.FrameError)) as e:
                read(b)
            sent = sim.replies[-1]
            assert len(sent) == len(CLEAN) - 1
            assert any(CLEAN[:i] + CLEAN[i + 1 :] == sent for i in range(len(CLEAN)))
            if sent[:3] == CLEAN[:3]:  # the header is whole: one byte short of its length
                assert isinstance(e.value, bb.ResponseTimeout)
                assert e.value.frame is not None
                assert bytes.fromhex(e.value.frame) == sent
            time.sleep(2 * TIMEOUT)
        sim.faults = once("drop_byte")
        b.close()
    with bus(sim, retries=1) as b:
        assert read(b) == VALUES


def test_truncate_is_a_timeout_with_the_partial_reply(sim: Simulator[RegisterDevice]) -> None:
    with bus(sim, retries=0) as b:
        for seed in range(8):
            sim.faults = once("truncate", seed)
            start = time.monotonic()
            with pytest.raises(bb.ResponseTimeout) as e:
                read(b)
            # Its own timeout, and the previous call's: listening for its late reply (three
            # timeouts at most after it timed out) before this request.
            assert time.monotonic() - start < 4 * TIMEOUT + 0.05
            sent = sim.replies[-1]
            assert 1 <= len(sent) < len(CLEAN) and CLEAN.startswith(sent)
            assert e.value.frame is not None and bytes.fromhex(e.value.frame) == sent
    sim.faults = once("truncate")
    with bus(sim, retries=1) as b:
        assert read(b) == VALUES
        assert (b.stats.timeouts, b.stats.retries) == (1, 1)


def test_garbage_before_is_a_frame_error_then_recovered(sim: Simulator[RegisterDevice]) -> None:
    with bus(sim, retries=0) as b:
        for seed in range(12):
            sim.faults = once("garbage_before", seed)
            with pytest.raises((bb.FrameError, bb.ResponseTimeout)):
                read(b)
            sent = sim.replies[-1]
            assert sent.endswith(CLEAN) and 1 <= len(sent) - len(CLEAN) <= 8
            time.sleep(2 * TIMEOUT)
            assert read(b) == VALUES  # nothing of it is left for the next call
    sim.faults = once("garbage_before")
    with bus(sim, retries=1) as b:
        assert read(b) == VALUES


def test_garbage_after_is_dropped_before_the_next_request(
    sim: Simulator[RegisterDevice],
) -> None:
    sim.faults = once("garbage_after", seed=5)
    with bus(sim, retries=0) as b:
        assert read(b) == VALUES  # the reply is whole, read by its length
        sent = sim.replies[-1]
        assert sent.startswith(CLEAN) and 1 <= len(sent) - len(CLEAN) <= 8
        assert b.read_holding_registers(1, 50, 2) == OTHER
        assert b.stats.stale_bytes == len(sent) - len(CLEAN)
        assert b.stats.crc_errors == b.stats.frame_errors == 0


def test_duplicate_reply_is_dropped_as_stale(sim: Simulator[RegisterDevice]) -> None:
    sim.faults = once("duplicate")
    with bus(sim, retries=0) as b:
        assert read(b) == VALUES
        assert sim.replies[-2:] == [CLEAN, CLEAN]
        # Same shape of reply, other values: the copy must not be taken for this answer.
        assert b.read_holding_registers(1, 50, 2) == OTHER
        assert b.stats.stale_bytes == len(CLEAN)


def test_wrong_unit_is_a_frame_error_not_a_crc_error(sim: Simulator[RegisterDevice]) -> None:
    with bus(sim, retries=0) as b:
        for seed in range(6):
            sim.faults = once("wrong_unit", seed)
            with pytest.raises(bb.FrameError) as e:
                read(b)
            assert not isinstance(e.value, bb.CrcError)
            sent = sim.replies[-1]
            assert sent[0] != 1 and 1 <= sent[0] <= 247
            assert sent[1:-2] == CLEAN[1:-2] and crc(sent[:-2]) == sent[-2:]
            assert f"unit {sent[0]}" in str(e.value)
        assert b.stats.frame_errors == 6
    sim.faults = once("wrong_unit")
    with bus(sim, retries=1) as b:
        assert read(b) == VALUES


def test_delay_is_a_timeout_and_the_late_reply_lands_in_the_retry(
    sim: Simulator[RegisterDevice],
) -> None:
    sim.faults = once("delay", delay=1.6 * TIMEOUT)
    with bus(sim, retries=0) as b:
        start = time.monotonic()
        with pytest.raises(bb.ResponseTimeout):
            read(b)
        assert time.monotonic() - start < TIMEOUT + 0.1
        time.sleep(2 * TIMEOUT)
        assert read(b) == VALUES
        assert b.stats.stale_bytes == len(CLEAN)  # the late reply, dropped before the request
    sim.faults = once("delay", delay=1.6 * TIMEOUT)
    with bus(sim, retries=1) as b:
        # The first attempt times out; the late reply arrives during the second attempt (to
        # the same request), and the second attempt's own reply, right behind it, is stale.
        assert read(b) == VALUES
        assert (b.stats.timeouts, b.stats.retries) == (1, 1)
        assert b.read_holding_registers(1, 50, 2) == OTHER
        assert b.stats.stale_bytes == len(CLEAN)


def test_a_late_reply_is_listened_for_and_dropped_before_the_next_request(
    sim: Simulator[RegisterDevice],
) -> None:
    # Both attempts of the first call are over before its late reply comes: the next call
    # listens for it first, drops it (counted as stale) and is answered by its own reply.
    sim.faults = once("delay", delay=2.4 * TIMEOUT)
    with bus(sim, retries=1) as b:
        with pytest.raises(bb.ResponseTimeout):
            read(b)
        assert b.read_holding_registers(1, 50, 1) == OTHER[:1]
        s = b.stats
        assert (s.timeouts, s.frame_errors, s.retries) == (2, 0, 1)
        assert s.stale_bytes > 0


# ---- a late reply of the same shape is never taken for the next call's ----------------------
#
# Modbus RTU replies carry no transaction id: a reply to "read 2 registers of unit 1" looks
# the same whatever address was read. After a call in which an attempt timed out, the Bus
# listens for a late reply (up to two timeouts) before its next request and drops it.


def test_late_reply_past_the_last_attempt_is_not_the_next_answer(
    sim: Simulator[RegisterDevice],
) -> None:
    sim.faults = once("delay", delay=1.6 * TIMEOUT)
    with bus(sim, retries=0) as b:
        with pytest.raises(bb.ResponseTimeout):
            read(b)  # registers 10..11; the reply comes 30 ms after the call gave up
        got = b.read_holding_registers(1, 50, 2)  # during this call
        assert got == OTHER, f"got {got}: the values of registers 10..11"


def test_a_late_reply_names_its_unit_so_other_units_are_not_held_up() -> None:
    """Unit 1's reply to registers 10..11 comes late. A request to unit 2 goes out at once
    (no listening for unit 1's late reply first) and drops that reply when it comes; unit
    1's next request, to other registers but a reply of the same shape, still listens for
    what is left of the window and gets its own values."""
    registers = {10: VALUES[0], 11: VALUES[1], 50: OTHER[0], 51: OTHER[1]}
    units = {1: RegisterDevice(registers), 2: RegisterDevice({10: 7, 11: 8})}
    with Simulator(units, baudrate=BAUD) as sim, bus(sim, retries=0) as b:
        sim.faults = once("delay", delay=1.6 * TIMEOUT)
        with pytest.raises(bb.ResponseTimeout):
            read(b)
        gave_up = time.monotonic()
        assert b.read_holding_registers(2, 10, 2) == [7, 8]
        assert b.stats.stale_bytes == len(CLEAN)  # unit 1's late reply, dropped
        assert b.stats.frame_errors == 0
        asked_unit_2 = time.monotonic() - gave_up
        assert b.read_holding_registers(1, 50, 2) == OTHER
        # Unit 2 waited for nothing but its own answer (and unit 1's late frame ahead of it).
        assert asked_unit_2 < 1.6 * TIMEOUT, asked_unit_2


def test_a_loop_over_absent_units_pays_one_timeout_each(sim: Simulator[RegisterDevice]) -> None:
    """A script's own loop over units (retries=0), most of them absent: each absent unit
    costs its timeout, not three (its own and two of listening for its late reply before
    the next unit's request); the unit that is there still answers with its own values."""
    with bus(sim, retries=0) as b:
        found = []
        start = time.monotonic()
        for unit in (2, 3, 4, 5, 6, 1):
            with contextlib.suppress(bb.ResponseTimeout):
                found.append((unit, b.read_holding_registers(unit, 10, 2)))
        took = time.monotonic() - start
    assert found == [(1, VALUES)]
    assert took < 5 * 2 * TIMEOUT, took  # listening for late replies would take 15 x


def test_a_unit_slower_than_the_timeout_does_not_shift_every_answer(
    sim: Simulator[RegisterDevice],
) -> None:
    # No random fault: the unit answers each request 60 ms late with a 50 ms timeout. The
    # first call's retry takes the late first reply; the retry's own reply then comes during
    # the second call and is taken for its answer, and so on: every answer is the previous
    # call's.
    for a in range(100, 110):
        sim.devices[1].registers[a] = a
    sim.reply_delay = 1.2 * TIMEOUT
    with bus(sim, retries=3) as b:
        got = {a: b.read_holding_registers(1, a, 1)[0] for a in range(100, 110)}
    assert got == {a: a for a in range(100, 110)}


# ---- the soak (CI length; bench/soak.py runs the long one) ----------------------------------


@pytest.mark.timeout(120)
def test_soak_on_a_noisy_line_never_returns_a_wrong_value() -> None:
    config = soak.SoakConfig(transactions=2000, rate=0.05, seed=11, retries=3, timeout=TIMEOUT)
    result = soak.run_soak(config)
    print(result.report())
    assert result.transactions == 2000
    assert result.wrong == []
    assert result.unexpected == []
    assert set(result.failures) <= {"ResponseTimeout", "FrameError", "CrcError"}
    assert result.over_bound == []
    assert result.recovered >= 0.995
    assert result.sim_errors == []
    assert result.problems() == []
    # Every kind was injected, at about the rate asked.
    assert all(result.faults[k] > 0 for k in FAULT_KINDS), result.faults
    assert 0.03 < sum(result.faults.values()) / result.requests < 0.08
    assert result.stats["retries"] > 0 and result.stats["stale_bytes"] > 0
    assert result.elapsed < 40
