"""Profiles by name: the ones a lab keeps (the folders of ``BENCHBUS_PROFILES``) and the ones
the package ships (``benchbus/profiles/``), each ``NAME.toml``.

Wherever a profile's path is taken (``bb.Profile``, ``bb.Device.from_profile``, the command
line's ``--profile``, ``benchbus.sim.ProfileDevice``, the pytest plugin, a bench file, the
frameworks), a name is taken too: :func:`locate` turns it into its file. A file that exists
wins over a name; a name found nowhere is a :class:`~benchbus.ProfileError` naming the close
ones.
"""

from __future__ import annotations

import os
from pathlib import Path

from benchbus.exceptions import ProfileError

__all__ = [
    "ENV",
    "SHIPPED",
    "families",
    "find",
    "folders",
    "is_name",
    "locate",
    "meant",
    "profiles",
]

#: The environment variable naming a lab's folders of profiles (``os.pathsep`` apart),
#: searched before the shipped ones.
ENV = "BENCHBUS_PROFILES"
#: The folder of the profiles the package ships.
SHIPPED = Path(__file__).parent / "profiles"


def folders() -> list[Path]:
    """The folders searched for a name, in order: ``BENCHBUS_PROFILES``'s (``~`` expanded,
    empty entries skipped), then the shipped one."""
    given = os.environ.get(ENV, "").split(os.pathsep)
    lab = [Path(os.path.expanduser(f.strip())) for f in given if f.strip()]
    return [*lab, SHIPPED]


def find(name: str) -> str | None:
    """The file of the profile called ``name`` in :func:`folders` (the first that has one),
    or None."""
    for folder in folders():
        path = folder / f"{name}.toml"
        if path.is_file():
            return str(path)
    return None


def meant(name: str) -> str:
    """``; the profile called 'NAME' is --profile NAME`` where ``name`` is a profile's name
    (what a command line's error ends with when a file or a family was given for it), else
    ""."""
    return f"; the profile called {name!r} is --profile {name}" if find(name) else ""


def profiles() -> dict[str, str]:
    """Every profile found by name, ``{name: path}`` sorted by name: each ``NAME.toml`` of
    :func:`folders`, the first folder's where two have one name."""
    found: dict[str, str] = {}
    for folder in folders():
        try:
            files = sorted(folder.glob("*.toml"))
        except OSError:
            continue
        for path in files:
            if path.is_file():
                found.setdefault(path.stem, str(path))
    return dict(sorted(found.items()))


def families() -> dict[str, str]:
    """The built-in families' tables (``bb.Profile.family``'s keys), each with the class a
    device of it is used through (``"pbl": "bb.PblDrive"``)."""
    from benchbus._core import Profile
    from benchbus._families import family

    found = {}
    for key in Profile.families():
        device = family(key.split("-")[0]).device
        found[key] = f"bb.{device.__name__}" if device is not None else ""
    return found


def is_name(text: str) -> bool:
    """Whether ``text`` may be a profile's name rather than a path: not empty, no folder in
    it and no ``.toml`` at its end."""
    seps = {os.sep, "/"} | ({os.altsep} if os.altsep else set())
    return bool(text) and not any(s in text for s in seps) and not text.endswith(".toml")


def locate(profile: str | os.PathLike[str], here: str | os.PathLike[str] | None = None) -> str:
    """The file ``profile`` names: itself if it is a file or a path (taken from ``here``,
    the current folder by default), else the profile of that name in :func:`folders`;
    ProfileError for a name found nowhere (naming the close ones, and where a built-in
    family is meant, its class)."""
    try:
        text = os.fsdecode(os.fspath(profile))
    except TypeError:
        raise TypeError(
            "argument 'path': a file (str or os.PathLike) or a profile's name, not"
            f" {type(profile).__name__}"
        ) from None
    given = text if here is None or os.path.isabs(text) else os.path.join(here, text)
    if not is_name(text) or os.path.isfile(given):
        return given
    found = find(text)
    if found is None:
        raise ProfileError(_unknown(text), path=text)
    return found


def _unknown(name: str) -> str:
    """Why ``name`` is no profile: where it was looked for, and what is close."""
    from benchbus._device import did_you_mean

    built_in = families()
    if name in built_in:
        return (
            f"{name}: a built-in family, used through {built_in[name]}"
            f" (its register table: bb.Profile.family({name!r}))"
        )
    searched = [f for f in folders() if f != SHIPPED]
    where = f" in {ENV} ({os.pathsep.join(map(str, searched))})," if searched else ""
    odd = [f"{f}: {'not a folder' if f.exists() else 'no such folder'}" for f in searched]
    odd = [o for o, f in zip(odd, searched) if not f.is_dir()]
    gone = f" ({'; '.join(odd)})" if odd else ""
    try:
        hint = did_you_mean(name, profiles()) or did_you_mean(name, built_in)
    except UnicodeError:  # a name of bytes no text holds: nothing is close to it
        hint = ""
    return (
        f"{name}: no such file, nor a profile of that name{where} nor shipped{gone}{hint}"
        " (`benchbus profile list` lists them)"
    )
