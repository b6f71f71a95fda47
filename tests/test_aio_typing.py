"""The async devices' members are typed one by one (``_aio_members.pyi``), generated from
the sync classes: the stub is up to date, declares what ``AsyncDevice.__getattr__`` serves
with the kind it serves it as, and mypy accepts the right uses and refuses the wrong ones.
"""

from __future__ import annotations

import ast
import asyncio
import inspect
import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from mypy import api

from benchbus import _aio_stubgen, aio
from benchbus._device import RegisterProperty, to_int
from benchbus._drive import Drive
from benchbus._families import FAMILIES
from benchbus.sim import DriveDevice, J2Device, PblDevice, ProfileDevice, Simulator, TaisongDevice

ROOT = Path(__file__).resolve().parent.parent
PROFILE = ROOT / "examples" / "profiles" / "xy_md02.toml"


class GrownDrive(Drive):
    """A drive class that gained a method and a property since the stub was made."""

    def spin_up(self, rpm: float, *, within: float = 2.0) -> int:
        """Start and wait for ``rpm``."""
        return 0

    @property
    def spin(self) -> bool:
        """Whether it turns."""
        return True


class UntypedDrive(Drive):
    """A drive class with a register property declared without its value type."""

    extra = RegisterProperty("speed_setpoint", to_int, "The setpoint again.")


# ---- the stub is the generator's output ---------------------------------------------------------


def test_the_checked_in_stub_is_what_the_generator_writes() -> None:
    assert _aio_stubgen.STUB.read_text(encoding="utf-8") == _aio_stubgen.generate()
    assert _aio_stubgen.main(["--check"]) == 0


def test_a_sync_class_that_gains_members_makes_the_stub_out_of_date(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(aio.Drive, "SYNC", GrownDrive)
    text = _aio_stubgen.generate()
    assert text != _aio_stubgen.STUB.read_text(encoding="utf-8")
    assert "async def spin_up(self, rpm: float, *, within: float = 2.0) -> int:" in text
    assert "def spin(self) -> Coroutine[Any, Any, bool]:" in text
    assert _aio_stubgen.main(["--check"]) == 1
    assert "out of date" in capsys.readouterr().err


def test_a_member_that_cannot_be_typed_stops_the_generator(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(aio.Drive, "SYNC", UntypedDrive)
    with pytest.raises(_aio_stubgen.StubError, match=r"extra: declare it with its type"):
        _aio_stubgen.generate()


def test_a_shared_member_that_a_family_would_declare_otherwise_stops_the_generator(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Declared once only if it is the same for every family (as a compiled class that
    gave a shared member a docstring of its own would make it)."""
    doc = _aio_stubgen._doc
    monkeypatch.setattr(
        _aio_stubgen,
        "_doc",
        lambda sync, name: "The drive's." if (sync, name) == (Drive, "unit") else doc(sync, name),
    )
    with pytest.raises(_aio_stubgen.StubError, match=r"DriveMembers.unit differs from Bus"):
        _aio_stubgen.generate()


def test_each_family_of_the_registry_has_its_async_class_as_the_stub_declares_it() -> None:
    """``bb.aio.Drive``... are made from the registry, each on ``AsyncDevice`` of its sync
    class and its members class; the stub declares each the same way, and ``aio`` exports
    them."""
    classes = stub_classes()
    syncs = [f.device for f in FAMILIES if f.device is not None]
    assert {"Drive", "PblDrive", "J2Controller", "Instrument"} <= {c.__name__ for c in syncs}
    for sync in syncs:
        name = sync.__name__
        cls = getattr(aio, name)
        assert cls.SYNC is sync and cls.__module__ == "benchbus.aio", name
        members = getattr(_aio_stubgen._aio_members, f"{name}Members")
        assert cls.__bases__ == (aio.AsyncDevice, members), name
        assert name in aio.__all__ and cls.__doc__ and f"benchbus.{name}`" in cls.__doc__
        bases = [ast.unparse(b) for b in classes[name].bases]
        assert bases == [f"AsyncDevice[_Sync{name}]", f"{name}Members"], name
    assert set(aio.__all__) == {"AsyncBus", "AsyncDevice", "AsyncPoll", "Device"} | {
        c.__name__ for c in syncs
    }


# ---- the stub declares what the devices serve ---------------------------------------------------


def stub_classes() -> dict[str, ast.ClassDef]:
    """The stub's classes by name."""
    tree = ast.parse(_aio_stubgen.STUB.read_text(encoding="utf-8"))
    return {node.name: node for node in tree.body if isinstance(node, ast.ClassDef)}


def families(classes: dict[str, ast.ClassDef]) -> list[str]:
    """The members classes the async devices extend: those no other members class of the
    stub extends."""
    members = [node for name, node in classes.items() if name.endswith("Members")]
    extended = {ast.unparse(base) for node in members for base in node.bases}
    return [node.name for node in members if node.name not in extended]


def chain(name: str, classes: dict[str, ast.ClassDef]) -> list[ast.ClassDef]:
    """The stub's class ``name`` and the stub's classes it extends, nearest first: where
    Python and mypy look a member up (a base that is not in the stub: KeyError)."""
    node = classes[name]
    return [node, *(found for base in node.bases for found in chain(ast.unparse(base), classes))]


def stub_members() -> dict[str, dict[str, ast.stmt]]:
    """Each family's members class of the stub: the declarations it gives, by name (its
    own, then those of the classes it extends)."""
    classes = stub_classes()
    out = {}
    for family in families(classes):
        members: dict[str, ast.stmt] = {}
        for node in chain(family, classes):
            for stmt in node.body:
                if isinstance(stmt, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    members.setdefault(stmt.name, stmt)
                elif isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name):
                    members.setdefault(stmt.target.id, stmt)
        out[family] = members
    return out


def declared(node: ast.ClassDef) -> dict[str, str]:
    """What a class of the stub declares itself, by name: each declaration's text (an
    attribute's with its docstring)."""
    out = {}
    for at, stmt in enumerate(node.body):
        if isinstance(stmt, (ast.FunctionDef, ast.AsyncFunctionDef)):
            out[stmt.name] = ast.unparse(stmt)
        elif isinstance(stmt, ast.AnnAssign):
            out[ast.unparse(stmt.target)] = ast.unparse(node.body[at : at + 2])
    return out


def test_what_the_families_share_is_declared_once() -> None:
    """A member the sync classes all get from their shared bases (``record`` and its long
    docstring, ``verify_identity``...) is declared on the one members class every family's
    extends; a family's class declares only what it has of its own (another type, another
    docstring), never the same again."""
    classes = stub_classes()
    (base,) = {ast.unparse(b) for family in families(classes) for b in classes[family].bases}
    shared = declared(classes[base])
    assert {"record", "verify_identity", "unit", "close", "sample_units"} <= set(shared)
    for family in families(classes):
        own = declared(classes[family])
        assert own, family
        assert not [name for name in own if own[name] == shared.get(name)], family
    # An override stays in the family's class: the drive's close stops its keepalive.
    assert "keepalive" in declared(classes["DriveMembers"])["close"]
    assert "keepalive" not in shared["close"]


def kind(node: ast.stmt) -> str:
    """How the stub declares a member: "coroutine function", "awaitable", "property",
    "method", "staticmethod" or "attribute"."""
    if isinstance(node, ast.AsyncFunctionDef):
        return "coroutine function"
    if isinstance(node, ast.AnnAssign):
        return "attribute"
    assert isinstance(node, ast.FunctionDef)
    decorators = [ast.unparse(d) for d in node.decorator_list]
    if decorators == ["property"]:
        assert node.returns is not None
        returns = ast.unparse(node.returns)
        return "awaitable" if returns.startswith("Coroutine[Any, Any, ") else "property"
    if decorators == ["staticmethod"]:
        return "staticmethod"
    assert decorators == [], decorators
    return "method"


def served_kind(value: Any, sync: object) -> str:
    """What the async device gave for a member, told apart the same way (``sync``: its
    sync device)."""
    if inspect.iscoroutine(value):
        value.close()  # never awaited: nothing was sent
        return "awaitable"
    if inspect.iscoroutinefunction(value):
        return "coroutine function"
    if getattr(value, "__self__", None) is sync:  # a method of the sync device, bound
        return "method"
    if inspect.isroutine(value):
        return "staticmethod"
    return "property or attribute"


def parameters(node: ast.stmt) -> list[str]:
    """The stub's parameter names and kinds, ``self`` left out."""
    assert isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
    args = node.args
    names = [a.arg for a in [*args.posonlyargs, *args.args]]
    if names[:1] == ["self"]:
        names = names[1:]
    names += [f"*{args.vararg.arg}"] if args.vararg else []
    names += [f"kw:{a.arg}" for a in args.kwonlyargs]
    names += [f"**{args.kwarg.arg}"] if args.kwarg else []
    return names


def runtime_parameters(value: Any) -> list[str]:
    """The same of what the device serves (its signature is the sync method's)."""
    out = []
    for p in inspect.signature(value).parameters.values():
        if p.kind is p.VAR_POSITIONAL:
            out.append(f"*{p.name}")
        elif p.kind is p.KEYWORD_ONLY:
            out.append(f"kw:{p.name}")
        elif p.kind is p.VAR_KEYWORD:
            out.append(f"**{p.name}")
        else:
            out.append(p.name)
    return out


@pytest.fixture
def sims() -> Iterator[dict[str, tuple[Simulator[Any], int]]]:
    """A simulator of each family: {members class: (simulator, unit)}."""
    with (
        Simulator({1: DriveDevice()}) as drive,
        Simulator({0x11: PblDevice()}, baudrate=115200) as pbl,
        Simulator({1: J2Device()}, baudrate=9600) as j2,
        Simulator({1: TaisongDevice()}, baudrate=9600) as meter,
        Simulator({1: ProfileDevice(PROFILE)}, baudrate=9600) as sensor,
    ):
        yield {
            "DriveMembers": (drive, 1),
            "PblDriveMembers": (pbl, 0x11),
            "J2ControllerMembers": (j2, 1),
            "InstrumentMembers": (meter, 1),
            "DeviceMembers": (sensor, 1),
        }


def make(cls: type[aio.AsyncDevice[Any]], bus: aio.AsyncBus, unit: int) -> Any:
    """An async device of ``cls`` (or of a class with the same SYNC) on ``bus``."""
    if cls.SYNC is aio.Device.SYNC:
        return cls(PROFILE, bus, unit)
    return cls(bus, unit)


def async_class(members: str) -> type[aio.AsyncDevice[Any]]:
    """The async device class ``members`` types."""
    cls: type[aio.AsyncDevice[Any]] = getattr(aio, members.removesuffix("Members"))
    return cls


def test_every_served_member_is_in_the_stub_as_the_kind_it_is_served_as(
    sims: dict[str, tuple[Simulator[Any], int]],
) -> None:
    stub = stub_members()
    assert set(stub) == set(sims)

    async def main() -> None:
        for members, (sim, unit) in sims.items():
            async with aio.AsyncBus(sim.port) as bus:
                device = make(async_class(members), bus, unit)
                declared = stub[members]
                served = {n for n in dir(device) if not n.startswith("_")}
                served -= set(dir(type(device)))  # what the async class itself has
                if members == "DeviceMembers":  # the registers stay dynamic
                    served -= {r.name for r in device.sync.profile.registers}
                assert set(declared) == served, members
                for name, node in declared.items():
                    value = getattr(device, name)
                    want = kind(node)
                    got = served_kind(value, device.sync)
                    if want in ("property", "attribute"):
                        assert got == "property or attribute", (members, name)
                    else:
                        assert got == want, (members, name)
                    if want in ("coroutine function", "method", "staticmethod"):
                        assert parameters(node) == runtime_parameters(value), (members, name)
                assert sim.requests == []  # nothing was sent

    asyncio.run(main())


def test_the_members_classes_change_nothing_at_run_time(
    sims: dict[str, tuple[Simulator[Any], int]],
) -> None:
    async def main() -> None:
        for members, (sim, unit) in sims.items():
            cls = async_class(members)
            base = getattr(_aio_stubgen._aio_members, members)
            assert cls.__mro__[1] is aio.AsyncDevice and base in cls.__mro__
            # The members class and those it extends, as the stub has them: all empty.
            stub = chain(members, stub_classes())
            assert [k.__name__ for k in base.__mro__[:-1]] == [node.name for node in stub]
            for klass in base.__mro__[:-1]:
                assert set(vars(klass)) <= {
                    "__module__",
                    "__qualname__",
                    "__doc__",
                    "__dict__",
                    "__weakref__",
                    "__firstlineno__",
                    "__static_attributes__",
                }, klass
            bare = type("Bare", (aio.AsyncDevice,), {"SYNC": cls.SYNC})
            async with aio.AsyncBus(sim.port) as bus:
                typed, untyped = make(cls, bus, unit), make(bare, bus, unit)
                assert dir(typed) == dir(untyped), members
                for name in dir(untyped):
                    if not name.startswith("_"):
                        one, other = getattr(typed, name), getattr(untyped, name)
                        assert served_kind(one, typed.sync) == served_kind(other, untyped.sync), (
                            name
                        )

    asyncio.run(main())


# ---- mypy --------------------------------------------------------------------------------------

#: Each line marked ``# E: text`` must give a mypy error containing the text, and no other
#: line any error; ``# N: text`` the same for a note (reveal_type).
SNIPPET = """\
import benchbus as bb
from benchbus import aio


async def uses(line: aio.AsyncBus) -> None:
    drive = aio.Drive(line, unit=1)
    await drive.set("speed_setpoint", 1500)
    await drive.forward()
    speed: int = await drive.speed
    setpoint: int = await drive.get("speed_setpoint")  # E: (expression has type "int | float"
    reveal_type(await drive.telemetry())  # N: Revealed type is "benchbus._drive.DriveTelemetry"
    reveal_type(await drive.state)  # N: Revealed type is "benchbus._drive.DriveState"
    reveal_type(await drive.wait_for_speed(1500, tolerance=20))  # N: Revealed type is "int"
    unit: int = drive.unit
    family: str = drive.family
    commands: list[tuple[str, int]] = drive.commands()
    units: dict[str, str] = drive.units()
    await drive.forwardd()  # E: "Drive" has no attribute "forwardd"
    name: str = await drive.speed  # E: expression has type "int", variable has type "str"
    await drive.set("speed_setpoint", "x")  # E: "set" of "DriveMembers" has incompatible type "str"
    await drive.wait_for_speed(1500, tolerence=20)  # E: argument "tolerence" for "wait_for_speed"
    late: int = drive.speed  # E: (expression has type "Coroutine[Any, Any, int]"
    drive.forward()  # E: Value of type "Coroutine[Any, Any, None]" must be used
    await drive.unit  # E: Incompatible types in "await" (actual type "int"

    pbl = aio.PblDrive(line, unit=0x11)
    await pbl.start()
    reveal_type(await pbl.direction)  # N: Revealed type is "benchbus._pbl.Direction"
    j2 = aio.J2Controller(line)
    reveal_type(await j2.pid)  # N: "tuple[float, float, float, fallback=benchbus._j2.Pid]"
    await j2.set_output(20.0, switch_to_manual=True)
    meter = aio.Instrument(line)
    reveal_type(await meter.read_float(0x000C, function=4))  # N: Revealed type is "float"
    await meter.read_float(12, function=5)  # E: has incompatible type "Literal[5]"; expected
    max_read: int = meter.max_read
    dev = aio.Device.from_profile("meter.toml", line)
    reveal_type(await dev.temperature)  # N: Revealed type is "Any"
    reveal_type(await dev.read_many(["temperature"]))  # N: Revealed type is "dict[str, Any]"
    sync: bb.Drive = drive.sync
"""


def expected(snippet: str) -> dict[tuple[int, str], list[str]]:
    """``{(line, "error" or "note"): [texts]}`` from the snippet's marks."""
    out: dict[tuple[int, str], list[str]] = {}
    for number, line in enumerate(snippet.splitlines(), start=1):
        mark = re.search(r"  # ([EN]): (.*)$", line)
        if mark:
            severity = "error" if mark.group(1) == "E" else "note"
            out.setdefault((number, severity), []).append(mark.group(2))
    return out


#: Third-party packages mypy does not read for the test below (their modules and below).
SKIPPED = tuple(
    f"{name}.*"
    for name in (
        "pandas",
        "numpy",
        "dask",
        "xarray",
        "IPython",
        "matplotlib",
        "prompt_toolkit",
        "PIL",
        "jinja2",
        "traitlets",
        "pymodbus",
    )
)


def test_mypy_accepts_the_right_uses_and_names_the_wrong_ones(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "uses.py"
    path.write_text(SNIPPET, encoding="utf-8")
    # This checkout's package, whatever the environment has installed.
    monkeypatch.setenv("MYPYPATH", str(ROOT / "python"))
    monkeypatch.chdir(tmp_path)  # no configuration file but the flags and the one below
    # The extras' libraries the package imports (pandas, matplotlib, pymodbus...) are taken
    # as Any rather than read: this test judges benchbus's own types, and reading theirs
    # was most of its time.
    config = tmp_path / "mypy.ini"
    config.write_text(f"[mypy]\n[mypy-{','.join(SKIPPED)}]\nfollow_imports = skip\n", "utf-8")
    started = time.monotonic()
    stdout, stderr, status = api.run(
        [
            "--config-file",
            str(config),
            "--strict",
            "--python-version",
            "3.10",
            "--cache-dir",
            str(tmp_path / "cache"),
            "--show-error-codes",
            "--no-pretty",
            "--no-error-summary",
            str(path),
        ]
    )
    took = time.monotonic() - started
    assert stderr == ""
    found: dict[tuple[int, str], list[str]] = {}
    for line in stdout.splitlines():
        where = re.match(r".*uses\.py:(\d+): (error|note): (.*)$", line)
        assert where, line
        # Older mypy names builtins in full ("builtins.int").
        text = where.group(3).replace("builtins.", "")
        found.setdefault((int(where.group(1)), where.group(2)), []).append(text)
    want = expected(SNIPPET)
    errors = {key for key in found if key[1] == "error"}
    assert errors == {key for key in want if key[1] == "error"}, stdout
    # A note is a revealed type where one is asked, or a hint beside an error.
    for line, severity in found:
        assert severity == "error" or (line, "note") in want or (line, "error") in want, stdout
    for key, texts in want.items():
        for text in texts:
            assert any(text in message for message in found.get(key, [])), (key, text, stdout)
    assert status == 1  # the errors above, and only those
    print(f"mypy took {took:.1f} s")


def test_each_data_attribute_has_its_comment_as_docstring() -> None:
    """An attribute the async devices serve as it is (``LINE_DEFAULTS``, ``enums``...) carries
    the ``#:`` comment of its nearest declaration in the sync classes, so that the API
    reference and editors show it."""
    classes = stub_classes()
    # Each family: {attribute: (its declaration, its docstring)}, through the classes it
    # extends (the nearest declaration first).
    served: dict[str, dict[str, tuple[str, str]]] = {}
    for family in families(classes):
        found = served[family] = {}
        for cls in chain(family, classes):
            for at, stmt in enumerate(cls.body):
                if isinstance(stmt, ast.AnnAssign) and ast.unparse(stmt.target) not in found:
                    after = cls.body[at + 1] if at + 1 < len(cls.body) else None
                    assert isinstance(after, ast.Expr), f"{cls.name}.{ast.unparse(stmt.target)}"
                    assert isinstance(after.value, ast.Constant) and after.value.value.strip()
                    found[ast.unparse(stmt.target)] = (ast.unparse(stmt), after.value.value)
    assert set(served) == set(stub_members())
    assert sum(map(len, served.values())) >= 11
    # The drive's own comment, not its base class's.
    assert served["DriveMembers"]["LINE_DEFAULTS"] == (
        "LINE_DEFAULTS: LineDefaults",
        "Line format and reply timeout when the device opens its own Bus: the family file's"
        " ``[line]`` (19200 8N1, 0.25 s).",
    )
    assert served["DriveMembers"]["SAMPLE_FIELDS"] == (
        "SAMPLE_FIELDS: tuple[str, ...] | None",
        "The names :meth:`sample` gives: the fields of :meth:`telemetry`.",
    )
