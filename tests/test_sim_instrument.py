"""The simulated Taisong instrument and ATV31 drive (manual 004), driven by the raw pty client.

The manual's example frames are written out literally, with their replies; other requests
are bytes with a CRC computed bit by bit in test_sim.py, so the tests do not lean on the
package's own framing. The measured value runs on a FakeClock that only the tests move.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
from test_sim import Client, crc_valid, frame

from benchbus.sim import Atv31Device, SimDevice, Simulator, TaisongDevice
from conftest import FakeClock

#: The manual's identification reply as its CRC (A8 0F) says it was sent: read code 01.
#: (The manual prints the read code as 02, which the CRC does not match.)
ATV31_IDENTIFICATION = bytes.fromhex(
    "02 2B 0E 01 02 00 00 03"
    " 00 0D 54 45 4C 45 4D 45 43 41 4E 49 51 55 45"
    " 01 0F 41 54 56 33 31 48 55 30 39 4D 33 53 32 33 32"
    " 02 04 30 32 30 31 A8 0F"
)
VENDOR, PRODUCT, REVISION = b"TELEMECANIQUE", b"ATV31HU09M3S232", b"0201"
EXTRA = {3: "http://www.telemecanique.com", 4: "Altivar 31", 5: "ATV31", 6: "bench", 0x80: "X1"}


class Bench:
    """Meters at units 1 and 9, the ATV31 at unit 2, and a raw client on their line."""

    def __init__(
        self,
        sim: Simulator[SimDevice],
        client: Client,
        clock: FakeClock,
    ) -> None:
        self.sim, self.client, self.clock = sim, client, clock

    def __getitem__(self, unit: int) -> SimDevice:
        return self.sim.devices[unit]

    def meter(self, unit: int = 1) -> TaisongDevice:
        device = self.sim.devices[unit]
        assert isinstance(device, TaisongDevice)
        return device

    def drive(self, unit: int = 2) -> Atv31Device:
        device = self.sim.devices[unit]
        assert isinstance(device, Atv31Device)
        return device

    def transact(self, request: bytes | str, reply_len: int) -> bytes:
        """One exchange; ``request`` as bytes, or hex without its CRC."""
        sent = frame(request) if isinstance(request, str) else request
        return self.client.transact(sent, reply_len)

    def read(self, unit: int, address: int, count: int = 1) -> list[int]:
        reply = self.transact(f"{unit:02X} 03 {address:04X} {count:04X}", 5 + 2 * count)
        assert crc_valid(reply) and reply[:3] == bytes([unit, 3, 2 * count]), reply.hex(" ")
        data = reply[3:-2]
        return [int.from_bytes(data[i : i + 2], "big") for i in range(0, len(data), 2)]

    def identify(self, unit: int, code: int, object_id: int) -> bytes:
        """An identification reply, whole (its length read from its own header)."""
        self.client.send(frame(f"{unit:02X} 2B 0E {code:02X} {object_id:02X}"))
        head = self.client.recv(8)
        assert len(head) == 8, head.hex(" ")
        body = b""
        for _ in range(head[7]):
            size = self.client.recv(2)
            body += size + self.client.recv(size[1])
        reply = head + body + self.client.recv(2)
        self.client.assert_quiet(0.05)
        return reply


@contextmanager
def open_bench(devices: dict[int, SimDevice], clock: FakeClock | None = None) -> Iterator[Bench]:
    with Simulator(devices, baudrate=TaisongDevice.BAUDRATE) as sim:
        client = Client(sim.port)
        try:
            yield Bench(sim, client, clock or FakeClock())
            assert sim.errors == []
        finally:
            client.close()


@pytest.fixture
def bench() -> Iterator[Bench]:
    """The manual's setting: unit 1 held at 1000, unit 9 at 256, the ATV31 at unit 2."""
    clock = FakeClock()
    one, nine = TaisongDevice(clock=clock), TaisongDevice(clock=clock)
    one.hold(1000)
    nine.hold(256)
    with open_bench({1: one, 9: nine, 2: Atv31Device()}, clock) as b:
        yield b


def objects_of(reply: bytes) -> tuple[int, int, int, dict[int, bytes]]:
    """Conformity, more follows, next object id and the objects of an identification reply."""
    assert crc_valid(reply), reply.hex(" ")
    assert reply[1:3] == b"\x2b\x0e", reply.hex(" ")
    objects: dict[int, bytes] = {}
    pos = 8
    for _ in range(reply[7]):
        objects[reply[pos]] = reply[pos + 2 : pos + 2 + reply[pos + 1]]
        pos += 2 + reply[pos + 1]
    assert pos == len(reply) - 2, reply.hex(" ")
    return reply[4], reply[5], reply[6], objects


def pv_formula(t: float, sv: float, start: float, tau: float, wobble: float, period: float) -> int:
    """What the manual's register 0x0000 should show at model time ``t``, worked out here."""
    value = sv + (start - sv) * math.exp(-t / tau) + wobble * math.sin(2 * math.pi * t / period)
    return round(value)


# ---- the Taisong manual's five examples, byte for byte ------------------------------------------


def test_manual_read_unit_1(bench: Bench) -> None:
    sent = bytes.fromhex("01 03 00 00 00 01 84 0A")
    assert bench.transact(sent, 7) == bytes.fromhex("01 03 02 03 E8 B8 FA")


def test_manual_read_unit_9(bench: Bench) -> None:
    sent = bytes.fromhex("09 03 00 00 00 01 85 42")
    assert bench.transact(sent, 7) == bytes.fromhex("09 03 02 01 00 58 15")


def test_manual_read_two_words(bench: Bench) -> None:
    # PV 1000 (held), status: at or above SV (1000 by default) and held.
    reply = bench.transact(bytes.fromhex("01 03 00 00 00 02 C4 0B"), 9)
    assert reply == bytes.fromhex("01 03 04 03 E8 00 03 3A 42")
    bench.meter().sv = 1001
    assert bench.read(1, 0x0000, 2) == [1000, TaisongDevice.STATUS_HOLD]
    bench.meter().hold(None)
    assert bench.read(1, 0x0000, 2) == [0, 0]  # the process, from 0 at the start


def test_manual_write_sv(bench: Bench) -> None:
    sent = bytes.fromhex("01 06 00 05 00 64 98 20")
    assert bench.transact(sent, 8) == sent
    assert bench.meter().sv == 100 and bench.meter().registers[0x0005] == 100
    assert bench.transact(bytes.fromhex("01 03 00 05 00 01 94 0B"), 7) == bytes.fromhex(
        "01 03 02 00 64 B9 AF"
    )
    assert bench.meter(9).sv == 1000  # the other meter is untouched


def test_manual_write_two_words(bench: Bench) -> None:
    sent = bytes.fromhex("01 10 00 08 00 02 04 00 64 00 C8 B2 40")
    assert bench.transact(sent, 8) == bytes.fromhex("01 10 00 08 00 02 C0 0A")
    assert bench.meter().registers[0x0008:0x000A] == [100, 200]
    assert bench.read(1, 0x0008, 2) == [100, 200]


# ---- the ATV31 section's examples, byte for byte ------------------------------------------------


def test_atv31_read_example(bench: Bench) -> None:
    sent = bytes.fromhex("02 03 0C 1E 00 04 27 6C")
    expected = bytes.fromhex("02 03 08 00 28 02 58 01 F4 00 00 52 B0")
    assert bench.transact(sent, len(expected)) == expected


def test_atv31_write_single_example(bench: Bench) -> None:
    assert bench.drive().registers[0x2329] == 3
    sent = bytes.fromhex("02 06 23 29 00 0D 92 70")
    assert bench.transact(sent, 8) == sent
    assert bench.drive().registers[0x2329] == 13
    assert bench.read(2, 0x2329) == [13]


def test_atv31_write_multiple_example(bench: Bench) -> None:
    assert bench.drive().registers[0x0FCB:0x0FCD] == [3, 3]
    sent = bytes.fromhex("02 10 0F CB 00 02 04 00 14 00 1E 30 F4")
    assert bench.transact(sent, 8) == bytes.fromhex("02 10 0F CB 00 02 33 11")
    assert bench.drive().registers[0x0FCB:0x0FCD] == [20, 30]
    assert bench.read(2, 0x0FCB, 2) == [20, 30]


def test_atv31_identification_example(bench: Bench) -> None:
    sent = bytes.fromhex("02 2B 0E 01 00 34 77")
    assert crc_valid(sent)
    reply = bench.transact(sent, len(ATV31_IDENTIFICATION))
    assert reply == ATV31_IDENTIFICATION
    conformity, more, next_id, objects = objects_of(reply)
    assert reply[3] == 0x01  # the request's read code
    assert (conformity, more, next_id) == (0x02, 0x00, 0x00)
    assert objects == {0: VENDOR, 1: PRODUCT, 2: REVISION}
    assert [len(o) for o in objects.values()] == [13, 15, 4]  # as the manual counts them


def test_the_manuals_printed_identification_reply_is_off_by_its_read_code() -> None:
    # The erratum, pinned down: the reply as printed fails its CRC; with the read code the
    # request asked for (01 instead of 02) it is exactly the reply the simulator sends.
    printed = bytearray(ATV31_IDENTIFICATION)
    printed[3] = 0x02
    assert not crc_valid(bytes(printed))
    printed[3] = 0x01
    assert crc_valid(bytes(printed)) and bytes(printed) == ATV31_IDENTIFICATION


# ---- limits -------------------------------------------------------------------------------------


def test_taisong_reads_37_and_writes_20_at_most(bench: Bench) -> None:
    meter = bench.meter()
    assert len(bench.read(1, 0x0100, 37)) == 37
    assert bench.transact("01 03 01 00 00 25", 5 + 74)[:3] == bytes.fromhex("01 03 4A")
    assert bench.transact("01 03 01 00 00 26", 5) == bytes.fromhex("01 83 03 01 31")
    assert bench.transact("01 03 00 00 00 26", 5) == bytes.fromhex("01 83 03 01 31")
    twenty = " ".join(f"{i:04X}" for i in range(1, 21))
    assert bench.transact(f"01 10 01 00 00 14 28 {twenty}", 8) == frame("01 10 01 00 00 14")
    assert meter.registers[0x0100:0x0114] == list(range(1, 21))
    many = " ".join(f"{i:04X}" for i in range(101, 122))
    assert bench.transact(f"01 10 02 00 00 15 2A {many}", 5) == bytes.fromhex("01 90 03 0C 01")
    assert meter.registers[0x0200:0x0215] == [0] * 21  # nothing written


def test_atv31_reads_and_writes_29_words_at_most(bench: Bench) -> None:
    drive = bench.drive()
    assert len(bench.read(2, 0x0C00, 29)) == 29
    assert bench.transact("02 03 0C 00 00 1E", 5) == bytes.fromhex("02 83 03 F1 31")
    words = " ".join(f"{i:04X}" for i in range(1, 30))
    assert bench.transact(f"02 10 30 00 00 1D 3A {words}", 8) == frame("02 10 30 00 00 1D")
    assert drive.registers[0x3000:0x301D] == list(range(1, 30))
    words = " ".join(f"{i:04X}" for i in range(1, 31))
    assert bench.transact(f"02 10 31 00 00 1E 3C {words}", 5) == bytes.fromhex("02 90 03 FC 01")
    assert drive.registers[0x3100:0x311E] == [0] * 30


def test_the_measured_value_and_status_are_read_only(bench: Bench) -> None:
    assert bench.transact("01 06 00 00 00 05", 5) == bytes.fromhex("01 86 02 C3 A1")
    assert bench.transact("01 10 00 01 00 02 04 00 01 00 02", 5) == frame("01 90 02")
    assert bench.meter().registers[0x0002] == 0  # all or nothing
    assert bench.read(1, 0x0000) == [1000]


def test_the_rest_is_a_plain_table_for_32_bit_values_and_text(bench: Bench) -> None:
    meter = bench.meter()
    # A float (21.5 = 41AC0000), a 32-bit int (123456789 = 075BCD15) and "AB12" as text.
    request = "01 10 01 00 00 06 0C 41 AC 00 00 07 5B CD 15 41 42 31 32"
    assert bench.transact(request, 8) == frame("01 10 01 00 00 06")
    assert meter.registers[0x0100:0x0106] == [0x41AC, 0, 0x075B, 0xCD15, 0x4142, 0x3132]
    assert bench.read(1, 0x0100, 6) == [0x41AC, 0, 0x075B, 0xCD15, 0x4142, 0x3132]
    meter.registers[0xFFFF] = 0xBEEF
    assert bench.read(1, 0xFFFF) == [0xBEEF]
    assert bench.transact("01 03 FF FF 00 02", 5) == frame("01 83 02")  # past 0xFFFF
    # The live words show through a read that spans them.
    assert bench.read(1, 0x0000, 10)[:6] == [1000, 3, 0, 0, 0, 1000]


# ---- the measured value over time --------------------------------------------------------------


def test_the_measured_value_approaches_sv_and_wobbles() -> None:
    clock = FakeClock()
    meter = TaisongDevice(clock=clock, setpoint=1000, initial=20.0, tau=10.0, period=4.0)
    assert (meter.tau, meter.wobble, meter.period) == (10.0, 2.0, 4.0)
    with open_bench({1: meter}, clock) as b:
        seen = []
        for t in (0.0, 1.0, 5.0, 10.0, 20.0, 101.0):
            clock.now = 1000.0 + t
            value = b.read(1, 0x0000)[0]
            assert value == pv_formula(t, 1000, 20.0, 10.0, 2.0, 4.0), t
            assert meter.pv == value
            seen.append(value)
        assert seen[0] == 20 and seen[1] == 20 + round(980 * (1 - math.exp(-0.1))) + 2
        assert seen == sorted(seen) and seen[-1] == 1002  # settled, at the top of the wobble
        clock.now = 1000.0 + 102.0  # the wobble goes on at rest
        assert b.read(1, 0x0000) == [1000]
        clock.now = 1000.0 + 103.0
        assert b.read(1, 0x0000) == [998]
        assert b.read(1, 0x0001) == [0]  # below SV
        clock.now = 1000.0 + 105.0
        assert b.read(1, 0x0000, 2) == [1002, TaisongDevice.STATUS_ALARM]


def test_a_new_sv_restarts_the_approach_from_where_it_is() -> None:
    clock = FakeClock()
    meter = TaisongDevice(clock=clock, setpoint=1000, initial=0.0, tau=10.0, wobble=0.0)
    with open_bench({1: meter}, clock) as b:
        clock.now += 10.0
        reached = 1000 * (1 - math.exp(-1.0))
        assert b.read(1, 0x0000) == [round(reached)]  # 632
        request = frame("01 06 00 05 00 64")  # SV = 100
        assert b.transact(request, 8) == request
        assert b.read(1, 0x0000) == [632]  # no jump
        clock.now += 10.0
        expected = 100 + (reached - 100) * math.exp(-1.0)
        assert b.read(1, 0x0000) == [round(expected)] and meter.process == pytest.approx(expected)
        # SV set in the table directly takes effect at the next access.
        meter.registers[0x0005] = 0xFF38  # -200
        assert meter.sv == -200
        clock.now += 10.0
        b.read(1, 0x0000)
        clock.now += 1000.0
        assert b.read(1, 0x0000, 2) == [0xFF38, TaisongDevice.STATUS_ALARM]  # -200 >= -200
        assert meter.pv == -200


def test_advance_and_speedup_move_the_model() -> None:
    clock = FakeClock()
    meter = TaisongDevice(clock=clock, tau=10.0, wobble=0.0, speedup=10.0)
    clock.now += 1.0  # ten model seconds
    assert meter.pv == round(1000 * (1 - math.exp(-1.0)))
    meter.advance(10.0)
    assert meter.pv == round(1000 * (1 - math.exp(-2.0)))


def test_hold_freezes_the_display_while_the_process_goes_on() -> None:
    clock = FakeClock()
    meter = TaisongDevice(clock=clock, tau=10.0, wobble=0.0)
    with open_bench({1: meter}, clock) as b:
        meter.hold(1234.4)
        assert meter.held == 1234
        clock.now += 10.0
        both = TaisongDevice.STATUS_ALARM | TaisongDevice.STATUS_HOLD
        assert b.read(1, 0x0000, 2) == [1234, both]
        meter.hold(-2)
        assert b.read(1, 0x0000) == [0xFFFE]
        meter.hold(None)
        assert meter.held is None
        assert b.read(1, 0x0000, 2) == [round(1000 * (1 - math.exp(-1.0))), 0]


def test_the_meter_has_no_identification(bench: Bench) -> None:
    assert bench.transact("01 2B 0E 01 00", 5) == bytes.fromhex("01 AB 01 9E F0")
    assert bench.transact("09 2B 0E 04 00", 5) == bytes.fromhex("09 AB 01 1F 32")


# ---- write pacing -------------------------------------------------------------------------------


def test_writes_closer_than_min_write_interval_answer_6() -> None:
    meter = TaisongDevice(clock=FakeClock(), min_write_interval=0.5)
    with open_bench({1: meter}) as b:
        first = frame("01 06 00 05 00 64")
        assert b.transact(first, 8) == first
        assert b.transact("01 06 00 05 00 C8", 5) == bytes.fromhex("01 86 06 C2 62")
        assert b.transact("01 10 00 08 00 01 02 00 07", 5) == frame("01 90 06")
        assert meter.sv == 100 and meter.registers[0x0008] == 0  # refused: nothing written
        assert b.read(1, 0x0005) == [100]  # reads are not paced
        assert len(meter.write_times) == 3 and len(meter.write_violations) == 2
        gaps = [later - earlier for earlier, later in zip(meter.write_times, meter.write_times[1:])]
        assert meter.write_violations == gaps and all(0 < gap < 0.5 for gap in gaps)
        time.sleep(0.52)
        second = frame("01 06 00 05 00 C8")
        assert b.transact(second, 8) == second
        assert meter.sv == 200 and len(meter.write_violations) == 2
        meter.min_write_interval = 0.0
        assert b.transact(first, 8) == first


def test_writes_are_not_paced_by_default(bench: Bench) -> None:
    for value in range(5):
        request = frame(f"01 06 00 05 00 {value:02X}")
        assert bench.transact(request, 8) == request
    assert bench.meter().write_violations == [] and len(bench.meter().write_times) == 5


# ---- Read Device Identification -----------------------------------------------------------------


def test_regular_and_extended_streams_carry_the_extra_objects() -> None:
    with open_bench({2: Atv31Device(extra_objects=EXTRA)}) as b:
        everything = {0: VENDOR, 1: PRODUCT, 2: REVISION}
        everything.update({k: v.encode() for k, v in EXTRA.items()})
        regular = {k: v for k, v in everything.items() if k < 7}
        assert objects_of(b.identify(2, 1, 0)) == (0x03, 0, 0, {0: VENDOR, 1: PRODUCT, 2: REVISION})
        assert objects_of(b.identify(2, 2, 0)) == (0x03, 0, 0, regular)
        assert objects_of(b.identify(2, 3, 0)) == (0x03, 0, 0, everything)
        # A stream from a later object; from one the stream lacks it restarts at 0.
        assert objects_of(b.identify(2, 3, 5))[3] == {5: b"ATV31", 6: b"bench", 0x80: b"X1"}
        assert objects_of(b.identify(2, 1, 5))[3] == {0: VENDOR, 1: PRODUCT, 2: REVISION}
        assert objects_of(b.identify(2, 2, 0x80))[3] == regular
        # One object by id (read code 4).
        reply = b.identify(2, 4, 0x80)
        assert reply[3] == 0x04 and objects_of(reply)[1:] == (0, 0, {0x80: b"X1"})


def test_paging_says_more_follows_and_the_next_object() -> None:
    drive = Atv31Device(identity_page_size=1)
    with open_bench({2: drive}) as b:
        # Literal frames: one object a reply, FF and the next id until the last.
        name = VENDOR.hex(" ")
        assert b.identify(2, 1, 0) == frame(f"02 2B 0E 01 02 FF 01 01 00 0D {name}")
        assert b.identify(2, 1, 1) == frame(f"02 2B 0E 01 02 FF 02 01 01 0F {PRODUCT.hex(' ')}")
        assert b.identify(2, 1, 2) == frame("02 2B 0E 01 02 00 00 01 02 04 30 32 30 31")
        drive.identity_page_size = 2
        assert objects_of(b.identify(2, 1, 0)) == (0x02, 0xFF, 0x02, {0: VENDOR, 1: PRODUCT})
        drive.identity_page_size = 3  # all fit: no more follows
        assert b.identify(2, 1, 0) == ATV31_IDENTIFICATION


def test_a_master_following_more_follows_collects_every_object() -> None:
    drive = Atv31Device(extra_objects=EXTRA, identity_page_size=2)
    with open_bench({2: drive}) as b:
        collected: dict[int, bytes] = {}
        pages, object_id, more = [], 0, 0xFF
        while more == 0xFF:
            conformity, more, next_id, objects = objects_of(b.identify(2, 3, object_id))
            assert conformity == 0x03 and len(objects) <= 2
            pages.append((list(objects), more, next_id))
            collected.update(objects)
            object_id = next_id
            assert len(pages) < 10
        assert pages == [
            ([0, 1], 0xFF, 2),
            ([2, 3], 0xFF, 4),
            ([4, 5], 0xFF, 6),
            ([6, 0x80], 0x00, 0),
        ]
        assert collected == {
            0: VENDOR,
            1: PRODUCT,
            2: REVISION,
            **{k: v.encode() for k, v in EXTRA.items()},
        }
        # Individual access is never paged.
        assert objects_of(b.identify(2, 4, 4))[1:] == (0, 0, {4: b"Altivar 31"})


def test_conformity_can_be_set() -> None:
    with open_bench({2: Atv31Device(conformity=0x81)}) as b:
        assert objects_of(b.identify(2, 1, 0))[0] == 0x81


def test_identification_errors_standard_form(bench: Bench) -> None:
    assert bench.transact("02 2B 0E 05 00", 5) == bytes.fromhex("02 AB 03 EF 31")  # read code
    assert bench.transact("02 2B 0E 00 00", 5) == bytes.fromhex("02 AB 03 EF 31")
    assert bench.transact("02 2B 0E 04 03", 5) == bytes.fromhex("02 AB 02 2E F1")  # no object 3
    assert bench.transact("02 2B 0D 01 00", 5) == bytes.fromhex("02 AB 01 6E F0")  # MEI type
    bench.drive().identity = None  # no identification at all
    assert bench.transact("02 2B 0E 01 00 ", 5) == bytes.fromhex("02 AB 01 6E F0")


def test_identification_errors_in_the_manuals_form() -> None:
    drive = Atv31Device(mei_exceptions=True)
    with open_bench({2: drive}) as b:
        # unit, 2B + 80, MEI type 0E, error code, CRC: 1 = a bad read code / MEI type,
        # 2 = a bad object id.
        assert b.transact("02 2B 0E 05 00", 6) == bytes.fromhex("02 AB 0E 01 B5 DC")
        assert b.transact("02 2B 0E 00 00", 6) == bytes.fromhex("02 AB 0E 01 B5 DC")
        assert b.transact("02 2B 0D 01 00", 6) == bytes.fromhex("02 AB 0E 01 B5 DC")
        assert b.transact("02 2B 0E 04 03", 6) == bytes.fromhex("02 AB 0E 02 F5 DD")
        # Good requests are answered as usual.
        assert b.transact("02 2B 0E 01 00", len(ATV31_IDENTIFICATION)) == ATV31_IDENTIFICATION
        # Other functions keep the standard 5-byte exception.
        assert b.transact("02 03 00 00 00 1E", 5) == bytes.fromhex("02 83 03 F1 31")
        # Without identification the function itself is missing: the standard form.
        drive.identity = None
        assert b.transact("02 2B 0E 01 00", 5) == bytes.fromhex("02 AB 01 6E F0")
        drive.identity = dict(Atv31Device.IDENTITY)
        drive.mei_exceptions = False
        assert b.transact("02 2B 0E 04 03", 5) == bytes.fromhex("02 AB 02 2E F1")


# ---- construction -------------------------------------------------------------------------------


def test_defaults() -> None:
    meter = TaisongDevice(clock=lambda: 0.0)
    assert (meter.max_read, meter.max_write, meter.min_write_interval) == (37, 20, 0.0)
    assert meter.sv == 1000 and meter.pv == 0 and meter.identity is None
    assert meter.readonly == {0x0000, 0x0001} and TaisongDevice.BAUDRATE == 9600
    assert repr(meter) == "<TaisongDevice PV=0 SV=1000>"
    drive = Atv31Device()
    assert (drive.max_read, drive.max_write) == (29, 29)
    assert drive.identity == {0: "TELEMECANIQUE", 1: "ATV31HU09M3S232", 2: "0201"}
    assert drive.identity_page_size is None and drive.mei_exceptions is False
    assert drive.registers[0x0C1E:0x0C22] == [0x0028, 0x0258, 0x01F4, 0x0000]
    assert Atv31Device({0x0C1E: 0x0010}).registers[0x0C1E] == 0x0010


@pytest.mark.parametrize(
    "options",
    [
        {"setpoint": 40000},
        {"setpoint": -40000},
        {"tau": 0.0},
        {"tau": -1.0},
        {"period": 0.0},
        {"wobble": -1.0},
        {"wobble": math.nan},
        {"speedup": 0.0},
        {"initial": math.inf},
        {"min_write_interval": -0.1},
        {"min_write_interval": math.inf},
        {"registers": {0x0005: 1}},
        {"registers": {0x0000: 1}},
        {"registers": {0x0010: 0x10000}},
    ],
)
def test_bad_taisong_options(options: dict[str, object]) -> None:
    with pytest.raises(ValueError):
        TaisongDevice(clock=lambda: 0.0, **options)  # type: ignore[arg-type]


def test_bad_taisong_values() -> None:
    meter = TaisongDevice(clock=lambda: 0.0)
    with pytest.raises(TypeError):
        TaisongDevice(setpoint=1.5)  # type: ignore[arg-type]
    with pytest.raises(TypeError):
        meter.hold("1000")  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        meter.hold(40000)
    with pytest.raises(ValueError):
        meter.sv = 32768
    with pytest.raises(TypeError):
        meter.sv = 1.5  # type: ignore[assignment]
    assert meter.held is None and meter.sv == 1000


@pytest.mark.parametrize(
    ("options", "error"),
    [
        ({"extra_objects": {2: "X"}}, ValueError),  # the manual's objects stay
        ({"extra_objects": {7: "X"}}, ValueError),  # reserved
        ({"extra_objects": {3: ""}}, ValueError),
        ({"extra_objects": {3: "é"}}, ValueError),
        ({"extra_objects": {3: "x" * 245}}, ValueError),
        ({"extra_objects": {3: 5}}, TypeError),
        ({"identity_page_size": 0}, ValueError),
        ({"identity_page_size": True}, ValueError),
        ({"conformity": 0x04}, ValueError),
        ({"conformity": "0x02"}, TypeError),
    ],
)
def test_bad_atv31_options(options: dict[str, object], error: type[Exception]) -> None:
    with pytest.raises(error):
        Atv31Device(**options)  # type: ignore[arg-type]
