"""benchbus devices as QCoDeS instruments: one Parameter per register of the device's profile.

::

    import benchbus as bb
    from benchbus.qcodes import instrument

    dev = bb.Device.from_profile("xy_md02.toml", "/dev/ttyUSB0")
    sensor = instrument(dev, "sensor")
    sensor.temperature()                  # 21.5, unit "degC", label "air temperature"
    sensor.temperature_correction(-0.5)   # checked by its validator, then written
    sensor.unit_address(300)              # ValueError: nothing is sent
    drive = instrument(bb.Drive(dev.bus, 2), "drive")   # a built-in device, the same way

Needs QCoDeS (``pip install 'benchbus[qcodes]'``, Python 3.11 or later). Without it the
module still imports, and :func:`instrument` raises an ImportError that says what to install.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Hashable, Mapping
from typing import TYPE_CHECKING, Any, Protocol

from benchbus._extras import need_framework

if TYPE_CHECKING:
    from benchbus._core import Profile
    from benchbus._profile import ProfileRegister

__all__ = ["DeviceInstrument", "Members", "RegisterDevice", "instrument", "validator"]

#: Why QCoDeS could not be imported (None: it is there).
_MISSING: ImportError | None = None
try:
    import numpy as np
    from qcodes import validators as vals
    from qcodes.instrument import Instrument
    from qcodes.parameters import Parameter
except ImportError as exc:  # the module imports without the extra; instrument() says so
    _MISSING = exc


class RegisterDevice(Protocol):
    """What :func:`instrument` wraps: any benchbus device, with its register table as
    ``profile`` and a register read and written by name with ``get`` / ``set``."""

    @property
    def profile(self) -> Profile:
        """The device's registers (a :class:`benchbus.Profile`)."""
        ...

    def get(self, name: str) -> Any:
        """The register ``name``, in engineering units."""
        ...

    def set(self, name: str, value: Any) -> None:
        """Write ``value`` to the register ``name``, checked before anything is sent."""
        ...


def _needs_qcodes() -> None:
    """ImportError saying what to install, when QCoDeS is missing."""
    need_framework("benchbus.qcodes", "QCoDeS", "qcodes", "qcodes", _MISSING)


def _plain(value: Any) -> Any:
    """``value`` as the device takes it: a numpy scalar (what a sweep gives) as the Python
    ``bool``, ``int``, ``float`` or ``str`` it holds."""
    return value.item() if isinstance(value, np.generic) else value


if _MISSING is None:

    class Members(vals.Enum):
        """The values an enum register takes: a member, its name or its number (not a bool,
        nor a float)."""

        def __init__(self, members: Mapping[int, str]) -> None:
            """The members ``{number: name}`` of a register's ``enum``."""
            super().__init__(*members, *members.values())
            #: The members, ``{number: name}``.
            self.members: dict[int, str] = dict(members)

        def validate(self, value: Hashable, context: str = "") -> None:
            """TypeError for a value of the wrong kind, ValueError for one that is not a
            member."""
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer, str)):
                raise TypeError(
                    f"{value!r} is not a member's name or number "
                    f"({', '.join(self.members.values())}); {context}"
                )
            super().validate(value, context)

        def __repr__(self) -> str:
            """The members, ``<Members: 0=off, 1=heat>``."""
            shown = ", ".join(f"{n}={name}" for n, name in self.members.items())
            return f"<Members: {shown}>"

    def validator(register: ProfileRegister) -> vals.Validator[Any]:
        """The QCoDeS validator of a register: ``Bool`` for a bool, ``Strings`` (at most two
        characters a register) for a string, :class:`Members` for an enum, ``Ints`` for an
        unscaled integer and ``Numbers`` for a float or a scaled value, over the register's
        ``min`` / ``max`` (its type's range where the profile gives none); any number for
        a register with ``decimals``, whose range is in digits whose places change (the
        write checks it at them)."""
        if register.type == "bool":
            return vals.Bool()
        if register.type == "string":
            length = register.length
            return vals.Strings(max_length=2 * length) if length else vals.Strings()
        if register.enum:
            return Members(register.enum)
        if register.decimals is not None:  # digits whose places change: checked at them
            return vals.Numbers()
        low = -math.inf if register.min is None else register.min
        high = math.inf if register.max is None else register.max
        whole = register.integer_range()
        if whole is not None:
            first = whole[0] if math.isinf(low) else max(math.ceil(low), whole[0])
            last = whole[1] if math.isinf(high) else min(math.floor(high), whole[1])
            return vals.Ints(first, last) if first < last else vals.Enum(first)
        return vals.Numbers(low, high) if low < high else vals.Enum(low)

    def _docstring(register: ProfileRegister) -> str:
        """What a register's Parameter says of itself: its description and where it lies."""
        where = f"{register.table} {register.address:#06x}, {register.type}"
        access = {
            "r": "read-only",
            "w": "write-only",
            "rw": "read and write",
            "rw-stopped": "read, and write while stopped",
        }[register.access]
        return f"{register.description or register.name} ({where}, {access})"

    class DeviceInstrument(Instrument):
        """A benchbus device as a QCoDeS instrument: one Parameter per register of its
        profile, named after the register (see :func:`instrument`)."""

        def __init__(
            self,
            name: str,
            device: RegisterDevice,
            *,
            close_device: bool = False,
            label: str | None = None,
        ) -> None:
            """The instrument ``name`` (unique among the QCoDeS instruments open) for
            ``device``; see :func:`instrument`."""
            if not all(hasattr(device, member) for member in ("profile", "get", "set")):
                raise TypeError(
                    "a QCoDeS instrument is made of a benchbus device (with .profile, .get "
                    f"and .set), got {type(device).__name__}"
                )
            profile = device.profile
            super().__init__(
                name,
                label=profile.name if label is None else label,
                metadata={
                    "benchbus": {
                        "profile": profile.name,
                        "description": profile.description,
                        "unit": getattr(device, "unit", None),
                    }
                },
            )
            #: The benchbus device the parameters read and write.
            self.device = device
            self._close_device = close_device
            for register in profile.registers:
                if register.name in self.parameters:
                    raise ValueError(
                        f"{profile.name}: a register may not be called {register.name!r} "
                        "in QCoDeS (the instrument has a parameter of that name)"
                    )
                self.add_parameter(
                    register.name,
                    parameter_class=Parameter,
                    label=register.description or register.name,
                    unit=register.unit,
                    get_cmd=(
                        functools.partial(device.get, register.name)
                        if register.access != "w"
                        else False
                    ),
                    set_cmd=(
                        functools.partial(_set, device, register.name)
                        if register.access != "r"
                        else False
                    ),
                    vals=validator(register),
                    docstring=_docstring(register),
                    metadata={
                        "table": register.table,
                        "address": register.address,
                        "type": register.type,
                        "access": register.access,
                    },
                )

        def get_idn(self) -> dict[str, str | None]:
            """The profile's maker as the vendor and its model (else its name) as the model:
            a Modbus device has no ``*IDN?``."""
            profile = self.device.profile
            return {
                "vendor": profile.maker or None,
                "model": profile.model or profile.name,
                "serial": None,
                "firmware": None,
            }

        def close(self) -> None:
            """Forget the instrument (its name is free again); with ``close_device``, close
            the device too, which closes a Bus it opened itself but never a Bus it was
            given (that one stays open for its other devices)."""
            device = self.__dict__.get("device")
            if self.__dict__.get("_close_device") and device is not None:
                close = getattr(device, "close", None)
                if callable(close):
                    close()
            super().close()

    def _set(device: RegisterDevice, name: str, value: Any) -> None:
        """``device.set(name, value)``, a numpy scalar as its Python value."""
        device.set(name, _plain(value))


def instrument(
    device: RegisterDevice,
    name: str,
    *,
    close_device: bool = False,
    label: str | None = None,
) -> DeviceInstrument:
    """A QCoDeS instrument called ``name`` for a benchbus device: one Parameter per register
    of ``device.profile``, named after the register.

    Each Parameter has the register's ``unit``, its description as the ``label`` (its name
    where it has none) and a validator from its range (see :func:`validator`), which
    refuses a value before anything is sent; the device checks it again (the steps of a
    scaled register, the text a string register holds). ``get`` reads the register with
    ``device.get(name)`` (an enum register gives the profile's ``IntEnum`` member, a number
    in a dataset), ``set`` writes it with ``device.set(name, value)`` (a numpy scalar as its
    Python value). A read-only register has no ``set`` (its Parameter is not ``settable``),
    a write-only one no ``get``. A register whose name the instrument already uses as an
    attribute (``label``, ``log``, ``metadata``...) is reached as ``inst.parameters[name]``.

    Any benchbus device works that has its register table as ``.profile`` and ``get`` /
    ``set`` by register name (:class:`RegisterDevice`), such as ``bb.Device.from_profile``.

    QCoDeS keeps one open instrument per name (another with the same name raises KeyError):
    ``inst.close()`` (or ``qcodes.Instrument.close_all()``) frees it. The device belongs to
    the caller and stays open, unless ``close_device=True`` hands it over: then closing the
    instrument (also when QCoDeS closes it as it is garbage-collected) closes the device,
    which closes a Bus it opened on its own port, never a Bus shared with other devices.
    """
    _needs_qcodes()
    return DeviceInstrument(name, device, close_device=close_device, label=label)


if not TYPE_CHECKING:

    def __getattr__(name: str) -> Any:
        """The QCoDeS classes and functions, or the ImportError saying what to install."""
        if name in ("DeviceInstrument", "Members", "validator"):
            _needs_qcodes()
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
