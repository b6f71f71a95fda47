"""The Modbus TCP framing the gateway and the simulators' network share (``benchbus._mbap``),
and that both speak it: the same request gets the same header back from each."""

from __future__ import annotations

import socket

import pytest

import benchbus as bb
from benchbus import _mbap
from benchbus.sim import RegisterDevice, Simulator

# Modbus Messaging on TCP/IP Implementation Guide, 3.1.3: transaction 0x1501, unit 0x11,
# read holding registers 0x006B, count 3.
REQUEST = bytes.fromhex("1501 0000 0006 11 03 006B 0003")


def test_header_fields_and_frame_round_trip() -> None:
    header = _mbap.Header.parse(REQUEST)
    assert header == (0x1501, 0, 6, 0x11)
    assert header.length_ok
    assert _mbap.frame(0x1501, 0x11, REQUEST[_mbap.HEADER_SIZE :]) == REQUEST


@pytest.mark.parametrize(
    ("buf", "length"),
    [
        (b"", 0),
        (REQUEST[:5], 0),  # the length field has not come yet
        (REQUEST[:6], 12),  # known from the length field on
        (REQUEST + b"\x99", 12),  # what follows is the next frame's
        (bytes.fromhex("0001 0001 0006 11 03 006B 0003"), -1),  # protocol id 1
        (bytes.fromhex("0001 0000 0001 11"), -1),  # a unit and no PDU
        (bytes.fromhex("0001 0000 0002 11 07"), 8),  # the shortest frame
        (bytes.fromhex("0001 0000 00FE"), 6 + 254),  # the longest
        (bytes.fromhex("0001 0000 00FF"), -1),  # one byte too long
    ],
)
def test_frame_length_is_told_by_the_length_field(buf: bytes, length: int) -> None:
    assert _mbap.frame_length(buf) == length
    if len(buf) >= _mbap.HEADER_SIZE:
        header = _mbap.Header.parse(buf)
        assert header.length_ok == (header.length in range(2, 255))


def exchange(port: int, request: bytes, size: int) -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=2.0) as sock:
        sock.sendall(request)
        reply = b""
        while len(reply) < size:
            chunk = sock.recv(size - len(reply))
            if not chunk:
                break
            reply += chunk
    return reply


def test_gateway_and_simulated_network_answer_in_the_same_framing() -> None:
    request = _mbap.frame(0xBEEF, 1, bytes.fromhex("03 3006 0002"))
    expected = _mbap.frame(0xBEEF, 1, bytes.fromhex("03 04 05AA 0007"))
    device = RegisterDevice({0x3006: 1450, 0x3007: 7})
    with Simulator({1: device}, network="tcp") as net:
        port = int(net.port.rsplit(":", 1)[1])
        assert exchange(port, request, len(expected)) == expected
    with (
        Simulator({1: device}) as line,
        bb.Bus(line.port, timeout=0.5) as bus,
        bb.Gateway(bus, "127.0.0.1:0") as gateway,
    ):
        assert exchange(gateway.address[1], request, len(expected)) == expected
