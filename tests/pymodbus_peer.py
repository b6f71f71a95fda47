"""A third-party Modbus server: pymodbus's own server and datastore, on loopback.

The simulators in ``benchbus.sim`` are the library's judges for the seed devices; this peer
is another's: pymodbus serves coils, discrete inputs, holding and input registers, and the
serial line functions (0x07, 0x08, 0x11) from its own code, over Modbus TCP or RTU frames
over TCP, or on a serial line (a pseudo-terminal). It is the one test module that knows
pymodbus's server API (3.16: the datastore classes are deprecated for 4.0, and a sequential
block's address is offset by one).
"""

from __future__ import annotations

import asyncio
import logging
import os
import select
import threading
import tty
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager

from pymodbus.datastore import (
    ModbusDeviceContext,
    ModbusSequentialDataBlock,
    ModbusServerContext,
)
from pymodbus.framer import FramerType
from pymodbus.server import ModbusBaseServer, ModbusSerialServer, ModbusTcpServer

#: The peer's tables at unit 1, from address 0.
COILS = [1, 0, 1, 1, 0, 0, 1, 1, 1, 0] + [0] * 1990
DISCRETE = [0, 1] * 1000
HOLDING = list(range(200))
INPUT = [1000 + i for i in range(200)]


def _block(values: Sequence[int]) -> ModbusSequentialDataBlock:
    # 3.16 offsets a sequential block's address by one: 1 is protocol address 0.
    return ModbusSequentialDataBlock(1, list(values))


#: A unit's four tables: ``{"coil": [...], "discrete": [...], "holding": [...], "input":
#: [...]}``, each from address 0.
Tables = Mapping[str, Sequence[int]]

#: The tables :func:`pymodbus_server` serves unless given others.
PEER_TABLES: Tables = {"coil": COILS, "discrete": DISCRETE, "holding": HOLDING, "input": INPUT}


def _context(tables: Tables = PEER_TABLES) -> ModbusServerContext:
    device = ModbusDeviceContext(
        co=_block(tables["coil"]),
        di=_block(tables["discrete"]),
        hr=_block(tables["holding"]),
        ir=_block(tables["input"]),
    )
    return ModbusServerContext(devices={1: device}, single=False)


@contextmanager
def _serving(create: Callable[[], ModbusBaseServer]) -> Iterator[ModbusBaseServer]:
    """The server ``create`` builds (in the event loop of a thread of its own), serving."""
    logging.getLogger("pymodbus").setLevel(logging.ERROR)
    ready = threading.Event()
    stop = threading.Event()
    found: list[ModbusBaseServer] = []

    async def serve() -> None:
        server = create()
        await server.serve_forever(background=True)
        found.append(server)
        ready.set()
        while not stop.is_set():
            await asyncio.sleep(0.02)
        await server.shutdown()

    thread = threading.Thread(target=lambda: asyncio.run(serve()), daemon=True)
    thread.start()
    try:
        assert ready.wait(10), "the pymodbus server did not start"
        yield found[0]
    finally:
        stop.set()
        thread.join(10)


@contextmanager
def pymodbus_server(
    rtu: bool, *, ascii: bool = False, tables: Tables = PEER_TABLES
) -> Iterator[str]:
    """A pymodbus TCP server on 127.0.0.1 serving unit 1 (``tables``: by default
    ``COILS``, ``DISCRETE``, ``HOLDING``, ``INPUT``): its URL, ``rtu+tcp://`` (RTU frames;
    with ``ascii``, Modbus ASCII frames) or ``tcp://`` (MBAP)."""

    def create() -> ModbusBaseServer:
        return ModbusTcpServer(
            _context(tables),
            framer=FramerType.ASCII if ascii else FramerType.RTU if rtu else FramerType.SOCKET,
            address=("127.0.0.1", 0),
        )

    with _serving(create) as server:
        assert server.transport is not None
        port = server.transport.sockets[0].getsockname()[1]
        yield f"{'rtu+tcp' if rtu or ascii else 'tcp'}://127.0.0.1:{port}"


@contextmanager
def pymodbus_serial_server() -> Iterator[str]:
    """pymodbus's serial server (RTU, 19200 8N1) on a pseudo-terminal, serving unit 1 as
    :func:`pymodbus_server` does: the path of the line's other end, for a Bus.

    Two pseudo-terminals, their masters joined by a thread that copies bytes both ways: the
    server opens one's slave end, the Bus the other's, as two ends of one cable. (3.16
    answers any other unit with exception 4 as if it were unit 1's failure, whatever
    ``ignore_missing_devices`` says: an absent unit is not for this peer to play.)"""
    pairs = [os.openpty(), os.openpty()]
    for _, slave in pairs:
        tty.setraw(slave)
    masters = [master for master, _ in pairs]
    stop = threading.Event()

    def carry() -> None:
        while not stop.is_set():
            for master in select.select(masters, [], [], 0.02)[0]:
                data = os.read(master, 4096)
                os.write(masters[1 - masters.index(master)], data)

    carrier = threading.Thread(target=carry, daemon=True)
    carrier.start()

    def create() -> ModbusBaseServer:
        return ModbusSerialServer(
            _context(),
            framer=FramerType.RTU,
            port=os.ttyname(pairs[0][1]),
            baudrate=19200,
        )

    try:
        with _serving(create):
            yield os.ttyname(pairs[1][1])
    finally:
        stop.set()
        carrier.join(5)
        for master, slave in pairs:
            os.close(master)
            os.close(slave)
