"""Numbers and tables as the command line prints them."""

from __future__ import annotations

import enum
from collections.abc import Sequence

from benchbus._device import member_name


def fmt(value: float) -> str:
    """A number for a table: integral values without a fraction, others to 4 decimals."""
    if float(value).is_integer():
        return str(int(value))
    return f"{value:.4f}".rstrip("0").rstrip(".")


def measured(value: float, unit: str) -> str:
    """A value with its unit: ``1450 rpm``, ``25.3 °C`` (the number alone without one)."""
    return f"{fmt(value)} {unit}".rstrip()


def csv_number(value: float) -> str:
    """A number for a CSV file, at full precision."""
    return str(int(value)) if float(value).is_integer() else repr(float(value))


def enum_name(value: object) -> str:
    """An enum member by its name (a value its enum does not list as ``UNKNOWN(9)``),
    anything else as ``str``."""
    return member_name(value) if isinstance(value, enum.Enum) else str(value)


def shown(value: object, unit: str = "") -> str:
    """A value as read: an enum member by its name, a bool as ``true`` or ``false``, a
    number with its unit (:func:`measured`), text as it is."""
    if isinstance(value, enum.Enum):
        return enum_name(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return measured(value, unit)
    return str(value)


def text_table(headers: Sequence[str] | None, rows: Sequence[Sequence[str]]) -> list[str]:
    """Left-aligned columns, two spaces apart."""
    lines = [list(headers)] if headers else []
    lines += [list(r) for r in rows]
    if not lines:
        return []
    widths = [max(len(line[i]) for line in lines if i < len(line)) for i in range(len(lines[0]))]
    return ["  ".join(c.ljust(w) for c, w in zip(line, widths)).rstrip() for line in lines]


def print_table(headers: Sequence[str] | None, rows: Sequence[Sequence[str]]) -> None:
    """Print :func:`text_table`'s lines."""
    for line in text_table(headers, rows):
        print(line)
