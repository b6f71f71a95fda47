"""The members of the async devices (:mod:`benchbus.aio`), for type checkers.

At run time these classes are empty: an async device serves every member of its sync
class through ``AsyncDevice.__getattr__``. A family's members class is made here from the
families' registry (:data:`benchbus._families.FAMILIES`), and ``benchbus.aio`` makes the
family's async class from both (and sets it here). Their types, and the async classes, are
in ``_aio_members.pyi`` beside this file, generated from the sync classes by ``python -m
benchbus._aio_stubgen`` (never edited by hand): a method is declared ``async def`` with the
sync method's parameters and result, a property as an awaitable of its value, and what is
read without asking the device with its sync type.
"""

from __future__ import annotations

from benchbus._device import BusDevice
from benchbus._families import FAMILIES

#: The sync classes of the families (those with a class, in the registry's order): each
#: has a members class here and an async class of the same name in ``benchbus.aio``.
SYNC_CLASSES: tuple[type[BusDevice], ...] = tuple(
    f.device for f in FAMILIES if f.device is not None
)


class BusDeviceMembers:
    """The members every async device serves from the sync classes' shared bases
    (:class:`benchbus._device.BusDevice` and the compiled ``_Station``), for type checkers:
    each family's members class extends it."""


class DeviceMembers(BusDeviceMembers):
    """The members of :class:`benchbus.aio.Device`, for type checkers."""


def _members_class(sync: type[BusDevice]) -> type[BusDeviceMembers]:
    """The (empty) members class of the async class of ``sync``."""
    name = f"{sync.__name__}Members"
    doc = f"The members of :class:`benchbus.aio.{sync.__name__}`, for type checkers."
    return type(name, (BusDeviceMembers,), {"__doc__": doc, "__module__": __name__})


globals().update((c.__name__, c) for c in map(_members_class, SYNC_CLASSES))

#: The families' async classes, which ``benchbus.aio`` makes (and sets here, where the stub
#: declares them) and exports.
__all__ = sorted(c.__name__ for c in SYNC_CLASSES)
