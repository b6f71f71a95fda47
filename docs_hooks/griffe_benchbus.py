"""A griffe extension for the API reference of the documentation site.

griffe reads benchbus without importing it. Three things it cannot see that way:

- the members ``benchbus.aio.AsyncBus`` makes at import time from the Bus's
  (``read_coils = _awaitable(Bus.read_coils)``, ``port = _BusProperty(Bus.port)``): they are
  given the Bus member's signature and docstring here, the methods marked async, as Python's
  own ``help()`` shows them;
- the families' async classes ``benchbus.aio`` makes at import time from the registry
  (``bb.aio.Drive``...): their declarations in ``_aio_members.pyi``, exported by ``aio``;
- the docstrings' reStructuredText: the inline roles (``:class:`Bus```, ``:meth:``, ``:func:``,
  ``:attr:``, ``:data:``, ``:exc:``, ``:mod:``) become cross-references to the page that
  documents their target (``[Bus][benchbus.Bus]``), or code where the target has no page; a
  paragraph ending in ``::`` before its literal block ends in ``:`` as it reads in Sphinx,
  and the literal block becomes a fenced one, ``python`` (highlighted as the site's own
  code blocks are) when it parses as Python, ``text`` otherwise (a diagram, a table).
"""

from __future__ import annotations

import ast
import re
import textwrap
from collections.abc import Iterable, Iterator
from typing import Any

import griffe

#: The public modules: the reference documents each (``:mod:`` links to it) and every name
#: of its ``__all__``, at ``module.name``.
PUBLIC_MODULES = (
    "benchbus",
    "benchbus.aio",
    "benchbus.sim",
    "benchbus.qcodes",
    "benchbus.ophyd",
    "benchbus.exceptions",
    "benchbus.pytest_plugin",
)

ROLE = re.compile(r":(?:py:)?(class|meth|func|attr|data|exc|mod|obj|const):`([^`]+)`")
LITERAL_INTRO = re.compile(r"(?m)^([ \t]*)(.*?)[ \t]*::[ \t]*$")
AWAITABLE = re.compile(r"^_awaitable\(Bus\.(\w+)\)$")
BUS_PROPERTY = re.compile(r"^_(?:Settable)?BusProperty\(Bus\.(\w+)\)$")


def _target(obj: griffe.Object | griffe.Alias) -> griffe.Object | None:
    """The object an alias finally points to (None if it leaves the package)."""
    try:
        return obj.final_target if obj.is_alias else obj  # type: ignore[union-attr,return-value]
    except (griffe.AliasResolutionError, griffe.CyclicAliasError):
        return None


def _member(scope: griffe.Object, dotted: str) -> griffe.Object | None:
    """``dotted`` looked up from ``scope`` (inherited members included), or None."""
    obj: griffe.Object | None = scope
    for part in dotted.split("."):
        if obj is None:
            return None
        try:
            found = obj.all_members.get(part) if obj.is_class else obj.members.get(part)
        except (griffe.AliasResolutionError, griffe.CyclicAliasError):
            found = obj.members.get(part)
        obj = _target(found) if found is not None else None
    return obj


def _copy_docstring(source: griffe.Object, parent: griffe.Object) -> griffe.Docstring | None:
    """A copy of ``source``'s docstring for ``parent`` (None if it has none)."""
    doc = source.docstring
    if doc is None:
        return None
    return griffe.Docstring(
        doc.value,
        lineno=doc.lineno,
        endlineno=doc.endlineno,
        parent=parent,
        parser=doc.parser,
        parser_options=doc.parser_options,
    )


def _copy_parameters(parameters: Iterable[griffe.Parameter]) -> list[griffe.Parameter]:
    """Copies of ``parameters`` for another function: griffe points each parameter at the
    function given it, so sharing them would move the source's to the copy."""
    return [
        griffe.Parameter(
            p.name, annotation=p.annotation, kind=p.kind, default=p.default, docstring=p.docstring
        )
        for p in parameters
    ]


def _bus_member(source: griffe.Object, attr: griffe.Attribute, is_async: bool) -> griffe.Object:
    """An AsyncBus member standing for the Bus's ``source``."""
    new: griffe.Object
    if isinstance(source, griffe.Function):
        new = griffe.Function(
            attr.name,
            lineno=attr.lineno,
            endlineno=attr.endlineno,
            parameters=griffe.Parameters(*_copy_parameters(source.parameters)),
            returns=source.returns,
        )
    else:
        annotation = getattr(source, "annotation", None)
        new = griffe.Attribute(
            attr.name, lineno=attr.lineno, endlineno=attr.endlineno, annotation=annotation
        )
    labels = set(source.labels)
    if is_async:
        labels -= {"method descriptor"}
        labels.add("async")
    else:  # read through: never set, never deleted
        labels -= {"writable", "deletable"}
        labels.add("property")
    new.labels = labels
    new.docstring = _copy_docstring(source, new)
    return new


def _async_bus(pkg: griffe.Module) -> None:
    """Give AsyncBus the members it copies from the Bus at import time."""
    bus = _member(pkg, "_core.Bus")
    async_bus = _member(pkg, "aio.AsyncBus")
    if bus is None or async_bus is None:
        raise RuntimeError("benchbus._core.Bus or benchbus.aio.AsyncBus not found")
    for name, member in list(async_bus.members.items()):
        if not isinstance(member, griffe.Attribute) or member.value is None:
            continue
        value = str(member.value)
        match = AWAITABLE.match(value) or BUS_PROPERTY.match(value)
        if match is None:
            if re.search(r"\b(_awaitable|_BusProperty|_SettableBusProperty)\b", value):
                raise RuntimeError(
                    f"AsyncBus.{name} = {value}: made from the Bus in a form this extension"
                    " does not read (it reads `_awaitable(Bus.name)`, `_BusProperty(Bus.name)`,"
                    " `_SettableBusProperty(Bus.name)`)"
                )
            continue
        found = bus.members.get(match.group(1))
        source = _target(found) if found is not None else None
        if source is None:
            raise RuntimeError(f"AsyncBus.{name}: benchbus.Bus has no {match.group(1)}")
        new = _bus_member(source, member, is_async=value.startswith("_awaitable"))
        del async_bus.members[name]
        async_bus.set_member(name, new)


def _async_families(pkg: griffe.Module) -> None:
    """Give ``benchbus.aio`` the families' async classes it makes at import time from the
    registry: ``_aio_members.pyi`` declares them, and exports them for ``aio`` to export."""
    aio, members = _member(pkg, "aio"), _member(pkg, "_aio_members")
    if not isinstance(aio, griffe.Module) or not isinstance(members, griffe.Module):
        raise RuntimeError("benchbus.aio or benchbus._aio_members not found")
    if not members.exports:
        raise RuntimeError("benchbus._aio_members exports nothing")
    for export in members.exports:
        name = str(export)
        if name not in members.members:
            raise RuntimeError(f"benchbus._aio_members exports {name}, which it does not declare")
        aio.set_member(name, griffe.Alias(name, f"{members.path}.{name}", parent=aio))
        aio.exports = [*(aio.exports or ()), name]


def _constructor(cls: griffe.Class) -> None:
    """A compiled class is made by ``__new__`` (its stub says so): give it an ``__init__``
    with that signature and docstring, which the class's entry shows as its constructor."""
    new = cls.members.get("__new__")
    if "__init__" in cls.all_members or not isinstance(new, griffe.Function):
        return
    first, *parameters = list(new.parameters)  # cls, then the constructor's own
    init = griffe.Function(
        "__init__",
        lineno=new.lineno,
        endlineno=new.endlineno,
        parameters=griffe.Parameters(
            griffe.Parameter("self", kind=first.kind),
            *_copy_parameters(parameters),
        ),
        returns="None",
    )
    init.docstring = _copy_docstring(new, init)
    cls.set_member("__init__", init)


class Reference:
    """Where each object of the package is documented: its public path."""

    def __init__(self, pkg: griffe.Module) -> None:
        self.pkg = pkg
        self.public: dict[str, str] = {}  # canonical path -> (first) documented path
        self.documented: set[str] = set()  # every documented path, inherited members too
        for module_path in PUBLIC_MODULES:
            module = _member(pkg, module_path.partition(".")[2]) if "." in module_path else pkg
            if module is None:
                raise RuntimeError(f"{module_path} not found")
            for export in module.exports or ():
                name = str(export)
                obj = _member(module, name)
                if obj is not None:
                    self._add(obj, f"{module_path}.{name}")

    def _add(self, obj: griffe.Object, path: str) -> None:
        if obj.path in self.public:  # documented under an earlier module's name
            return
        self.public[obj.path] = path
        self.documented.add(path)
        if obj.is_class:
            # The members the page shows: public, with a docstring, inherited ones too.
            for name, member in obj.all_members.items():
                target = _target(member)
                if name.startswith("_") or target is None or target.is_class:
                    continue
                if target.docstring is not None and target.docstring.value.strip():
                    self.public.setdefault(target.path, f"{path}.{name}")
                    self.documented.add(f"{path}.{name}")

    def find(self, scope: griffe.Object, target: str) -> str | None:
        """The documented path of ``target`` as written in ``scope``'s docstring, or None."""
        target = target.lstrip(".")
        if target.startswith("benchbus."):
            obj = _member(self.pkg, target.partition(".")[2])
            if obj is not None:
                return self.public.get(obj.path)
        obj = None
        current: griffe.Object | None = scope
        while current is not None and obj is None:
            # A member of the class being documented: its entry on that class's page, not
            # the entry of the first class that shows the same (inherited) member.
            here = self.public.get(current.path) if current.is_class else None
            if here is not None and f"{here}.{target}" in self.documented:
                return f"{here}.{target}"
            obj = _member(current, target)
            current = current.parent
        if obj is not None and obj.path in self.public:
            return self.public[obj.path]
        # A name its module does not import (a stub speaking of another module's class).
        suffix = "." + target
        found = {p for p in self.public.values() if p.endswith(suffix)}
        return found.pop() if len(found) == 1 else None

    def rewrite(self, scope: griffe.Object, text: str) -> str:
        """``text``, a docstring of ``scope``, with its roles as links to the entries of
        their targets (code where there is none, or where the target starts with ``!``) and
        its ``::`` as ``:`` before a fenced literal block (see :func:`fence_literals`)."""

        def role(match: re.Match[str]) -> str:
            kind, content = match.groups()
            title = None
            explicit = re.fullmatch(r"(.*?)\s*<(.+)>", content)
            if explicit:
                title, content = explicit.groups()
            unlinked = content.startswith("!")  # Sphinx's way to say: no link
            content = content.lstrip("!")
            short = content.startswith("~")
            content = content.lstrip("~")
            bare = content.removesuffix("()")
            if title is None:
                title = bare.rpartition(".")[2] if short else bare
                if kind in ("meth", "func") and not title.endswith("()"):
                    title += "()"
            if unlinked:
                path = None
            elif kind == "mod":  # a module's entry is at its name; a private one has none
                path = bare if bare in PUBLIC_MODULES else None
            else:
                path = self.find(scope, bare)
            code = f"`{title}`"
            return f"[{code}][{path}]" if path else code

        text = ROLE.sub(role, text)
        return fence_literals(text)


def fence_literals(text: str) -> str:
    """``text`` with each reStructuredText literal block (the lines indented under a line
    ending in ``::``) as a fenced code block at the introducing line's indent, in the
    language :func:`literal_language` finds, and its ``::`` as ``:`` (a ``::`` alone on its
    line goes). Markdown would make the block an indented code block, which the site's
    highlighter leaves plain."""
    lines = text.splitlines()
    out: list[str] = []
    i = 0
    while i < len(lines):
        match = LITERAL_INTRO.fullmatch(lines[i])
        if match is None:
            out.append(lines[i])
            i += 1
            continue
        indent = _indent(lines[i])
        out.append(_literal_intro(match))
        i += 1
        gap = i
        while i < len(lines) and not lines[i].strip():
            i += 1
        start = i
        while i < len(lines) and (not lines[i].strip() or _indent(lines[i]) > indent):
            i += 1
        end = i
        while end > start and not lines[end - 1].strip():
            end -= 1
        out.extend(lines[gap:start])
        if end == start:  # no literal block follows: a paragraph
            continue
        code = textwrap.dedent("\n".join(lines[start:end]))
        pad = " " * indent
        if out and out[-1].strip():  # a fence stands apart from the paragraph before it
            out.append("")
        out.append(f"{pad}```{literal_language(code)}")
        out.extend(pad + line if line.strip() else "" for line in code.splitlines())
        out.append(f"{pad}```")
        out.extend(lines[end:i])
        if i < len(lines) and end == i:  # and from the one after it
            out.append("")
    return "\n".join(out) + ("\n" if text.endswith("\n") else "")


def literal_language(code: str) -> str:
    """``python`` if ``code`` parses as Python (``await`` and ``async with`` at the top
    level too), else ``text``."""
    flags = ast.PyCF_ONLY_AST | ast.PyCF_ALLOW_TOP_LEVEL_AWAIT
    try:
        compile(code, "<docstring>", "exec", flags=flags, dont_inherit=True)
    except (SyntaxError, ValueError):
        return "text"
    return "python"


def unindented_literals(text: str) -> list[int]:
    """The lines (1-based) of ``text`` that end in ``::`` without the indented literal block
    reStructuredText expects after them (a block at the same indent reads as a paragraph)."""
    lines = text.splitlines()
    found = []
    for number, line in enumerate(lines, 1):
        if not LITERAL_INTRO.fullmatch(line):
            continue
        following = next((rest for rest in lines[number:] if rest.strip()), None)
        if following is None or _indent(following) <= _indent(line):
            found.append(number)
    return found


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip())


def _literal_intro(match: re.Match[str]) -> str:
    """``text::`` -> ``text:``; a ``::`` alone on its line goes."""
    indent, text = match.groups()
    return f"{indent}{text}:" if text.strip() else ""


def _comment_docstring(attr: griffe.Attribute, lines: list[str]) -> None:
    """An attribute's ``#:`` comment lines above it (``lines``: its file's), as Sphinx reads
    them, as its docstring."""
    if attr.docstring is not None or attr.lineno is None:
        return
    comment: list[str] = []
    number = attr.lineno - 1  # the line above, 1-based
    while 1 <= number <= len(lines) and lines[number - 1].strip().startswith("#:"):
        comment.insert(0, lines[number - 1].strip()[2:].removeprefix(" "))
        number -= 1
    if comment:
        attr.docstring = griffe.Docstring(
            "\n".join(comment), lineno=number + 1, endlineno=attr.lineno - 1, parent=attr
        )


#: The descriptors device classes declare their register-backed properties with:
#: ``speed = RegisterProperty("speed", to_int, "docstring")``, writable or not.
REGISTER_PROPERTIES = {"RegisterProperty": True, "MeasuredProperty": False}


def _register_property(attr: griffe.Attribute) -> None:
    """A register-backed property: its docstring is the descriptor's third argument."""
    if attr.docstring is not None or attr.value is None:
        return
    try:
        call = ast.parse(str(attr.value), mode="eval").body
    except SyntaxError:
        return
    if not (isinstance(call, ast.Call) and isinstance(call.func, ast.Name)):
        return
    writable = REGISTER_PROPERTIES.get(call.func.id)
    docs = [k.value for k in call.keywords if k.arg == "doc"] + call.args[2:3]
    if writable is None or not docs or not isinstance(docs[0], ast.Constant):
        return
    attr.docstring = griffe.Docstring(
        str(docs[0].value), lineno=attr.lineno, endlineno=attr.endlineno, parent=attr
    )
    attr.labels |= {"property", "writable"} if writable else {"property"}
    attr.value = None  # the descriptor, not a value a reader can use


def _walk(obj: griffe.Object) -> Iterator[griffe.Object]:
    """``obj`` and every object under it, aliases left out."""
    yield obj
    for member in obj.members.values():
        if not member.is_alias:
            yield from _walk(member)  # type: ignore[arg-type]


#: The enum classes of the standard library; a class deriving from one is an enum.
ENUM_BASES = frozenset({"enum.Enum", "enum.IntEnum", "enum.StrEnum", "enum.Flag", "enum.IntFlag"})


def _is_enum(cls: griffe.Class) -> bool:
    """Whether ``cls`` derives from one of :data:`ENUM_BASES`."""
    if any(isinstance(b, griffe.Expr) and b.canonical_path in ENUM_BASES for b in cls.bases):
        return True
    return any(isinstance(b, griffe.Class) and _is_enum(b) for b in cls.resolved_bases)


def _enum_members(cls: griffe.Class) -> None:
    """An enum's members, which have no docstring of their own: their value as one, so that
    the class's entry lists them."""
    if not _is_enum(cls):
        return
    for name, member in cls.members.items():
        if (
            isinstance(member, griffe.Attribute)
            and not name.startswith("_")
            and member.value is not None
            and member.docstring is None
        ):
            member.docstring = griffe.Docstring(
                f"Value: ``{member.value}``.",
                lineno=member.lineno,
                endlineno=member.endlineno,
                parent=member,
            )


class BenchbusReference(griffe.Extension):
    """The extension mkdocs.yml names (``extensions:`` of the Python handler)."""

    def on_attribute_instance(
        self, *, node: Any, attr: griffe.Attribute, agent: Any, **kwargs: Any
    ) -> None:
        """An attribute's ``#:`` comment, read as griffe meets its first assignment: griffe
        keeps that docstring through later ones (``self.x = ...`` in ``__init__``)."""
        if isinstance(agent, griffe.Visitor):
            collection, path = agent.lines_collection, agent.filepath
            lines = collection[path] if path in collection else agent.code.splitlines()
            _comment_docstring(attr, lines)

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        """Complete benchbus's objects (constructors, register-backed properties, enum
        members, AsyncBus's members), then rewrite every docstring's roles as links."""
        if pkg.name != "benchbus":
            return
        for obj in _walk(pkg):
            if isinstance(obj, griffe.Attribute):
                _register_property(obj)
            elif isinstance(obj, griffe.Class):
                _constructor(obj)
                _enum_members(obj)
        _async_bus(pkg)
        _async_families(pkg)
        reference = Reference(pkg)
        for obj in _walk(pkg):
            if obj.docstring is not None:
                for line in unindented_literals(obj.docstring.value):
                    # A warning fails the strict build (mkdocstrings logs griffe's).
                    griffe.logger.warning(
                        "%s: docstring line %d ends in '::' but no indented block follows: "
                        "indent the example under it",
                        obj.path,
                        line,
                    )
                obj.docstring.value = reference.rewrite(obj, obj.docstring.value)
