"""The command line on the bench: a raw read of a drive that reads one register a request,
labelled output, float registers as the device meant them, refusals (exit 2) before
anything is written, the CSV path checked before the port opens, and errors that suggest
the command line's own commands rather than Python code."""

from __future__ import annotations

from pathlib import Path

from test_cli import ok, one_line_error, run

from benchbus.sim import DriveDevice, RegisterDevice, Simulator

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
