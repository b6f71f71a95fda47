"""Without the ``sim`` extra (pymodbus, pyserial), ``import benchbus.sim``, the command line
and the pytest plugin all say the same thing: ``pip install 'benchbus[sim]'``; without their
framework, ``benchbus.qcodes``, ``benchbus.ophyd`` and ``benchbus.epics`` say which extra to
install.

Each case runs in a fresh interpreter in which a finder placed first on ``sys.meta_path``
makes the module look uninstalled (``ModuleNotFoundError``, as Python raises for a module
that is not there).
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

PYTHON_DIR = Path(__file__).resolve().parent.parent / "python"
HINT = "pip install 'benchbus[sim]'"

HIDE = textwrap.dedent(
    """
    import importlib.abc, sys

    class Hide(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] == {module!r}:
                raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
            return None

    sys.meta_path.insert(0, Hide())
    """
)


def run_python(code: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(PYTHON_DIR))
    return subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
        cwd=cwd,
        check=False,
    )


@pytest.mark.parametrize("module", ["pymodbus", "serial"])
def test_import_benchbus_sim_says_what_to_install(module: str) -> None:
    done = run_python(
        HIDE.format(module=module)
        + textwrap.dedent(
            """
            try:
                import benchbus.sim
            except ImportError as exc:
                print(type(exc).__name__, exc.name, "|", exc)
            else:
                print("imported")
            """
        )
    )
    assert done.returncode == 0, done.stderr
    kind, name, message = done.stdout.strip().split(" ", 2)
    assert kind == "ModuleNotFoundError"  # an ImportError, as `except ImportError` expects
    assert name == module
    assert message == (
        f"| the simulators need pymodbus and pyserial: {HINT} (No module named {name!r})"
    )


def test_the_library_without_the_extra_still_imports() -> None:
    done = run_python(HIDE.format(module="pymodbus") + "import benchbus; print(benchbus.Bus)")
    assert done.returncode == 0, done.stderr
    assert "benchbus" in done.stdout


def test_an_import_error_of_another_module_is_not_dressed_up() -> None:
    from benchbus._extras import sim_missing

    assert sim_missing(ModuleNotFoundError("No module named 'numpy'", name="numpy")) is None
    assert sim_missing(ImportError("cannot import name 'x'")) is None
    old = ImportError("cannot import name 'SimData' from 'pymodbus.simulator'")
    old.name = "pymodbus.simulator"  # a pymodbus without what the simulators use
    assert HINT in str(sim_missing(old))


def test_the_command_line_gives_the_same_message() -> None:
    done = run_python(
        HIDE.format(module="pymodbus")
        + "from benchbus.cli import main; raise SystemExit(main(['sim', 'drive']))"
    )
    assert done.returncode == 1
    assert done.stdout == ""
    assert done.stderr.splitlines() == [
        f"benchbus: the simulators need pymodbus and pyserial: {HINT} (No module named 'pymodbus')"
    ]


def test_the_pytest_plugin_gives_the_same_message(tmp_path: Path) -> None:
    (tmp_path / "conftest.py").write_text(HIDE.format(module="pymodbus"))
    (tmp_path / "test_one.py").write_text("def test_spin(sim_drive):\n    pass\n")
    done = run_python(
        "import sys, pytest; sys.exit(pytest.main(['-q', '-p', 'no:cacheprovider']))",
        cwd=tmp_path,
    )
    assert done.returncode == 1, done.stdout + done.stderr
    assert f"the simulators need pymodbus and pyserial: {HINT}" in done.stdout
    assert "1 error" in done.stdout


@pytest.mark.parametrize(
    ("module", "hidden", "call", "message"),
    [
        (
            "qcodes",
            "qcodes",
            "qcodes.instrument(object(), 'x')",
            "benchbus.qcodes needs QCoDeS (Python 3.11 or later): pip install 'benchbus[qcodes]'",
        ),
        (
            "ophyd",
            "ophyd_async",
            "ophyd.device(object(), 'x')",
            "benchbus.ophyd needs ophyd-async and Bluesky (Python 3.11 or later): "
            "pip install 'benchbus[bluesky]'",
        ),
        (
            "epics",
            "softioc",
            "epics.Ioc()",
            "benchbus.epics needs pythonSoftIOC: pip install 'benchbus[epics]'",
        ),
    ],
)
def test_a_framework_integration_without_its_extra_says_what_to_install(
    module: str, hidden: str, call: str, message: str
) -> None:
    """``benchbus.qcodes``, ``benchbus.ophyd`` and ``benchbus.epics`` import without their
    framework (the package imports them all), and say what to install when used."""
    done = run_python(
        HIDE.format(module=hidden)
        + textwrap.dedent(
            f"""
            from benchbus import {module}
            try:
                {call}
            except ImportError as exc:
                print(exc.name, "|", exc)
            else:
                print("made")
            """
        )
    )
    assert done.returncode == 0, done.stderr
    name, text = done.stdout.strip().split(" | ", 1)
    assert name == hidden
    assert text == f"{message} (No module named {hidden!r})"
