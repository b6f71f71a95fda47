"""Profiles by name: the ones a lab keeps (the folders of ``BENCHBUS_PROFILES``) and the ones
the package ships (``benchbus/profiles/``), each ``NAME.toml``.

Wherever a profile's path is taken (``bb.Profile``, ``bb.Device.from_profile``, the command
line's ``--profile``, ``benchbus.sim.ProfileDevice``, the pytest plugin, the frameworks), a
name is taken too: :func:`locate` turns it into its file. A file that exists wins over a
name; a name found nowhere is a :class:`~benchbus.ProfileError` naming the close ones.
"""

from __future__ import annotations

import os
from pathlib import Path

from benchbus.exceptions import ProfileError

__all__ = ["ENV", "SHIPPED", "folders", "is_name", "locate", "profiles"]

#: The environment variable naming a lab's folders of profiles (``os.pathsep`` apart),
#: searched before the shipped ones.
ENV = "BENCHBUS_PROFILES"
#: The folder of the profiles the package ships.
SHIPPED = Path(__file__).parent / "profiles"
#: The built-in families' keys (``bb.Profile.family``) and the class each is used through.
FAMILIES = {
    "drive": "bb.Drive",
    "drive-c20": "bb.Drive",
    "pbl": "bb.PblDrive",
    "j2": "bb.J2Controller",
}


def folders() -> list[Path]:
    """The folders searched for a name, in order: ``BENCHBUS_PROFILES``'s (empty entries
    skipped), then the shipped one."""
    given = os.environ.get(ENV, "")
    return [Path(f) for f in given.split(os.pathsep) if f] + [SHIPPED]


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


def is_name(text: str) -> bool:
    """Whether ``text`` may be a profile's name rather than a path: no folder in it and no
    ``.toml`` at its end."""
    seps = {os.sep, "/"} | ({os.altsep} if os.altsep else set())
    return bool(text) and not any(s in text for s in seps) and not text.endswith(".toml")


def locate(profile: str | os.PathLike[str]) -> str:
    """The file ``profile`` names: itself if it is a file or a path, else the profile of
    that name in :func:`folders`; ProfileError for a name found nowhere (naming the close
    ones, and where a built-in family is meant, its class)."""
    text = os.fspath(profile)
    if not is_name(text) or os.path.isfile(text):
        return text
    found = profiles()
    if text in found:
        return found[text]
    raise ProfileError(_unknown(text, found), path=text)


def _unknown(name: str, found: dict[str, str]) -> str:
    """Why ``name`` is no profile: where it was looked for, and what is close."""
    from benchbus._device import did_you_mean

    if name in FAMILIES:
        return (
            f"{name}: a built-in family, used through {FAMILIES[name]}"
            f" (its register table: bb.Profile.family({name!r}))"
        )
    searched = [f for f in folders() if f != SHIPPED]
    where = f" in {ENV} ({os.pathsep.join(map(str, searched))})," if searched else ""
    missing = [str(f) for f in searched if not f.is_dir()]
    gone = f" ({', '.join(missing)}: no such folder)" if missing else ""
    hint = did_you_mean(name, found) or did_you_mean(name, FAMILIES)
    return (
        f"{name}: no such file, nor a profile of that name{where} nor shipped{gone}{hint}"
        " (`benchbus profile list` lists them)"
    )
