"""``benchbus ports`` and ``benchbus._core.list_ports`` on a sysfs tree built in a tmp dir:
an FTDI adapter, a CH340 adapter and a board's own UART, as Linux shows them."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_cli import ok, one_line_error, run

import benchbus as bb
from benchbus._core import list_ports


def _usb(root: Path, tty: str, usb: str, ids: tuple[str, str], driver: str, **strings: str) -> None:
    """A USB adapter at ``devices/.../<usb>`` whose interface holds the port ``tty``."""
    device = root / "devices/pci0000:00/usb1" / usb
    port = device / f"{usb}:1.0" / tty
    port.mkdir(parents=True)
    (device / "idVendor").write_text(ids[0] + "\n")
    (device / "idProduct").write_text(ids[1] + "\n")
    for name, text in strings.items():
        (device / name).write_text(text + "\n")
    (root / "bus/usb-serial/drivers" / driver).mkdir(parents=True)
    (port / "driver").symlink_to(root / "bus/usb-serial/drivers" / driver)
    (root / "class/tty" / tty).mkdir(parents=True)
    (root / "class/tty" / tty / "device").symlink_to(port)


def _ftdi(root: Path) -> None:
    """An FTDI FT232R adapter holding ``ttyUSB0``."""
    _usb(
        root,
        "ttyUSB0",
        "1-1",
        ("0403", "6001"),
        "ftdi_sio",
        manufacturer="FTDI",
        product="FT232R USB UART",
        serial="A50285BI",
    )


def _board_uart(root: Path) -> None:
    """A board's own UART (a PL011, as on a Raspberry Pi) holding ``ttyAMA0``."""
    uart = root / "devices/platform/fe201000.serial"
    uart.mkdir(parents=True)
    (root / "bus/amba/drivers/uart-pl011").mkdir(parents=True)
    (uart / "driver").symlink_to(root / "bus/amba/drivers/uart-pl011")
    (root / "class/tty/ttyAMA0").mkdir(parents=True)
    (root / "class/tty/ttyAMA0/device").symlink_to(uart)


@pytest.fixture
def sysfs(tmp_path: Path) -> Path:
    root = tmp_path / "sys"
    _ftdi(root)
    _usb(root, "ttyUSB1", "1-2", ("1a86", "7523"), "ch341-uart", product="USB Serial")
    _board_uart(root)
    (root / "class/tty/tty0").mkdir()  # a virtual console: not a serial port
    return root


def test_list_ports_reads_what_sysfs_knows(sysfs: Path) -> None:
    ports = list_ports(sysfs)
    assert [p["path"] for p in ports] == ["/dev/ttyAMA0", "/dev/ttyUSB0", "/dev/ttyUSB1"]
    assert ports[0] == {
        "path": "/dev/ttyAMA0",
        "driver": "uart-pl011",
        "vid": None,
        "pid": None,
        "manufacturer": None,
        "product": None,
        "serial_number": None,
        "chip": None,
    }
    assert ports[1] == {
        "path": "/dev/ttyUSB0",
        "driver": "ftdi_sio",
        "vid": 0x0403,
        "pid": 0x6001,
        "manufacturer": "FTDI",
        "product": "FT232R USB UART",
        "serial_number": "A50285BI",
        "chip": "FTDI",
    }
    assert (ports[2]["chip"], ports[2]["vid"], ports[2]["serial_number"]) == ("CH340", 0x1A86, None)
    assert list_ports(str(sysfs)) == ports  # a str or a path
    assert bb.list_ports is list_ports


def test_no_tty_class_is_no_port(tmp_path: Path) -> None:
    assert list_ports(tmp_path) == []
    with pytest.raises(TypeError):
        list_ports(5)  # type: ignore[arg-type]


def test_benchbus_ports_shows_a_table(sysfs: Path) -> None:
    lines = ok(run("ports", "--sysfs-root", sysfs))
    assert lines[0].split() == [
        "port",
        "chip",
        "usb",
        "id",
        "manufacturer",
        "product",
        "serial",
        "driver",
    ]
    rows = {line.split()[0]: line for line in lines[1:]}
    assert list(rows) == ["/dev/ttyAMA0", "/dev/ttyUSB0", "/dev/ttyUSB1"]
    assert rows["/dev/ttyUSB0"].split() == [
        "/dev/ttyUSB0",
        "FTDI",
        "0403:6001",
        "FTDI",
        "FT232R",
        "USB",
        "UART",
        "A50285BI",
        "ftdi_sio",
    ]
    assert rows["/dev/ttyUSB1"].split()[:3] == ["/dev/ttyUSB1", "CH340", "1a86:7523"]
    assert rows["/dev/ttyAMA0"].split() == ["/dev/ttyAMA0", "-", "-", "-", "-", "-", "uart-pl011"]


def test_benchbus_ports_with_none_says_so(tmp_path: Path) -> None:
    assert "no serial port found" in one_line_error(run("ports", "--sysfs-root", tmp_path), 1)
