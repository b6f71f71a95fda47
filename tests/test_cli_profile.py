"""``benchbus read``, ``write`` and ``monitor`` with ``--profile FILE``: the example profiles,
each served by its own simulator (benchbus.sim.ProfileDevice, which reads the profile
itself) on a pseudo-terminal, the real command run as a subprocess; values checked against
the simulator's, writes against its state afterwards, requests frame by frame."""

from __future__ import annotations

import csv
import struct
from collections.abc import Iterator
from pathlib import Path

import pytest
from test_cli import ok, one_line_error, run, table

import benchbus as bb
from benchbus import cli
from benchbus.cli._line import open_bus, profile_options
from benchbus.sim import ProfileDevice, Simulator
from conftest import crc

PROFILES = Path(__file__).resolve().parent.parent / "examples" / "profiles"
SENSOR = PROFILES / "xy_md02.toml"
RELAYS = PROFILES / "relay_board.toml"
CONTROLLER = PROFILES / "flow_controller.toml"

#: The function that reads each table.
READS = {"coil": 0x01, "discrete": 0x02, "holding": 0x03, "input": 0x04}

Rig = tuple[Simulator[ProfileDevice], ProfileDevice, list[str]]


def frame(*pdu: int, unit: int = 1) -> bytes:
    body = bytes([unit, *pdu])
    return body + crc(body)


def planned(path: Path, names: list[str], unit: int = 1) -> list[bytes]:
    """The read requests the profile's plan makes for ``names``."""
    return [
        frame(READS[table], start >> 8, start & 0xFF, count >> 8, count & 0xFF, unit=unit)
        for table, start, count, _ in bb.Profile(path).plan(names)
    ]


def rig(path: Path, unit: int = 1, **values: object) -> Iterator[Rig]:
    model = ProfileDevice(path, values=values)
    with Simulator({unit: model}) as sim:
        yield sim, model, ["--profile", str(path), "--port", sim.port, "--unit", str(unit)]
        assert sim.errors == []


@pytest.fixture
def sensor() -> Iterator[Rig]:
    yield from rig(SENSOR, temperature=-12.3, humidity=56.7)


@pytest.fixture
def relays() -> Iterator[Rig]:
    yield from rig(RELAYS, relay3=True, input2=True)


@pytest.fixture
def controller() -> Iterator[Rig]:
    yield from rig(CONTROLLER, unit=7)


def readable(path: Path) -> list[str]:
    return [r.name for r in bb.Profile(path).registers if r.access != "w"]


# ---- read ----------------------------------------------------------------------------------


def test_read_prints_the_named_registers_with_units_in_one_request(sensor: Rig) -> None:
    sim, _, profile = sensor
    lines = ok(run("read", *profile, "temperature", "humidity"))
    assert table(lines) == {"temperature": "-12.3 degC", "humidity": "56.7 %RH"}
    assert list(table(lines)) == ["temperature", "humidity"]
    assert sim.requests == [frame(0x04, 0x00, 0x01, 0x00, 0x02)]
    # The order asked for is the order printed.
    assert list(table(ok(run("read", *profile, "humidity", "temperature")))) == [
        "humidity",
        "temperature",
    ]


def test_read_without_names_prints_every_readable_register(sensor: Rig) -> None:
    sim, model, profile = sensor
    model.set_value("baud", "b19200")
    rows = table(ok(run("read", *profile)))
    assert list(rows) == readable(SENSOR)
    assert rows["baud"] == "b19200"  # an enum by its member's name
    for name in ("temperature", "humidity", "unit_address", "temperature_correction"):
        number, _, unit = rows[name].partition(" ")
        assert float(number) == pytest.approx(model.value(name)), name
        assert unit == model.unit_of(name), name
    assert sim.requests == planned(SENSOR, readable(SENSOR))
    assert len(sim.requests) == 2  # holding and input registers, each in one request


def test_read_a_controller_of_floats_64_bit_values_enums_and_a_string(controller: Rig) -> None:
    sim, _, profile = controller
    rows = table(ok(run("read", *profile)))
    assert list(rows) == readable(CONTROLLER) and "reset_total" not in rows  # write-only
    assert rows == {
        "setpoint": "50 sccm",
        "flow": "49.75 sccm",
        "total": "1234.56 scc",
        "mode": "control",
        "gas_temperature": "22.5 degC",
        "runtime": "86400 s",
        "zero_offset": "-42",
        "gain": "1",
        "device_name": "FC-200 #1",
    }
    # block_reads = false: one request per register, each at unit 7.
    assert sim.requests == planned(CONTROLLER, readable(CONTROLLER), unit=7)
    assert len(sim.requests) == len(rows)


def test_read_coils_and_inputs_as_true_or_false(relays: Rig) -> None:
    sim, model, profile = relays
    rows = table(ok(run("read", *profile)))
    assert list(rows) == readable(RELAYS) and "relay8" not in rows
    assert rows["relay1"] == "true"  # its default
    assert rows["relay3"] == "true" and rows["input2"] == "true"
    assert rows["relay2"] == "false" and rows["input1"] == "false" and rows["all_on"] == "false"
    for name, shown in rows.items():
        if name != "board_address":
            assert shown == str(model.value(name)).lower(), name
    assert sim.requests == planned(RELAYS, readable(RELAYS))
    assert sorted(f[1] for f in sim.requests) == [0x01, 0x02, 0x03, 0x03]  # a table each


# ---- write ---------------------------------------------------------------------------------


def test_write_an_enum_by_name_or_number_and_scaled_numbers(sensor: Rig) -> None:
    sim, model, profile = sensor
    assert ok(run("write", *profile, "baud", "b19200")) == ["unit 1: wrote baud b19200"]
    assert model.value("baud") == "b19200"
    assert sim.requests[-1] == frame(0x06, 0x01, 0x02, 0x00, 0x02)
    assert ok(run("write", *profile, "baud", "1")) == ["unit 1: wrote baud b14400"]
    assert model.value("baud") == "b14400"
    line = ok(run("write", *profile, "temperature_correction", "-1.5"))
    assert line == ["unit 1: wrote temperature_correction -1.5 degC"]
    assert model.value("temperature_correction") == pytest.approx(-1.5)
    assert sim.requests[-1] == frame(0x06, 0x01, 0x03, 0xFF, 0xF1)  # -15 raw
    ok(run("write", *profile, "unit_address", "0x20"))
    assert model.value("unit_address") == 32
    assert len(sim.requests) == 4  # one request each, nothing read first


def test_write_floats_64_bit_values_and_strings_of_a_controller(controller: Rig) -> None:
    sim, model, profile = controller
    assert ok(run("write", *profile, "setpoint", "120.5")) == ["unit 7: wrote setpoint 120.5 sccm"]
    assert model.value("setpoint") == 120.5
    high, low = struct.unpack(">HH", struct.pack(">f", 120.5))
    data = [low >> 8, low & 0xFF, high >> 8, high & 0xFF]  # CDAB: the low word first
    assert sim.requests[-1] == frame(0x10, 0x00, 0x00, 0x00, 0x02, 0x04, *data, unit=7)
    ok(run("write", *profile, "setpoint", "150"))  # a whole number for a float register
    assert model.value("setpoint") == 150.0
    assert ok(run("write", *profile, "mode", "purge")) == ["unit 7: wrote mode purge"]
    assert model.value("mode") == "purge"
    ok(run("write", *profile, "zero_offset", "-123456"))
    assert model.value("zero_offset") == -123456
    ok(run("write", *profile, "gain", "1.25"))
    assert model.value("gain") == 1.25
    ok(run("write", *profile, "device_name", "line 2 #7"))
    assert model.value("device_name") == "line 2 #7"
    ok(run("write", *profile, "reset_total", "1"))  # write-only
    assert model.value("reset_total") == 1


@pytest.mark.parametrize(
    ("text", "value"),
    [("on", True), ("off", False), ("TRUE", True), ("false", False), ("1", True), ("0", False)],
)
def test_write_a_coil_from_each_way_of_saying_true_or_false(
    relays: Rig, text: str, value: bool
) -> None:
    sim, model, profile = relays
    model.set_value("relay5", not value)
    assert ok(run("write", *profile, "relay5", text)) == [
        f"unit 1: wrote relay5 {str(value).lower()}"
    ]
    assert model.value("relay5") is value
    assert sim.requests == [frame(0x05, 0x00, 0x04, 0xFF if value else 0x00, 0x00)]


def test_write_a_bit_of_a_holding_register_keeps_the_others(relays: Rig) -> None:
    sim, model, profile = relays
    model.set_value("all_off", True)
    ok(run("write", *profile, "all_on", "on"))
    assert model.value("all_on") is True and model.value("all_off") is True
    assert [f[1] for f in sim.requests] == [0x03, 0x06]  # read, then written back


# ---- refused before anything is sent -------------------------------------------------------


@pytest.mark.parametrize(
    ("path", "args", "message"),
    [
        (SENSOR, ["read", "temprature"], "no register 'temprature'; did you mean 'temperature'"),
        (SENSOR, ["write", "humidty", "5"], "no register 'humidty'; did you mean 'humidity'"),
        (SENSOR, ["write", "humidity", "50"], "humidity is read-only"),
        (SENSOR, ["write", "unit_address", "300"], "unit_address must be 1 to 247, got 300"),
        (SENSOR, ["write", "temperature_correction", "0.15"], "goes in steps of 0.1 degC"),
        (SENSOR, ["write", "temperature_correction", "11"], "must be -10 to 10 degC"),
        (SENSOR, ["write", "baud", "b115200"], 'baud is one of b9600, b14400, b19200, got "b'),
        (SENSOR, ["write", "baud", "7"], "baud is one of b9600, b14400, b19200, got 7"),
        (SENSOR, ["write", "baud", "b9600", "b19200"], "writes one register: give NAME VALUE"),
        (SENSOR, ["read", "temperature", "--hex"], "leave out --table, --hex"),
        (SENSOR, ["read", "--table", "input"], "leave out --table"),
        (SENSOR, ["write", "baud", "1", "--decimals", "1"], "leave out --table, --type"),
        (SENSOR, ["write", "baud", "1", "--unit", "0"], "unit 0 is the broadcast address"),
        (RELAYS, ["write", "relay1", "yes"], "relay1 takes true or false (on/off, 1/0)"),
        (RELAYS, ["write", "relay1", "2"], "got '2'"),
        (RELAYS, ["write", "input1", "on"], "input1 is read-only"),
        (CONTROLLER, ["write", "setpoint", "fast"], "setpoint takes a number"),
        (CONTROLLER, ["write", "setpoint", "nan"], "setpoint takes a number"),
        (CONTROLLER, ["write", "setpoint", "200.5"], "setpoint must be 0 to 200 sccm"),
        (CONTROLLER, ["write", "gain", "3"], "gain must be 0.5 to 2"),
        (CONTROLLER, ["write", "zero_offset", "1.5"], "zero_offset goes in steps of 1"),
        (CONTROLLER, ["write", "device_name", "x" * 17], "at most 16 characters"),
        (CONTROLLER, ["read", "flow", "reset_total"], "reset_total is write-only"),
    ],
)
def test_a_bad_name_or_value_is_a_usage_error_and_nothing_is_sent(
    path: Path, args: list[str], message: str
) -> None:
    model = ProfileDevice(path)
    with Simulator({1: model}) as sim:
        done = run(*args, "--profile", path, "--port", sim.port)
        assert message in one_line_error(done, 2)
        assert done.stdout == ""
        assert sim.requests == []


@pytest.mark.parametrize(
    "args",
    [
        ["read", "temperature"],
        ["write", "mode", "heat"],
        ["monitor", "--count", "1"],
    ],
)
def test_a_bad_profile_is_a_usage_error_naming_its_line_before_any_port_opens(
    tmp_path: Path, args: list[str]
) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text('[device]\nname = "x"\n\n[[register]]\nname = "read"\naddress = 1\n')
    port = ["--port", "/dev/no-such-benchbus-port"]  # opening it would fail with status 1
    message = one_line_error(run(*args, "--profile", bad, *port), 2)
    assert f"{bad}:5: register[0].name" in message and "shadow" in message
    missing = one_line_error(run(*args, "--profile", tmp_path / "none.toml", *port), 2)
    assert "No such file" in missing


def test_the_raw_commands_still_check_their_address() -> None:
    assert "argument ADDRESS: 'temperature' is not a number" in one_line_error(
        run("read", "temperature", "--port", "/dev/null"), 2
    )
    assert "ADDRESS must be 0 to 65535" in one_line_error(
        run("write", "0x10000", "1", "--port", "/dev/null"), 2
    )
    assert "COUNT must be 1 to 65536" in one_line_error(
        run("read", "0", "0", "--port", "/dev/null"), 2
    )
    assert "unrecognized arguments: 3" in one_line_error(
        run("read", "0", "2", "3", "--port", "/dev/null"), 2
    )


# ---- monitor -------------------------------------------------------------------------------


def test_monitor_a_profile_shows_its_sample_with_units_and_logs_it(
    sensor: Rig, tmp_path: Path
) -> None:
    sim, model, profile = sensor
    log = tmp_path / "sensor.csv"
    lines = ok(run("monitor", *profile, "--count", "2", "--interval", "0.1", "--csv", log))
    fields = readable(SENSOR)  # the sample: every readable register but strings
    header = ["t", "(s)"]
    for name in fields:
        header += [name] + ([f"({model.unit_of(name)})"] if model.unit_of(name) else [])
    assert lines[0].split() == header
    assert len(lines) == 3
    for line in lines[1:]:
        cells = dict(zip(fields, line.split()[1:]))
        assert cells["baud"] == "b9600"  # the member's name in the table
        assert float(cells["temperature"]) == pytest.approx(-12.3)
        assert float(cells["humidity"]) == pytest.approx(56.7)
    with log.open() as f:
        rows = list(csv.reader(f))
    assert rows[0][2:] == [f"{n} ({model.unit_of(n)})" if model.unit_of(n) else n for n in fields]
    assert len(rows) == 3
    for row in rows[1:]:
        values = dict(zip(fields, row[2:]))
        assert values["baud"] == "0"  # its number in the file
        assert float(values["temperature"]) == pytest.approx(-12.3)
    # Each sample: the plan's two requests.
    assert sim.requests == planned(SENSOR, fields) * 2
    some = ok(run("monitor", *profile, "--count", "1", "--fields", "humidity,baud"))
    assert some[0].split() == ["t", "(s)", "humidity", "(%RH)", "baud"]
    assert some[1].split()[1:] == ["56.7", "b9600"]
    bad = run("monitor", *profile, "--count", "1", "--fields", "humid")
    assert "choose from temperature, humidity" in one_line_error(bad, 2)


def test_monitor_takes_a_family_or_a_profile_not_both_nor_neither(sensor: Rig) -> None:
    _, _, profile = sensor
    assert "not both" in one_line_error(run("monitor", "j2", *profile, "--count", "1"), 2)
    neither = one_line_error(run("monitor", "--port", "/dev/null"), 2)
    assert "or --profile FILE" in neither
    assert "not both" not in neither  # neither was given: it says what to give
    family = run("monitor", *profile, "--family", "C20", "--count", "1")
    assert "--family goes with drive" in one_line_error(family, 2)


# ---- the line ------------------------------------------------------------------------------


def test_the_profiles_line_is_the_default_and_the_options_override_it(tmp_path: Path) -> None:
    parser = cli.build_parser()
    silent = tmp_path / "silent.toml"
    silent.write_text('[device]\nname = "x"\n\n[[register]]\nname = "a"\naddress = 1\n')
    with Simulator({1: ProfileDevice(CONTROLLER)}) as sim:

        def line(path: Path, *options: str) -> tuple[object, ...]:
            args = parser.parse_args(["read", "--profile", str(path), "--port", sim.port, *options])
            with open_bus(args, profile_options(bb.Profile(path))) as bus:
                return (
                    bus.baudrate, bus.bytesize, bus.parity, bus.stopbits, bus.framing,
                    bus.timeout, bus.retries,
                )  # fmt: skip

        assert line(CONTROLLER) == (19200, 8, "E", 1, "rtu", 0.2, 2)
        assert line(SENSOR) == (9600, 8, "N", 1, "rtu", 0.5, 2)
        assert line(silent) == (9600, 8, "N", 1, "rtu", 0.2, 2)  # the device's own defaults
        given = ("--baudrate", "38400", "--parity", "O", "--stopbits", "2", "--timeout", "0.3")
        assert line(CONTROLLER, *given, "--retries", "0") == (38400, 8, "O", 2, "rtu", 0.3, 0)
        # Modbus ASCII brings its 7E1 unless given, as for the built-in families.
        assert line(SENSOR, "--framing", "ascii") == (9600, 7, "E", 1, "ascii", 0.5, 2)
        ascii = tmp_path / "ascii.toml"
        ascii.write_text(
            '[device]\nname = "x"\n\n[line]\nframing = "ascii"\nparity = "N"\n\n'
            '[[register]]\nname = "a"\naddress = 1\n'
        )
        assert line(ascii) == (9600, 7, "N", 2, "ascii", 0.2, 2)  # 7N2: ASCII has no 7N1


def test_read_at_the_unit_given(sensor: Rig) -> None:
    model = ProfileDevice(SENSOR, values={"humidity": 33.3})
    with Simulator({5: model}) as sim:
        port = ["--profile", SENSOR, "--port", sim.port]
        assert table(ok(run("read", *port, "--unit", "5", "humidity"))) == {"humidity": "33.3 %RH"}
        assert sim.requests == [frame(0x04, 0x00, 0x02, 0x00, 0x01, unit=5)]


def test_what_the_device_refuses_or_a_silent_unit_is_an_error_of_the_line(tmp_path: Path) -> None:
    # The master's profile allows setpoints up to 1000; the device's own table, 200.
    wider = tmp_path / "wider.toml"
    wider.write_text(CONTROLLER.read_text().replace("max = 200.0", "max = 1000.0"))
    model = ProfileDevice(CONTROLLER)
    with Simulator({1: model}) as sim:
        port = ["--profile", wider, "--port", sim.port]
        assert "illegal data value" in one_line_error(run("write", *port, "setpoint", "500"), 1)
        assert model.value("setpoint") == 50.0 and len(sim.requests) == 1
        sim.set_silent(1)
        quick = ["--timeout", "0.05", "--retries", "0"]
        assert "no complete reply" in one_line_error(run("read", *port, "flow", *quick), 1)
