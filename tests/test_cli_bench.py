"""The command line on the bench: a raw read of a drive that reads one register a request,
labelled output, float registers as the device meant them, refusals (exit 2) before
anything is written, the CSV path checked before the port opens, and errors that suggest
the command line's own commands rather than Python code."""

from __future__ import annotations

import csv
import re
import time
from pathlib import Path

import pytest
from test_cli import ok, one_line_error, run, table

import benchbus as bb
from benchbus import cli
from benchbus.cli._errors import one_line
from benchbus.sim import DriveDevice, J2Device, PblDevice, ProfileDevice, RegisterDevice, Simulator

CONTROLLER = (
    Path(__file__).resolve().parent.parent / "examples" / "profiles" / "flow_controller.toml"
)


# ---- read: one register a request, labelled ------------------------------------------------------


def test_the_guides_raw_read_works_on_a_drive_that_reads_one_register_a_request() -> None:
    """``benchbus read 0x3000 21``: the BLD refuses the block read with exception 3; the
    command says why and reads the 21 registers one a request."""
    device = DriveDevice("BLD2")  # refuses a read of more than one register, as the manual's
    with Simulator({1: device}) as sim:
        done = run("read", "0x3000", "21", "--port", sim.port)
        lines = ok(done)
        assert len(lines) == 21
        assert lines[0] == "0x3000 (12288) = 0"
        assert lines[8] == f"0x3008 (12296) = {DriveDevice.BUS_VOLTAGE}"
        assert lines[20].startswith("0x3014 (12308) = ")
        note = done.stderr.strip()
        assert "\n" not in note and note.startswith("benchbus: read: unit 1 refused 21 registers")
        assert "exception 0x03" in note and "one a request" in note
        counts = [f[4] << 8 | f[5] for f in sim.requests]
        assert counts == [21] + [1] * 21
        assert [f[2] << 8 | f[3] for f in sim.requests[1:]] == list(range(0x3000, 0x3015))


def test_a_device_that_reads_blocks_is_read_in_one_request_and_no_note() -> None:
    device = DriveDevice("BLD2", single_register_reads=False)
    with Simulator({1: device}) as sim:
        done = run("read", "0x3000", "21", "--port", sim.port)
        assert len(ok(done)) == 21 and done.stderr == ""
        assert [f[4] << 8 | f[5] for f in sim.requests] == [21]


def test_another_refusal_is_no_reason_to_read_one_at_a_time() -> None:
    with Simulator({1: DriveDevice("BLD2", single_register_reads=False)}) as sim:
        line = one_line_error(run("read", "0x1234", "3", "--port", sim.port), 1)
        assert "illegal data address" in line and len(sim.requests) == 1


def test_read_labels_the_address_in_hex_and_decimal_and_the_value() -> None:
    device = RegisterDevice({0x2001: 1234})
    with Simulator({1: device}) as sim:
        assert ok(run("read", "0x2001", "--port", sim.port)) == ["0x2001 (8193) = 1234"]
        help_text = "\n".join(ok(run("read", "--help")))
        assert "0x2001 (8193) = 1500" in " ".join(help_text.split())


def test_the_guides_raw_read_prints_what_the_guide_shows() -> None:
    """The command line guide's raw read, run as written on a simulated drive: every line
    the guide shows (on stderr, then stdout) is what the command prints."""
    guide = (Path(__file__).resolve().parent.parent / "docs" / "guides" / "cli.md").read_text()
    block = guide.split("```console\n$ ", 1)[1].split("```", 1)[0]
    command, *shown = block.splitlines()
    args = command.split()[1:]
    assert args[:3] == ["read", "0x3000", "21"]
    with Simulator({1: DriveDevice("BLD2")}) as sim:
        done = run(*[sim.port if a == "/dev/ttyUSB0" else a for a in args])
    printed = done.stderr.splitlines() + ok(done)
    assert shown[0] == printed[0] and shown[-1] == printed[-1]
    assert [line for line in shown if line != "..."] == [line for line in printed if line in shown]


# ---- f32 registers: the shortest decimal of the single -------------------------------------------


def test_a_float_register_is_its_shortest_decimal_in_python_the_table_and_the_csv(
    tmp_path: Path,
) -> None:
    model = ProfileDevice(CONTROLLER, values={"flow": 231.7, "setpoint": 129.9})
    with Simulator({7: model}) as sim:
        with bb.Bus(sim.port) as bus:
            device = bb.Device.from_profile(CONTROLLER, bus, 7)
            assert device.read("flow") == 231.7 and repr(device.read("setpoint")) == "129.9"
            assert device.read_many(["flow", "setpoint"]) == {"flow": 231.7, "setpoint": 129.9}
            assert device.sample()["flow"] == 231.7
        profile = ["--profile", str(CONTROLLER), "--port", sim.port, "--unit", "7"]
        assert table(ok(run("read", *profile, "flow")))["flow"] == "231.7 sccm"
        log = tmp_path / "flow.csv"
        lines = ok(run("monitor", *profile, "--count", "1", "--fields", "flow", "--csv", log))
        assert lines[1].split()[1] == "231.7"
        with log.open() as f:
            rows = list(csv.DictReader(f))
        assert rows[0]["flow (sccm)"] == "231.7" and rows[0]["setpoint (sccm)"] == "129.9"
        raw = ok(run("read", "2", "--table", "input", "--type", "f32", "--order", "CDAB",
                     "--port", sim.port, "--unit", "7"))  # fmt: skip
        assert raw == ["0x0002 (2) = 231.7"]


def test_from_registers_gives_a_single_as_its_shortest_decimal() -> None:
    assert bb.from_registers([0x4365, 0xE666], "f32") == [229.9]
    assert bb.from_registers([0x3DCC, 0xCCCD], "f32") == [0.1]
    assert bb.from_registers([0x0000, 0x0001], "f32") == [1e-45]
    # Written back, the decimal is the same single.
    assert bb.to_registers(229.9, "f32") == [0x4365, 0xE666]
    # f64 is exact as it is.
    assert bb.from_registers(bb.to_registers(0.1 + 0.2, "f64"), "f64") == [0.1 + 0.2]


def test_an_instruments_float_is_its_shortest_decimal() -> None:
    device = RegisterDevice({0x10: 0x4365, 0x11: 0xE666})
    with Simulator({1: device}) as sim, bb.Bus(sim.port) as bus:
        assert bb.Instrument(bus, 1).read_float(0x10) == 229.9


# ---- refusals: exit 2, before anything is written ------------------------------------------------


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["j2", "set-sv", "9999"], "SV must be -1999 to 3276.7"),
        (["j2", "set-sv", "500"], "LSP to USP"),
        (["j2", "set-output", "150", "--manual"], "MV"),
        (["j2", "set-output", "30"], "run 'benchbus j2 manual' first, or add --manual"),
        (["j2", "set-limits", "-10", "9999"], "USP"),
        (["drive", "set-speed", "5000"], "RPM must be 0 to 3000"),
        (["drive", "start", "--speed", "5000"], "rpm must be 0 to 3000"),
        (["pbl", "set-speed", "70000"], "RPM must be 0 to 65535"),
    ],
)
def test_a_refusal_before_anything_is_written_exits_2_in_every_command(
    args: list[str], says: str
) -> None:
    units = {1: J2Device(), 2: DriveDevice("BLD2"), 3: PblDevice()}
    unit = {"j2": 1, "drive": 2, "pbl": 3}[args[0]]
    with Simulator(units) as sim:
        line = one_line_error(run(*args, "--port", sim.port, "--unit", unit), 2)
        assert says in line
        assert not [f for f in sim.requests if f[1] in (0x06, 0x10)]  # nothing written


# ---- errors speak of the command line ------------------------------------------------------------


def test_j2_limits_are_set_from_the_command_line_and_errors_say_how() -> None:
    device = J2Device()
    with Simulator({1: device}) as sim:
        port = ["--port", sim.port]
        line = one_line_error(run("j2", "set-sv", "500", *port), 2)
        assert "set both with 'benchbus j2 set-limits LOW HIGH'" in line
        assert "j2.limits" not in line
        assert ok(run("j2", "set-limits", "0", "600", *port)) == ["unit 1: limits 0 to 600 °C"]
        assert (device.value("LSP"), device.value("USP")) == (0.0, 600.0)
        time.sleep(0.2)  # the J2 takes a write 150 ms after the last one at the soonest
        assert ok(run("j2", "set-sv", "500", *port)) == ["unit 1: SV 500"]
        assert device.value("SV") == 500.0
        assert table(ok(run("j2", "status", *port)))["limits"] == "0 to 600 °C"


def test_a_lost_port_says_to_run_the_command_again_not_to_call_reopen() -> None:
    lost = bb.PortError("/dev/ttyUSB0: lost: No such device (call reopen() once it is back)")
    earlier = bb.PortError(
        "/dev/ttyUSB0: lost earlier (gone); call reopen() once it is back, or open the Bus "
        "with reconnect=True"
    )
    for exc in (lost, earlier):
        text = one_line(exc)
        assert "reopen()" not in text and "reconnect=True" not in text
        assert "run the command again once it is back" in text


def test_a_j2_in_automatic_mode_is_told_of_the_command_not_set_output() -> None:
    exc = bb.StateError(
        "unit 1: MV can be written only in manual mode (AM = 0), and the controller is in "
        "automatic mode; switch with mode = manual, or set_output(percent, "
        "switch_to_manual=True)"
    )
    text = one_line(exc)
    assert "set_output(" not in text and "mode = manual" not in text
    assert text.endswith("run 'benchbus j2 manual' first, or add --manual to set-output")


def test_every_suggestion_the_library_makes_in_python_has_a_command_line_wording() -> None:
    """The library's messages that suggest Python code are those the command line rewords
    (found in the compiled core's sources, so that a new one is not missed)."""
    sources = Path(__file__).resolve().parent.parent / "src"
    text = " ".join(
        " ".join(p.read_text(encoding="utf-8").split()) for p in sources.rglob("*.rs")
    ).replace("\\ ", "")
    for python, _ in cli._errors.CLI_WORDS:
        assert python in text, python
    # And the other way: every Bus option the core's messages ask for has its wording.
    asked = set(re.findall(r"open the Bus with(?:out)? \w+=True|\w+=True (?:is for|sets)", text))
    assert asked >= {"open the Bus with echo=True", "open the Bus with rs485=True"}
    for phrase in asked:
        assert any(phrase in python for python, _ in cli._errors.CLI_WORDS), phrase
    assert "open the Bus without echo=True" in asked and "echo=True is for" in asked


def test_an_echoing_adapter_is_read_with_echo_as_the_doctor_says() -> None:
    with Simulator({1: RegisterDevice({0: 7})}, echo=True) as sim:
        found = ok(run("doctor", "--port", sim.port, "--timeout", "0.2"))
        (echo,) = [line for line in found if line.split()[1:2] == ["echo"]]
        assert echo.startswith("warn") and echo.endswith("fix: give the commands --echo")
        assert "bb.Bus(" not in "\n".join(found)
        assert ok(run("read", "0", "--port", sim.port, "--echo")) == ["0x0000 (0) = 7"]
        # Without it the reply begins with the request: the message says what to give.
        line = one_line_error(run("read", "0", "--port", sim.port, "--retries", "0"), 1)
        assert "give the commands --echo" in line and "echo=True" not in line


# ---- the CSV path: checked before the port opens -------------------------------------------------


@pytest.mark.parametrize("where", ["no-such-folder/run.csv", "."])
def test_an_unwritable_csv_path_is_a_usage_error_before_the_port_opens(
    tmp_path: Path, where: str
) -> None:
    path = tmp_path / where
    done = run("monitor", "j2", "--port", "/dev/no-such-benchbus-port", "--csv", path)
    line = one_line_error(done, 2)
    assert line.startswith(f"benchbus: monitor: --csv {path}: cannot write there (")
    assert "cannot open" not in line and "Errno" not in line


def test_a_csv_path_checked_and_not_used_is_not_left_behind(tmp_path: Path) -> None:
    path = tmp_path / "run.csv"
    done = run("monitor", "j2", "--port", "/dev/no-such-benchbus-port", "--csv", path)
    assert "cannot open" in one_line_error(done, 1)
    assert not path.exists()
