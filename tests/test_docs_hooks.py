"""The documentation site's hooks (docs_hooks/), called directly on small parsers and on
packages griffe reads from a temporary directory."""

from __future__ import annotations

import argparse
import importlib
import inspect
import types
from collections.abc import Iterator
from pathlib import Path

import griffe
import pytest

from benchbus.cli import build_parser
from conftest import HOOKS, hook

cli_reference = hook("cli_reference")


# ---- the CLI reference ---------------------------------------------------------------------------


class Colourful(argparse.ArgumentParser):
    """A parser that colours its usage while its ``color`` is true, as Python 3.14's do when
    stdout is a terminal or FORCE_COLOR is set."""

    color = True

    def format_usage(self) -> str:
        usage = super().format_usage()
        return f"\x1b[1;34m{usage}\x1b[0m" if self.color else usage


def test_the_cli_reference_has_no_colour(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("FORCE_COLOR", "1")
    monkeypatch.delenv("NO_COLOR", raising=False)
    parser = Colourful(prog="tool", description="A tool.")
    parser.add_argument("--level", type=int, default=3, help="how much")
    commands = parser.add_subparsers(dest="command")
    commands.add_parser("go", description="Go somewhere.").add_argument("where")
    text = cli_reference.reference(parser)
    assert "\x1b" not in text
    assert "usage: tool [-h] [--level LEVEL] {go} ..." in text
    assert "usage: tool go [-h] where" in text
    # benchbus's own parser (argparse's colours where it has them: Python 3.14).
    assert "\x1b" not in cli_reference.reference(build_parser())


# ---- the API reference (griffe) ------------------------------------------------------------------

griffe_benchbus = hook("griffe_benchbus")
PYTHON = HOOKS.parent / "python"


@pytest.fixture(scope="module")
def api() -> griffe.Module:
    """benchbus as the site's API reference reads it: from its sources and stubs, with the
    extension."""
    extensions = griffe.load_extensions(griffe_benchbus.BenchbusReference())
    loader = griffe.GriffeLoader(
        extensions=extensions,
        search_paths=[str(PYTHON)],
        docstring_parser=griffe.Parser.sphinx,
        allow_inspection=False,
    )
    pkg = loader.load("benchbus")
    assert isinstance(pkg, griffe.Module)
    return pkg


def test_every_public_module_has_its_link(api: griffe.Module) -> None:
    reference = griffe_benchbus.Reference(api)
    modules = ":mod:`benchbus.exceptions`, :mod:`benchbus.sim`, :mod:`benchbus._recognise`"
    assert reference.rewrite(api, modules) == (
        "[`benchbus.exceptions`][benchbus.exceptions], [`benchbus.sim`][benchbus.sim], "
        "`benchbus._recognise`"
    )
    # The exceptions are documented once, at benchbus's names, from anywhere.
    display = api["_display"]
    for scope in (api, api["exceptions"], display):
        text = reference.rewrite(scope, ":exc:`PortError`")
        assert text == "[`PortError`][benchbus.PortError]", scope.path
    assert "PortError" not in display.members  # found by its name alone


def test_the_public_modules_are_each_on_a_page() -> None:
    directives = {
        line.removeprefix(":::").strip()
        for page in (HOOKS.parent / "docs" / "reference").glob("*.md")
        for line in page.read_text("utf-8").splitlines()
        if line.startswith(":::")
    }
    assert set(griffe_benchbus.PUBLIC_MODULES) <= directives


def test_a_literal_block_that_is_not_indented_is_found() -> None:
    find = griffe_benchbus.unindented_literals
    assert find("An example::\n\n    bus.scan()\n") == []
    assert find("An example::\n\nbus.scan()\n") == [1]
    assert find("Text.\n\n    Nested::\n\n    same indent\n\nMore::\n") == [3, 7]
    assert find("Tight::\n        bus.scan()\nThe ``a::b`` form.\n") == []


def docstrings(module: types.ModuleType) -> Iterator[tuple[str, str]]:
    """The docstrings of ``module``'s public names and of their members, as Python keeps
    them (indentation after the first line removed)."""
    for name in module.__all__:
        obj = getattr(module, name)
        members = vars(obj).items() if inspect.isclass(obj) else ()
        for path, each in [(name, obj), *((f"{name}.{m}", v) for m, v in members)]:
            documented = inspect.isroutine(each) or inspect.isclass(each)
            doc = inspect.getdoc(each) if documented or isinstance(each, property) else None
            if doc:
                yield f"{module.__name__}.{path}", doc


def test_every_literal_block_of_the_docstrings_is_indented() -> None:
    found = [
        (path, line)
        for name in griffe_benchbus.PUBLIC_MODULES
        for path, doc in docstrings(importlib.import_module(name))
        for line in griffe_benchbus.unindented_literals(doc)
    ]
    assert found == []


def test_a_member_links_to_the_entry_of_the_class_being_documented(api: griffe.Module) -> None:
    """An inherited member is shown on each subclass's page: a role in a class's docstring
    (or in one of its own members') links to that class's entry of it."""
    reference = griffe_benchbus.Reference(api)
    pbl = griffe_benchbus._member(api, "PblDrive")
    device = griffe_benchbus._member(api, "sim.RegisterDevice")
    assert reference.rewrite(pbl, ":meth:`close`") == "[`close()`][benchbus.PblDrive.close]"
    assert reference.rewrite(device, ":attr:`max_read`") == (
        "[`max_read`][benchbus.sim.RegisterDevice.max_read]"
    )
    sim_device = griffe_benchbus._member(api, "sim.SimDevice")
    assert reference.rewrite(sim_device["read_holding"], ":attr:`max_read`") == (
        "[`max_read`][benchbus.sim.SimDevice.max_read]"
    )


THING = """
import enum

class Colour(enum.IntEnum):
    RED = 1
    _hidden = 2

class Plain:
    RED = 1

class Thing:
    #: Its size.
    size: int

    def __init__(self) -> None:
        self.size = 3
        #: Its name.
        self.name = "x"
        self.other = None
"""


def test_comments_and_enum_members_become_docstrings(api: griffe.Module) -> None:
    extensions = griffe.load_extensions(griffe_benchbus.BenchbusReference())
    with griffe.temporary_visited_module(THING, extensions=extensions) as module:
        for cls in ("Colour", "Plain"):
            griffe_benchbus._enum_members(module[cls])
        assert module["Colour.RED"].docstring.value == "Value: ``1``."
        assert module["Colour._hidden"].docstring is None
        assert module["Plain.RED"].docstring is None  # not an enum
        # The #: comment of an attribute assigned again in __init__ is kept.
        assert module["Thing.size"].docstring.value == "Its size."
        assert module["Thing.name"].docstring.value == "Its name."
        assert module["Thing.other"].docstring is None
    # benchbus's: an enum deriving from the package's own enum base, a str enum, and an
    # attribute declared with its comment and set in __init__.
    assert api["_drive.DriveState.FORWARD"].docstring.value == "Value: ``1``."
    assert api["_drive.Model.BLD2"].docstring.value == "Value: ``'BLD2'``."
    enums = api["_profile.Device.enums"].docstring
    assert enums.value == "Each enum register's enum class, by register name."


def test_every_public_member_has_a_docstring_for_the_reference(api: griffe.Module) -> None:
    """mkdocstrings shows no entry for a member without a docstring: each public member of
    each public class, as Python sees the class, has one as the reference reads it."""
    missing = []
    for name in griffe_benchbus.PUBLIC_MODULES:
        module = importlib.import_module(name)
        scope = griffe_benchbus._member(api, name.partition(".")[2]) if "." in name else api
        for export in module.__all__:
            cls = getattr(module, export)
            if not inspect.isclass(cls):
                continue
            for member in vars(cls):
                if member.startswith("_"):
                    continue
                found = griffe_benchbus._member(scope, f"{export}.{member}")
                if found is None or found.docstring is None or not found.docstring.value.strip():
                    missing.append(f"{name}.{export}.{member}")
    assert missing == []


def markdown_table_cells(markdown: str, row_start: str) -> list[str]:
    """The cells of the table row of ``markdown`` that starts with ``row_start``, as
    Python-Markdown (MkDocs's) renders them."""
    import markdown as md

    (row,) = [line for line in markdown.splitlines() if line.startswith(row_start)]
    table = "| a | b | c |\n| --- | --- | --- |\n" + row
    html = md.markdown(table, extensions=["tables"])
    return html.split("<td>")[1:]


def test_the_cli_reference_takes_what_argparse_allows(monkeypatch: pytest.MonkeyPatch) -> None:
    parser = argparse.ArgumentParser(prog="tool")
    parser.add_argument("--how", default=print, help="a function as default")
    parser.add_argument("--empty", default="", help="an empty default")
    parser.add_argument("--quote", default="a`b", help="a backtick in the default")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    remove = commands.add_parser("remove", aliases=["rm", "del"], description="Remove a thing.")
    remove.add_argument("mode", choices=["fast", "slow"], help="a positional with choices")
    remove.add_argument("what", help="a positional without metavar")
    remove.add_argument("count", nargs="?", type=int, default=5, help="may be left out")
    text = cli_reference.reference(parser)
    # A sub-command with aliases: one section, its aliases said in the list.
    assert text.count("## tool remove {#tool-remove}") == 1
    assert "- [`remove`](#tool-remove) (also `rm`, `del`): Remove a thing." in text
    assert "## tool {#tool}" in text
    # Positionals named as --help names them.
    assert "| `{fast,slow}` | a positional with choices |  |" in text
    assert "| `what` | a positional without metavar |  |" in text
    assert "| `count` | may be left out | `5` |" in text
    # Defaults: a function's repr (its address changes every run) left out, the empty
    # string shown as such, a backtick kept inside its code span.
    assert "| `--how HOW` | a function as default |  |" in text
    assert '| `--empty EMPTY` | an empty default | `""` |' in text
    quote = markdown_table_cells(text, "| `--quote")
    assert len(quote) == 3
    assert quote[2].startswith("<code>a`b</code>"), quote
    assert cli_reference.reference(parser) == text


def test_each_build_reads_the_parser_afresh(monkeypatch: pytest.MonkeyPatch) -> None:
    """``mkdocs serve`` rebuilds in one process: a change to a command's help is in the
    next build, not the help of the module imported for the first one."""
    import sys

    import benchbus
    import benchbus.cli.read

    names = [n for n in sys.modules if n == "benchbus.cli" or n.startswith("benchbus.cli.")]
    for name in names:  # put back afterwards, as the other tests imported them
        monkeypatch.setitem(sys.modules, name, sys.modules[name])
    monkeypatch.setattr(benchbus, "cli", sys.modules["benchbus.cli"])
    monkeypatch.setattr(benchbus.cli.read, "HELP", "help from before the sources changed")
    page = types.SimpleNamespace(file=types.SimpleNamespace(src_uri=cli_reference.PAGE))
    cli_reference.on_pre_build(config=None)
    text = cli_reference.on_page_markdown(cli_reference.MARKER, page=page)
    assert "benchbus read" in text
    assert "from before the sources changed" not in text
    assert sys.modules["benchbus.cli.read"].HELP not in ("help from before the sources changed",)
    for name in [n for n in sys.modules if n.startswith("benchbus.cli.") and n not in names]:
        monkeypatch.delitem(sys.modules, name)


def test_async_bus_members_have_parameters_of_their_own(api: griffe.Module) -> None:
    """AsyncBus's methods are made from the Bus's: the Bus keeps its own parameters."""
    bus = griffe_benchbus._member(api, "_core.Bus")
    async_bus = griffe_benchbus._member(api, "aio.AsyncBus")
    for owner, name in ((bus, "read_holding_registers"), (async_bus, "read_holding_registers")):
        method = owner.members[name]
        assert [p.name for p in method.parameters][:3] == ["self", "unit", "address"]
        assert all(p.function is method for p in method.parameters), owner.path
    # A compiled class's constructor, made from its __new__, which keeps its own too.
    new = bus.members["__new__"]
    assert all(p.function is new for p in new.parameters)


def test_an_exclamation_mark_suppresses_the_link(api: griffe.Module) -> None:
    reference = griffe_benchbus.Reference(api)
    assert reference.rewrite(api, ":meth:`!Bus.close`") == "`Bus.close()`"
    assert reference.rewrite(api, ":meth:`Bus.close`") == "[`Bus.close()`][benchbus.Bus.close]"


def test_every_async_bus_member_made_from_the_bus_is_documented(api: griffe.Module) -> None:
    """Each AsyncBus method that is a coroutine at run time is an async method in the
    reference, and each property a property, whatever their number."""
    from benchbus.aio import AsyncBus

    async_bus = griffe_benchbus._member(api, "aio.AsyncBus")
    coroutines = properties = 0
    for name in dir(AsyncBus):
        if name.startswith("_"):
            continue
        member = async_bus.all_members.get(name)
        assert member is not None, name
        value = inspect.getattr_static(AsyncBus, name)
        if inspect.iscoroutinefunction(getattr(AsyncBus, name)):
            coroutines += 1
            assert "async" in member.labels, name
        elif type(value).__name__ == "_BusProperty":
            properties += 1
            assert "property" in member.labels, name
            assert member.docstring is not None and member.docstring.value.strip(), name
    assert coroutines > 20 and properties > 3


def test_a_member_made_in_another_form_stops_the_build(tmp_path: Path) -> None:
    package = tmp_path / "benchbus"
    package.mkdir()
    (package / "__init__.py").write_text("")
    bus = "class Bus:\n    def scan(self) -> None:\n        '''Scan.'''\n"
    (package / "_core.py").write_text(bus)
    aio = "from benchbus._core import Bus\nclass AsyncBus:\n    scan = {}\n"
    (package / "aio.py").write_text(aio.format("_awaitable(Bus.scan)"))
    loaded = griffe.load("benchbus", search_paths=[str(tmp_path)])
    griffe_benchbus._async_bus(loaded)
    assert "async" in loaded["aio.AsyncBus.scan"].labels
    (package / "aio.py").write_text(aio.format("_awaitable(Bus.scan, timeout=1)"))
    loaded = griffe.load("benchbus", search_paths=[str(tmp_path)])
    with pytest.raises(RuntimeError, match=r"AsyncBus.scan = _awaitable\(Bus.scan, timeout=1\)"):
        griffe_benchbus._async_bus(loaded)


# ---- the shipped profiles' pages ---------------------------------------------------------------

profile_library = hook("profile_library")
LIBRARY = Path(__file__).resolve().parent.parent / "docs" / profile_library.FOLDER


def test_each_kind_of_shipped_profile_has_its_page_and_each_page_its_kind() -> None:
    kinds = {p.kind for p in profile_library.shipped().values()}
    pages = {
        m.group(1): page.name
        for page in LIBRARY.glob("*.md")
        for m in profile_library.MARKER.finditer(page.read_text("utf-8"))
    }
    assert set(pages) == kinds | {"all"}
    for kind in kinds:
        assert pages[kind] == profile_library.KINDS[kind][0]


def test_a_kinds_section_is_made_from_its_files() -> None:
    profiles = profile_library.shipped()
    for kind in {p.kind for p in profiles.values()}:
        text = profile_library.section(kind)
        for name, p in profiles.items():
            assert (f"## {name}\n" in text) == (p.kind == kind)
            if p.kind == kind:
                assert p.source in text and f'from_profile("{name}"' in text
                assert f"The {len(p)} registers" in text
                for r in p.registers:
                    assert f"| `{r.name}` | {r.table} | 0x{r.address:04X} |" in text
    listing = profile_library.section("all")
    for name, p in profiles.items():
        page, _ = profile_library.KINDS[p.kind]
        assert f"[`{name}`]({page}#{name})" in listing
    with pytest.raises(ValueError, match="no kind 'toaster'"):
        profile_library.section("toaster")
    with pytest.raises(ValueError, match="no shipped profile is of kind 'power-supply'"):
        profile_library.section("power-supply")
