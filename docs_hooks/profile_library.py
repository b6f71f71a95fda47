"""A MkDocs hook: the pages of the shipped profiles, written at build time from the files.

A page of ``devices/library/`` holds a marker ``<!-- profiles: KIND -->``; each build
replaces it with every profile the package ships whose ``[device] kind`` is KIND: its maker,
model, source, line and limits, the notes at the top of its file (what the vendor's map
leaves unclear, the rules a profile cannot hold) and its register table, as ``benchbus
profile show`` prints it. ``<!-- profiles: all -->`` is the list of them all. The pages
cannot drift from the files.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

#: The marker's pattern; its group is the kind (or ``all``).
MARKER = re.compile(r"<!-- profiles: ([a-z0-9-]+) -->")
#: The folder of the pages, under docs/.
FOLDER = "devices/library/"
#: The page of each kind, under :data:`FOLDER`, and its title in the list.
KINDS = {
    "energy-meter": ("energy-meters.md", "Energy meters"),
    "power-monitor": ("power-monitors.md", "Power monitors"),
    "sensor": ("sensors.md", "Sensors"),
    "temperature-controller": ("temperature-controllers.md", "Temperature controllers"),
    "relay-board": ("relay-boards.md", "Relay boards"),
    "motor-driver": ("motor-drivers.md", "Motor drivers"),
    "flow-controller": ("flow-controllers.md", "Flow controllers"),
    "power-supply": ("power-supplies.md", "Power supplies"),
}


def on_page_markdown(markdown: str, *, page: Any, **kwargs: Any) -> str:
    """Fill the markers of the library's pages."""
    if not page.file.src_uri.startswith(FOLDER):
        return markdown
    return MARKER.sub(lambda m: section(m.group(1)), markdown)


def shipped() -> dict[str, Any]:
    """The shipped profiles, ``{name: Profile}`` by name."""
    import benchbus as bb
    from benchbus._library import SHIPPED

    return {p.stem: bb.Profile(str(p)) for p in sorted(SHIPPED.glob("*.toml"))}


def section(kind: str) -> str:
    """The Markdown of the profiles of ``kind``, or for ``all`` the list of every one."""
    profiles = shipped()
    if kind == "all":
        return listing(profiles)
    if kind not in KINDS:
        raise ValueError(f"no kind {kind!r} of shipped profiles: one of {', '.join(KINDS)}")
    chosen = {name: p for name, p in profiles.items() if p.kind == kind}
    if not chosen:
        raise ValueError(f"no shipped profile is of kind {kind!r}")
    return "\n\n".join(described(name, p) for name, p in chosen.items())


def listing(profiles: dict[str, Any]) -> str:
    """A table of every shipped profile: its name, maker, model and kind's page."""
    rows = ["| name | maker | model | kind |", "|---|---|---|---|"]
    for name, p in profiles.items():
        page, title = KINDS[p.kind]
        anchor = name.replace(".", "")
        rows.append(f"| [`{name}`]({page}#{anchor}) | {p.maker} | {p.model} | {title} |")
    return "\n".join(rows)


def note(path: str) -> list[str]:
    """The comment lines at the top of the file at ``path``, without their ``#``."""
    lines = []
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        if not line.startswith("#"):
            break
        lines.append(line[1:].strip())
    return lines


def _cell(text: str) -> str:
    """``text`` fit for a table cell."""
    return text.replace("|", "\\|").replace("\n", " ")


def described(name: str, profile: Any) -> str:
    """The Markdown of one profile: a heading, what it is, where it comes from, its notes
    and its registers."""
    from benchbus._profile import profile_line
    from benchbus.cli.profile import _kind, _range, _scale

    line = profile_line(profile)
    limits = profile.limits
    parts = [
        f"## {name}",
        f"**{profile.maker} {profile.model}**: {profile.description}.",
        f"Source: {profile.source}.",
        f"Line: {line.baudrate} {line.bytesize}{line.parity}{line.stopbits} {line.framing}"
        f" (the device's own port; a shared Bus keeps its own); at most"
        f" {limits.max_read or 'the protocol limit of 125'} registers a read,"
        f" {limits.max_write or 'the protocol limit of 123'} a write"
        + ("; every write by 0x10" if limits.write_multiple else "")
        + ".",
        "```python\n"
        "import benchbus as bb\n\n"
        f'dev = bb.Device.from_profile("{name}", "/dev/ttyUSB0", unit=1)\n'
        "print(dev.sample())\n"
        "```",
    ]
    said = note(profile.path)
    if said:
        body = "\n".join("    " + line for line in ["```text", *said, "```"])
        parts.append(f'!!! info "The top of the file"\n\n{body}')
    rows = [
        "| name | table | address | type | scale | unit | access | range | description |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in profile.registers:
        cells = [
            f"`{r.name}`",
            r.table,
            f"0x{r.address:04X}",
            _kind(r),
            _scale(r),
            r.unit,
            r.access,
            _range(r),
            r.description,
        ]
        rows.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    table = "\n".join("    " + row for row in rows)
    parts.append(f'??? note "The {len(profile)} registers"\n\n{table}')
    return "\n\n".join(parts)
