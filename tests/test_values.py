"""Values over registers: ``bb.from_registers`` / ``bb.to_registers``, held to the layouts'
definition and to a third-party peer (pymodbus's converters, which know the word order)."""

from __future__ import annotations

import math
import random
import struct

import pytest
from pymodbus.client import ModbusSerialClient

import benchbus as bb

PEER = ModbusSerialClient.DATATYPE
#: benchbus's type names and pymodbus's.
TYPES = {
    "u16": PEER.UINT16,
    "i16": PEER.INT16,
    "u32": PEER.UINT32,
    "i32": PEER.INT32,
    "u64": PEER.UINT64,
    "i64": PEER.INT64,
    "f32": PEER.FLOAT32,
    "f64": PEER.FLOAT64,
}
#: The orders pymodbus knows: the word order only, bytes high first.
WORD_ORDERS = {"ABCD": "big", "CDAB": "little"}


def sample(kind: str, rng: random.Random) -> int | float:
    """A value of ``kind`` drawn over its whole range."""
    bits = int(kind[1:])
    if kind.startswith("f"):
        fmt = ">f" if bits == 32 else ">d"
        while True:
            raw = rng.getrandbits(bits).to_bytes(bits // 8, "big")
            value: float = struct.unpack(fmt, raw)[0]
            if math.isfinite(value):
                return value
    if kind.startswith("i"):
        return rng.randrange(-(2 ** (bits - 1)), 2 ** (bits - 1))
    return rng.randrange(2**bits)


@pytest.mark.parametrize("kind", list(TYPES))
@pytest.mark.parametrize("order", list(WORD_ORDERS))
def test_values_agree_with_pymodbus(kind: str, order: str) -> None:
    rng = random.Random(f"{kind}{order}")
    for _ in range(200):
        value = sample(kind, rng)
        ours = bb.to_registers(value, kind, order)  # type: ignore[arg-type]
        theirs = ModbusSerialClient.convert_to_registers(
            value, TYPES[kind], word_order=WORD_ORDERS[order]
        )
        assert ours == theirs, (kind, order, value)
        back = bb.from_registers(ours, kind, order)  # type: ignore[arg-type]
        assert back == [value] or (kind == "f32" and back[0] == pytest.approx(value, rel=1e-7))


#: 0x01020304 in the four layouts (the values table of docs/devices/instruments.md).
FOUR = {
    "ABCD": [0x0102, 0x0304],
    "CDAB": [0x0304, 0x0102],
    "BADC": [0x0201, 0x0403],
    "DCBA": [0x0403, 0x0201],
}


@pytest.mark.parametrize("order", list(FOUR))
def test_the_four_layouts(order: str) -> None:
    assert bb.to_registers(0x01020304, "u32", order) == FOUR[order]  # type: ignore[arg-type]
    assert bb.from_registers(FOUR[order], "u32", order) == [0x01020304]  # type: ignore[arg-type]
    # The byte order applies to a single register too; the word order cannot.
    swapped = order in ("BADC", "DCBA")
    assert bb.to_registers(0x0102, "u16", order) == [0x0201 if swapped else 0x0102]  # type: ignore[arg-type]


def test_several_values_and_the_defaults() -> None:
    assert bb.to_registers([1, -1], "i16") == [1, 0xFFFF]
    assert bb.from_registers([1, 0xFFFF]) == [1, 0xFFFF]
    assert bb.from_registers([1, 0xFFFF], "i16") == [1, -1]
    assert bb.from_registers(bb.to_registers([21.5, -0.5], "f32"), "f32") == [21.5, -0.5]
    assert bb.to_registers(2**64 - 1, "u64") == [0xFFFF] * 4
    assert bb.from_registers([0x8000, 0, 0, 0], "i64") == [-(2**63)]


@pytest.mark.parametrize(
    ("call", "error", "message"),
    [
        (lambda: bb.to_registers(65536), ValueError, "u16 value must be 0 to 65535"),
        (lambda: bb.to_registers(-1, "u32"), ValueError, "u32 value must be 0 to"),
        (lambda: bb.to_registers(2**64, "u64"), ValueError, "u64 value"),
        (lambda: bb.to_registers(1.5, "i32"), TypeError, "i32 value must be an int"),
        (lambda: bb.to_registers(True), TypeError, "must be an int"),
        (lambda: bb.to_registers(math.nan, "f64"), ValueError, "finite"),
        (lambda: bb.to_registers(1e39, "f32"), ValueError, "finite"),
        (lambda: bb.to_registers([], "u16"), ValueError, "at least one value"),
        (lambda: bb.to_registers("12"), TypeError, "not str"),
        (lambda: bb.to_registers(1, "u8"), ValueError, "type must be one of u16"),  # type: ignore[arg-type]
        (lambda: bb.to_registers(1, 16), TypeError, "type must be one of"),  # type: ignore[arg-type]
        (lambda: bb.to_registers(1, "u16", "ACBD"), ValueError, "order must be"),  # type: ignore[arg-type]
        (lambda: bb.from_registers([1, 2, 3], "u32"), ValueError, "whole u32 values"),
        (lambda: bb.from_registers([], "u16"), ValueError, "whole u16 values"),
        (lambda: bb.from_registers([65536]), ValueError, "each register"),
        (lambda: bb.from_registers(b"\x01\x02"), TypeError, "not str or bytes"),  # type: ignore[arg-type]
    ],
)
def test_bad_values_are_refused_with_what_is_wrong(
    call: object, error: type[Exception], message: str
) -> None:
    with pytest.raises(error, match=message):
        call()  # type: ignore[operator]
