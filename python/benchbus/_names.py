"""The names a device profile may give its registers and enum members, by Python's rules.

A profile's register becomes an attribute of its device (``dev.temperature``) and an enum's
member a member of an ``IntEnum``; which names Python takes is Python's business, so the
rules are here, not in the core: the core's profile reader checks the form of a name (an
ASCII identifier) and asks these two functions, with the file's line for the error, which
is how every profile read from Python is checked (``bb.Profile``, ``Device.from_profile``).
Each returns why the name cannot be, or None.
"""

from __future__ import annotations

import keyword

__all__ = ["RESERVED", "class_name", "member_refusal", "register_refusal"]

#: Names a register may not take: the members every profile device has, and those its
#: QCoDeS and ophyd-async wrappers give it (``name``, ``describe``...).
RESERVED = frozenset(
    {
        "IDENTITY",
        "LINE_DEFAULTS",
        "SAMPLE_FIELDS",
        "bus",
        "close",
        "describe",
        "enums",
        "from_profile",
        "get",
        "get_many",
        "name",
        "profile",
        "read",
        "read_many",
        "record",
        "registers",
        "sample",
        "sample_units",
        "set",
        "set_many",
        "table",
        "unit",
        "units",
        "verify_identity",
        "write",
        "write_many",
    }
)

#: Names Python's ``enum`` refuses as members beyond the ``_sunder_`` and ``__dunder__``
#: names: ``mro``, the method every class has ("invalid enum member name").
_ENUM_RESERVED = frozenset({"mro"})


def class_name(register: str) -> str:
    """The name of the enum class of the register ``register``: its words, capitalised,
    joined (``op_mode`` gives ``OpMode``)."""
    return "".join(part[:1].upper() + part[1:] for part in register.split("_"))


def register_refusal(name: str) -> str | None:
    """Why a register may not be called ``name`` (an ASCII identifier), or None."""
    if keyword.iskeyword(name):
        return f'"{name}" is not a Python identifier'
    if name in RESERVED or name.startswith("_"):
        return f'"{name}" would shadow a member of the device'
    return None


def member_refusal(register: str, member: str) -> str | None:
    """Why ``member`` (an ASCII identifier) may not be a member of the enum of the register
    ``register``, or None. These are Python's rules (``enum.py``, 3.9 to 3.14), each of
    which fails the class's creation or leaves the name out of its members: a keyword; a
    ``_sunder_`` name (``_missing_``, ``_order_``: Enum keeps them); a ``__dunder__`` name;
    ``mro``; a private name of the class (``_Mode__fast`` in ``Mode``), which Python 3.11
    and later do not make a member, and the bare ``_Mode__``, on which 3.9's enum fails.
    Names such as ``name``, ``value``, ``_9600`` or ``name_1`` are members like any other."""
    shown = f'"{member}"'
    private = f"_{class_name(register)}__"
    if keyword.iskeyword(member):
        return f"{shown} is not a Python identifier"
    if _wrapped(member, 1):
        return f"{shown} is a _sunder_ name, which Python's enum keeps for itself"
    if _wrapped(member, 2):
        return f"{shown} is a __dunder__ name, one of Python's special names"
    if member in _ENUM_RESERVED:
        return f"{shown} is a method of every Python class, which an enum member may not shadow"
    if member == private:
        return (
            f"{shown} is the prefix of the private names of the enum {class_name(register)},"
            " which Python 3.9's enum cannot take"
        )
    if member.startswith(private) and not member.endswith("__"):
        return (
            f"{shown} is a private name of the enum {class_name(register)}, which Python 3.11"
            " and later do not make a member"
        )
    return None


def _wrapped(name: str, n: int) -> bool:
    """Whether ``name`` has ``n`` underscores each side and no more: a ``_sunder_`` name for
    1, a ``__dunder__`` name for 2, as Python's ``enum.py`` tells them."""
    bar = "_" * n
    inner = name[n:-n]
    return (
        len(name) > 2 * n
        and name.startswith(bar)
        and name.endswith(bar)
        and not inner.startswith("_")
        and not inner.endswith("_")
    )
