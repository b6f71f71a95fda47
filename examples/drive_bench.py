"""A small motor test bench on a simulated BLD2 drive (no hardware needed).

Spins the motor up, samples telemetry, meets an undervoltage fault, resets it and leaves
the ``with`` block, which stops the motor. Run: ``python examples/drive_bench.py``.
"""

from __future__ import annotations

import benchbus as bb
from benchbus.sim import DriveDevice, Simulator


def main() -> None:
    """Run the bench and print what the drive reports."""
    device = DriveDevice("BLD2")
    with Simulator(device) as sim, bb.Drive(sim.port, unit=1) as drive:
        print(f"{drive.model} on {sim.port}, {drive.state}")
        drive.pole_pairs = 4
        drive.accel_time = 0.5
        drive.decel_time = 0.5
        drive.speed_setpoint = 1200
        drive.forward()
        speed = drive.wait_for_speed(1200, tolerance=20, timeout=5)
        t = drive.telemetry()
        print(
            f"  running at {speed} rpm: {t.output_frequency:.2f} Hz, {t.output_current:.2f} A,"
            f" {t.output_power} W, bus {t.bus_voltage:.1f} V, {t.temperature:.1f} degC"
        )

        try:
            drive.pole_pairs = 2
        except bb.ModbusException as e:
            print(f"  refused while running (code {e.code}): {e.meaning}")

        device.inject_fault(0x0A)
        status = drive.status()
        print(f"  {status.state}, fault {status.fault}")
        drive.reset_fault()
        print(f"  after reset: {drive.state}, fault {drive.fault}")
    state = bb.DriveState(device.state)
    print(f"  left the block: the drive got command {device.commands[-1]} (stop), {state}")


if __name__ == "__main__":
    main()
