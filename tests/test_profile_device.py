"""bb.Device.from_profile: the three example profiles, each against its own simulator
(benchbus.sim.ProfileDevice, which reads the profile itself), with every request checked
frame by frame as it crossed the line and every value against the simulator's."""

from __future__ import annotations

import struct
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from test_cli import ok, run
from test_profile_parse import big_profile

import benchbus as bb
from benchbus.sim import ProfileDevice, Simulator
from conftest import crc

PROFILES = Path(__file__).resolve().parent.parent / "examples" / "profiles"
SENSOR = PROFILES / "xy_md02.toml"
RELAYS = PROFILES / "relay_board.toml"
CONTROLLER = PROFILES / "flow_controller.toml"


def frame(*pdu: int, unit: int = 1) -> bytes:
    body = bytes([unit, *pdu])
    return body + crc(body)


Rig = tuple[Simulator[ProfileDevice], bb.Device, ProfileDevice]


def rig(path: Path, **values: object) -> Iterator[Rig]:
    model = ProfileDevice(path, values=values)
    with Simulator({1: model}) as sim, bb.Bus(sim.port, baudrate=9600, timeout=0.5) as bus:
        yield sim, bb.Device.from_profile(path, bus, unit=1), model
        assert sim.errors == []


@pytest.fixture
def sensor() -> Iterator[Rig]:
    yield from rig(SENSOR, temperature=-12.3)


@pytest.fixture
def relays() -> Iterator[Rig]:
    yield from rig(RELAYS)


@pytest.fixture
def controller() -> Iterator[Rig]:
    yield from rig(CONTROLLER)


def sent_by(sim: Simulator[ProfileDevice], before: int) -> list[bytes]:
    """The requests the simulator received since it had ``before``."""
    return list(sim.requests[before:])


# ---- the sensor: input registers read together, settings one by one -----------------------


def test_sensor_sample_reads_neighbours_in_one_request_per_table(sensor: Rig) -> None:
    sim, dev, model = sensor
    before = len(sim.requests)
    values = dev.sample()
    assert sent_by(sim, before) == [
        frame(0x03, 0x01, 0x01, 0x00, 0x04),  # unit_address, baud and the two corrections
        frame(0x04, 0x00, 0x01, 0x00, 0x02),  # temperature and humidity
    ]
    assert list(values) == [
        "temperature",
        "humidity",
        "unit_address",
        "baud",
        "temperature_correction",
        "humidity_correction",
    ]
    assert values["temperature"] == pytest.approx(-12.3)
    assert values["humidity"] == pytest.approx(45.0)
    for name, value in values.items():
        assert value == pytest.approx(model.value(name)) or value.name == model.value(name)


def test_sensor_attributes_in_engineering_units(sensor: Rig) -> None:
    sim, dev, model = sensor
    model.set_value("humidity", 61.7)
    assert dev.humidity == pytest.approx(61.7)
    assert dev.read("temperature") == pytest.approx(-12.3)
    assert isinstance(dev.unit_address, int) and dev.unit_address == 1
    before = len(sim.requests)
    dev.temperature_correction = -1.5
    assert sent_by(sim, before) == [frame(0x06, 0x01, 0x03, 0xFF, 0xF1)]  # -15 tenths
    assert model.value("temperature_correction") == pytest.approx(-1.5)


def test_sensor_enum_by_member_name_and_number(sensor: Rig) -> None:
    sim, dev, model = sensor
    baud = dev.baud
    baud_enum = dev.enums["baud"]
    assert type(baud) is baud_enum and baud_enum.__name__ == "Baud"
    assert baud is baud_enum.b9600 and str(baud) == "Baud.b9600"
    dev.baud = "b19200"
    assert model.value("baud") == "b19200"
    assert dev.baud is baud_enum.b19200
    dev.baud = baud_enum.b14400
    assert sim.requests[-1] == frame(0x06, 0x01, 0x02, 0x00, 0x01)
    dev.write("baud", 0)
    assert model.value("baud") == "b9600"


def test_enums_are_a_mapping_each_class_made_once(sensor: Rig) -> None:
    _, dev, _ = sensor
    assert list(dev.enums) == ["baud"] and len(dev.enums) == 1
    assert "baud" in dev.enums and "temperature" not in dev.enums
    assert dev.enums.get("temperature") is None
    with pytest.raises(KeyError):
        dev.enums["temperature"]
    baud = dev.enums["baud"]
    assert dev.enums["baud"] is baud and dict(dev.enums) == {"baud": baud}
    assert repr(dev.enums) == f"{{'baud': {baud!r}}}"
    # Another device of the same profile reads the same class, so members compare alike.
    other = bb.Device.from_profile(SENSOR, dev.bus, unit=2)
    assert other.enums["baud"] is baud


def test_enum_members_named_like_an_enums_own_attributes_work(tmp_path: Path) -> None:
    path = tmp_path / "fine.toml"
    path.write_text(
        '[device]\nname = "fine"\n[[register]]\nname = "mode"\naddress = 1\n'
        'enum = { 0 = "name_1", 1 = "name", 2 = "value", 3 = "_9600", 4 = "_Mod__e" }\n'
    )
    model = ProfileDevice(path)
    with Simulator({1: model}) as sim, bb.Bus(sim.port, baudrate=9600, timeout=0.5) as bus:
        dev = bb.Device.from_profile(path, bus, unit=1)
        mode = dev.enums["mode"]
        assert [(m.name, m.value) for m in mode] == [
            ("name_1", 0),
            ("name", 1),
            ("value", 2),
            ("_9600", 3),
            ("_Mod__e", 4),
        ]
        assert dev.mode is mode["name_1"]
        dev.mode = "value"
        assert dev.mode is mode["value"] and model.value("mode") == "value"
        dev.mode = mode["_9600"]
        assert dev.mode == 3 and str(dev.mode) == "Mode._9600"
        assert sim.errors == []


def test_sensor_checks_before_sending(sensor: Rig) -> None:
    sim, dev, model = sensor
    before = len(sim.requests)
    with pytest.raises(ValueError, match=r"unit_address must be 1 to 247, got 248"):
        dev.unit_address = 248
    with pytest.raises(ValueError, match=r"steps of 0\.1 degC"):
        dev.temperature_correction = 0.25
    with pytest.raises(ValueError, match="temperature is read-only"):
        dev.temperature = 20.0
    with pytest.raises(ValueError, match="baud is one of b9600, b14400, b19200"):
        dev.baud = "b115200"
    with pytest.raises(TypeError, match="unit_address takes a number, got str"):
        dev.write("unit_address", "5")
    with pytest.raises(TypeError, match="a member, its name or its number"):
        dev.baud = True
    with pytest.raises(ValueError, match=r"no register 'humidty'; did you mean 'humidity'"):
        dev.read("humidty")
    assert sent_by(sim, before) == []
    assert model.value("unit_address") == 1


def test_typos_are_attribute_errors_with_suggestions(sensor: Rig) -> None:
    _, dev, _ = sensor
    with pytest.raises(AttributeError, match=r"'temprature'; did you mean 'temperature'") as got:
        dev.temprature  # noqa: B018
    assert got.value.name == "temprature"
    with pytest.raises(AttributeError, match=r"'humidty' to set; did you mean 'humidity'"):
        dev.humidty = 5
    assert "humidity" in dir(dev) and "read_many" in dir(dev)


# ---- the relay board: coils, discrete inputs, bits of a register ---------------------------


def test_relays_sample_one_request_per_table(relays: Rig) -> None:
    sim, dev, model = relays
    model.set_value("input3", True)
    before = len(sim.requests)
    values = dev.sample()
    assert sent_by(sim, before) == [
        frame(0x03, 0x00, 0x10, 0x00, 0x01),  # all_on and all_off: one word
        frame(0x03, 0x00, 0x20, 0x00, 0x01),  # board_address
        frame(0x01, 0x00, 0x00, 0x00, 0x07),  # relay1..7 (relay8 is write-only)
        frame(0x02, 0x00, 0x00, 0x00, 0x08),  # input1..8
    ]
    assert "relay8" not in values
    assert values["relay1"] is True and values["relay2"] is False
    assert values["input3"] is True and values["input4"] is False


def test_relays_coils_and_bits_written(relays: Rig) -> None:
    sim, dev, model = relays
    before = len(sim.requests)
    dev.relay2 = True
    dev.relay8 = True
    assert sent_by(sim, before) == [
        frame(0x05, 0x00, 0x01, 0xFF, 0x00),
        frame(0x05, 0x00, 0x07, 0xFF, 0x00),
    ]
    assert model.value("relay2") is True
    with pytest.raises(ValueError, match="relay8 is write-only"):
        dev.relay8  # noqa: B018
    with pytest.raises(TypeError, match="relay3 takes True or False, got int"):
        dev.relay3 = 1
    # A bit of a holding register: the word read, the bit set, the word written back.
    model.set_value("all_off", True)
    before = len(sim.requests)
    dev.all_on = True
    assert sent_by(sim, before) == [
        frame(0x03, 0x00, 0x10, 0x00, 0x01),
        frame(0x06, 0x00, 0x10, 0x00, 0x03),
    ]
    assert (model.value("all_on"), model.value("all_off")) == (True, True)
    assert dev.read_many(["all_off", "input1"]) == {"all_off": True, "input1": False}


# ---- the controller: wide values, word orders, strings, one register a request -------------


def test_controller_reads_each_register_apart_without_block_reads(controller: Rig) -> None:
    sim, dev, model = controller
    before = len(sim.requests)
    values = dev.read_many(["setpoint", "mode", "flow", "total"])
    assert sent_by(sim, before) == [
        frame(0x03, 0x00, 0x00, 0x00, 0x02),
        frame(0x03, 0x00, 0x10, 0x00, 0x01),
        frame(0x04, 0x00, 0x02, 0x00, 0x02),
        frame(0x04, 0x00, 0x04, 0x00, 0x02),
    ]
    assert values["setpoint"] == pytest.approx(50.0)
    assert values["flow"] == pytest.approx(49.75)
    assert values["total"] == pytest.approx(1234.56)
    assert values["mode"] == 1 and values["mode"].name == "control"
    assert dev.gas_temperature == pytest.approx(model.value("gas_temperature"))
    assert dev.runtime == 86400 and dev.zero_offset == -42 and dev.gain == 1.0
    assert dev.device_name == "FC-200 #1"


def test_controller_writes_wide_values_in_their_order(controller: Rig) -> None:
    sim, dev, model = controller
    before = len(sim.requests)
    dev.setpoint = 120.5
    dev.zero_offset = -1000
    dev.device_name = "line 3"
    abcd = struct.unpack(">HH", struct.pack(">f", 120.5))
    counts = struct.unpack(">HHHH", struct.pack(">q", -1000))
    text = b"line 3".ljust(16, b"\0")
    assert sent_by(sim, before) == [
        frame(0x10, 0x00, 0x00, 0x00, 0x02, 4, *struct.pack(">HH", abcd[1], abcd[0])),  # CDAB
        frame(0x10, 0x00, 0x24, 0x00, 0x04, 8, *struct.pack(">HHHH", *counts)),
        frame(0x10, 0x00, 0x30, 0x00, 0x08, 16, *text),
    ]
    assert model.value("setpoint") == pytest.approx(120.5)
    assert model.value("zero_offset") == -1000
    assert model.value("device_name") == "line 3"
    with pytest.raises(ValueError, match="holds at most 16 characters"):
        dev.device_name = "x" * 17
    with pytest.raises(ValueError, match=r"gain must be 0\.5 to 2, got 2\.5"):
        dev.gain = 2.5


def test_controller_writes_are_paced(controller: Rig) -> None:
    _, dev, model = controller
    start = time.monotonic()
    dev.mode = "purge"
    dev.mode = "close"
    dev.mode = "off"
    # min_write_interval = 0.05: three writes span at least two intervals.
    assert time.monotonic() - start >= 0.1
    assert model.value("mode") == "off"


def test_controller_record_keeps_the_units(controller: Rig) -> None:
    _, dev, _ = controller
    rec = dev.record(0.25, 0.1, columns=["flow", "gas_temperature"])
    assert len(rec) >= 2
    assert rec.unit_map() == {"flow": "sccm", "gas_temperature": "degC"}
    assert rec["flow"][0] == pytest.approx(49.75)
    pytest.importorskip("pandas")
    frame_ = rec.to_pandas()
    assert frame_.attrs["units"] == {"flow": "sccm", "gas_temperature": "degC"}
    assert frame_.attrs["device"] == "FC-200 unit 1"
    assert dev.sample_units()["total"] == "scc"
    assert "device_name" not in dev.SAMPLE_FIELDS  # a string is no measurement


def test_repr_and_html(controller: Rig) -> None:
    _, dev, _ = controller
    assert repr(dev).startswith("<Device 'FC-200' unit=1 on Bus(")
    page = dev._repr_html_()
    assert "FC-200 (unit 1)" in page
    assert "<td>sccm</td>" in page and "gas_temperature" in page


# ---- the profile object, and mistakes before any port is opened ----------------------------


def test_profile_plan_groups_neighbours_within_max_read() -> None:
    profile = bb.Profile(RELAYS)
    assert profile.plan(["input8", "input1", "relay1", "relay2", "all_off", "all_on"]) == [
        ("holding", 0x10, 1, ["all_on", "all_off"]),
        ("coil", 0, 2, ["relay1", "relay2"]),
        ("discrete", 0, 1, ["input1"]),
        ("discrete", 7, 1, ["input8"]),
    ]
    assert len(profile) == 19 and "relay1" in profile and profile["relay1"].table == "coil"
    with pytest.raises(KeyError):
        profile["relay9"]


def test_a_bad_profile_fails_before_the_port_opens(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text('[device]\nname = "x"\n[[register]]\nname = "read"\naddress = 0\n')
    with pytest.raises(bb.ProfileError, match=r"bad.toml:4: register\[0\].name"):
        bb.Device.from_profile(path, "/dev/does-not-exist")


@pytest.mark.parametrize(
    "member", [*sorted(n for n in dir(bb.Device) if not n.startswith("_")), "name", "enums"]
)
def test_no_register_may_shadow_a_device_member(member: str) -> None:
    text = f'[device]\nname = "x"\n[[register]]\nname = "{member}"\naddress = 0\n'
    with pytest.raises(bb.ProfileError, match="would shadow a member of the device"):
        bb.Profile.parse(text)


def test_the_device_opens_its_own_port_at_the_profiles_line() -> None:
    with Simulator({1: ProfileDevice(SENSOR)}) as sim:
        with bb.Device.from_profile(SENSOR, sim.port) as dev:
            assert (dev.bus.baudrate, dev.bus.parity, dev.bus.timeout) == (9600, "N", 0.5)
            assert dev.humidity == pytest.approx(45.0)
            bus = dev.bus
        assert bus.closed


def test_a_device_of_every_address_samples_every_register(tmp_path: Path) -> None:
    # 65,536 registers, 3.5 MB: made a device and read in 525 requests of 125.
    path = tmp_path / "big.toml"
    path.write_text(big_profile(65_536))
    model = ProfileDevice(path, values={"r00000": "on", "r32769": 5, "r65535": 7})
    with Simulator({1: model}) as sim, bb.Bus(sim.port, baudrate=9600, timeout=0.5) as bus:
        dev = bb.Device.from_profile(path, bus, unit=1)
        assert dev.SAMPLE_FIELDS is not None and len(dev.SAMPLE_FIELDS) == 65_536
        before = len(sim.requests)
        values = dev.sample()
        assert len(sim.requests) - before == 525
        assert list(values) == list(dev.SAMPLE_FIELDS)
        assert values["r00000"] is dev.enums["r00000"].on and values["r00016"] == 0
        assert (values["r32769"], values["r65535"], dev.r65535) == (5, 7, 7)
        assert sim.errors == []


# ---- read_gaps: one request across the addresses a profile does not list -------------------

GAPPED = """
[device]
name = "gapped"
[limits]
max_read = 8
read_gaps = {gaps}
[[register]]
name = "a"
address = 0
type = "i16"
scale = 0.1
[[register]]
name = "b"
address = 4
[[register]]
name = "c"
address = 10
"""


@pytest.mark.parametrize("gaps", [False, True])
def test_read_gaps_reads_across_unlisted_addresses_up_to_max_read(
    tmp_path: Path, gaps: bool
) -> None:
    """With read_gaps, a and b (0 and 4) come in one request, the simulated device answers
    the unlisted 1..3 with 0, and c (10) stays apart: 0..10 is past max_read 8."""
    path = tmp_path / "gapped.toml"
    path.write_text(GAPPED.format(gaps=str(gaps).lower()), encoding="utf-8")
    for sim, dev, _ in rig(path, a=-1.5, b=7, c=9):
        before = len(sim.requests)
        assert dev.read_many(["a", "b", "c"]) == {"a": -1.5, "b": 7, "c": 9}
        reads = (
            [(0x03, 0, 0, 0, 5), (0x03, 0, 10, 0, 1)]
            if gaps
            else [
                (0x03, 0, 0, 0, 1),
                (0x03, 0, 4, 0, 1),
                (0x03, 0, 10, 0, 1),
            ]
        )
        assert sent_by(sim, before) == [frame(*r) for r in reads]
        # A read that starts or ends on an unlisted address is still refused.
        with pytest.raises(bb.ModbusException, match="0x02"):
            dev.bus.read_holding_registers(1, 1, 4)
        with pytest.raises(bb.ModbusException, match="0x02"):
            dev.bus.read_holding_registers(1, 0, 2)
        sim.errors.clear()


def test_read_gaps_misuse_is_refused_by_the_parser_and_the_simulator(tmp_path: Path) -> None:
    path = tmp_path / "gapped.toml"
    path.write_text(
        GAPPED.format(gaps="true").replace("[limits]", "[limits]\nblock_reads = false"),
        encoding="utf-8",
    )
    with pytest.raises(bb.ProfileError, match="read_gaps: needs block reads"):
        bb.Profile(path)
    with pytest.raises(ValueError, match="read_gaps needs block reads"):
        ProfileDevice(path)


def test_the_j2_class_reads_a_simulated_profile_device_serving_its_file(tmp_path: Path) -> None:
    """The J2 file's read_gaps: J2Controller reads PV, SV and MV (0, 2, 6) in one request
    from a profile device serving the family file, as it does from a J2."""
    path = tmp_path / "j2.toml"
    path.write_text(bb.Profile.family("j2").to_toml(), encoding="utf-8")
    model = ProfileDevice(path, values={"PV": 21.5, "SV": 40.0, "MV": 12.5})
    with Simulator({1: model}) as sim, bb.Bus(sim.port, timeout=0.5) as bus:
        j2 = bb.J2Controller(bus, 1, check_identity=False)
        before = len(sim.requests)
        sample = j2.sample()
        assert sample == {"pv": 21.5, "sv": 40.0, "mv": 12.5}
        assert sent_by(sim, before) == [frame(0x03, 0, 0, 0, 7)]
        assert sim.errors == []


# ---- write_echo: a device that answers a 0x06 write with a register count ----------------

COUNTING = """
[device]
name = "counting"
[limits]
write_echo = "{echo}"
[[register]]
name = "setpoint"
address = 3
max = 1000
"""


def test_a_device_answering_writes_with_a_count_is_written_with_write_echo_count(
    tmp_path: Path,
) -> None:
    """The PBL drives' reply to a 0x06 write: a register count of 1 where the value was.
    Declared, it is taken (and the value is written); not declared, it is a wrong echo."""
    path = tmp_path / "counting.toml"
    path.write_text(COUNTING.format(echo="count"), encoding="utf-8")
    assert bb.Profile(path).limits.write_echo == "count"
    assert 'write_echo = "count"' in bb.Profile(path).to_toml()
    for sim, dev, model in rig(path, setpoint=5):
        before = len(sim.requests)
        dev.setpoint = 300
        assert sent_by(sim, before) == [frame(0x06, 0, 3, 0x01, 0x2C)]
        assert sim.replies[-1] == frame(0x06, 0, 3, 0, 1)  # the count, not 0x012C
        assert model.value("setpoint") == 300
        assert dev.bus.stats.frame_errors == 0
    # The same device under a profile that expects the Modbus echo: refused.
    strict = tmp_path / "strict.toml"
    strict.write_text(COUNTING.format(echo="strict"), encoding="utf-8")
    model = ProfileDevice(path, values={"setpoint": 5})
    with Simulator({1: model}) as sim, bb.Bus(sim.port, timeout=0.3, retries=0) as bus:
        device = bb.Device.from_profile(strict, bus, unit=1)
        with pytest.raises(bb.FrameError, match="echo"):
            device.setpoint = 300


def test_write_echo_misuse_is_refused_by_the_parser_and_the_simulator(tmp_path: Path) -> None:
    path = tmp_path / "counting.toml"
    path.write_text(COUNTING.format(echo="value"), encoding="utf-8")
    with pytest.raises(bb.ProfileError, match="write_echo"):
        bb.Profile(path)
    with pytest.raises(ValueError, match="write_echo must be 'strict' or 'count'"):
        ProfileDevice(path)


def test_a_device_of_the_pbl_file_writes_to_a_simulated_pbl(tmp_path: Path) -> None:
    """The PBL file says how the drive answers a write, so a profile's Device made from it
    writes to a PBL (the family's simulator, written from the manual) as PblDrive does."""
    from benchbus.sim import PblDevice

    path = tmp_path / "pbl.toml"
    path.write_text(bb.Profile.family("pbl").to_toml(), encoding="utf-8")
    model = PblDevice()
    with Simulator({1: model}) as sim, bb.Bus(sim.port, timeout=0.3) as bus:
        dev = bb.Device.from_profile(path, bus, unit=1)
        dev.acceleration = 750
        assert sim.replies[-1][4:6] == b"\x00\x01"  # the drive's count
        assert bus.read_holding_registers(1, 209, 1) == [750]


STATUS_WORD = """
[device]
name = "pump"
[limits]
block_reads = false

[[register]]
name = "status"
address = 2
access = "r"

[[register]]
name = "running"
address = 2
type = "bool"
bit = 0
access = "r"

[[register]]
name = "fault"
address = 2
type = "bool"
bit = 3
access = "r"

[[register]]
name = "control"
address = 7

[[register]]
name = "start"
address = 7
type = "bool"
bit = 0
"""


def test_a_status_word_and_its_flags_are_read_in_one_request(tmp_path: Path) -> None:
    """The word and its flags share address 2: one request (even without block reads),
    each flag the word's bit; a flag of a writable word is written by read-modify-write."""
    path = tmp_path / "pump.toml"
    path.write_text(STATUS_WORD, encoding="utf-8")
    for sim, dev, model in rig(path, status=0b1001, control=0b0110):
        before = len(sim.requests)
        assert dev.read_many(["status", "running", "fault"]) == {
            "status": 9,
            "running": True,
            "fault": True,
        }
        assert sent_by(sim, before) == [frame(0x03, 0, 2, 0, 1)]
        model.set_value("status", 0b0001)
        assert (dev.status, dev.running, dev.fault) == (1, True, False)
        dev.start = True  # bit 0 of the control word; its other bits kept
        assert model.value("control") == 0b0111
        assert model.value("start") is True
        dev.control = 0
        assert dev.start is False


FIELDS = """
[device]
name = "drive"

[[register]]
name = "status"
address = 2
access = "r"

[[register]]
name = "source"
address = 2
bits = [5, 6]
access = "r"
enum = { 0 = "keypad", 1 = "terminals", 2 = "communication" }

[[register]]
name = "mode"
address = 7
bits = [2, 4]
max = 5

[[register]]
name = "gain"
address = 7
bits = [8, 11]
scale = 0.5
"""


def test_fields_of_a_word_read_and_write_only_their_bits(tmp_path: Path) -> None:
    """A field (``bits``) is its bits of the word as an unsigned number, an enum or a scaled
    value; written by read-modify-write, its word's other bits kept; a value beyond its
    bits or its range is refused before anything is sent."""
    path = tmp_path / "fields.toml"
    path.write_text(FIELDS, encoding="utf-8")
    rows = {r.name: r for r in bb.Profile(path).registers}
    assert (rows["source"].bits, rows["gain"].bits, rows["status"].bits) == ((5, 6), (8, 11), None)
    assert (rows["gain"].min, rows["gain"].max) == (0.0, 7.5)
    assert "bits = [5, 6]" in bb.Profile(path).to_toml()
    # 0x8041: bit 15, bits 5..6 = 2 (communication), bit 0; control word 0xF003.
    for sim, dev, model in rig(path, status=0x8041, mode=0, gain=0):
        model.set_value("mode", 0)
        dev.bus.write_register(1, 7, 0xF003)
        before = len(sim.requests)
        assert dev.read_many(["status", "source"]) == {
            "status": 0x8041,
            "source": dev.enums["source"].communication,
        }
        assert sent_by(sim, before) == [frame(0x03, 0, 2, 0, 1)]
        assert (dev.mode, dev.gain) == (0, 0.0)
        dev.mode = 5  # bits 2..4 of 0xF003
        dev.gain = 2.5  # bits 8..11
        assert dev.bus.read_holding_registers(1, 7, 1) == [0xF003 & ~0x0F1C | 5 << 2 | 5 << 8]
        assert (dev.mode, dev.gain) == (5, 2.5)
        before = len(sim.requests)
        for name, value in (("mode", 6), ("gain", 8.0), ("gain", 0.25)):
            with pytest.raises(ValueError, match=name):
                setattr(dev, name, value)
        assert len(sim.requests) == before


def test_only_a_one_word_number_shares_its_address_with_bits(tmp_path: Path) -> None:
    """A u32 under a flag, or two whole words at one address: refused by the parser and by
    the simulator, each on its own reading of the file."""
    for text in (
        STATUS_WORD.replace(
            'name = "status"\naddress = 2', 'name = "status"\naddress = 2\ntype = "u32"'
        ),
        STATUS_WORD + '\n[[register]]\nname = "again"\naddress = 7\n',
    ):
        path = tmp_path / "bad.toml"
        path.write_text(text, encoding="utf-8")
        with pytest.raises(bb.ProfileError, match="overlaps"):
            bb.Profile(path)
        with pytest.raises(ValueError, match="is also"):
            ProfileDevice(path)


@pytest.mark.parametrize(
    "extra",
    [
        "bits = [3, 2]",
        'bits = [0, 3]\ntype = "i16"',
        'bits = [0, 3]\norder = "BADC"',
        "bits = [0, 1]\nmax = 4",
        "bits = [0, 1]\nscale = 0.5\nmin = -1",
        'bits = [0, 1]\nenum = { 4 = "four" }',
    ],
)
def test_a_field_its_bits_cannot_hold_is_refused_by_both_readers(
    tmp_path: Path, extra: str
) -> None:
    """The core and the simulator each refuse, on their own reading of the file, a field
    with its bits reversed, on another type, with a byte order, or a range or enum member
    beyond what its bits hold."""
    path = tmp_path / "bad.toml"
    path.write_text(f'[device]\nname = "d"\n[[register]]\nname = "f"\naddress = 1\n{extra}\n')
    with pytest.raises(bb.ProfileError):
        bb.Profile(path)
    with pytest.raises(ValueError, match=r"bits|byte order"):
        ProfileDevice(path)


@pytest.mark.parametrize("multiple", [True, False])
def test_write_multiple_sends_every_register_write_by_0x10(tmp_path: Path, multiple: bool) -> None:
    """A device that takes no 0x06 (Eastron's meters): one word, and a bit written back
    into its word, go by 0x10; without the key, by 0x06. The simulator reads the key
    itself and answers 0x06 with exception 1 when it is set."""
    path = tmp_path / "meter.toml"
    path.write_text(
        '[device]\nname = "meter"\n'
        f"[limits]\nwrite_multiple = {str(multiple).lower()}\n"
        '[[register]]\nname = "mode"\naddress = 0x10\naccess = "rw"\nmax = 9\n'
        '[[register]]\nname = "word"\naddress = 0x11\naccess = "rw"\n'
        '[[register]]\nname = "flag"\naddress = 0x11\ntype = "bool"\nbit = 3\naccess = "rw"\n'
    )
    assert bb.Profile(path).limits.write_multiple is multiple
    assert ("write_multiple = " + str(multiple).lower()) in bb.Profile(path).to_toml()
    model = ProfileDevice(path, values={"word": 0x8001})
    with Simulator({1: model}) as sim, bb.Bus(sim.port, baudrate=9600, timeout=0.5) as bus:
        dev = bb.Device.from_profile(path, bus, unit=1)
        before = len(sim.requests)
        dev.mode = 7
        dev.flag = True
        sent = sent_by(sim, before)
        if multiple:
            assert sent == [
                frame(0x10, 0x00, 0x10, 0x00, 0x01, 0x02, 0x00, 0x07),
                frame(0x03, 0x00, 0x11, 0x00, 0x01),
                frame(0x10, 0x00, 0x11, 0x00, 0x01, 0x02, 0x80, 0x09),
            ]
            with pytest.raises(bb.ModbusException) as refused:
                bus.write_register(1, 0x10, 1)
            assert refused.value.code == 1
        else:
            assert sent == [
                frame(0x06, 0x00, 0x10, 0x00, 0x07),
                frame(0x03, 0x00, 0x11, 0x00, 0x01),
                frame(0x06, 0x00, 0x11, 0x80, 0x09),
            ]
        assert (model.value("mode"), model.value("word")) == (7, 0x8009)
        assert sim.errors == []


def test_write_multiple_cannot_go_with_a_count_echo(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(
        '[device]\nname = "bad"\n[limits]\nwrite_multiple = true\nwrite_echo = "count"\n'
    )
    with pytest.raises(bb.ProfileError, match=r"bad.toml:5: limits.write_echo: .*0x06"):
        bb.Profile(path)
    with pytest.raises(ValueError, match="write_echo 'count' is for 0x06"):
        ProfileDevice(path)


DECIMALS = """
[device]
name = "controller"

[[register]]
name = "pv"
address = 0x10
table = "input"
type = "i16"
decimals = "dp"
default = 253

[[register]]
name = "dp"
address = 0x11
table = "input"
min = 0
max = 3
default = 1

[[register]]
name = "sp"
address = 0x20
type = "i16"
access = "rw"
min = -1999
max = 9999
decimals = "dp"
default = 1000

[[register]]
name = "mode"
address = 0x21
access = "rw"
max = 9
"""


@pytest.fixture
def decimals(tmp_path: Path) -> Iterator[Rig]:
    """A controller whose PV and SP take their decimal places from ``dp``."""
    path = tmp_path / "controller.toml"
    path.write_text(DECIMALS)
    yield from rig(path)


def test_decimals_read_with_the_places_their_register_gives(decimals: Rig) -> None:
    sim, dev, model = decimals
    assert dev.profile["pv"].decimals == "dp" and dev.profile["pv"].integer_range() is None
    before = len(sim.requests)
    assert dev.pv == 25.3 and dev.sp == 100.0
    # PV with its places in one request (neighbours); SP with dp in another.
    assert sent_by(sim, before) == [
        frame(0x04, 0x00, 0x10, 0x00, 0x02),
        frame(0x03, 0x00, 0x20, 0x00, 0x01),
        frame(0x04, 0x00, 0x11, 0x00, 0x01),
    ]
    for places, pv in ((0, 253), (2, 2.53), (3, 0.253)):
        model.input_registers[0x11] = places
        assert dev.pv == pv and model.value("pv") == pv
        assert isinstance(dev.pv, float)  # whatever the places: a value's type stays
    assert dev.profile.plan(["pv", "sp"]) == [
        ("holding", 0x20, 1, ["sp"]),
        ("input", 0x10, 2, ["pv", "dp"]),
    ]
    model.input_registers[0x10] = 0xFFFF - 1998  # -1999 digits at 3 places
    assert dev.read_many(["pv", "dp"]) == {"pv": -1.999, "dp": 3}


def test_decimals_are_read_before_a_write_is_checked_at_them(decimals: Rig) -> None:
    sim, dev, model = decimals
    before = len(sim.requests)
    dev.sp = 30.5
    assert sent_by(sim, before) == [
        frame(0x04, 0x00, 0x11, 0x00, 0x01),
        frame(0x06, 0x00, 0x20, 0x01, 0x31),  # 305 digits
    ]
    assert model.registers[0x20] == 305 and model.value("sp") == 30.5
    for bad, said in ((30.55, "steps"), (1000.0, "999.9")):
        before = len(sim.requests)
        with pytest.raises(ValueError, match=said):
            dev.sp = bad
        assert sent_by(sim, before) == [frame(0x04, 0x00, 0x11, 0x00, 0x01)]  # no write
    model.input_registers[0x11] = 0
    dev.sp = 1000
    assert model.registers[0x20] == 1000
    # Checks that need no places are made before anything is sent.
    before = len(sim.requests)
    with pytest.raises(TypeError):
        dev.sp = "hot"
    with pytest.raises(ValueError, match="read-only"):
        dev.pv = 1.0
    assert sent_by(sim, before) == []
    dev.profile.check("sp", 30.55)  # its steps wait for its places
    with pytest.raises(TypeError):
        dev.profile.check("sp", "hot")
    # What no places can take is refused before anything is sent, the read of them too.
    for bad in (float("nan"), 1e12, -2000.0):
        with pytest.raises(ValueError, match="-1999 to 9999"):
            dev.sp = bad
        with pytest.raises(ValueError):
            dev.profile.check("sp", bad)
    assert sent_by(sim, before) == []


def test_set_many_checks_every_value_at_its_places_before_writing_any(decimals: Rig) -> None:
    sim, dev, model = decimals
    before = len(sim.requests)
    with pytest.raises(ValueError, match="steps"):
        dev.set_many({"mode": 3, "sp": 30.55})
    assert sent_by(sim, before) == [frame(0x04, 0x00, 0x11, 0x00, 0x01)]  # no write
    assert model.registers[0x21] == 0
    dev.set_many([("mode", 3), ("sp", 30.5)])
    assert (model.value("mode"), model.value("sp")) == (3, 30.5)


def test_a_sequence_that_writes_the_places_writes_the_values_after_at_them(
    tmp_path: Path,
) -> None:
    path = tmp_path / "settable.toml"
    path.write_text(
        DECIMALS.replace('table = "input"\nmin = 0', 'access = "rw"\nmin = 0').replace(
            "address = 0x11", "address = 0x22"
        )
    )
    for rig_ in rig(path):
        _, dev, model = rig_
        dev.set_many([("dp", 2), ("sp", 30.55)])  # 3055 digits at the 2 places just written
        assert model.registers[0x22] == 2 and model.registers[0x20] == 3055
        assert dev.sp == 30.55


def test_places_no_count_of_places_reads_as_a_state_error(decimals: Rig) -> None:
    _, dev, model = decimals
    model.input_registers[0x11] = 12
    with pytest.raises(bb.StateError, match=r"pv's decimal places \(dp\) read .*12.*not 0..9"):
        dev.read("pv")
    with pytest.raises(bb.StateError):
        dev.sp = 1.0
    assert model.registers[0x20] == 1000


def test_decimals_round_trip_and_show(tmp_path: Path) -> None:
    profile = bb.Profile.parse(DECIMALS, "c.toml")
    again = bb.Profile.parse(profile.to_toml())
    assert again["sp"].decimals == "dp" and again["sp"] == profile["sp"]._replace(
        line=again["sp"].line
    )
    (tmp_path / "c.toml").write_text(DECIMALS)
    shown = ok(run("profile", "check", tmp_path / "c.toml"))
    assert any(line.split()[:5] == ["sp", "holding", "0x0020", "i16", "10^-dp"] for line in shown)


@pytest.mark.parametrize(
    ("change", "key", "said"),
    [
        (
            ('decimals = "dp"\ndefault = 253', 'decimals = "nope"\ndefault = 253'),
            "register[0].decimals",
            "no register",
        ),
        (
            ('decimals = "dp"\ndefault = 253', 'decimals = "pv"\ndefault = 253'),
            "register[0].decimals",
            "another register",
        ),
        (("min = 0\nmax = 3\n", ""), "register[0].decimals", "within 0..9"),
        (
            ('type = "i16"\ndecimals = "dp"\ndefault = 253', 'type = "f32"\ndecimals = "dp"'),
            "register[0].decimals",
            "integer",
        ),
        (
            (
                'type = "i16"\ndecimals = "dp"\ndefault = 253',
                'type = "i16"\nscale = 0.1\ndecimals = "dp"',
            ),
            "register[0].decimals",
            "scale",
        ),
        (
            ('table = "input"\nmin = 0', 'access = "w"\nmin = 0'),
            "register[0].decimals",
            "write-only",
        ),
        (
            ('type = "i16"\ndecimals = "dp"\ndefault = 253', 'type = "bool"\ndecimals = "dp"'),
            "",
            "integer",
        ),
        (
            ('decimals = "dp"\ndefault = 253', 'enum = { 1 = "a" }\ndecimals = "dp"'),
            "",
            "enum",
        ),
        (('table = "input"\nmin = 0', 'table = "input"\nscale = 0.5\nmin = 0'), "", "unscaled"),
    ],
)
def test_a_misused_decimals_is_a_profile_error(
    change: tuple[str, str], key: str, said: str
) -> None:
    old, new = change
    assert old in DECIMALS
    with pytest.raises(bb.ProfileError, match=said) as refused:
        bb.Profile.parse(DECIMALS.replace(old, new, 1), "c.toml")
    assert refused.value.key == (key or "register[0].decimals")


def test_a_places_register_is_on_every_model_its_value_is_on() -> None:
    models = DECIMALS.replace('name = "controller"', 'name = "c"\nmodels = ["A", "B"]')
    only_a = models.replace("max = 3\ndefault = 1", 'max = 3\ndefault = 1\nmodels = ["A"]')
    with pytest.raises(bb.ProfileError, match="not on every model") as refused:
        bb.Profile.parse(only_a, "c.toml")
    assert refused.value.key == "register[0].decimals"
    ranged = models.replace(
        "max = 3\ndefault = 1", "max = 3\ndefault = 1\nranges = { B = [0, 12] }"
    )
    with pytest.raises(bb.ProfileError, match=r"within 0\.\.9"):
        bb.Profile.parse(ranged, "c.toml")


BITS_PLACES = """
[device]
name = "bits"

[[register]]
name = "status"
address = 0x22
access = "rw"

[[register]]
name = "dp"
address = 0x22
bits = [0, 1]
access = "rw"

[[register]]
name = "sp"
address = 0x20
type = "i16"
access = "rw"
min = 3
max = 9999
decimals = "dp"
"""


def test_places_in_a_field_of_bits_written_in_the_sequence_count(tmp_path: Path) -> None:
    path = tmp_path / "bits.toml"
    path.write_text(BITS_PLACES)
    for _, dev, model in rig(path, status=0x80):
        dev.set_many([("dp", 1), ("sp", 30)])  # 300 digits at the one place just written
        assert model.registers[0x22] == 0x81 and model.registers[0x20] == 300
        assert dev.sp == 30.0
        dev.set_many([("dp", 2), ("sp", 30.55)])
        assert model.registers[0x20] == 3055
        # The whole word would change the places behind the sequence: refused, unsent.
        with pytest.raises(ValueError, match="status shares its register with dp"):
            dev.set_many([("status", 0x80), ("sp", 30)])
        assert model.registers[0x22] == 0x82
        # The digits' range at the most places its field holds (3): 3 digits is 0.003.
        dev.profile.check("sp", 0.003)
        with pytest.raises(ValueError, match=r"0\.003 to 9999"):
            dev.profile.check("sp", 0.002)


def test_the_simulator_takes_a_places_register_as_the_core_does(tmp_path: Path) -> None:
    max_only = DECIMALS.replace("min = 0\nmax = 3\ndefault = 1", "max = 3\ndefault = 1")
    (tmp_path / "max_only.toml").write_text(max_only)
    assert ProfileDevice(tmp_path / "max_only.toml").value("pv") == 25.3
    bb.Profile(tmp_path / "max_only.toml")  # a u16 of max 3: 0..3
    ranged = max_only.replace('name = "controller"', 'name = "c"\nmodels = ["A", "B"]').replace(
        "max = 3\ndefault = 1", "max = 3\ndefault = 1\nranges = { B = [0, 12] }"
    )
    (tmp_path / "ranged.toml").write_text(ranged)
    with pytest.raises(ValueError, match=r"0\.\.9 places"):
        ProfileDevice(tmp_path / "ranged.toml")
    with pytest.raises(bb.ProfileError):
        bb.Profile(tmp_path / "ranged.toml")
