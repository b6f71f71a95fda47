"""Instrument in all four tables (input registers, coils, discrete inputs beside holding
registers), against a third-party server (pymodbus's own, on loopback), with the requests
split by the instrument's limits."""

from __future__ import annotations

import logging
import struct
from collections.abc import Iterator

import pytest
from pymodbus_peer import COILS, DISCRETE, HOLDING, INPUT, pymodbus_server

import benchbus as bb


@pytest.fixture
def peer() -> Iterator[bb.Bus]:
    with pymodbus_server(rtu=True) as url, bb.Bus(url, timeout=1.0) as bus:
        yield bus


def test_input_registers_are_read_with_function_4(peer: bb.Bus) -> None:
    inst = bb.Instrument(peer, 1, max_read=10)
    assert inst.read_registers(0, 25, function=4) == INPUT[:25]
    assert inst.read_registers(0, 25) == HOLDING[:25]
    assert inst.read_registers(0, 25, function=3) == HOLDING[:25]
    assert inst.read_register(3, function=4) == INPUT[3]
    assert inst.read_register(3, decimals=1, function=4) == INPUT[3] / 10
    # Two registers as one value, from the input table: (1004 << 16) | 1005.
    assert inst.read_long(4, function=4) == INPUT[4] << 16 | INPUT[5]
    raw = struct.pack(">HH", INPUT[6], INPUT[7])
    # A single is read as the shortest decimal that is that single.
    single = struct.unpack(">f", raw)[0]
    texts = (f"{single:.{digits}g}" for digits in range(1, 10))
    shortest = next(float(t) for t in texts if struct.pack(">f", float(t)) == raw)
    assert inst.read_float(6, function=4) == shortest
    text = b"".join(w.to_bytes(2, "big") for w in INPUT[8:10]).rstrip(b"\0").decode("latin-1")
    assert inst.read_string(8, 2, function=4) == text


def test_coils_and_discrete_inputs_split_by_the_bit_limits(
    peer: bb.Bus, caplog: pytest.LogCaptureFixture
) -> None:
    inst = bb.Instrument(peer, 1, max_read_bits=300, max_write_bits=100)
    assert (inst.max_read_bits, inst.max_write_bits) == (300, 100)
    with caplog.at_level(logging.DEBUG, logger="benchbus.wire"):
        coils = inst.read_coils(0, 700)
    assert coils == [bool(c) for c in COILS[:700]]
    # 700 coils in reads of at most 300: 300 + 300 + 100.
    sent = [r for r in caplog.records if r.getMessage().startswith("-> ")]
    assert len(sent) == 3
    assert inst.read_discrete_inputs(1, 5) == [bool(d) for d in DISCRETE[1:6]]
    assert inst.read_coil(2) is True and inst.read_coil(1) is False
    assert inst.read_discrete_input(1) is True and inst.read_discrete_input(0) is False
    inst.write_coil(1, True)
    assert inst.read_coil(1) is True
    pattern = [i % 3 == 0 for i in range(250)]
    inst.write_coils(100, pattern)  # 100 + 100 + 50
    assert inst.read_coils(100, 250) == pattern


def test_the_defaults_are_the_protocols_limits(peer: bb.Bus) -> None:
    inst = bb.Instrument(peer, 1)
    assert (inst.max_read_bits, inst.max_write_bits) == (2000, 1968)
    assert inst.read_coils(0, 2000) == [bool(c) for c in COILS]


@pytest.mark.parametrize(
    ("call", "error", "message"),
    [
        (lambda i: i.read_registers(0, 1, function=6), ValueError, "function must be 3"),
        (lambda i: i.read_register(0, function="4"), TypeError, "function"),
        (lambda i: i.read_long(0, function=1), ValueError, "function must be 3"),
        (lambda i: i.write_coil(0, 1), TypeError, "a coil is True or False"),
        (lambda i: i.write_coils(0, [True, 0]), TypeError, "a coil is True or False"),
        (lambda i: i.write_coils(0, []), ValueError, "values must hold 1 to"),
        (lambda i: i.write_coils(0xFFFF, [True, True]), ValueError, "values must hold 1 to 1"),
        (lambda i: i.write_coils(0, "10"), TypeError, "not str"),
        (lambda i: i.read_coils(0, 0), ValueError, "count"),
        (lambda i: i.read_coils(0xFFFF, 2), ValueError, "count"),
        (lambda i: i.read_discrete_inputs(-1, 1), ValueError, "address"),
    ],
)
def test_bad_input_is_refused_before_anything_is_sent(
    peer: bb.Bus, call: object, error: type[Exception], message: str
) -> None:
    inst = bb.Instrument(peer, 1)
    before = peer.stats.transactions
    with pytest.raises(error, match=message):
        call(inst)  # type: ignore[operator]
    assert peer.stats.transactions == before


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"max_read_bits": 0}, "max_read_bits must be 1 to 2000"),
        ({"max_read_bits": 2001}, "max_read_bits must be 1 to 2000"),
        ({"max_write_bits": 1969}, "max_write_bits must be 1 to 1968"),
    ],
)
def test_bit_limits_are_checked(peer: bb.Bus, options: dict[str, int], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        bb.Instrument(peer, 1, **options)
