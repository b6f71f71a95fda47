"""A MkDocs hook: the pytest plugin's fixtures of each device family, written at build time.

The plugin makes ``sim_<key>_model``, ``sim_<key>`` and ``bench_<key>`` for every family of
the registry (``benchbus._families.FAMILIES``) when it is imported, so the reference cannot
read them from the source as it reads the rest. The page ``reference/integrations.md``
holds the marker below; each build replaces it with those fixtures and their docstrings, in
the registry's order: the page cannot miss a family.
"""

from __future__ import annotations

import importlib
import re
import sys
from typing import Any

MARKER = "<!-- family-fixtures -->"
PAGE = "reference/integrations.md"
PLUGIN = "benchbus.pytest_plugin"
#: The kinds of fixture, in the order each family's are listed.
KINDS = ("sim_{}_model", "sim_{}", "bench_{}")


def on_page_markdown(markdown: str, *, page: Any, **kwargs: Any) -> str:
    """Fill the marker of the integrations reference."""
    if page.file.src_uri != PAGE:
        return markdown
    if MARKER not in markdown:
        raise ValueError(f"{PAGE} lacks the marker {MARKER} the family fixtures go in")
    # Read afresh: `mkdocs serve` rebuilds in one process.
    for name in [n for n in sys.modules if n in (PLUGIN, "benchbus._families")]:
        del sys.modules[name]
    plugin = importlib.import_module(PLUGIN)
    families = importlib.import_module("benchbus._families").FAMILIES
    keys = [f.key for f in families if f.device is not None]
    return markdown.replace(MARKER, fixtures(plugin, keys))


def fixtures(plugin: Any, keys: list[str]) -> str:
    """The Markdown of each family's fixtures: a heading and its docstring."""
    out = []
    for kind in KINDS:
        for key in keys:
            name = kind.format(key)
            doc = getattr(plugin, name).__doc__ or ""
            out += [f"#### `{name}` {{ #{PLUGIN}.{name} }}", "", markdown_of(doc), ""]
    return "\n".join(out)


def markdown_of(doc: str) -> str:
    """A fixture's docstring (reStructuredText roles and literals) as Markdown: a role's
    target becomes a link to its entry in the reference."""
    doc = re.sub(r":(?:class|data|func):`~?(benchbus\.[\w.]+)`", r"[`\1`][\1]", doc)
    doc = re.sub(r":(?:class|data|func):`~?(\w+)`", rf"[`\1`][{PLUGIN}.\1]", doc)
    return doc.replace("``", "`")
