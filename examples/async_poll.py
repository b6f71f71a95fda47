"""Poll a drive from asyncio while other tasks run, on a simulated drive (no hardware).

A simulated BLD2 drive serves its registers on a pseudo-terminal. One task spins it up and
polls its speed at 20 Hz through ``bb.aio``; another ticks every 10 ms meanwhile, to show
the event loop is never held up by the line. Leaving the drive's ``async with`` stops the
motor. Run: ``python examples/async_poll.py``.
"""

from __future__ import annotations

import asyncio
import time

import benchbus as bb
from benchbus.sim import DriveDevice, Simulator


async def ticker(lags: list[float]) -> None:
    """Sleep 10 ms again and again, noting how late each wake-up comes."""
    while True:
        before = time.monotonic()
        await asyncio.sleep(0.01)
        lags.append(time.monotonic() - before - 0.01)


async def main(port: str) -> None:
    """Spin the drive up and poll its speed for a second, with a ticker beside it."""
    lags: list[float] = []
    ticks = asyncio.create_task(ticker(lags))
    async with bb.aio.AsyncBus(port, timeout=0.25) as bus, bb.aio.Drive(bus, unit=1) as drive:
        await drive.set("accel_time", 0.5)
        await drive.set("speed_setpoint", 1200)
        await drive.forward()
        poll = bus.poll(1, 0x3006, interval=0.05, duration=1.0)
        samples = 0
        async for t, (speed,) in poll:
            samples += 1
            if round(t / 0.05) % 4 == 0:
                print(f"{t:4.2f} s  {speed:4d} rpm")
        print(f"{samples} samples, {poll.missed} missed")
    ticks.cancel()
    print(f"the loop ticked {len(lags)} times meanwhile, at most {max(lags) * 1e3:.1f} ms late")


if __name__ == "__main__":
    device = DriveDevice()
    with Simulator({1: device}) as sim:
        asyncio.run(main(sim.port))
        print(f"commands the drive received: {device.commands}")
