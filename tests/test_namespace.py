"""``benchbus``'s public namespace is its ``__all__`` and its submodules: nothing an import
of its own binds (such as ``annotations``, from ``from __future__ import annotations``)
shows as if it were part of the API."""

from __future__ import annotations

import subprocess
import sys
import types

import benchbus as bb


def test_the_public_names_are_all_and_the_submodules() -> None:
    public = {n for n in dir(bb) if not n.startswith("_")}
    extra = {
        n for n in public - set(bb.__all__) if not isinstance(getattr(bb, n), types.ModuleType)
    }
    assert extra == set()
    assert "annotations" not in public
    assert {n for n in bb.__all__ if not n.startswith("_")} <= public


def test_asyncio_is_imported_only_with_benchbus_aio() -> None:
    # A command's start pays for what `import benchbus` imports: asyncio (some 70 ms) comes
    # with `bb.aio`, when first used, and `bb.aio` still works and is listed.
    code = (
        "import sys, benchbus as bb\n"
        "print('asyncio' in sys.modules, 'aio' in dir(bb))\n"
        "print(bb.aio.Drive.__name__, 'asyncio' in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["False", "True", "Drive", "True"]
