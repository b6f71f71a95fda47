"""A MkDocs hook: the command-line reference, written at build time from the argument parser.

The page ``reference/cli.md`` holds the marker below; each build replaces it with every
command and sub-command of ``benchbus.cli.build_parser()``: its usage, description,
arguments (with their help and defaults) and epilog. The page cannot drift from the parser.
"""

from __future__ import annotations

import argparse
import contextlib
import enum
import html
import os
import re
import sys
from collections.abc import Iterator
from typing import Any

MARKER = "<!-- cli-reference -->"
PAGE = "reference/cli.md"
#: The width usage lines are wrapped at (argparse reads it from $COLUMNS).
WIDTH = 88


#: The package the parser comes from.
CLI = "benchbus.cli"


def on_pre_build(**kwargs: Any) -> None:
    """Forget the modules of ``benchbus.cli``, so that each build reads the parser from the
    sources as they are now: ``mkdocs serve`` rebuilds in one process, where a module once
    imported stays as it was."""
    for name in [name for name in sys.modules if name == CLI or name.startswith(CLI + ".")]:
        del sys.modules[name]


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
    """$COLUMNS set to ``width`` meanwhile (argparse wraps usage at it), then put back."""
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
    for _, sub in _subcommands(parser):
        yield from _parsers(sub)


def _subcommands(
    parser: argparse.ArgumentParser,
) -> list[tuple[list[str], argparse.ArgumentParser]]:
    """The sub-commands of ``parser``, each once: its names (the name, then its aliases,
    which argparse keeps as more keys to the same parser) and its parser."""
    commands: dict[int, tuple[list[str], argparse.ArgumentParser]] = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                commands.setdefault(id(sub), ([], sub))[0].append(name)
    return list(commands.values())


def _anchor(parser: argparse.ArgumentParser) -> str:
    """The id of the heading of ``parser``'s section: ``benchbus-drive-set``."""
    return re.sub(r"[^\w-]+", "-", parser.prog).strip("-")


def _help(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    """The action's help as ``--help`` prints it (``%(default)s`` and the like expanded)."""
    if not action.help:
        return ""
    return parser._get_formatter()._expand_help(action)


def _names(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    """The action's names as ``--help`` lists them: each option with its metavar, or the
    positional's metavar (``{a,b}`` for choices, its dest without one)."""
    formatter = parser._get_formatter()
    if not action.option_strings:
        return _code(formatter._format_action_invocation(action))
    metavar = ""
    if action.nargs != 0:
        default = formatter._get_default_metavar_for_optional(action)
        metavar = " " + formatter._format_args(action, default)
    return ", ".join(_code(option + metavar) for option in action.option_strings)


#: The default values the page shows, written as ``str()`` gives them; another object (a
#: function, an instance) has no text a reader can use, and its repr changes between runs.
PLAIN = (str, int, float, enum.Enum, os.PathLike)


def _default(action: argparse.Action) -> str:
    """The action's default as code, where one applies: an option taking a value, or a
    positional that may be left out; empty where none does."""
    default = action.default
    if action.nargs == 0 or default is None or default is argparse.SUPPRESS:
        return ""
    if not action.option_strings and action.nargs not in ("?", "*"):
        return ""  # a positional that must be given
    values = default if isinstance(default, (list, tuple)) else [default]
    if not values or not all(isinstance(value, PLAIN) for value in values):
        return ""  # nothing (an empty list to append to), or nothing a reader can use
    text = ",".join(str(value) for value in values)
    return _code(text) if text else '`""`'


def _code(text: str) -> str:
    """``text`` as a Markdown code span, whatever backticks it holds."""
    text = " ".join(text.split())
    fence = "`" * (max(map(len, re.findall("`+", text)), default=0) + 1)
    pad = " " if text.startswith("`") or text.endswith("`") else ""
    return f"{fence}{pad}{text}{pad}{fence}"


def _parser(parser: argparse.ArgumentParser, level: int, child_level: int) -> Iterator[str]:
    """The Markdown of ``parser``, then of its sub-commands (their headings at ``child_level``)."""
    yield f"{'#' * level} {parser.prog} {{#{_anchor(parser)}}}"
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
            names, meaning = _names(parser, action), _text(_help(parser, action))
            yield f"| {names} | {meaning} | {_default(action)} |"
        yield ""
    if subcommands:
        yield "**commands**"
        yield ""
        for (name, *aliases), sub in subcommands:
            also = f" (also {', '.join(_code(alias) for alias in aliases)})" if aliases else ""
            yield f"- [`{name}`](#{_anchor(sub)}){also}: {_text(sub.description or '')}"
        yield ""
    if parser.epilog:
        yield _text(parser.epilog)
        yield ""
    for _, sub in subcommands:
        yield from _parser(sub, child_level, child_level + 1)
