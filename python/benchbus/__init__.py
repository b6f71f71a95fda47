"""benchbus: a Modbus RTU master for lab automation.

Drive RS485 motor drives and process controllers from Python scripts, notebooks and pytest
benches, with the wire timing done right and every failure raised as a clear exception::

    import benchbus as bb

    with bb.Bus("/dev/ttyUSB0", baudrate=19200, timeout=0.1, retries=2) as bus:
        speed = bus.read_holding_registers(1, 0x3006, 1)[0]
        bus.write_register(1, 0x2001, 1500)

    with bb.Drive("/dev/ttyUSB0", unit=1) as drive:   # a BLD2 / BLD3H / ZBLD.C20 drive
        drive.speed_setpoint = 1500
        drive.forward()

    with bb.J2Controller("/dev/ttyUSB1", unit=1) as j2:   # a J2 PID controller
        j2.sv = 120.0
        print(j2.pv)

Simulated devices for tests without hardware are in :mod:`benchbus.sim`.
"""

import typing as _typing

from benchbus._core import (
    Bus,
    CancelToken,
    Poll,
    Profile,
    Stats,
    __version__,
    crc16,
    from_registers,
    list_ports,
    refresh_logging,
    to_registers,
)
from benchbus._device import is_unknown
from benchbus._doctor import Finding, doctor
from benchbus._drive import (
    C20ControlMode,
    CommandSource,
    ControlMode,
    Drive,
    DriveRegister,
    DriveState,
    DriveStatus,
    DriveTelemetry,
    Fault,
    Model,
    SpeedSource,
    StopMode,
)
from benchbus._gateway import Gateway, GatewayStats
from benchbus._instrument import Identification, Instrument
from benchbus._j2 import InputType, J2Controller, J2Mode, J2Parameter, J2Status, Limits, Pid
from benchbus._keepalive import KeepAlive
from benchbus._pbl import (
    DecelMode,
    Direction,
    DirectionSetting,
    PblControlMode,
    PblDrive,
    PblParameter,
    PblStatus,
    PblTelemetry,
    StartStopSource,
)
from benchbus._profile import Device, ProfileLimits, ProfileLine, ProfileRegister
from benchbus._record import Recording
from benchbus._results import CommEventCounter, CommEventLog
from benchbus._wirelog import enable_wire_log
from benchbus.exceptions import (
    BenchbusError,
    Cancelled,
    CrcError,
    FrameError,
    GatewayError,
    ModbusException,
    PortError,
    ProfileError,
    ResponseTimeout,
    StateError,
    WrongDevice,
)

__all__ = [
    "BenchbusError",
    "Bus",
    "C20ControlMode",
    "CancelToken",
    "Cancelled",
    "CommEventCounter",
    "CommEventLog",
    "CommandSource",
    "ControlMode",
    "CrcError",
    "DecelMode",
    "Device",
    "Direction",
    "DirectionSetting",
    "Drive",
    "DriveRegister",
    "DriveState",
    "DriveStatus",
    "DriveTelemetry",
    "Fault",
    "Finding",
    "FrameError",
    "Gateway",
    "GatewayError",
    "GatewayStats",
    "Identification",
    "InputType",
    "Instrument",
    "J2Controller",
    "J2Mode",
    "J2Parameter",
    "J2Status",
    "KeepAlive",
    "Limits",
    "ModbusException",
    "Model",
    "PblControlMode",
    "PblDrive",
    "PblParameter",
    "PblStatus",
    "PblTelemetry",
    "Pid",
    "Poll",
    "PortError",
    "Profile",
    "ProfileError",
    "ProfileLimits",
    "ProfileLine",
    "ProfileRegister",
    "Recording",
    "ResponseTimeout",
    "SpeedSource",
    "StartStopSource",
    "StateError",
    "Stats",
    "StopMode",
    "WrongDevice",
    "__version__",
    "aio",
    "crc16",
    "doctor",
    "enable_wire_log",
    "from_registers",
    "is_unknown",
    "list_ports",
    "refresh_logging",
    "to_registers",
]

if _typing.TYPE_CHECKING:
    from benchbus import aio
else:

    def __getattr__(name: str) -> object:
        """:mod:`benchbus.aio` when first asked for: it imports asyncio, which takes some
        70 ms, half of what ``import benchbus`` would (a command line's start)."""
        if name == "aio":
            import benchbus.aio

            return benchbus.aio
        raise AttributeError(f"module 'benchbus' has no attribute {name!r}")

    def __dir__() -> list[str]:
        """The module's names, :mod:`benchbus.aio` among them before it is imported."""
        return sorted({*globals(), "aio"})
