"""A MkDocs hook: the command-line reference, written at build time from the argument parser.

The page ``reference/cli.md`` holds the marker below; each build replaces it with every
command and sub-command of ``benchbus.cli.build_parser()``: its usage, description,
arguments (with their help and defaults) and epilog. The page cannot drift from the parser.
"""

from __future__ import annotations

import argparse
import contextlib
import html
import os
import re
from collections.abc import Iterator
from typing import Any

MARKER = "<!-- cli-reference -->"
PAGE = "reference/cli.md"
#: The width usage lines are wrapped at (argparse reads it from $COLUMNS).
WIDTH = 88


def on_page_markdown(markdown: str, *, page: Any, **kwargs: Any) -> str:
    """Fill the marker of the CLI reference page."""
    if page.file.src_uri != PAGE:
        return markdown
    if MARKER not in markdown:
        raise ValueError(f"{PAGE} lacks the marker {MARKER} the CLI reference goes in")
    from benchbus.cli import build_parser

    return markdown.replace(MARKER, reference(build_parser()))


def reference(parser: argparse.ArgumentParser) -> str:
    """The Markdown of ``parser`` and of every sub-command under it, as plain text: Python
    3.14's parsers colour their usage and help when stdout is a terminal or FORCE_COLOR is
    set, which would put escape codes into the page."""
    for each in _parsers(parser):
        if hasattr(each, "color"):
            setattr(each, "color", False)  # noqa: B010 (Python 3.14's attribute)
    with _columns(WIDTH):
        return "\n".join(_parser(parser, level=2, child_level=2))


@contextlib.contextmanager
def _columns(width: int) -> Iterator[None]:
    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(width)
    try:
        yield
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old


def _text(value: str) -> str:
    """Plain text for Markdown: HTML-escaped, Markdown's own characters escaped."""
    return re.sub(r"([\\`*_\[\]|#])", r"\\\1", html.escape(" ".join(value.split()), quote=False))


def _parsers(parser: argparse.ArgumentParser) -> Iterator[argparse.ArgumentParser]:
    """``parser`` and every sub-command's parser under it."""
    yield parser
    for sub in _subcommands(parser).values():
        yield from _parsers(sub)


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """The sub-commands of ``parser`` by name (none: empty)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _help(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    """The action's help as ``--help`` prints it (``%(default)s`` and the like expanded)."""
    if not action.help:
        return ""
    return parser._get_formatter()._expand_help(action)


def _names(action: argparse.Action) -> str:
    if action.option_strings:
        metavar = ""
        if action.nargs != 0:
            metavar = " " + argparse.HelpFormatter("")._format_args(action, action.dest.upper())
        return ", ".join(f"`{option}{metavar}`" for option in action.option_strings)
    metavar = action.metavar if isinstance(action.metavar, str) else action.dest.upper()
    return f"`{metavar}`"


def _default(action: argparse.Action) -> str:
    default = action.default
    if action.nargs == 0 or default in (None, argparse.SUPPRESS) or not action.option_strings:
        return ""
    if isinstance(default, (list, tuple)):
        default = ",".join(str(value) for value in default)
    return f"`{default}`"


def _parser(parser: argparse.ArgumentParser, level: int, child_level: int) -> Iterator[str]:
    """The Markdown of ``parser``, then of its sub-commands (their headings at ``child_level``)."""
    yield f"{'#' * level} {parser.prog}"
    yield ""
    yield "```text"
    yield parser.format_usage().strip()
    yield "```"
    yield ""
    if parser.description:
        yield _text(parser.description)
        yield ""
    subcommands = _subcommands(parser)
    for group in parser._action_groups:
        actions = [
            action
            for action in group._group_actions
            if action.help != argparse.SUPPRESS
            and not isinstance(action, argparse._SubParsersAction)
        ]
        if not actions:
            continue
        yield f"**{_text(group.title or '')}**"
        yield ""
        yield "| Argument | Meaning | Default |"
        yield "| --- | --- | --- |"
        for action in actions:
            yield f"| {_names(action)} | {_text(_help(parser, action))} | {_default(action)} |"
        yield ""
    if subcommands:
        yield "**commands**"
        yield ""
        for name, sub in subcommands.items():
            anchor = sub.prog.replace(" ", "-")
            yield f"- [`{name}`](#{anchor}): {_text(sub.description or '')}"
        yield ""
    if parser.epilog:
        yield _text(parser.epilog)
        yield ""
    for sub in subcommands.values():
        yield from _parser(sub, child_level, child_level + 1)
