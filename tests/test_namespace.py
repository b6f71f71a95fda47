"""``benchbus``'s public namespace is its ``__all__`` and its submodules: nothing an import
of its own binds (such as ``annotations``, from ``from __future__ import annotations``)
shows as if it were part of the API."""

from __future__ import annotations

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
