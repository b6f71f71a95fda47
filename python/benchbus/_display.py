"""HTML tables for notebooks: the ``_repr_html_`` of status, telemetry and recording objects.

Jupyter shows an object through its ``_repr_html_`` when it has one. Every such method in
benchbus builds its table here, so they all look alike and every value is escaped.
"""

from __future__ import annotations

import dataclasses
import enum
import html
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

__all__ = ["dataclass_table", "field_table", "format_value", "html_table", "plural"]


def plural(count: int, noun: str) -> str:
    """``1 sample``, ``2 samples``, ``0 samples``."""
    return f"{count} {noun}{'' if count == 1 else 's'}"


def format_value(value: object) -> str:
    """``value`` as a short text: an enum by its ``str`` (``DriveState.FORWARD``), a float
    as Python prints it (``nan`` for NaN), anything else by ``str``."""
    if isinstance(value, enum.Enum):
        return str(value)
    if isinstance(value, float):
        return "nan" if math.isnan(value) else repr(value)
    return str(value)


def html_table(
    header: Sequence[str],
    rows: Iterable[Sequence[object]],
    *,
    caption: str | None = None,
    numeric: Sequence[bool] | None = None,
) -> str:
    """A ``<table>`` with ``header`` and ``rows`` (each cell through :func:`format_value`,
    then escaped). ``numeric[i]`` right-aligns column ``i``; ``caption`` goes above."""
    align = list(numeric or [False] * len(header))

    def cell(tag: str, i: int, text: str) -> str:
        style = ' style="text-align: right"' if i < len(align) and align[i] else ""
        return f"<{tag}{style}>{html.escape(text)}</{tag}>"

    parts = ["<table>"]
    if caption:
        parts.append(f'<caption style="text-align: left">{html.escape(caption)}</caption>')
    parts.append("<thead><tr>")
    parts.extend(cell("th", i, name) for i, name in enumerate(header))
    parts.append("</tr></thead><tbody>")
    for row in rows:
        parts.append("<tr>")
        parts.extend(cell("td", i, format_value(value)) for i, value in enumerate(row))
        parts.append("</tr>")
    parts.append("</tbody></table>")
    return "".join(parts)


def field_table(title: str, fields: Iterable[tuple[str, object, str]]) -> str:
    """A field / value / unit table titled ``title``; the unit column only if some field
    has a unit."""
    rows = list(fields)
    if any(unit for _, _, unit in rows):
        return html_table(("field", "value", "unit"), rows, caption=title)
    return html_table(("field", "value"), [(f, v) for f, v, _ in rows], caption=title)


def dataclass_table(obj: Any, units: Mapping[str, str] | None = None) -> str:
    """:func:`field_table` of a dataclass instance: its fields shown in its repr, in order,
    titled by its class name; ``units`` gives a unit by field name."""
    units = units or {}
    return field_table(
        type(obj).__name__,
        (
            (f.name, getattr(obj, f.name), units.get(f.name, ""))
            for f in dataclasses.fields(obj)
            if f.repr
        ),
    )
