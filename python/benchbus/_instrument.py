"""Generic Modbus RTU instruments (the Taisong v2.1 panel meters of manual 004, and any other
device with holding registers) as Python objects.

The request limits, the value conversions, the identification and every call to the
instrument live in the compiled base class (``InstrumentCore``); this module adds the
class's defaults, the identity record, the repr and the context manager.
"""

from __future__ import annotations

import dataclasses
import os

from benchbus._core import Bus, InstrumentCore
from benchbus._device import BusDevice, LineDefaults, check_baudrate
from benchbus._display import field_table

__all__ = ["Identification", "Instrument"]

#: A Taisong v2.1 meter's request limits (its manual): registers per read and per write.
TAISONG_MAX_READ = 37
TAISONG_MAX_WRITE = 20

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


class Instrument(InstrumentCore, BusDevice):
    """Any Modbus instrument, in all four tables (holding and input registers, coils,
    discrete inputs); the defaults fit a Taisong v2.1 panel meter (manual 004): 9600 8N1, at
    most 37 registers a read and 20 a write.

    ::

        with bb.Instrument("/dev/ttyUSB0", unit=1) as meter:
            print(meter.read_register(0x0000))             # the measured value
            meter.write_register(0x0005, 100)              # the setpoint SV
            block = meter.read_registers(0x0000, 100)      # 37 + 37 + 26 on the wire
            meter.write_float(0x0100, 21.5, order="CDAB")    # low word first
            power = meter.read_float(0x000C, function=4)   # an input register
            meter.write_coil(0x0002, True)                 # a relay
            print(meter.identify())                        # 0x2B / 0x0E, if supported

    Given a path, the instrument opens its own Bus at ``baudrate`` 8N1 (2400, 4800, 9600 or
    19200, the Taisong's; for other speeds open a Bus yourself); given a Bus, it shares it
    (``timeout`` / ``retries`` then apply to this instrument's requests only; ``baudrate``
    is not used). Reads and writes of any length are split into requests of at most
    ``max_read`` / ``max_write`` registers, and of ``max_read_bits`` / ``max_write_bits``
    coils or inputs (the protocol's 2000 / 1968 unless the device takes fewer); writes go
    at least ``min_write_interval`` seconds apart. Register reads take ``function=4`` for
    input registers (3, holding registers, by default). A split write that fails part-way
    leaves the requests before it written.
    The timeout counts from the start of the request (a request longer than half of it on
    the wire still leaves the device half of it after its end); a long reply's own time on
    the wire comes on top.
    """

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
        max_read_bits: int = 2000,
        max_write_bits: int = 1968,
        timeout: float | None = None,
        retries: int | None = None,
    ) -> None:
        """The instrument at ``unit`` on a Bus, or on a port opened at ``baudrate`` 8N1."""
        check_baudrate(baudrate, (2400, 4800, 9600, 19200))
        line = self.LINE_DEFAULTS._replace(baudrate=baudrate)
        self._on_line(
            port_or_bus,
            unit,
            max_read,
            max_write,
            min_write_interval,
            max_read_bits,
            max_write_bits,
            timeout=timeout,
            retries=retries,
            line=line,
        )
