"""Device profiles: the issue's example parsed by the core, and every mistake a ProfileError
naming the file, the line and the key."""

from __future__ import annotations

import enum
import keyword
from pathlib import Path

import pytest

import benchbus as bb
from benchbus._names import RESERVED
from benchbus.sim import ProfileDevice

EXAMPLE = """\
[device]
name = "XY-MD02"                 # shown in reprs, CLI, errors
description = "RS485 temperature and humidity sensor"

[line]                           # used when the device opens its own port
baudrate = 9600
parity = "N"

[limits]                         # all optional
max_read = 10                    # registers (or bits for coil tables) per request
max_write = 1
min_write_interval = 0.0         # s between writes to this unit (as on Instrument)
block_reads = true               # may read neighbouring registers in one request

[[register]]
name = "temperature"             # a Python identifier; unique
address = 0x0001                 # decimal or hex
table = "input"                  # holding (default) | input | coil | discrete
type = "i16"
order = "ABCD"
scale = 0.1                      # value = raw * scale + offset (offset optional)
unit = "degC"
access = "r"
min = -40.0                      # checked before a write; also documents the range
max = 125.0
description = "air temperature"

[[register]]
name = "mode"
address = 0x0101
access = "rw"
enum = { 0 = "off", 1 = "heat", 2 = "cool" }   # read as the name, written by name or number
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "device.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_the_example_parses(tmp_path: Path) -> None:
    p = bb.Profile(write(tmp_path, EXAMPLE))
    assert p.name == "XY-MD02"
    assert p.description == "RS485 temperature and humidity sensor"
    assert p.line._asdict() == {
        "baudrate": 9600,
        "parity": "N",
        "stopbits": None,
        "timeout": None,
        "framing": None,
        "bytesize": None,
    }
    assert p.limits._asdict() == {
        "max_read": 10,
        "max_write": 1,
        "min_write_interval": 0.0,
        "block_reads": True,
        "read_gaps": None,
        "write_echo": None,
        "write_multiple": None,
    }
    temperature, mode = p.registers
    assert temperature._asdict() == {
        "name": "temperature",
        "address": 1,
        "table": "input",
        "type": "i16",
        "bit": None,
        "length": None,
        "order": "ABCD",
        "scale": 0.1,
        "offset": 0.0,
        "unit": "degC",
        "access": "r",
        "min": -40.0,
        "max": 125.0,
        "enum": {},
        "default": None,
        "description": "air temperature",
        "line": 15,
        "models": (),
        "ranges": {},
        "bits": None,
        "decimals": None,
    }
    assert mode.address == 0x0101
    assert mode.table == "holding"
    assert mode.type == "u16"
    assert mode.access == "rw"
    assert mode.enum == {0: "off", 1: "heat", 2: "cool"}
    assert (mode.min, mode.max) == (0.0, 65535.0)
    assert mode.line == 28


def test_every_field_of_the_other_types(tmp_path: Path) -> None:
    text = """\
[device]
name = "relay"
[line]
stopbits = 2
parity = "E"
timeout = 0.25
framing = "ascii"
bytesize = 7
[[register]]
name = "relay1"
address = 0
table = "coil"
default = true
[[register]]
name = "alarm"
address = 7
type = "bool"
bit = 3
[[register]]
name = "fault"
address = 7
type = "bool"
bit = 4
access = "r"
[[register]]
name = "label"
address = 8
type = "string"
length = 4
default = "relay"
[[register]]
name = "energy"
address = 20
table = "input"
type = "f64"
order = "CDAB"
offset = -1.5
[[register]]
name = "command"
address = 30
access = "w"
default = 7
"""
    p = bb.Profile(str(write(tmp_path, text)))
    assert p.line._asdict() == {
        "baudrate": None,
        "parity": "E",
        "stopbits": 2,
        "timeout": 0.25,
        "framing": "ascii",
        "bytesize": 7,
    }
    rows = {r.name: r for r in p.registers}
    assert list(rows) == ["relay1", "alarm", "fault", "label", "energy", "command"]
    assert (rows["relay1"].type, rows["relay1"].access, rows["relay1"].default) == (
        "bool",
        "rw",
        True,
    )
    assert (rows["alarm"].bit, rows["fault"].bit, rows["fault"].access) == (3, 4, "r")
    assert (rows["label"].length, rows["label"].default) == (4, "relay")
    assert rows["label"].min is None
    assert (rows["energy"].order, rows["energy"].offset) == ("CDAB", -1.5)
    assert rows["energy"].access == "r"
    assert (rows["command"].access, rows["command"].default) == ("w", 7)


HEAD = '[device]\nname = "d"\n'  # lines 1-2
REG = '[[register]]\nname = "a"\naddress = 1\n'  # lines 3-5

# (what follows HEAD, the line, the key)
CASES = [
    ("colour = 1\n", 3, "device.colour"),
    ("[line]\nbaud = 9600\n", 4, "line.baud"),
    ("[limits]\nmax = 1\n", 4, "limits.max"),
    (REG + "scal = 0.1\n", 6, "register[0].scal"),
    ("[[register]]\naddress = 1\n", 3, "register[0].name"),
    ('[[register]]\nname = "a"\n', 3, "register[0].address"),
    (REG + REG, 7, "register[1].name"),
    ('[[register]]\nname = "2x"\naddress = 1\n', 4, "register[0].name"),
    ('[[register]]\nname = "my-reg"\naddress = 1\n', 4, "register[0].name"),
    ('[[register]]\nname = "read"\naddress = 1\n', 4, "register[0].name"),
    ('[[register]]\nname = "sample"\naddress = 1\n', 4, "register[0].name"),
    ('[[register]]\nname = "bus"\naddress = 1\n', 4, "register[0].name"),
    ('[[register]]\nname = "a"\naddress = 0x10000\n', 5, "register[0].address"),
    ('[[register]]\nname = "a"\naddress = 0xFFFE\ntype = "u64"\n', 5, "register[0].address"),
    (
        '[[register]]\nname = "a"\naddress = 1\ntype = "f32"\n'
        '[[register]]\nname = "b"\naddress = 2\n',
        9,
        "register[1].address",
    ),
    (
        '[[register]]\nname = "a"\naddress = 4\ntype = "bool"\nbit = 2\n'
        '[[register]]\nname = "b"\naddress = 4\ntype = "bool"\nbit = 2\n',
        10,
        "register[1].address",
    ),
    (REG + 'table = "coil"\ntype = "u16"\n', 7, "register[0].type"),
    (REG + 'table = "discrete"\ntype = "string"\nlength = 1\n', 7, "register[0].type"),
    (REG + 'type = "u8"\n', 6, "register[0].type"),
    (REG + 'table = "coil"\nbit = 0\n', 7, "register[0].bit"),
    (REG + 'type = "i16"\nbit = 0\n', 7, "register[0].bit"),
    (REG + 'type = "bool"\nbit = 16\n', 7, "register[0].bit"),
    (REG + "bits = [3, 2]\n", 6, "register[0].bits"),
    (REG + 'type = "i16"\nbits = [0, 1]\n', 7, "register[0].bits"),
    (REG + "bits = [0, 1]\nmax = 4\n", 7, "register[0].max"),
    (REG + 'bits = [0, 1]\nenum = { 4 = "x" }\n', 7, "register[0].enum.4"),
    (REG + 'type = "string"\n', 3, "register[0].length"),
    (REG + 'enum = { one = "a" }\n', 6, "register[0].enum.one"),
    (REG + 'type = "i16"\nenum = { 32768 = "big" }\n', 7, "register[0].enum.32768"),
    (REG + 'enum = { 0 = "not ok" }\n', 6, "register[0].enum.0"),
    (REG + 'enum = { 0 = "on", 1 = "on" }\n', 6, "register[0].enum.1"),
    (REG + "min = 5\nmax = 1\n", 6, "register[0].min"),
    (REG + 'type = "i16"\nmin = -40000\n', 7, "register[0].min"),
    (REG + 'table = "input"\naccess = "rw"\n', 7, "register[0].access"),
    (REG + 'table = "discrete"\naccess = "w"\n', 7, "register[0].access"),
    (REG + 'type = "u32"\norder = "ACDB"\n', 7, "register[0].order"),
    (REG + "scale = 0\n", 6, "register[0].scale"),
    (REG + "default = -1\n", 6, "register[0].default"),
    (REG + "scale = 0.5\ndefault = 0.75\n", 7, "register[0].default"),
    ('[[register]]\nname = "sample_units"\naddress = 1\n', 4, "register[0].name"),
    ('[line]\nparity = "X"\n', 4, "line.parity"),
    ("[line]\nstopbits = 3\n", 4, "line.stopbits"),
    ("[line]\nbytesize = 6\n", 4, "line.bytesize"),
    ('[line]\nframing = "tcp"\n', 4, "line.framing"),
    ("[line]\ntimeout = -0.1\n", 4, "line.timeout"),
    ("[line]\nbaudrate = 0\n", 4, "line.baudrate"),
    ("[limits]\nmax_read = 0\n", 4, "limits.max_read"),
    ("[limits]\nmin_write_interval = -1\n", 4, "limits.min_write_interval"),
    ('[limits]\nblock_reads = "yes"\n', 4, "limits.block_reads"),
]


@pytest.mark.parametrize(("body", "line", "key"), CASES, ids=[c[2] + str(c[1]) for c in CASES])
def test_every_mistake_is_a_profile_error(tmp_path: Path, body: str, line: int, key: str) -> None:
    path = write(tmp_path, HEAD + body)
    with pytest.raises(bb.ProfileError) as raised:
        bb.Profile(path)
    err = raised.value
    assert isinstance(err, ValueError)
    assert isinstance(err, bb.BenchbusError)
    assert (err.path, err.line, err.key) == (str(path), line, key)
    assert str(err).startswith(f"{path}:{line}: {key}: ")


#: Enum member names Python's enum keeps for itself, one of each kind: sunder names of
#: Enum's own and another, dunder names of Python's and another, the method every class has,
#: and a private name of the register's enum class (``op_mode`` gives ``OpMode``).
RESERVED_MEMBERS = [
    ("_missing_", "_sunder_"),
    ("_generate_next_value_", "_sunder_"),
    ("_colour_", "_sunder_"),
    ("__init__", "__dunder__"),
    ("__colour__", "__dunder__"),
    ("mro", "method of every Python class"),
    ("_OpMode__fast", "private name of the enum OpMode"),
]


@pytest.mark.parametrize(("member", "kind"), RESERVED_MEMBERS)
def test_an_enum_member_python_keeps_for_itself_is_a_profile_error(
    tmp_path: Path, member: str, kind: str
) -> None:
    register = '[[register]]\nname = "op_mode"\naddress = 1\n\n[register.enum]\n0 = "off"\n'
    path = write(tmp_path, f'{HEAD}{register}1 = "{member}"\n')  # the member on line 9
    with pytest.raises(bb.ProfileError) as raised:
        bb.Profile(path)
    err = raised.value
    assert (err.path, err.line, err.key) == (str(path), 9, "register[0].enum.1")
    assert str(err).startswith(f'{path}:9: register[0].enum.1: "{member}" is a')
    assert kind in str(err)


@pytest.mark.parametrize("register", ["op_mode", "mode", "mode_2", "a__b", "x1_y"])
def test_the_private_names_refused_are_those_of_the_class_python_makes(register: str) -> None:
    from benchbus._names import class_name

    def text(member: str) -> str:
        return f'{HEAD}[[register]]\nname = "{register}"\naddress = 1\nenum = {{ 1 = "{member}" }}'

    with pytest.raises(bb.ProfileError, match="private name"):
        bb.Profile.parse(text(f"_{class_name(register)}__fast"))
    # Another class's private name is a name like any other.
    assert bb.Profile.parse(text("_Other__fast"))[register].enum[1] == "_Other__fast"


#: Member names Python's enum takes as any other, however close to the ones it keeps.
TAKEN_MEMBERS = [
    "name", "value", "name_1", "_9600", "_x", "x_", "_", "__", "___", "____", "__a_", "_a__",
    "___x___", "_OpMode____", "_OpMode__x__", "_Mode__x", "_opmode__x", "mro_",
]  # fmt: skip


@pytest.mark.parametrize("member", TAKEN_MEMBERS)
def test_a_member_name_python_takes_is_taken_and_is_a_member(member: str) -> None:
    text = f'{HEAD}[[register]]\nname = "op_mode"\naddress = 1\nenum = {{ 0 = "{member}" }}\n'
    profile = bb.Profile.parse(text)
    assert profile["op_mode"].enum == {0: member}
    # Python's own enum agrees: the class is made and the name is one of its members.
    made = enum.IntEnum("OpMode", [(member, 0)])
    assert made[member] == 0


@pytest.mark.parametrize(("member", "kind"), RESERVED_MEMBERS)
def test_python_itself_refuses_or_drops_each_refused_member(member: str, kind: str) -> None:
    try:
        made = enum.IntEnum("OpMode", [("off", 0), (member, 1)])
    except (ValueError, TypeError, AttributeError):
        return  # refused outright
    assert member not in made.__members__, kind  # or silently not made a member


@pytest.mark.parametrize("name", ["class", "None", "lambda", *sorted(RESERVED)])
def test_a_keyword_or_a_member_of_the_device_is_no_register_name(name: str) -> None:
    text = f'{HEAD}[[register]]\nname = "{name}"\naddress = 1\n'
    with pytest.raises(bb.ProfileError) as raised:
        bb.Profile.parse(text, "d.toml")
    assert (raised.value.line, raised.value.key) == (4, "register[0].name")
    why = "is not a Python identifier" if keyword.iskeyword(name) else "would shadow a member"
    assert why in str(raised.value)


def test_a_file_that_is_not_toml_names_its_line(tmp_path: Path) -> None:
    path = write(tmp_path, HEAD + "[[register]]\nname = \n")
    with pytest.raises(bb.ProfileError) as raised:
        bb.Profile(path)
    assert (raised.value.line, raised.value.key) == (4, "")
    assert str(raised.value).startswith(f"{path}:4: ")


def test_a_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "absent.toml"
    with pytest.raises(bb.ProfileError, match="cannot read the file") as raised:
        bb.Profile(path)
    assert raised.value.path == str(path)
    assert raised.value.line == 0
    assert str(raised.value).startswith(f"{path}: cannot read the file: ")  # no line 0


def test_the_path_must_be_a_path() -> None:
    with pytest.raises(TypeError):
        bb.Profile(3)  # type: ignore[arg-type]


def big_profile(registers: int) -> str:
    """``registers`` holding registers at 0 up, named ``r00000`` up, five lines each after
    two of [device] (the header on the second): every 16th an enum, the others with a unit
    (every 4th "degC"). bench/run.py's scenario (l) times profiles like it."""
    out = ['[device]\nname = "big"\n']
    for i in range(registers):
        out.append(f'\n[[register]]\nname = "r{i:05d}"\naddress = {i}\n')
        if i % 16 == 0:
            out.append('enum = { 0 = "off", 1 = "on" }\n')
        else:
            out.append(f'unit = "{"degC" if i % 4 == 0 else ""}"\n')
    return "".join(out)


def test_a_profile_of_every_address_loads_every_register(tmp_path: Path) -> None:
    # 65,536 registers: the whole address space of a table, 3.5 MB. Loading is linear in
    # the registers (bench/run.py's scenario (l) measures it; it was quadratic).
    path = write(tmp_path, big_profile(65_536))
    profile = bb.Profile(path)
    rows = profile.registers
    assert len(profile) == len(rows) == 65_536
    first, last = rows[0], rows[-1]
    assert (first.name, first.address, first.line) == ("r00000", 0, 4)
    assert (last.name, last.address, last.line) == ("r65535", 65_535, 4 + 5 * 65_535)
    assert first.enum == {0: "off", 1: "on"} and last.enum == {} and last.unit == ""
    assert [r.address for r in rows] == list(range(65_536))
    assert profile["r65532"].unit == "degC" and profile["r65520"].enum == {0: "off", 1: "on"}
    assert "r65535" in profile and "r65536" not in profile
    # One request for each 125 registers, in address order.
    plan = profile.plan([r.name for r in reversed(rows)])
    assert len(plan) == 525 and plan[0][:3] == ("holding", 0, 125)
    assert plan[-1][:3] == ("holding", 65_500, 36) and plan[-1][3][-1] == "r65535"
    # Written back, it reads the same.
    again = bb.Profile.parse(profile.to_toml(), "again.toml")
    assert [r._replace(line=0) for r in again.registers] == [r._replace(line=0) for r in rows]


def test_a_mistake_at_the_end_of_a_big_profile_names_its_line(tmp_path: Path) -> None:
    text = big_profile(20_000) + '[[register]]\nname = "r00007"\naddress = 20000\n'
    path = write(tmp_path, text)
    with pytest.raises(bb.ProfileError) as raised:
        bb.Profile(path)
    err = raised.value
    assert (err.line, err.key) == (4 + 5 * 20_000, "register[20000].name")
    assert "duplicate name" in str(err)


TWO_MODELS = """
[device]
name = "d"
models = ["A", "B"]

[[register]]
name = "mode"
address = 1
access = "rw-stopped"
max = 5
ranges = { B = [1, 3] }

[[register]]
name = "extra"
address = 2
models = ["A"]
"""


def test_a_file_of_two_models_gives_each_its_rows_and_ranges(tmp_path: Path) -> None:
    p = bb.Profile.parse(TWO_MODELS, "d.toml")
    assert p.models == ("A", "B")
    assert p["mode"].access == "rw-stopped" and p["mode"].ranges == {"B": (1.0, 3.0)}
    assert p["extra"].models == ("A",)
    b = p.for_model("B")
    assert [r.name for r in b.registers] == ["mode"]
    assert (b["mode"].min, b["mode"].max, b["mode"].ranges) == (1.0, 3.0, {})
    assert b.models == () and len(p.for_model("A")) == 2
    with pytest.raises(ValueError, match=r'no model "C" \(models: A, B\)'):
        p.for_model("C")
    with pytest.raises(ValueError, match="models: none"):
        bb.Profile.parse(EXAMPLE).for_model("A")
    # The simulator reads the file on its own: it serves the rows as written, and takes a
    # write of a rw-stopped register.
    path = tmp_path / "d.toml"
    path.write_text(TWO_MODELS, encoding="utf-8")
    model = ProfileDevice(path)
    assert model.models == ("A", "B")
    model.write_holding(1, [5])
    assert model.read_holding(1, 2) == [5, 0]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ('models = ["B"]\n', "no model 'B'"),
        ("ranges = { C = [0, 1] }\n", "no model 'C'"),
        ("ranges = { A = [2, 1] }\n", r"ranges must be \{ MODEL = \[min, max\] \}"),
        ("models = 1\n", "models must be an array of names"),
        ("models = []\n", "models must be an array of names"),
        ('models = ["A", "A"]\n', "models must be an array of names"),
        ("ranges = {}\n", r"ranges must be \{ MODEL = \[min, max\] \}"),
        ('type = "bool"\nranges = { A = [0, 1] }\n', "a bool register takes no ranges"),
    ],
)
def test_the_simulator_refuses_a_model_the_file_does_not_name(
    tmp_path: Path, change: str, message: str
) -> None:
    text = '[device]\nname = "d"\nmodels = ["A"]\n[[register]]\nname = "z"\naddress = 9\n'
    path = tmp_path / "d.toml"
    path.write_text(text + change, encoding="utf-8")
    with pytest.raises(ValueError, match=message):
        ProfileDevice(path)
