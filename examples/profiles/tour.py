"""The three example profiles, each served by its own simulator and driven through
``bb.Device.from_profile`` (no hardware needed). Run: ``python examples/profiles/tour.py``.

- ``xy_md02.toml``: a temperature and humidity sensor on input registers, settings in
  holding registers, an enum.
- ``relay_board.toml``: eight relays on coils, eight inputs, bits of a command register.
- ``flow_controller.toml``: floats in word-swapped order, 32- and 64-bit values, an
  operating mode and a name, one register a request (``block_reads = false``).
"""

from __future__ import annotations

from pathlib import Path

import benchbus as bb
from benchbus.sim import ProfileDevice, Simulator

HERE = Path(__file__).resolve().parent


def show(dev: bb.Device) -> None:
    """One line per readable register: name, value, unit."""
    units = dev.sample_units()
    for name, value in dev.sample().items():
        print(f"    {name:24} {value!s:>14} {units[name]}".rstrip())


def main() -> None:
    """Each profile: its table, a sample, a write or two and what refuses before sending."""
    for file, writes in (
        ("xy_md02.toml", {"temperature_correction": -0.5, "baud": "b19200"}),
        ("relay_board.toml", {"relay3": True, "all_off": True}),
        ("flow_controller.toml", {"setpoint": 120.5, "mode": "purge"}),
    ):
        profile = bb.Profile(HERE / file)
        with Simulator({1: ProfileDevice(profile.path)}) as sim, bb.Bus(sim.port) as bus:
            dev = bb.Device.from_profile(profile, bus, unit=1)
            requests = len(sim.requests)
            print(f"{profile.name} ({profile.description}), {len(profile)} registers")
            show(dev)
            print(f"  one sample took {len(sim.requests) - requests} requests")
            for name, value in writes.items():
                dev.write(name, value)
                print(f"  wrote {name} = {value!r}: reads back {dev.read(name)!s}")
            requests = len(sim.requests)
            try:
                dev.write(profile.registers[0].name, "not a value")
            except (TypeError, ValueError) as refused:
                print(f"  refused: {refused} ({len(sim.requests) - requests} requests sent)")


if __name__ == "__main__":
    main()
