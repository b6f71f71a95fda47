"""A third-party Modbus server: pymodbus's own server and datastore, on loopback.

The simulators in ``benchbus.sim`` are the library's judges for the seed devices; this peer
is another's: pymodbus serves coils, discrete inputs, holding and input registers, and the
serial line functions (0x07, 0x08, 0x11) from its own code, over Modbus TCP or RTU frames
over TCP. It is the one test module that knows pymodbus's server API (3.16: the datastore
classes are deprecated for 4.0, and a sequential block's address is offset by one).
"""

from __future__ import annotations

import asyncio
import logging
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager

from pymodbus.datastore import (
    ModbusDeviceContext,
    ModbusSequentialDataBlock,
    ModbusServerContext,
)
from pymodbus.framer import FramerType
from pymodbus.server import ModbusTcpServer

#: The peer's tables at unit 1, from address 0.
COILS = [1, 0, 1, 1, 0, 0, 1, 1, 1, 0] + [0] * 1990
DISCRETE = [0, 1] * 1000
HOLDING = list(range(200))
INPUT = [1000 + i for i in range(200)]


def _block(values: Sequence[int]) -> ModbusSequentialDataBlock:
    # 3.16 offsets a sequential block's address by one: 1 is protocol address 0.
    return ModbusSequentialDataBlock(1, list(values))


@contextmanager
def pymodbus_server(rtu: bool, *, ascii: bool = False) -> Iterator[str]:
    """A pymodbus TCP server on 127.0.0.1 serving unit 1 (``COILS``, ``DISCRETE``,
    ``HOLDING``, ``INPUT``): its URL, ``rtu+tcp://`` (RTU frames; with ``ascii``, Modbus
    ASCII frames) or ``tcp://`` (MBAP)."""
    logging.getLogger("pymodbus").setLevel(logging.ERROR)
    ready = threading.Event()
    stop = threading.Event()
    found: dict[str, int] = {}

    async def serve() -> None:
        device = ModbusDeviceContext(
            co=_block(COILS), di=_block(DISCRETE), hr=_block(HOLDING), ir=_block(INPUT)
        )
        server = ModbusTcpServer(
            ModbusServerContext(devices={1: device}, single=False),
            framer=FramerType.ASCII if ascii else FramerType.RTU if rtu else FramerType.SOCKET,
            address=("127.0.0.1", 0),
        )
        await server.serve_forever(background=True)
        assert server.transport is not None
        found["port"] = server.transport.sockets[0].getsockname()[1]
        ready.set()
        while not stop.is_set():
            await asyncio.sleep(0.02)
        await server.shutdown()

    thread = threading.Thread(target=lambda: asyncio.run(serve()), daemon=True)
    thread.start()
    try:
        assert ready.wait(10), "the pymodbus server did not start"
        yield f"{'rtu+tcp' if rtu or ascii else 'tcp'}://127.0.0.1:{found['port']}"
    finally:
        stop.set()
        thread.join(10)
