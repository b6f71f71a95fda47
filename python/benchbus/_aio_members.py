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


class BusDeviceMembers:
    """The members every async device serves from the sync classes' shared bases
    (:class:`benchbus._device.BusDevice` and the compiled ``_Station``), for type checkers:
    each family's members class extends it."""


class DriveMembers(BusDeviceMembers):
    """The members of :class:`benchbus.aio.Drive`, for type checkers."""


class PblDriveMembers(BusDeviceMembers):
    """The members of :class:`benchbus.aio.PblDrive`, for type checkers."""


class J2ControllerMembers(BusDeviceMembers):
    """The members of :class:`benchbus.aio.J2Controller`, for type checkers."""


class InstrumentMembers(BusDeviceMembers):
    """The members of :class:`benchbus.aio.Instrument`, for type checkers."""


class DeviceMembers(BusDeviceMembers):
    """The members of :class:`benchbus.aio.Device`, for type checkers."""
