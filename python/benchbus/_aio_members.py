"""The members of the async devices (:mod:`benchbus.aio`), for type checkers.

At run time these classes are empty: an async device serves every member of its sync
class through ``AsyncDevice.__getattr__``. Their types are in ``_aio_members.pyi`` beside
this file, generated from the sync classes by ``python -m benchbus._aio_stubgen`` (never
edited by hand): a method is declared ``async def`` with the sync method's parameters and
result, a property as an awaitable of its value, and what is read without asking the
device with its sync type.
"""

from __future__ import annotations

__all__ = [
    "DeviceMembers",
    "DriveMembers",
    "InstrumentMembers",
    "J2ControllerMembers",
    "PblDriveMembers",
]


class DriveMembers:
    """The members of :class:`benchbus.aio.Drive`, for type checkers."""


class PblDriveMembers:
    """The members of :class:`benchbus.aio.PblDrive`, for type checkers."""


class J2ControllerMembers:
    """The members of :class:`benchbus.aio.J2Controller`, for type checkers."""


class InstrumentMembers:
    """The members of :class:`benchbus.aio.Instrument`, for type checkers."""


class DeviceMembers:
    """The members of :class:`benchbus.aio.Device`, for type checkers."""
