"""The documentation site: built with ``mkdocs build --strict`` once per session, then checked
like code. Every public name has a docstring and an entry; the CLI reference covers the
whole argument parser; no page is blank; Debian's chromium renders pages with their
navigation and code blocks."""

from __future__ import annotations

import argparse
import contextlib
import functools
import html
import http.server
import importlib
import inspect
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
import types
import zlib
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

import benchbus
import benchbus.aio
from benchbus.cli import build_parser
from conftest import hook

ROOT = Path(__file__).resolve().parent.parent


#: The public modules: every name of their ``__all__`` has a docstring and a page. The
#: reference's own list, so that the two cannot differ.
PUBLIC_MODULES: tuple[str, ...] = hook("griffe_benchbus").PUBLIC_MODULES


#: How long one build may take: less than the tests' own timeout (pyproject's
#: ``[tool.pytest.ini_options] timeout``), so that a slow build fails here, with its output.
BUILD_TIMEOUT = 100


@dataclass
class Build:
    """One ``mkdocs build --strict``: its site directory, exit status, output and duration."""

    site: Path
    returncode: int
    output: str
    seconds: float


def once(factory: pytest.TempPathFactory, name: str, make: Callable[[Path], Build]) -> Build:
    """The build ``name``, made by ``make(folder)`` once for the whole run: under
    pytest-xdist the first worker to ask makes it while the others wait on a lock, then
    read its result (each build takes some 20 s of a core)."""
    import fcntl  # the site's tests run where chromium and mkdocs do: not on Windows

    root = factory.getbasetemp()
    if "PYTEST_XDIST_WORKER" in os.environ:
        root = root.parent  # the run's, shared by its workers
    folder, result = root / f"build-{name}", root / f"build-{name}.json"
    with (root / f"build-{name}.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if result.exists():
            made = json.loads(result.read_text("utf-8"))
            return Build(Path(made["site"]), made["returncode"], made["output"], made["seconds"])
        folder.mkdir(exist_ok=True)
        try:
            built = make(folder)
        except Exception as error:  # a build that timed out: failed once, for every worker
            built = Build(folder, -1, f"{type(error).__name__}: {error}", 0.0)
        fields = {**built.__dict__, "site": str(built.site)}
        partial = result.with_suffix(".partial")
        partial.write_text(json.dumps(fields), "utf-8")
        partial.replace(result)
        return built


def build_site(config: Path, site: Path) -> Build:
    """Build the site of ``config`` into ``site``, strictly, as ``make docs`` does."""
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT / "python"), env.get("PYTHONPATH")]))
    command = [sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(config)]
    start = time.monotonic()
    done = subprocess.run(
        [*command, "-d", str(site)],
        env=env,
        capture_output=True,
        text=True,
        timeout=BUILD_TIMEOUT,
        check=False,
    )
    seconds = time.monotonic() - start
    return Build(site, done.returncode, done.stdout + done.stderr, seconds)


@pytest.fixture(scope="session")
def site(tmp_path_factory: pytest.TempPathFactory) -> Build:
    """The site, built once for the run."""
    built = once(tmp_path_factory, "site", lambda f: build_site(ROOT / "mkdocs.yml", f / "site"))
    print(f"mkdocs build --strict: {built.seconds:.1f} s", file=sys.stderr)
    return built


def built(site: Build) -> Path:
    """The site directory, after checking that the build passed."""
    assert site.returncode == 0, f"mkdocs build --strict failed:\n{site.output}"
    return site.site


# ---- the strict build ----------------------------------------------------------------------------


def test_strict_build_passes_without_a_warning(site: Build) -> None:
    path = built(site)
    assert "WARNING" not in site.output, site.output
    # Material's notice about MkDocs 2 is silenced, so that a real warning stands out.
    assert "end of life" not in site.output, site.output
    assert (path / "index.html").is_file()
    assert (path / "objects.inv").is_file()


def test_a_build_times_out_before_the_test(request: pytest.FixtureRequest) -> None:
    assert 0 < BUILD_TIMEOUT < float(request.config.getini("timeout"))


def copy_of_the_docs(tmp_path: Path) -> Path:
    """A copy of the site's sources (docs/ copied, the rest linked), to break on purpose."""
    tmp_path.mkdir()
    for entry in ROOT.iterdir():  # whatever the pages include, by whatever path
        if entry.name not in {"docs", "mkdocs.yml", "site", ".venv", "target", ".git"}:
            (tmp_path / entry.name).symlink_to(entry)
    shutil.copy(ROOT / "mkdocs.yml", tmp_path)
    shutil.copytree(ROOT / "docs", tmp_path / "docs")
    return tmp_path


#: Links that do not resolve, each with what the build's complaint names.
BROKEN_LINKS = {
    "page": ("[a page](no-such-page.md)", "no-such-page.md"),
    "anchor": ("[an anchor](getting-started.md#no-such-anchor)", "no-such-anchor"),
    "api-object": ("[an object][benchbus.NoSuchName]", "benchbus.NoSuchName"),
}


@pytest.fixture(scope="module")
def broken(tmp_path_factory: pytest.TempPathFactory) -> Build:
    """One build of a copy whose home page has each of :data:`BROKEN_LINKS` and includes a
    file of the tree, and whose package's ``aio`` docstring names reStructuredText roles the
    reference does not link (a strict build reports every warning before it fails, and
    writes the pages: so one build shows them all)."""
    return once(tmp_path_factory, "broken", build_broken)


def build_broken(tmp_path: Path) -> Build:
    """The build of :func:`broken`, in ``tmp_path``."""
    copy = copy_of_the_docs(tmp_path / "src")
    index = copy / "docs" / "index.md"
    links = "".join(f"\nSee {link}.\n" for link, _ in BROKEN_LINKS.values())
    index.write_text(
        index.read_text("utf-8") + links + '\n```toml\n--8<-- "Cargo.toml"\n```\n', "utf-8"
    )
    (copy / "python").unlink()
    shutil.copytree(ROOT / "python" / "benchbus", copy / "python" / "benchbus")
    aio = copy / "python" / "benchbus" / "aio.py"
    source = aio.read_text("utf-8")
    marked = source.replace(
        '"""', '"""See :ref:`wiring` and :term:`slave`, and :class:`Bus`.\n\n', 1
    )
    assert marked != source
    aio.write_text(marked, "utf-8")
    return build_site(copy / "mkdocs.yml", tmp_path / "site")


def warnings_of(build: Build) -> list[str]:
    """The build's warning lines."""
    return [line for line in build.output.splitlines() if "WARNING" in line]


@pytest.mark.parametrize("kind", BROKEN_LINKS)
def test_a_broken_link_fails_the_build(broken: Build, kind: str) -> None:
    assert broken.returncode != 0, broken.output
    complaint = BROKEN_LINKS[kind][1]
    # Its own warning line, so that another link's cannot stand for it.
    assert any(complaint in line for line in warnings_of(broken)), broken.output


def test_the_copy_builds_with_a_file_of_the_tree_included(broken: Build) -> None:
    """The copy the tests above break has every file a page may include (a missing one
    would warn too), so that they fail for the break they make and no other reason: each
    warning is one of the breaks'."""
    complaints = [complaint for _, complaint in BROKEN_LINKS.values()]
    assert warnings_of(broken), broken.output
    for line in warnings_of(broken):
        assert any(complaint in line for complaint in complaints), broken.output
    assert "[package]" in (broken.site / "index.html").read_text("utf-8")


# ---- every public name: a docstring and an entry -------------------------------------------------


def read_inventory(path: Path) -> dict[str, str]:
    """A Sphinx inventory (version 2, as mkdocstrings writes objects.inv): name -> URI."""
    data = path.read_bytes()
    header = data.split(b"\n", 4)
    assert header[0] == b"# Sphinx inventory version 2", header[0]
    assert b"zlib" in header[3], header[3]
    entries = {}
    for line in zlib.decompress(header[4]).decode("utf-8").splitlines():
        match = re.fullmatch(r"(\S+)\s+\S+:\S+\s+-?\d+\s+(\S*)\s+.*", line)
        assert match, f"not an inventory line: {line!r}"
        name, uri = match.groups()
        entries[name] = uri[:-1] + name if uri.endswith("$") else uri
    return entries


def own_docstring(obj: Any) -> str | None:
    """The docstring ``obj`` has itself (a class's, not one inherited from a base)."""
    doc = vars(obj).get("__doc__") if inspect.isclass(obj) else getattr(obj, "__doc__", None)
    return doc if isinstance(doc, str) and doc.strip() else None


def entry_text(page: str, anchor: str) -> str:
    """The text of the documentation under the heading ``anchor`` of ``page`` (the object's
    own docstring, not its members')."""
    start = page.find(f'id="{anchor}"')
    if start < 0:
        return ""
    following = re.compile(r"<h[1-6][ >]").search(page, start)  # the next object's heading
    contents = page.find('class="doc doc-contents', start)
    if contents < 0 or (following and following.start() < contents):
        return ""
    contents = page.index(">", contents) + 1
    end = re.compile(r'<h[1-6][ >]|<div class="doc doc-children').search(page, contents)
    own = page[contents : end.start() if end else len(page)]
    own = re.sub(r'<p class="doc doc-class-bases">.*?</p>', " ", own, flags=re.S)  # not its doc
    text = re.sub(r"<[^>]+>", " ", own)
    return " ".join(html.unescape(text).split())


def undocumented(
    modules: Iterable[types.ModuleType], inventory: dict[str, str], site: Path
) -> list[str]:
    """What is wrong with the reference of ``modules``: a public name without a docstring,
    without an entry in the inventory, or whose entry's page lacks it."""
    problems = []
    pages: dict[Path, str] = {}
    for module in modules:
        for name in module.__all__:
            path = f"{module.__name__}.{name}"
            obj = getattr(module, name, None)
            if (inspect.isclass(obj) or inspect.isroutine(obj) or inspect.ismodule(obj)) and (
                own_docstring(obj) is None
            ):
                problems.append(f"{path}: no docstring")
            uri = inventory.get(path)
            if uri is None:
                problems.append(f"{path}: no entry in the site's objects.inv")
                continue
            file, _, anchor = uri.partition("#")
            page_path = (
                site / file / "index.html" if file.endswith("/") or not file else site / file
            )
            if not page_path.is_file():
                problems.append(f"{path}: its page {file} does not exist")
                continue
            page = pages.setdefault(page_path, page_path.read_text("utf-8"))
            if f'id="{anchor}"' not in page:
                problems.append(f"{path}: {file} has no #{anchor}")
            elif not inspect.ismodule(obj) and not entry_text(page, anchor):
                problems.append(f"{path}: its entry in {file} has no text (no docstring)")
    return problems


def public_modules() -> list[types.ModuleType]:
    return [importlib.import_module(name) for name in PUBLIC_MODULES]


def test_every_public_name_has_a_docstring_and_a_page(site: Build) -> None:
    path = built(site)
    inventory = read_inventory(path / "objects.inv")
    modules = public_modules()
    assert sum(len(m.__all__) for m in modules) > 100
    assert undocumented(modules, inventory, path) == []


def test_a_name_without_docstring_or_page_is_found(
    site: Build, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = built(site)
    inventory = read_inventory(path / "objects.inv")

    class Undocumented:
        pass

    def crc16(data: bytes) -> int:
        return 0

    import benchbus.sim

    monkeypatch.setattr(benchbus.sim, "Undocumented", Undocumented, raising=False)
    monkeypatch.setattr(benchbus.sim, "__all__", [*benchbus.sim.__all__, "Undocumented"])
    monkeypatch.setattr(benchbus, "crc16", crc16)  # documented, but now without a docstring
    problems = undocumented([benchbus, benchbus.sim], inventory, path)
    assert problems == [
        "benchbus.crc16: no docstring",
        "benchbus.sim.Undocumented: no docstring",
        "benchbus.sim.Undocumented: no entry in the site's objects.inv",
    ]
    # A data entry whose page shows no text for it is found too.
    page = path / inventory["benchbus.sim.FAULT_KINDS"].partition("#")[0] / "index.html"
    text = page.read_text("utf-8")
    assert entry_text(text, "benchbus.sim.FAULT_KINDS")
    assert not entry_text(text, "benchbus.sim.NoSuchAnchor")


def test_an_entry_without_text_is_found(site: Build, tmp_path: Path) -> None:
    """A class entry with no docstring is found, though it still says its bases."""
    path = built(site)
    inventory = read_inventory(path / "objects.inv")
    copy = tmp_path / "site"
    shutil.copytree(path, copy)
    aio = copy / "reference" / "aio" / "index.html"
    page = aio.read_text("utf-8")
    start = page.index('id="benchbus.aio.Drive"')
    bases = page.index('<p class="doc doc-class-bases">', start)
    docstring = page.index("</p>", bases) + len("</p>")
    children = page.index('<div class="doc doc-children', docstring)
    assert entry_text(page, "benchbus.aio.Drive").startswith("benchbus.Drive for asyncio")
    aio.write_text(page[:docstring] + page[children:], "utf-8")
    assert undocumented([benchbus.aio], inventory, copy) == [
        "benchbus.aio.Drive: its entry in reference/aio/ has no text (no docstring)"
    ]


#: Public members of public classes that have no entry of their own, on purpose: each with
#: why. ``module.Class.member``; ``*`` stands for any class of the module.
UNLISTED_MEMBERS = {
    # The synchronous class each asyncio device wraps: the machinery of benchbus.aio (one
    # line in aio.Device's docstring says what it is), not something to call.
    "benchbus.aio.*.SYNC",
}


def unlisted_members(modules: Iterable[types.ModuleType], inventory: dict[str, str]) -> list[str]:
    """Each public entry of ``vars(cls)`` of each public class of ``modules`` (enum members,
    class attributes, methods, properties) without an entry in the inventory, except those
    of :data:`UNLISTED_MEMBERS`."""
    missing = []
    for module in modules:
        for name in module.__all__:
            cls = getattr(module, name, None)
            if not inspect.isclass(cls):
                continue
            for member in vars(cls):
                path = f"{module.__name__}.{name}.{member}"
                allowed = {path, f"{module.__name__}.*.{member}"} & UNLISTED_MEMBERS
                if not member.startswith("_") and not allowed and path not in inventory:
                    missing.append(path)
    return missing


def test_every_public_member_has_an_entry(site: Build) -> None:
    inventory = read_inventory(built(site) / "objects.inv")
    assert unlisted_members(public_modules(), inventory) == []


def test_a_member_without_an_entry_is_found(site: Build, monkeypatch: pytest.MonkeyPatch) -> None:
    inventory = read_inventory(built(site) / "objects.inv")
    import benchbus.aio

    monkeypatch.setattr(benchbus.Drive, "BRAND_NEW", 2, raising=False)
    monkeypatch.setattr(benchbus.aio.Drive, "brand_new", lambda self: 3, raising=False)
    found = unlisted_members([benchbus, benchbus.aio], inventory)
    assert "benchbus.Drive.BRAND_NEW" in found
    assert "benchbus.aio.Drive.brand_new" in found
    assert "SYNC" in vars(benchbus.aio.Drive)  # allowed, so not listed
    assert not [path for path in found if path.endswith(".SYNC")]
    # Documented members are not listed (the compiled Bus's, a drive's properties).
    assert not [path for path in found if path.startswith(("benchbus.Bus.", "benchbus.Drive.s"))]


def test_async_bus_methods_are_documented_from_the_bus(site: Build) -> None:
    """AsyncBus makes its methods from the Bus's at import time: each has its entry, marked
    async, with the Bus method's parameters and docstring."""
    path = built(site)
    inventory = read_inventory(path / "objects.inv")
    page = (path / "reference" / "aio" / "index.html").read_text("utf-8")
    bus_page = (path / "reference" / "benchbus" / "index.html").read_text("utf-8")
    for name in ("read_holding_registers", "write_register", "scan", "reopen"):
        assert f"benchbus.aio.AsyncBus.{name}" in inventory
        # The compiled Bus's method, from its stubs; the AsyncBus's says the same.
        text = entry_text(bus_page, f"benchbus.Bus.{name}")
        assert text
        assert entry_text(page, f"benchbus.aio.AsyncBus.{name}") == text
        start = page.find(f'id="benchbus.aio.AsyncBus.{name}"')
        heading = page[start : page.find("</h", start)]
        assert "async" in heading
    # The Bus method's parameters, in the signature under the heading.
    start = page.find('id="benchbus.aio.AsyncBus.read_holding_registers"')
    signature = page[start : page.find("doc-contents", start)]
    parameters = list(inspect.signature(benchbus.Bus.read_holding_registers).parameters)
    assert parameters[0] == "self"
    for parameter in parameters[1:]:
        assert f">{parameter}<" in signature, parameter
    # The properties read through to the Bus's, and a drive's register-backed properties.
    assert "benchbus.aio.AsyncBus.port" in inventory
    assert entry_text(page, "benchbus.aio.AsyncBus.port")
    assert "benchbus.Drive.speed_setpoint" in inventory
    # A compiled class's constructor (its stub's __new__) is the class's signature.
    start = bus_page.find('id="benchbus.Bus"')
    signature = bus_page[start : bus_page.find("doc-contents", start)]
    for parameter in inspect.signature(benchbus.Bus).parameters:
        assert f">{parameter}<" in signature, parameter


#: A reStructuredText role left in a page, as written (":ref:`x`") or as Markdown renders
#: its backticks (":ref:<code>x</code>").
LEFTOVER_ROLE = re.compile(r":[a-z]+(?::[a-z]+)*:(?:`|<code>)")


def leftover_roles(site: Path) -> list[str]:
    """Each reStructuredText role left in the pages of ``site``: ``page: role``."""
    found = []
    for page in sorted(site.rglob("*.html")):
        text = page.read_text("utf-8")
        found += [f"{page.relative_to(site)}: {m.group(0)}" for m in LEFTOVER_ROLE.finditer(text)]
    return found


def test_no_rest_roles_are_left_and_they_link(site: Build) -> None:
    path = built(site)
    assert leftover_roles(path) == []
    aio = (path / "reference" / "aio" / "index.html").read_text("utf-8")
    # ":class:`benchbus.Bus`" in benchbus.aio's docstring: a link to the Bus's entry.
    assert 'href="../benchbus/#benchbus.Bus"' in aio


def test_a_leftover_role_is_found(broken: Build) -> None:
    """Roles the reference does not turn into links (``:ref:``, ``:term:``) in a docstring are
    found, as Markdown renders them and as written."""
    left = [entry.partition(": ")[2] for entry in leftover_roles(broken.site)]
    assert left == [":ref:<code>", ":term:<code>"]
    assert LEFTOVER_ROLE.search("a :py:any:`Bus` as written")


# ---- the CLI reference ---------------------------------------------------------------------------


def parsers(parser: argparse.ArgumentParser) -> Iterator[argparse.ArgumentParser]:
    """``parser`` and every sub-command's parser under it."""
    yield parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                yield from parsers(sub)


def flat(text: str) -> str:
    """``text`` with its whitespace runs made single spaces."""
    return " ".join(text.split())


def cli_problems(page: str, root: argparse.ArgumentParser) -> tuple[list[str], int]:
    """What the CLI reference ``page`` (HTML) lacks of ``root`` and its sub-commands: each
    command's heading, its usage (in full, whitespace aside), description, every option (as
    a whole word in the Argument column) and the start of every help; and how many commands
    it checked."""
    problems = []
    if "\x1b" in page:
        problems.append("terminal escape codes (colours) in the page")
    following = re.compile(r'<h[2-6] id="benchbus-')
    count = 0
    for parser in parsers(root):
        if hasattr(parser, "color"):  # Python 3.14 colours --help on a terminal
            parser.color = False
        start = page.find(f'id="{parser.prog.replace(" ", "-")}"')
        if start < 0:
            problems.append(f"{parser.prog}: no heading")
            continue
        count += 1
        match = following.search(page, start + 1)
        raw = page[start : match.start() if match else len(page)]
        text = flat(html.unescape(re.sub(r"<[^>]+>", "", raw)))
        if flat(parser.format_usage()) not in text:
            problems.append(f"{parser.prog}: usage differs from {flat(parser.format_usage())!r}")
        if parser.description and flat(parser.description) not in text:
            problems.append(f"{parser.prog}: no description")
        for action in parser._actions:
            if action.help == argparse.SUPPRESS or isinstance(action, argparse._SubParsersAction):
                continue
            for option in action.option_strings:
                if not re.search(f"<code>{re.escape(html.escape(option))}[ <]", raw):
                    problems.append(f"{parser.prog}: {option} missing")
            if action.help:
                first = " ".join(action.help.split("%")[0].split()[:4])
                if first not in text:
                    problems.append(f"{parser.prog}: help {first!r} missing")
    return problems, count


def test_the_cli_reference_has_every_command_and_option(site: Build) -> None:
    page = (built(site) / "reference" / "cli" / "index.html").read_text("utf-8")
    problems, count = cli_problems(page, build_parser())
    assert problems == []
    assert count > 20  # the commands and the sub-commands of drive, pbl, j2, profile


def test_a_wrong_cli_reference_is_found(site: Build) -> None:
    """A usage that differs in one word, colours from a terminal, an option whose short form
    is missing (though it is a substring of the long one, and in the usage) are found."""
    page = (built(site) / "reference" / "cli" / "index.html").read_text("utf-8")
    read = page.index('id="benchbus-read"')
    head, tail = page[:read], page[read:]

    def problems(broken_tail: str) -> list[str]:
        assert broken_tail != tail
        return cli_problems(head + broken_tail, build_parser())[0]

    usage = "usage: benchbus read [-h] [-v]"
    (wrong,) = problems(tail.replace(usage, usage.replace("[-v]", "[-V]"), 1))
    assert wrong.startswith("benchbus read: usage differs"), wrong
    coloured = tail.replace(usage, usage.replace("benchbus read", "\x1b[1;35mbenchbus read\x1b[0m"))
    assert problems(coloured) == [
        "terminal escape codes (colours) in the page",
        wrong,
    ]
    assert problems(
        tail.replace("<td><code>-h</code>, <code>--help</code>", "<td><code>--help</code>", 1)
    ) == ["benchbus read: -h missing"]


def test_the_cli_reference_follows_the_parser(monkeypatch: pytest.MonkeyPatch) -> None:
    """An option added to the parser is in the next build's page."""
    cli_reference = hook("cli_reference")

    def with_new_option() -> argparse.ArgumentParser:
        parser = build_parser()
        (read,) = [p for p in parsers(parser) if p.prog == "benchbus read"]
        read.add_argument("--brand-new", metavar="X", help="an option made a moment ago")
        return parser

    page = types.SimpleNamespace(file=types.SimpleNamespace(src_uri=cli_reference.PAGE))
    markdown = f"# Command line\n\n{cli_reference.MARKER}\n"
    before = cli_reference.on_page_markdown(markdown, page=page)
    assert "--brand-new" not in before
    monkeypatch.setattr("benchbus.cli.build_parser", with_new_option)
    after = cli_reference.on_page_markdown(markdown, page=page)
    assert "`--brand-new X` | an option made a moment ago |" in after
    with pytest.raises(ValueError, match="marker"):
        cli_reference.on_page_markdown("# Command line\n", page=page)


# ---- no blank page -------------------------------------------------------------------------------


def main_text(page: str) -> str:
    """The text of a page's main content (Material's article), its title and permalinks
    left out."""
    match = re.search(r'<article class="md-content__inner md-typeset">(.*?)</article>', page, re.S)
    if match is None:
        return ""
    content = re.sub(r"<h1.*?</h1>", " ", match.group(1), flags=re.S)
    content = re.sub(r"<[^>]+>", " ", content)
    return " ".join(html.unescape(content).replace("¶", " ").split())


def test_no_page_is_blank(site: Build) -> None:
    path = built(site)
    pages = sorted(set(path.rglob("*.html")) - {path / "404.html"})  # a title, by design
    assert len(pages) > 20
    blank = [str(p.relative_to(path)) for p in pages if len(main_text(p.read_text("utf-8"))) < 80]
    assert blank == [], f"pages without content: {blank}"


def test_a_blank_page_is_found() -> None:
    title_only = '<article class="md-content__inner md-typeset"><h1 id="x">Drives</h1></article>'
    assert main_text(title_only) == ""
    assert main_text("<html><body>no article</body></html>") == ""
    assert main_text(title_only.replace("</h1>", "</h1><p>Some text.</p>")) == "Some text."


# ---- chromium ------------------------------------------------------------------------------------


def chromium() -> str:
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    pytest.fail(
        "chromium is not installed: `make test` installs it (.ci/need.sh), "
        "or run `apt-get install chromium` (Debian's package)"
    )


@contextlib.contextmanager
def serving(directory: Path) -> Iterator[str]:
    """``directory`` served over HTTP on loopback, from a thread: its base URL."""

    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, format: str, *args: Any) -> None:
            pass

    handler = functools.partial(Quiet, directory=str(directory))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()
        thread.join(5)


def dump_dom(url: str, profile: Path, timeout: float = 20, *, settle: bool = True) -> str:
    """The DOM of ``url`` once headless chromium has rendered it (scripts run). chromium and
    every process it starts run in a process group of their own, killed afterwards. A
    chromium that hangs with nothing rendered (seen now and then beside the other tests'
    builds, the same page rendering in seconds the next time; a page here renders in about
    2 s, 5 s on a loaded machine) is started once more after half of ``timeout``, with a
    fresh profile, and given all of it; a second hang fails. ``settle``: the DOM once the
    page's timers have had 5 s of virtual time, not at its load event."""
    out, hung = _dump_dom_once(url, profile, timeout / 2, settle)
    if hung:
        again = profile.with_name(profile.name + "-again")
        out, hung = _dump_dom_once(url, again, timeout, settle)
    assert not hung, f"chromium failed on {url}: chromium took more than {timeout} s, twice"
    return out


def _dump_dom_once(url: str, profile: Path, timeout: float, settle: bool) -> tuple[str, bool]:
    """One run of :func:`dump_dom`: the DOM, and whether chromium hung with nothing
    rendered (the checks of processes left behind and of a failure made all the same, but
    for a hang, which the caller may try once more)."""
    command = [chromium(), "--headless", "--disable-gpu", "--no-first-run"]
    # No sandbox, whoever runs it: chromium refuses its sandbox as root, and where AppArmor
    # forbids unprivileged user namespaces (Ubuntu 24.04, as GitHub's runners) it finds "No
    # usable sandbox!". The page is the site just built, served from loopback.
    command += ["--no-sandbox", "--no-default-browser-check", f"--user-data-dir={profile}"]
    # Only loopback resolves: a font or script from another host fails at once, where a
    # firewall that drops packets would hold the page until the timeout.
    command += ["--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1"]
    command += ["--virtual-time-budget=5000"] if settle else []
    command += ["--dump-dom", url]
    process = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    hung = False
    try:
        out, err = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        out, err, hung = "", f"chromium took more than {timeout} s", True
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    # No chromium process is left: none of its session (whose id is its first process's).
    deadline = time.monotonic() + 5
    while (left := session_processes(process.pid)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert left == [], f"chromium processes left behind: {left}"
    if hung:
        return out, True
    assert process.returncode == 0 or out, f"chromium failed on {url}: {err[-2000:]}"
    return out, False


def session_processes(session: int) -> list[int]:
    """The live (not zombie) processes of the session ``session``."""
    found = []
    for entry in filter(str.isdigit, os.listdir("/proc")):
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:  # gone meanwhile
            continue
        # "pid (name) state ppid pgrp session ...", the name possibly holding ") ".
        state, _ppid, _pgrp, sid = stat[stat.rindex(")") + 2 :].split()[:4]
        if int(sid) == session and state != "Z":
            found.append(int(entry))
    return found


def test_the_processes_of_a_session_are_found() -> None:
    """The leftover check sees the processes of chromium's session, and no other."""
    process = subprocess.Popen(["sleep", "30"], start_new_session=True)
    try:
        assert session_processes(process.pid) == [process.pid]
        assert os.getpid() not in session_processes(process.pid)
        assert process.pid not in session_processes(os.getsid(0))
    finally:
        process.kill()
        process.wait()
    assert session_processes(process.pid) == []


@pytest.mark.timeout(240)
@pytest.mark.parametrize(
    ("page", "title"),
    [("", "benchbus"), ("reference/aio/", "benchbus.aio - benchbus")],
    ids=["home", "api"],
)
def test_chromium_renders_the_page(site: Build, tmp_path: Path, page: str, title: str) -> None:
    path = built(site)
    with serving(path) as base:
        dom = dump_dom(base + page, tmp_path / "profile")
    assert re.search(r"<title>\s*" + re.escape(title) + r"\s*</title>", dom), dom[:2000]
    nav = re.search(r'<nav class="md-nav md-nav--primary".*?</nav>\s*</div>\s*</div>', dom, re.S)
    assert nav, "no Material navigation in the rendered page"
    for entry in ("Getting started", "Concepts", "Command line", "benchbus.sim", "Changelog"):
        assert entry in nav.group(0), f"navigation lacks {entry!r}"
    codes = re.findall(r"<pre[^>]*>.*?<code[^>]*>(.*?)</code>", dom, re.S)
    texts = [html.unescape(re.sub(r"<[^>]+>", "", code)).strip() for code in codes]
    assert any(texts), "no code block with content"
    # Material's scripts ran (its bundle marks the document).
    assert re.search(r'<html[^>]*class="[^"]*js-focus-visible', dom), dom[:300]


#: Pages with long code lines: the home page's ``make demo`` comment, the profile file's
#: ``[line]`` comment, and the API reference's docstring examples and signatures.
WIDE_PAGES = ("index.html", "devices/profiles/index.html", "reference/benchbus/index.html")

#: A page that loads each of ``WIDE_PAGES`` in a frame as wide as a laptop's browser window
#: and writes, as JSON, how many code blocks each has, the longest line of each block whose
#: text is wider than the block (cut off, or scrolled sideways), and by how many pixels the
#: page itself is wider than its window.
PROBE = """<!doctype html>
<html><body>
<iframe id="frame" style="width: 1000px; height: 800px"></iframe>
<pre id="result">pending</pre>
<script>
const pages = PAGES;
const found = {};
const frame = document.getElementById("frame");
function next(i) {
  if (i === pages.length) {
    document.getElementById("result").textContent = JSON.stringify(found);
    return;
  }
  frame.onload = () => {
    const doc = frame.contentDocument;
    const blocks = [...doc.querySelectorAll(".md-content pre > code")];
    const longest = (c) =>
      c.textContent.split("\\n").reduce((a, b) => (b.length > a.length ? b : a), "");
    found[pages[i]] = {
      blocks: blocks.length,
      overflowing: blocks.filter((c) => c.scrollWidth > c.clientWidth + 1).map(longest),
      page: doc.documentElement.scrollWidth - doc.documentElement.clientWidth,
    };
    next(i + 1);
  };
  frame.src = "site/" + pages[i];
}
next(0);
</script>
</body></html>
"""


@pytest.mark.timeout(240)
def test_long_code_lines_stay_within_the_page(site: Build, tmp_path: Path) -> None:
    root = tmp_path / "root"
    root.mkdir()
    (root / "site").symlink_to(built(site))
    (root / "probe.html").write_text(PROBE.replace("PAGES", json.dumps(list(WIDE_PAGES))))
    with serving(root) as base:
        # The probe writes its result as its frame loads each page, which holds the
        # probe's own load event, when the DOM is taken: no virtual time is needed, and
        # with it one run in seven hung with four chromiums at once (none in forty without).
        dom = dump_dom(base + "probe.html", tmp_path / "profile", settle=False)
    result = re.search(r'<pre id="result">(.*?)</pre>', dom, re.S)
    assert result, dom[:2000]
    found = json.loads(html.unescape(result.group(1)))
    assert set(found) == set(WIDE_PAGES), found
    for page, seen in found.items():
        assert seen["blocks"] > 0, f"{page}: no code block measured"
        assert seen["overflowing"] == [], f"{page}: code lines wider than their block"
        assert seen["page"] <= 0, f"{page}: the page is {seen['page']} px wider than its window"


#: A code block of a docstring as the reference renders it (signatures are apart:
#: ``doc-signature highlight``).
DOCSTRING_CODE = re.compile(r'<div class="highlight"><pre><span></span><code>(.*?)</code>', re.S)


def test_docstring_code_blocks_are_highlighted(site: Build) -> None:
    path = built(site)
    page = (path / "reference/benchbus/index.html").read_text()
    # The package docstring's example (a reStructuredText literal block after ``::``).
    first = DOCSTRING_CODE.search(page)
    assert first, "no code block in the API reference"
    assert '<span class="kn">import</span>' in first.group(1), first.group(1)[:300]
    # Every page's: all but the few that are not Python (a diagram, the exception tree).
    for name in ("benchbus", "aio", "sim", "integrations"):
        codes = DOCSTRING_CODE.findall((path / f"reference/{name}/index.html").read_text())
        plain = [html.unescape(c)[:60] for c in codes if '<span class="' not in c]
        assert codes and len(plain) <= 2, f"reference/{name}: not highlighted: {plain}"


def test_a_literal_block_becomes_a_fenced_block_in_its_language() -> None:
    fence = hook("griffe_benchbus").fence_literals
    doc = "Use it::\n\n    import benchbus as bb\n    bb.Bus(port)\n\nThen::\n\n    a -> b\n"
    assert fence(doc) == (
        "Use it:\n\n```python\nimport benchbus as bb\nbb.Bus(port)\n```\n\n"
        "Then:\n\n```text\na -> b\n```\n"
    )
    assert fence(
        "Async::\n\n    async with bb.aio.AsyncBus(p) as bus:\n        await bus.scan()\n"
    ) == ("Async:\n\n```python\nasync with bb.aio.AsyncBus(p) as bus:\n    await bus.scan()\n```\n")
    assert fence("Not a block::\nsame indent\n") == "Not a block:\nsame indent\n"
