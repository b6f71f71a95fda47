"""First steps with benchbus, on a simulated device (no hardware needed).

A simulated instrument at unit 1 serves holding registers on a pseudo-terminal; benchbus
talks to it exactly as it would to an RS485 adapter. Run: ``python examples/first_steps.py``.
"""

from __future__ import annotations

import benchbus as bb
from benchbus.sim import RegisterDevice, Simulator


def main() -> None:
    """Read, write, see an exception and a timeout, and print the bus statistics."""
    device = RegisterDevice({0x0000: 1000, 0x0005: 250}, max_read=37, max_write=20)
    with (
        Simulator({1: device}, baudrate=19200) as sim,
        bb.Bus(sim.port, baudrate=19200, timeout=0.1, retries=2) as bus,
    ):
        print(f"simulated instrument on {sim.port}: {bus!r}")
        print(f"  char time {bus.char_time * 1e6:.1f} us, t3.5 {bus.t3_5 * 1e3:.3f} ms")

        pv, _, _, _, _, sv = bus.read_holding_registers(1, 0x0000, 6)
        print(f"  measured value = {pv}, setpoint = {sv}")

        bus.write_register(1, 0x0005, 100)
        bus.write_registers(1, 0x0008, [100, 200])
        print(
            f"  after writing: setpoint = {bus.read_holding_registers(1, 0x0005, 1)[0]},"
            f" 0x0008..9 = {bus.read_holding_registers(1, 0x0008, 2)}"
        )
        assert device.registers[0x0005] == 100

        try:
            bus.read_holding_registers(1, 0x0000, 38)  # over the instrument's 37-register limit
        except bb.ModbusException as e:
            print(f"  refused at once (code {e.code}): {e.meaning}")

        sim.set_silent(1)
        try:
            bus.read_holding_registers(1, 0x0000, 1)
        except bb.ResponseTimeout as e:
            print(f"  silent unit: {e}")
        sim.set_silent(1, False)

        print(f"  {bus.stats}")


if __name__ == "__main__":
    main()
