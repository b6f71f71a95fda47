"""benchbus installed from its wheel: where it comes from, a read through a simulator (on a
pseudo-terminal and over TCP), the command line, the pytest plugin's fixtures, the demo."""

from __future__ import annotations

import importlib
import json
import os
import pkgutil
import shutil
import subprocess
import sys
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

import benchbus as bb

if TYPE_CHECKING:
    from benchbus.pytest_plugin import SimBench
    from benchbus.sim import DriveDevice

#: The source checkout the wheel was built from: nothing may be imported from it.
CHECKOUT = os.environ.get("BENCHBUS_CHECKOUT", "")
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def inside(path: str | Path, root: str | Path) -> bool:
    try:
        Path(path).resolve().relative_to(Path(root).resolve())
    except ValueError:
        return False
    return True


def benchbus_command(*args: str) -> subprocess.CompletedProcess[str]:
    """The installed ``benchbus`` console script with ``args``, output captured."""
    script = shutil.which("benchbus", path=str(Path(sys.executable).parent))
    assert script is not None, f"no benchbus script beside {sys.executable}"
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "MPLBACKEND")}
    return subprocess.run(
        [script, *args], capture_output=True, text=True, timeout=60, check=False, env=env
    )


def test_benchbus_is_the_installed_wheel() -> None:
    assert CHECKOUT, "run by .ci/wheel-smoke.sh, which sets BENCHBUS_CHECKOUT"
    package = Path(bb.__file__).parent
    assert not inside(package, CHECKOUT), package
    assert inside(package, sys.prefix), (package, sys.prefix)
    assert not [p for p in sys.path if p and inside(p, CHECKOUT)]
    # The compiled core came with it, not from a build in the checkout.
    assert inside(bb._core.__file__, package)
    dist = metadata.distribution("benchbus")
    origin = json.loads(dist.read_text("direct_url.json") or "{}")
    assert "archive_info" in origin and origin["url"].endswith(".whl"), origin
    tags = (dist.read_text("WHEEL") or "").splitlines()
    assert any(t.startswith("Tag: cp39-abi3-") for t in tags), tags
    # One version: the wheel's metadata is Cargo.toml's, as the compiled core reports it.
    assert dist.version == bb.__version__, (dist.version, bb.__version__)


def modules(prefix: str) -> list[str]:
    names = [m.name for m in pkgutil.walk_packages(bb.__path__, "benchbus.")]
    return [n for n in names if n == prefix or n.startswith(prefix + ".")]


def test_every_module_compiles_and_imports_on_this_python() -> None:
    """Python 3.9 and up: no newer syntax anywhere, no newer runtime feature at import."""
    package = Path(bb.__file__).parent
    sources = sorted(package.rglob("*.py"))
    assert len(sources) > 20
    for source in sources:
        compile(source.read_text(encoding="utf-8"), str(source), "exec")
    names = [n for n in modules("benchbus") if not n.startswith("benchbus.sim")]
    assert {"benchbus.cli", "benchbus.pytest_plugin", "benchbus._demo"} <= set(names)
    for name in names:
        importlib.import_module(name)


def test_the_type_information_ships() -> None:
    """PEP 561: the marker, the compiled module's stub and the async devices' members and
    classes (the families' are made at import, so type checkers read them there)."""
    package = Path(bb.__file__).parent
    for name in ("py.typed", "_core.pyi", "_aio_members.pyi"):
        assert (package / name).is_file(), name
    members = (package / "_aio_members.pyi").read_text(encoding="utf-8")
    assert "class DriveMembers(BusDeviceMembers):" in members
    assert "class Drive(AsyncDevice[_SyncDrive], DriveMembers):" in members


def test_the_family_files_ship_and_are_the_exports() -> None:
    """Each built-in family whose register map is a file ships it, and the export is it."""
    files = sorted((Path(bb.__file__).parent / "families").glob("*.toml"))
    assert "pbl.toml" in [f.name for f in files]
    for file in files:
        text = file.read_text(encoding="utf-8")
        assert bb.Profile.family(file.stem).to_toml() == text, file.name


def test_the_shipped_profiles_ship_and_open_by_name() -> None:
    """The profiles the package ships are in the wheel, each found by its name there."""
    shipped = Path(bb.__file__).parent / "profiles"
    files = sorted(shipped.glob("*.toml"))
    assert len(files) >= 10 and "sdm630.toml" in [f.name for f in files]
    for file in files:
        profile = bb.Profile(file.stem)
        assert profile.path == str(file) and profile.source, file.name
    listed = subprocess.run(
        [sys.executable, "-m", "benchbus", "profile", "list"],
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    ).stdout
    assert all(f.stem in listed for f in files)


@pytest.mark.sim
def test_the_simulators_import() -> None:
    names = modules("benchbus.sim")
    assert "benchbus.sim._network" in names
    for name in names:
        importlib.import_module(name)


def test_bad_input_is_refused_before_anything_is_sent() -> None:
    with pytest.raises(bb.PortError):
        bb.Bus("tcp://127.0.0.1:1", timeout=0.2)  # nothing listens on port 1
    with pytest.raises(ValueError):
        bb.Bus("/no/such/port", baudrate=0)


@pytest.mark.sim
@pytest.mark.pty
def test_a_read_and_a_write_through_a_simulator_on_a_pseudo_terminal() -> None:
    from benchbus.sim import RegisterDevice, Simulator

    with Simulator({1: RegisterDevice({0x3006: 1450})}) as sim, bb.Bus(sim.port) as bus:
        assert bus.read_holding_registers(1, 0x3006, 1) == [1450]
        bus.write_register(1, 0x3006, 900)
        assert bus.read_holding_registers(1, 0x3006, 1) == [900]
        sim.set_silent(1)
        with pytest.raises(bb.ResponseTimeout):
            bus.read_holding_registers(1, 0x3006, 1)


@pytest.mark.sim
def test_a_read_through_a_simulator_over_tcp() -> None:
    from benchbus.sim import DriveDevice, Simulator

    with (
        Simulator({2: DriveDevice("BLD2")}, network="tcp") as sim,
        bb.Drive(sim.port, unit=2) as drive,
    ):
        drive.speed_setpoint = 1200
        assert drive.speed_setpoint == 1200
        assert drive.state == bb.DriveState.STOPPED


@pytest.mark.sim
def test_the_command_line_reads_through_a_simulator() -> None:
    from benchbus.sim import RegisterDevice, Simulator

    with Simulator({7: RegisterDevice({0x10: 0xFFFB, 0x11: 1234})}, network="tcp") as sim:
        done = benchbus_command("read", "--port", sim.port, "--unit", "7", "0x10", "2")
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["0x0010 (16) = 65531", "0x0011 (17) = 1234"]


def test_the_command_line_fails_in_one_line() -> None:
    done = benchbus_command("read", "--port", "tcp://127.0.0.1:1", "--timeout", "0.2", "0")
    assert done.returncode == 1
    assert done.stderr.startswith("benchbus: ") and len(done.stderr.splitlines()) == 1


@pytest.mark.sim
@pytest.mark.pty
def test_the_pytest_plugin_gives_simulated_devices(
    sim_drive: SimBench[bb.Drive, DriveDevice], bench_j2: bb.J2Controller
) -> None:
    drive, sim, model = sim_drive
    assert isinstance(drive, bb.Drive) and drive.bus.port == sim.port
    drive.accel_time = 0.1
    drive.speed_setpoint = 900
    drive.forward()
    assert abs(drive.wait_for_speed(900, tolerance=20, timeout=3) - 900) <= 20
    assert model.state == model.FORWARD
    assert isinstance(bench_j2, bb.J2Controller)
    bench_j2.sv = 55.0
    assert bench_j2.sv == 55.0


@pytest.mark.sim
@pytest.mark.pty
@pytest.mark.plot
def test_the_demo_runs_and_writes_its_plot(tmp_path: Path) -> None:
    out = tmp_path / "demo.png"
    done = benchbus_command("demo", "--out", str(out))
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0] == "benchbus demo on simulated devices"
    assert lines[-1] == f"plot written to {out.resolve()}"
    drive = [float(line.split()[-5]) for line in lines[2:-1]]
    assert max(drive) > 1400 and min(drive) < -1400 and abs(drive[-1]) < 1
    assert out.read_bytes().startswith(PNG_SIGNATURE)
