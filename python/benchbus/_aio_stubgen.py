"""Writes ``_aio_members.pyi``: the async devices' members and the families' async classes.

::

    python -m benchbus._aio_stubgen            # rewrite the stub
    python -m benchbus._aio_stubgen --check    # exit 1 if it is out of date

An async device (:mod:`benchbus.aio`) serves each member of its sync class through
``AsyncDevice.__getattr__``; this module declares, for type checkers, what that gives, in
the same order of rules:

- a name in ``aio._LOCAL``, a staticmethod or a classmethod: as the sync class declares it;
- a method: ``async def`` with the sync method's parameters and result;
- anything else readable (a property, a register descriptor): a read-only property whose
  value is a ``Coroutine`` of the sync value.

Each is declared once, on the members class that mirrors the sync class declaring it: what
every family inherits (from ``BusDevice``, the compiled ``_Station``) on the base that each
family's members class extends (``BusDeviceMembers``), a family's own or overriding
declaration on the family's.

The declarations are read from the source where they are written: the Python modules for
the Python classes, ``_core.pyi`` for the compiled bases (annotations as written, each name
imported from the module that defines it). A register descriptor is declared with its
value type (``speed: MeasuredProperty[Drive, int] = ...``), which mypy checks against its
converter. What cannot be typed this way raises :class:`StubError` rather than being left
out. The result goes through ``ruff`` (imports sorted, formatted), so it needs the dev
tools.
"""

from __future__ import annotations

import argparse
import ast
import builtins
import copy
import functools
import inspect
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from benchbus import _aio_members, aio
from benchbus._device import _annotations

__all__ = ["STUB", "StubError", "generate", "main"]

#: The generated stub.
STUB = Path(__file__).with_name("_aio_members.pyi")

#: Where the compiled module's declarations are.
_CORE_STUB = Path(__file__).with_name("_core.pyi")

#: The decorators a declaration may have (anything else is refused).
_DECORATORS = frozenset({"property", "staticmethod", "classmethod"})

#: The longest docstring line a member's docstring keeps (the stub's lines are 100 at most,
#: indented by 8 and quoted).
_DOC_WIDTH = 88

_HEADER = '''"""The families' async devices (benchbus.aio) and their members, for type checkers.

Generated from the sync classes by ``python -m benchbus._aio_stubgen``: do not edit.
"""
'''


class StubError(Exception):
    """A member of a sync class whose async type cannot be declared."""


@dataclass(frozen=True)
class _Source:
    """A module's parsed declarations."""

    tree: ast.Module
    #: Names the module defines at its top level.
    defined: frozenset[str]
    #: Names it imports: ``{local name: (module, name in it or None for a module)}``.
    imported: dict[str, tuple[str, str | None]]
    #: Its source lines (for the ``#:`` comments above a declaration).
    lines: tuple[str, ...] = ()


def _flat(stmts: list[ast.stmt]) -> list[ast.stmt]:
    """``stmts`` with those under an ``if`` (either branch) in its place."""
    return [
        one
        for stmt in stmts
        for one in (_flat([*stmt.body, *stmt.orelse]) if isinstance(stmt, ast.If) else [stmt])
    ]


@functools.cache
def _source(module: str) -> _Source:
    """The declarations of ``module`` (``benchbus._core``'s from its stub)."""
    found = _CORE_STUB if module == "benchbus._core" else inspect.getsourcefile(sys.modules[module])
    if found is None:
        raise StubError(f"{module} has no source to read declarations from")
    path = Path(found)
    text = path.read_text(encoding="utf-8")
    tree = ast.parse(text, filename=str(path))
    defined: set[str] = set()
    imported: dict[str, tuple[str, str | None]] = {}
    for stmt in _flat(tree.body):
        if isinstance(stmt, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            defined.add(stmt.name)
        elif isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name):
            defined.add(stmt.target.id)
        elif isinstance(stmt, ast.Assign):
            defined.update(t.id for t in stmt.targets if isinstance(t, ast.Name))
        elif isinstance(stmt, ast.ImportFrom) and stmt.module and not stmt.level:
            for alias in stmt.names:
                imported[alias.asname or alias.name] = (stmt.module, alias.name)
        elif isinstance(stmt, ast.Import):
            for alias in stmt.names:
                local = alias.asname or alias.name.partition(".")[0]
                imported[local] = (alias.name if alias.asname else local, None)
    return _Source(tree, frozenset(defined), imported, tuple(text.splitlines()))


def _origin(module: str, name: str) -> tuple[str, str | None]:
    """Where the name ``name`` used in ``module`` is defined: ``(module, name)``, or
    ``(module, None)`` for a module; ``("builtins", name)`` for a builtin."""
    source = _source(module)
    if name in source.defined:
        return module, name
    if name in source.imported:
        where, what = source.imported[name]
        if what is not None and where.startswith("benchbus") and where != module:
            return _origin(where, what)  # a name benchbus imports from elsewhere
        return where, what
    if hasattr(builtins, name):
        return "builtins", name
    raise StubError(f"{module}: cannot tell where {name!r} comes from")


class _Imports:
    """The imports a stub needs, by the name it uses."""

    def __init__(self) -> None:
        self._by_name: dict[str, tuple[str, str | None]] = {}

    def need(self, local: str, where: tuple[str, str | None]) -> None:
        """Import ``where`` as ``local``; StubError if ``local`` already names another."""
        if where[0] == "builtins":
            return
        known = self._by_name.setdefault(local, where)
        if known != where:
            raise StubError(f"{local!r} would name both {known} and {where}")

    def lines(self) -> list[str]:
        """The import statements (ruff sorts them)."""
        out = []
        for local, (module, name) in sorted(self._by_name.items()):
            line = f"import {module}" if name is None else f"from {module} import {name}"
            out.append(line if local == (name or module) else f"{line} as {local}")
        return out


def _annotation(node: ast.expr | None, module: str, imports: _Imports, what: str) -> ast.expr:
    """``node`` as the stub writes it (a quoted annotation unquoted), its names imported."""
    if node is None:
        raise StubError(f"{what} has no annotation")
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        node = ast.parse(node.value, mode="eval").body
    for sub in ast.walk(node):
        if isinstance(sub, ast.Name):
            if sub.id == "Self":
                raise StubError(f"{what}: Self would mean the members' class")
            imports.need(sub.id, _origin(module, sub.id))
    return node


def _default(node: ast.expr | None) -> ast.expr | None:
    """A parameter's default as a stub shows it: a literal as written, else ``...``."""
    if node is None:
        return None
    literal = node.operand if isinstance(node, ast.UnaryOp) else node
    if isinstance(literal, ast.Constant) and len(repr(literal.value)) <= 40:
        return node
    return ast.Constant(Ellipsis)


def _decorators(node: ast.FunctionDef) -> list[str]:
    """The names of ``node``'s decorators; StubError for one the stub cannot repeat."""
    names = []
    for decorator in node.decorator_list:
        if isinstance(decorator, ast.Name) and decorator.id in _DECORATORS:
            names.append(decorator.id)
        else:
            raise StubError(f"{node.name}: cannot declare a {ast.unparse(decorator)} member")
    return names


def _members(stmts: list[ast.stmt]) -> dict[str, ast.stmt]:
    """The declarations of a class body by name (under ``if`` blocks too; a property's
    setter or deleter declares nothing)."""
    found: dict[str, ast.stmt] = {}
    for stmt in _flat(stmts):
        if isinstance(stmt, ast.FunctionDef) and not any(
            isinstance(d, ast.Attribute) and d.attr in ("setter", "deleter")
            for d in stmt.decorator_list
        ):
            found.setdefault(stmt.name, stmt)
        elif isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name):
            found.setdefault(stmt.target.id, stmt)
        elif isinstance(stmt, ast.Assign):
            for target in stmt.targets:
                if isinstance(target, ast.Name):
                    found.setdefault(target.id, stmt)
        elif isinstance(stmt, ast.AsyncFunctionDef):
            raise StubError(f"{stmt.name}: a sync class has no coroutine methods")
    return found


def _class_body(klass: type) -> dict[str, ast.stmt]:
    """The declarations of ``klass`` by name ({} for a builtin such as ``object``)."""
    if klass.__module__ == "builtins":
        return {}
    source = _source(klass.__module__)
    for stmt in _flat(source.tree.body):
        if isinstance(stmt, ast.ClassDef) and stmt.name == klass.__qualname__:
            return _members(stmt.body)
    raise StubError(f"no declaration of {klass.__qualname__} in {klass.__module__}")


def _declaration(sync: type, name: str, *, typed: bool = False) -> tuple[type, ast.stmt]:
    """The class of ``sync``'s MRO that declares ``name`` first, and its declaration (with
    ``typed``, the first one that gives it an annotation)."""
    for klass in sync.__mro__:
        node = _class_body(klass).get(name)
        if node is not None and (not typed or not isinstance(node, ast.Assign)):
            return klass, node
    raise StubError(f"{sync.__name__}.{name}: no declaration found")


def _body(doc: str | None) -> list[ast.stmt]:
    """A stub's body: the docstring, or ``...``."""
    return [ast.Expr(ast.Constant(doc if doc else Ellipsis))]


def _node(kind: type[ast.stmt], **fields: Any) -> ast.stmt:
    """A class or function declaration (without type parameters, where Python has them)."""
    if "type_params" in kind._fields:
        fields["type_params"] = []
    return kind(**fields)


def _function(
    node: ast.FunctionDef,
    module: str,
    imports: _Imports,
    doc: str | None,
    *,
    is_async: bool,
) -> ast.stmt:
    """``node`` as a stub declaration: its parameters with their annotations, its result,
    ``async`` if asked, its decorators."""
    what = f"{module}.{node.name}"
    args = copy.deepcopy(node.args)
    for arg in [*args.posonlyargs, *args.args, *args.kwonlyargs, args.vararg, args.kwarg]:
        if arg is not None and arg.annotation is not None:
            arg.annotation = _annotation(arg.annotation, module, imports, what)
    args.defaults = [d for d in map(_default, args.defaults) if d is not None]
    args.kw_defaults = [_default(d) for d in args.kw_defaults]
    return _node(
        ast.AsyncFunctionDef if is_async else ast.FunctionDef,
        name=node.name,
        args=args,
        body=_body(doc),
        decorator_list=[ast.Name(d) for d in _decorators(node)],
        returns=_annotation(node.returns, module, imports, what),
    )


def _value_type(node: ast.stmt, module: str, imports: _Imports, what: str) -> ast.expr:
    """The type a readable member gives: a property's result, or a descriptor's value
    (``Descriptor[Owner, T]``: T)."""
    if isinstance(node, ast.FunctionDef) and "property" in _decorators(node):
        return _annotation(node.returns, module, imports, what)
    if isinstance(node, ast.AnnAssign):
        annotation = node.annotation
        if isinstance(annotation, ast.Subscript) and isinstance(annotation.slice, ast.Tuple):
            return _annotation(annotation.slice.elts[-1], module, imports, what)
        return _annotation(annotation, module, imports, what)
    raise StubError(f"{what}: declare it with its type (name: Descriptor[Owner, T] = ...)")


def _property(name: str, returns: ast.expr, doc: str | None) -> ast.stmt:
    """A read-only property declaration."""
    self = ast.arguments(
        posonlyargs=[], args=[ast.arg("self")], kwonlyargs=[], kw_defaults=[], defaults=[]
    )
    return _node(
        ast.FunctionDef,
        name=name,
        args=self,
        body=_body(doc),
        decorator_list=[ast.Name("property")],
        returns=returns,
    )


def _doc(sync: type, name: str) -> str | None:
    """The member's docstring, as ``help()`` shows it on the sync class."""
    found = inspect.getattr_static(sync, name, None)
    if isinstance(found, (staticmethod, classmethod)):
        found = found.__func__
    if not (inspect.isroutine(found) or inspect.isdatadescriptor(found)):
        return None
    doc = found.__doc__
    return _wrapped(doc) if isinstance(doc, str) and doc.strip() else None


def _wrapped(doc: str) -> str:
    """``doc`` cleaned as ``help()`` shows it, a line too long for the stub (a docstring
    built of joined strings, a long comment) wrapped."""
    return "\n".join(
        textwrap.fill(line, _DOC_WIDTH, subsequent_indent=line[: len(line) - len(line.lstrip())])
        if len(line) > _DOC_WIDTH
        else line
        for line in inspect.cleandoc(doc).splitlines()
    )


def _comment(klass: type, node: ast.stmt) -> str | None:
    """The ``#:`` comment lines right above ``node`` in ``klass``'s module: a data
    attribute's docstring, as Sphinx and the API reference read it."""
    lines = _source(klass.__module__).lines
    found: list[str] = []
    at = node.lineno - 2  # the line above, 0-based
    while at >= 0 and lines[at].strip().startswith("#:"):
        found.insert(0, lines[at].strip()[2:].strip())
        at -= 1
    return " ".join(found) or None


def _member(sync: type, name: str, imports: _Imports) -> list[ast.stmt]:
    """The declaration of ``name`` on the async device of ``sync``: the rules of
    ``AsyncDevice.__getattr__``."""
    what = f"{sync.__name__}.{name}"
    found = inspect.getattr_static(sync, name, None)
    klass, node = _declaration(sync, name)
    module = klass.__module__
    doc = _doc(sync, name)
    if name in aio._LOCAL or isinstance(found, (staticmethod, classmethod)):
        if isinstance(node, ast.FunctionDef):
            if "property" in _decorators(node):
                return [_property(name, _value_type(node, module, imports, what), doc)]
            return [_function(node, module, imports, doc, is_async=False)]
        return _attribute(sync, name, imports)
    if found is None:
        raise StubError(f"{what} is neither in the class nor local")
    if inspect.isroutine(found):
        if not isinstance(node, ast.FunctionDef) or _decorators(node):
            raise StubError(f"{what}: a method declared as {ast.dump(node)[:60]}")
        return [_function(node, module, imports, doc, is_async=True)]
    value = _value_type(node, module, imports, what)
    imports.need("Coroutine", ("collections.abc", "Coroutine"))
    imports.need("Any", ("typing", "Any"))
    coroutine = ast.parse(f"Coroutine[Any, Any, {ast.unparse(value)}]", mode="eval").body
    return [_property(name, coroutine, doc)]


def _attribute(sync: type, name: str, imports: _Imports) -> list[ast.stmt]:
    """A data attribute read as it is: its annotation in the first class that has one,
    else the type of its value; then its ``#:`` comment as its docstring."""
    what = f"{sync.__name__}.{name}"
    try:
        klass, node = _declaration(sync, name, typed=True)
    except StubError:
        value = inspect.getattr_static(sync, name)
        kind = type(value)
        imports.need(kind.__qualname__, (kind.__module__, kind.__qualname__))
        annotation: ast.expr = ast.Name(kind.__qualname__)
    else:
        if not isinstance(node, ast.AnnAssign):
            raise StubError(f"{what}: not a data attribute")
        annotation = _annotation(node.annotation, klass.__module__, imports, what)
    declared: list[ast.stmt] = [ast.AnnAssign(ast.Name(name), annotation, None, simple=1)]
    # The nearest declaration that has a comment (a subclass may set the value alone).
    comments = (_comment(k, n) for k in sync.__mro__ if (n := _class_body(k).get(name)))
    doc = next((c for c in comments if c), None)
    if doc is not None:
        declared.append(ast.Expr(ast.Constant(doc)))
    return declared


def _public_names(sync: type) -> list[str]:
    """The public names the async device of ``sync`` serves from it."""
    names = {n for n in dir(sync) if not n.startswith("_")}
    for klass in sync.__mro__:
        names.update(n for n in _annotations(klass) if not n.startswith("_"))
    return sorted(names)


def _classes() -> list[tuple[type, type[aio.AsyncDevice[Any]]]]:
    """Each family's members class and the async device class it is for (the profile's
    ``Device`` first)."""
    out = []
    for name in ("Device", *_aio_members.__all__):
        members, device = getattr(_aio_members, f"{name}Members"), getattr(aio, name)
        if members not in device.__mro__:
            raise StubError(f"aio.{name} does not inherit {members.__name__}")
        out.append((members, device))
    return out


def _layers() -> dict[type, frozenset[type]]:
    """Each members class (a family's, or a base that several extend) and the sync classes
    that every family it is for inherits: it declares the members they declare."""
    out: dict[type, frozenset[type]] = {}
    for members, device in _classes():
        syncs = frozenset(device.SYNC.__mro__[:-1])
        for klass in members.__mro__[:-1]:
            out[klass] = out.get(klass, syncs) & syncs
    return out


def _ruff(text: str, *args: str) -> str:
    """``text`` through ``ruff <args>`` (the project's settings apply)."""
    done = subprocess.run(
        [sys.executable, "-m", "ruff", *args, "--stdin-filename", str(STUB), "-"],
        input=text,
        capture_output=True,
        text=True,
        check=False,
    )
    if done.returncode != 0:
        raise StubError(f"ruff {' '.join(args)}: {done.stderr.strip() or done.stdout.strip()}")
    return done.stdout


def generate() -> str:
    """The text of ``_aio_members.pyi`` for the sync classes as they are now."""
    _source.cache_clear()  # read the sources as they are now
    imports = _Imports()
    layers = _layers()
    bodies: dict[type, dict[str, list[ast.stmt]]] = {klass: {} for klass in layers}
    for members, device in _classes():
        own = set(dir(device))  # what the async class itself defines, or its base
        for name in (n for n in _public_names(device.SYNC) if n not in own):
            member = _member(device.SYNC, name, imports)
            # Declared once: on the most general members class whose families all inherit
            # the sync class that declares it.
            where = _declaration(device.SYNC, name)[0]
            home = next(k for k in reversed(members.__mro__[:-1]) if where in layers[k])
            known = bodies[home].setdefault(name, member)
            if [ast.dump(n) for n in known] != [ast.dump(n) for n in member]:
                raise StubError(f"{members.__name__}.{name} differs from {home.__name__}'s")
    classes = [
        _node(
            ast.ClassDef,
            name=klass.__name__,
            bases=[ast.Name(b.__name__) for b in klass.__bases__ if b is not object],
            keywords=[],
            body=[ast.Expr(ast.Constant(inspect.getdoc(klass)))]
            + [n for _, member in sorted(bodies[klass].items()) for n in member],
            decorator_list=[],
        )
        for klass in sorted(layers, key=lambda k: (len(k.__mro__), k.__name__))
    ]
    imports.need("AsyncDevice", ("benchbus.aio", "AsyncDevice"))
    for name in _aio_members.__all__:  # the families' async classes, which aio makes
        device = getattr(aio, name)
        imports.need(f"_Sync{name}", (device.SYNC.__module__, device.SYNC.__name__))
        base = ast.parse(f"AsyncDevice[_Sync{name}]", mode="eval").body
        classes.append(
            _node(
                ast.ClassDef,
                name=name,
                bases=[base, ast.Name(f"{name}Members")],
                keywords=[],
                body=[ast.Expr(ast.Constant(inspect.getdoc(device)))],
                decorator_list=[],
            )
        )
    imports.need("BusDevice", ("benchbus._device", "BusDevice"))
    declared = ast.unparse(ast.fix_missing_locations(ast.Module(classes, type_ignores=[])))
    head = [
        f"__all__: list[str] = {sorted(_aio_members.__all__)!r}",
        "SYNC_CLASSES: tuple[type[BusDevice], ...]",
    ]
    text = "\n".join([_HEADER, *imports.lines(), *head, declared])
    text = _ruff(text, "check", "--fix", "--select", "I", "--quiet", "--exit-zero")
    return _ruff(text, "format", "--quiet")


def main(argv: list[str] | None = None) -> int:
    """Write the stub, or with ``--check`` say whether it is up to date (exit 1 if not)."""
    parser = argparse.ArgumentParser(prog="python -m benchbus._aio_stubgen")
    parser.add_argument("--check", action="store_true", help="only compare, write nothing")
    options = parser.parse_args(argv)
    text = generate()
    if options.check:
        if STUB.read_text(encoding="utf-8") != text:
            print(f"{STUB} is out of date: run python -m benchbus._aio_stubgen", file=sys.stderr)
            return 1
        return 0
    STUB.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
