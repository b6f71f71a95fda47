"""Generic Modbus RTU instruments (the Taisong v2.1 panel meters of manual 004, and any other
device with holding registers) as Python objects.

The request limits, the value conversions and the identification live in the compiled core
(``InstrumentCore``); this module adds the class, its defaults and the identity record.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterable
from typing import Literal

from benchbus._core import Bus, InstrumentCore
from benchbus._device import BusDevice, LineDefaults, check_baudrate
from benchbus._display import field_table

__all__ = ["Identification", "Instrument"]

#: A Taisong v2.1 meter's request limits (its manual): registers per read and per write.
TAISONG_MAX_READ = 37
TAISONG_MAX_WRITE = 20

#: Which register of a 32-bit value comes first: "big" the high word (the Modbus
#: convention), "little" the low word.
WordOrder = Literal["big", "little"]

#: The object ids of Read Device Identification, by name (Modbus application protocol 6.21).
_OBJECT_NAMES = {
    0: "vendor",
    1: "product_code",
    2: "revision",
    3: "vendor_url",
    4: "product_name",
    5: "model_name",
    6: "user_application_name",
}

#: The read codes of :meth:`Instrument.identify`, by name.
_LEVELS = {"basic": 1, "regular": 2, "extended": 3}


@dataclasses.dataclass(frozen=True)
class Identification:
    """What a device says of itself through Read Device Identification (0x2B / MEI 0x0E)."""

    #: Vendor name (object 0).
    vendor: str | None
    #: Product code (object 1).
    product_code: str | None
    #: Major and minor revision (object 2).
    revision: str | None
    #: Every object the device sent, ``{object id: text}`` (Latin-1), also the regular
    #: (3..6) and private (0x80..0xFF) ones.
    objects: dict[int, str]
    #: The device's conformity level (0x01 basic .. 0x83 extended with single access).
    conformity: int

    def __getitem__(self, name: str) -> str | None:
        """An object by its name ("vendor", "product_name", ...) or None if not sent."""
        for object_id, object_name in _OBJECT_NAMES.items():
            if object_name == name:
                return self.objects.get(object_id)
        raise KeyError(name)

    def _repr_html_(self) -> str:
        """A table of vendor, product code and revision (None if not sent), every other
        object the device sent (by its name, or its id for a private one) and the
        conformity level, for notebooks."""
        rows: list[tuple[str, object, str]] = [
            ("vendor", self.vendor, ""),
            ("product_code", self.product_code, ""),
            ("revision", self.revision, ""),
        ]
        rows.extend(
            (_OBJECT_NAMES.get(object_id, f"object 0x{object_id:02X}"), text, "")
            for object_id, text in sorted(self.objects.items())
            if object_id > 2
        )
        rows.append(("conformity", f"0x{self.conformity:02X}", ""))
        return field_table("Identification", rows)


class Instrument(BusDevice):
    """Any Modbus RTU instrument with holding registers; the defaults fit a Taisong v2.1
    panel meter (manual 004): 9600 8N1, at most 37 registers a read and 20 a write.

    ::

        with bb.Instrument("/dev/ttyUSB0", unit=1) as meter:
            print(meter.read_register(0x0000))             # the measured value
            meter.write_register(0x0005, 100)              # the setpoint SV
            block = meter.read_registers(0x0000, 100)      # 37 + 37 + 26 on the wire
            meter.write_float(0x0100, 21.5, word_order="little")
            print(meter.identify())                        # 0x2B / 0x0E, if supported

    Given a path, the instrument opens its own Bus at ``baudrate`` 8N1 (2400, 4800, 9600 or
    19200, the Taisong's; for other speeds open a Bus yourself); given a Bus, it shares it
    (``timeout`` / ``retries`` then apply to this instrument's requests only; ``baudrate``
    is not used). Reads and writes of any length are split into requests of at most
    ``max_read`` / ``max_write`` registers; writes go at least ``min_write_interval``
    seconds apart. A split write that fails part-way leaves the requests before it written.
    The timeout counts from the start of the request (a request longer than half of it on
    the wire still leaves the device half of it after its end); a long reply's own time on
    the wire comes on top.
    """

    core: InstrumentCore
    #: Line format and reply timeout when the device opens its own Bus.
    LINE_DEFAULTS = LineDefaults(9600, "N", 0.1)

    def __init__(
        self,
        port_or_bus: str | os.PathLike[str] | Bus,
        unit: int = 1,
        max_read: int = TAISONG_MAX_READ,
        max_write: int = TAISONG_MAX_WRITE,
        min_write_interval: float = 0.0,
        baudrate: int = 9600,
        *,
        timeout: float | None = None,
        retries: int | None = None,
    ) -> None:
        """The instrument at ``unit`` on a Bus, or on a port opened at ``baudrate`` 8N1."""
        check_baudrate(baudrate, (2400, 4800, 9600, 19200))
        self._attach(
            port_or_bus,
            lambda bus, t, r: InstrumentCore(
                bus, unit, max_read, max_write, min_write_interval, t, r
            ),
            baudrate=baudrate,
            parity=self.LINE_DEFAULTS.parity,
            timeout=timeout,
            retries=retries,
            default_timeout=self.LINE_DEFAULTS.timeout,
        )

    @property
    def max_read(self) -> int:
        """Most registers one read asks for."""
        return self.core.max_read

    @property
    def max_write(self) -> int:
        """Most registers one write carries."""
        return self.core.max_write

    @property
    def min_write_interval(self) -> float:
        """Least time between two writes, seconds."""
        return self.core.min_write_interval

    # ---- registers -----------------------------------------------------------------------------

    def read_register(self, address: int, decimals: int = 0, signed: bool = False) -> int | float:
        """One register as a value: ``raw / 10**decimals`` (an int when ``decimals`` is 0),
        two's complement if ``signed``."""
        return self.core.read_register(address, decimals, signed)

    def write_register(
        self,
        address: int,
        value: float,
        decimals: int = 0,
        signed: bool = False,
        *,
        function: int = 6,
    ) -> None:
        """Write ``value * 10**decimals`` to one register with 0x06 (or 0x10 if ``function``
        is 16). A value that does not fit or has more decimals raises ValueError before
        anything is sent."""
        self.core.write_register(address, value, decimals, signed, function)

    def read_registers(self, address: int, count: int) -> list[int]:
        """``count`` raw registers from ``address``, in requests of at most ``max_read``."""
        return self.core.read_registers(address, count)

    def write_registers(self, address: int, values: Iterable[int]) -> None:
        """Write raw ``values`` from ``address`` with 0x10, in requests of at most
        ``max_write``."""
        if isinstance(values, (str, bytes, bytearray)):
            raise TypeError("values must be a sequence of ints, not str or bytes")
        if not isinstance(values, Iterable):
            raise TypeError(f"values must be a sequence of ints, got {type(values).__name__}")
        self.core.write_registers(address, list(values))

    # ---- 32-bit values and text ----------------------------------------------------------------

    def read_long(self, address: int, signed: bool = False, word_order: WordOrder = "big") -> int:
        """A 32-bit integer over the registers ``address`` and ``address + 1``."""
        return self.core.read_long(address, signed, word_order)

    def write_long(
        self, address: int, value: int, signed: bool = False, word_order: WordOrder = "big"
    ) -> None:
        """Write a 32-bit integer over two registers, in one request (two if ``max_write`` is
        1)."""
        self.core.write_long(address, value, signed, word_order)

    def read_float(self, address: int, word_order: WordOrder = "big") -> float:
        """An IEEE 754 single-precision float over two registers."""
        return self.core.read_float(address, word_order)

    def write_float(self, address: int, value: float, word_order: WordOrder = "big") -> None:
        """Write an IEEE 754 single over two registers (NaN and infinities are refused)."""
        self.core.write_float(address, value, word_order)

    def read_string(self, address: int, count: int) -> str:
        """``count`` registers as text, two Latin-1 characters a register (high byte
        first), without the NULs that pad it."""
        return self.core.read_string(address, count)

    def write_string(self, address: int, text: str, count: int) -> None:
        """Write ``text`` into ``count`` registers, two characters a register, padded with
        NULs (longer text or characters outside Latin-1 raise ValueError)."""
        self.core.write_string(address, text, count)

    # ---- identification ------------------------------------------------------------------------

    def identify(self, level: Literal["basic", "regular", "extended"] = "basic") -> Identification:
        """Read Device Identification (0x2B / MEI 0x0E) from object 0, following "more
        follows" until the device has sent them all.

        A device without the function raises :class:`~benchbus.ModbusException` with code 1
        (its ``meaning`` says so).
        """
        if not isinstance(level, str):
            raise TypeError(
                f"level must be 'basic', 'regular' or 'extended', got {type(level).__name__}"
            )
        if level not in _LEVELS:
            raise ValueError(f"level must be 'basic', 'regular' or 'extended', got {level!r}")
        conformity, objects = self.core.identify(_LEVELS[level])
        return Identification(
            vendor=objects.get(0),
            product_code=objects.get(1),
            revision=objects.get(2),
            objects=dict(objects),
            conformity=conformity,
        )
