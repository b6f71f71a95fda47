"""Simulated Modbus devices on pseudo-terminals or loopback TCP, for tests without hardware.

::

    import benchbus as bb
    from benchbus.sim import RegisterDevice, Simulator

    with Simulator({1: RegisterDevice({0x3006: 1450})}) as sim, bb.Bus(sim.port) as bus:
        assert bus.read_holding_registers(1, 0x3006, 1) == [1450]
        sim.set_silent(1)  # now unit 1 times out

A device simulator subclasses :class:`SimDevice` (or :class:`RegisterDevice`) and raises
:class:`SimException` from its handlers to answer with an exception reply.
:class:`RegisterDevice` is a whole Modbus unit: holding and input registers, coils and
discrete inputs (``dev.coils[20] = True``, ``sim.peek(1, 20, table="coils")``), and every
function a master needs (0x01..0x06, 0x0F, 0x10, 0x16, 0x17, 0x07, 0x08 / 0x0000, 0x11)
with the Modbus Application Protocol's limits and exception codes; any other function is
answered with exception 1, as is any function a device does not declare in
:attr:`SimDevice.functions` (the families declare their manuals'; :data:`BASIC_FUNCTIONS`
and :data:`STANDARD_FUNCTIONS` are the two sets a device of your own may start from).
:class:`DriveDevice` simulates a BLD2 / BLD3H / ZBLD.C20 brushless drive,
:class:`PblDevice` a PBL-series brushless drive, :class:`J2Device` a J2-series PID
temperature controller with a thermal process under its control, :class:`TaisongDevice` a
Taisong panel instrument (a measured value moving toward its setpoint) and
:class:`Atv31Device` the ATV31 drive of the Taisong manual's Modbus section, with Read Device
Identification (paged on request, and the manual's 6-byte error form). Each refuses what its
manual does not allow, among it requests for more registers than the manual's frame takes
(:attr:`SimDevice.max_read` / :attr:`SimDevice.max_write`: a BLD drive reads one register a
request, a PBL drive 61, a J2 16, a Taisong meter 37), with exception 3.
:class:`ProfileDevice` serves a device profile (a TOML file of registers) of your own:
every table it declares, values encoded as it says, its access, ranges and limits.

The same units can sit behind a Modbus TCP gateway instead:
``Simulator(devices, network="tcp")`` (MBAP) or ``network="rtu+tcp"`` (RTU frames over TCP)
makes :attr:`Simulator.port` a URL (``tcp://127.0.0.1:N``) served by a pymodbus TCP server
behind a proxy that logs the frames and injects the faults, among them
:meth:`Simulator.reset_next` (a reply cut by a connection reset),
:meth:`Simulator.refuse_connections` and :meth:`Simulator.drop_connections`.

A noisy line is one argument away: ``Simulator(devices, faults=Faults(rate=0.05, seed=1))``
spoils 5 % of the replies with bit flips, dropped bytes, truncation, garbage, late,
duplicated and wrong-unit replies (:class:`Faults`), and ``sim.fault_counts`` says which.

Pure Python on pymodbus and pyserial (``pip install "benchbus[sim]"``); it does not need the
compiled core.
"""

from __future__ import annotations

from benchbus.sim._device import (
    BASIC_FUNCTIONS,
    STANDARD_FUNCTIONS,
    RegisterDevice,
    SimDevice,
    SimException,
)
from benchbus.sim._drive import DriveDevice
from benchbus.sim._faults import FAULT_KINDS, Faults
from benchbus.sim._instrument import Atv31Device, TaisongDevice
from benchbus.sim._j2 import J2Device
from benchbus.sim._pbl import PblDevice
from benchbus.sim._profile import ProfileDevice
from benchbus.sim._simulator import Simulator

__all__ = [
    "BASIC_FUNCTIONS",
    "FAULT_KINDS",
    "STANDARD_FUNCTIONS",
    "Atv31Device",
    "DriveDevice",
    "Faults",
    "J2Device",
    "PblDevice",
    "ProfileDevice",
    "RegisterDevice",
    "SimDevice",
    "SimException",
    "Simulator",
    "TaisongDevice",
]
