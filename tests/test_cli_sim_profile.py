"""``benchbus sim --profile``: a device profile served by the real command, read by pymodbus's
client and by benchbus's own Bus, and its usage errors.

Each test runs ``python -m benchbus sim --profile ...`` as a user does and reads the
pseudo-terminal path it prints; the values expected are the profiles' own ``default =``
keys (examples/profiles/), encoded as the profile format says.
"""

from __future__ import annotations

import signal
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from pymodbus.client import ModbusSerialClient
from test_cli import ok, one_line_error, readline, run, start, stop

import benchbus as bb

PROFILES = Path(__file__).resolve().parent.parent / "examples" / "profiles"
XY_MD02 = PROFILES / "xy_md02.toml"
FLOW = PROFILES / "flow_controller.toml"
RELAYS = PROFILES / "relay_board.toml"


@contextmanager
def serving(*args: object) -> Iterator[tuple[str, subprocess.Popen[str]]]:
    """``benchbus sim ARGS`` in the background: its port; stopped with SIGTERM after, and
    its exit status checked (0, no traceback)."""
    proc = start("sim", *args)
    try:
        port = readline(proc.stdout).strip()
        assert port.startswith("/dev/"), port
        yield port, proc
    finally:
        status, _, err = stop(proc, signal.SIGTERM)
    assert status == 0, err
    assert "Traceback" not in err


def test_a_profile_is_served_at_its_defaults_to_pymodbus() -> None:
    with serving("--profile", XY_MD02, "--unit", "2,5") as (port, proc):
        said = readline(proc.stderr)
        assert said.startswith("simulating XY-MD02 from xy_md02.toml (unit 2, 5, 9600 baud")
        client = ModbusSerialClient(port, baudrate=9600, parity="N", timeout=1, retries=0)
        assert client.connect()
        try:
            for unit in (2, 5):
                # temperature 21.5 degC and humidity 45.0 %RH at a scale of 0.1
                assert client.read_input_registers(1, count=2, device_id=unit).registers == [
                    215,
                    450,
                ]
                # unit_address 1, baud "b9600" (0), the corrections 0
                assert client.read_holding_registers(0x101, count=4, device_id=unit).registers == [
                    1,
                    0,
                    0,
                    0,
                ]
            assert not client.write_register(0x101, 7, device_id=2).isError()
            refused = client.write_register(0x101, 248, device_id=2)  # max = 247
            assert refused.isError() and refused.exception_code == 3
            assert client.read_holding_registers(0x101, count=1, device_id=2).registers == [7]
            # one device a unit: unit 5 keeps its own
            assert client.read_holding_registers(0x101, count=1, device_id=5).registers == [1]
            # [limits] max_read = 10
            too_many = client.read_holding_registers(0x101, count=11, device_id=5)
            assert too_many.isError() and too_many.exception_code == 3
        finally:
            client.close()


def test_values_and_the_profiles_line_read_by_a_bus() -> None:
    args = ["--profile", FLOW, "--value", "setpoint=12.5", "--value", "mode=purge"]
    with serving(*args, "--value", "zero_offset=-0x10") as (port, proc):
        assert "(unit 1, 19200 baud frame timing)" in readline(proc.stderr)
        # The profile's line is 19200 8E1: the Bus opens the pty at it (a pty has no parity).
        with bb.Bus(port, baudrate=19200, parity="E") as bus:
            assert bb.from_registers(bus.read_input_registers(1, 2, 2), "f32", "CDAB") == [49.75]
            assert bb.from_registers(bus.read_holding_registers(1, 0, 2), "f32", "CDAB") == [12.5]
            assert bb.from_registers(bus.read_input_registers(1, 4, 2), "u32") == [123456]
            assert bus.read_holding_registers(1, 0x10, 1) == [2]  # purge
            assert bb.from_registers(bus.read_holding_registers(1, 0x24, 4), "i64") == [-16]
            name = bus.read_holding_registers(1, 0x30, 8)
            assert b"".join(w.to_bytes(2, "big") for w in name).rstrip(b"\0") == b"FC-200 #1"
            with pytest.raises(bb.ModbusException) as refused:
                bus.read_holding_registers(1, 0x40, 1)  # reset_total is write-only
            assert refused.value.code == 2


def test_coils_and_an_ascii_line_from_the_profile(tmp_path: Path) -> None:
    with (
        serving("--profile", RELAYS, "--value", "relay3=on", "--value", "input2=true") as (
            port,
            _,
        ),
        bb.Bus(port, baudrate=9600) as bus,
    ):
        assert bus.read_coils(1, 0, 7) == [True, False, True, False, False, False, False]
        assert bus.read_discrete_inputs(1, 0, 8) == [False, True] + [False] * 6
        with pytest.raises(bb.ModbusException) as refused:
            bus.read_coils(1, 7, 1)  # relay8 is write-only
        assert refused.value.code == 2
    ascii_profile = tmp_path / "ascii.toml"
    ascii_profile.write_text(
        '[device]\nname = "meter"\n\n[line]\nbaudrate = 4800\nframing = "ascii"\n\n'
        '[[register]]\nname = "reading"\naddress = 7\ndefault = 1234\n'
    )
    with serving("--profile", ascii_profile) as (port, proc):
        assert "(unit 1, 4800 baud frame timing, Modbus ASCII)" in readline(proc.stderr)
        with bb.Bus(port, baudrate=4800, framing="ascii") as bus:
            assert bus.read_holding_registers(1, 7, 1) == [1234]
    with serving("--profile", ascii_profile, "--framing", "rtu", "--baudrate", "9600") as (
        port,
        proc,
    ):
        assert "(unit 1, 9600 baud frame timing)" in readline(proc.stderr)
        with bb.Bus(port, baudrate=9600) as bus:
            assert bus.read_holding_registers(1, 7, 1) == [1234]


def test_a_sigterm_as_soon_as_the_port_is_out_is_a_clean_stop() -> None:
    """Whoever stops the simulator once it has read the port gets exit status 0, however
    soon: SIGTERM's handler is in place before the port is printed."""
    for _ in range(3):
        with serving("--profile", RELAYS) as (port, _):
            assert port.startswith("/dev/")


def test_a_profiles_mistake_is_a_usage_error_and_nothing_is_served(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text('[device]\nname = "x"\n\n[[register]]\nname = "sample"\naddress = 1\n')
    done = run("sim", "--profile", bad, "--seconds", "5")
    message = one_line_error(done, 2)
    assert message.startswith(f"benchbus: sim: {bad}:5: register[0].name")
    assert "shadow" in message and done.stdout == ""
    missing = run("sim", "--profile", tmp_path / "none.toml", "--seconds", "5")
    assert "No such file" in one_line_error(missing, 2) and missing.stdout == ""


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["drive", "--profile", XY_MD02], "not both"),
        ([], "give a device (drive|pbl|j2|instrument|atv31) or --profile FILE"),
        (["drive", "--value", "a=1"], "--value sets a register of a --profile device"),
        (["--profile", XY_MD02, "--model", "C20"], "--model and --speedup are for the built-in"),
        (["--profile", XY_MD02, "--speedup", "2"], "--model and --speedup are for the built-in"),
        (["--profile", XY_MD02, "--value", "tempo=1"], "XY-MD02 has no register 'tempo'"),
        (["--profile", XY_MD02, "--value", "humidity"], "NAME=VALUE"),
        (
            ["--profile", XY_MD02, "--value", "humidity=wet"],
            "--value humidity takes a number (decimal or 0x hex), got 'wet'",
        ),
        (["--profile", XY_MD02, "--value", "temperature=300"], "-40.0..125.0, not 300"),
        (["--profile", XY_MD02, "--value", "baud=b1200"], "one of b9600, b14400, b19200"),
        (
            ["--profile", RELAYS, "--value", "relay1=maybe"],
            "--value relay1 takes true or false (on/off, 1/0), got 'maybe'",
        ),
    ],
)
def test_usage_errors_serve_nothing(args: list[object], words: str) -> None:
    done = run("sim", *args, "--seconds", "5")
    assert words in one_line_error(done, 2)
    assert done.stdout == ""


def test_the_help_tells_of_profiles() -> None:
    text = " ".join("\n".join(ok(run("sim", "--help"))).split())
    assert "--profile FILE" in text and "--value NAME=VALUE" in text
    assert "[drive|pbl|j2|instrument|atv31]" in text
