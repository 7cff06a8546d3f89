"""cocotb tests of the USB device core (ms_usb_device) through the wire-level host model.

Every transaction crosses the wire: usb_host.py encodes/decodes packets, usb_host_phy_tb.sv
shifts the symbols at the host's own clock (error and D- skew set per test), the device runs
at 48 MHz. test_transaction_level repeats the checks through the wire-less port (tl_*).
"""

from __future__ import annotations

import os
import random
import struct
import time

import cocotb
from cocotb.triggers import ClockCycles
from cocotb.utils import get_sim_time

from tbutil import reset, start_clock
from usb_host import PID_ACK, PID_DATA0, PID_DATA1, PID_IN, PID_NAK, PID_STALL, StallError, UsbHost, token_bytes

from multisonar import protocol as P
from multisonar.usb.descriptors import multisonar_descriptors

# the expectations below are spelled out from USB 2.0 ch. 9 and MS OS 2.0; check_source() also
# compares every byte with the one source the ROM image is generated from
VID, PID, BCD = P.USB_VID, P.USB_PID, P.PROTOCOL_VERSION << 8
MS_VENDOR_CODE = 0x4D
ADDR = 5
SERIAL = int(os.environ.get("MS_USB_SERIAL", "1"))
GUID = "{8C6A1E2D-5B3F-4A7E-9D21-6F0B3C4E5A71}"


def usb_string(s: str) -> bytes:
    return bytes([2 + 2 * len(s), 3]) + s.encode("utf-16-le")


async def start(dut, clock_error: float = 0.0, device_clock: bool = True, tl: bool = False) -> UsbHost:
    """Start the clocks (the device clock only once per test) and reset the device."""
    if device_clock:
        start_clock(dut.clk_i)
    dut.out_ready_i.value = 1
    dut.src_go_i.value = 0
    dut.src_flush_i.value = 0
    dut.src_len_i.value = 0
    host = UsbHost(dut, clock_error, tl=tl)
    await reset(dut.clk_i, dut.rst_i)
    assert int(dut.pullup_o.value) == 1, "pull-up not enabled after reset"
    return host


async def enumerate_device(host: UsbHost, addr: int = ADDR) -> dict[str, bytes]:
    """What Linux does: reset, GET_DESCRIPTOR(device, 64) at address 0, reset, SET_ADDRESS,
    device descriptor, configuration (9 then total), strings, BOS, SET_CONFIGURATION(1)."""
    got: dict[str, bytes] = {}
    await host.bus_reset()
    dev64 = await host.control_read(0, 0x80, 6, 0x0100, 0, 64)
    assert len(dev64) == 18, f"device descriptor of {len(dev64)} bytes"
    await host.bus_reset()
    await host.control_nodata(0, 0x00, 5, addr, 0)
    got["device"] = await host.control_read(addr, 0x80, 6, 0x0100, 0, 18)
    assert got["device"] == dev64
    cfg9 = await host.control_read(addr, 0x80, 6, 0x0200, 0, 9)
    total = struct.unpack_from("<H", cfg9, 2)[0]
    got["config"] = await host.control_read(addr, 0x80, 6, 0x0200, 0, total)
    got["str0"] = await host.control_read(addr, 0x80, 6, 0x0300, 0, 255)
    for i, name in ((1, "manufacturer"), (2, "product"), (3, "serial"), (4, "interface")):
        got[name] = await host.control_read(addr, 0x80, 6, 0x0300 | i, 0x0409, 255)
    bos5 = await host.control_read(addr, 0x80, 6, 0x0F00, 0, 5)
    got["bos"] = await host.control_read(addr, 0x80, 6, 0x0F00, 0, struct.unpack_from("<H", bos5, 2)[0])
    await host.control_nodata(addr, 0x00, 9, 1, 0)
    return got


def check_descriptors(got: dict[str, bytes]) -> None:
    dev = got["device"]
    assert dev[0] == 18 and dev[1] == 1
    bcd_usb, _, _, _, mps0, vid, pid, bcd_dev = struct.unpack_from("<HBBBBHHH", dev, 2)
    assert bcd_usb >= 0x0201, "bcdUSB must be >= 2.01 for the BOS descriptor"
    assert (mps0, vid, pid, bcd_dev) == (64, VID, PID, BCD)
    assert dev[14:18] == bytes([1, 2, 3, 1])
    cfg = got["config"]
    assert len(cfg) == struct.unpack_from("<H", cfg, 2)[0] == 32 and cfg[4] == 1 and cfg[5] == 1
    itf = cfg[9:18]
    assert itf[1] == 4 and itf[4] == 2 and itf[5] == 0xFF and itf[8] == 4, f"interface {itf.hex()}"
    eps = {cfg[20]: cfg[18:25], cfg[27]: cfg[25:32]}
    for ep in (0x01, 0x81):
        assert eps[ep][1] == 5 and eps[ep][3] == 2 and struct.unpack_from("<H", eps[ep], 4)[0] == 64
    assert got["str0"] == bytes([4, 3, 0x09, 0x04])
    assert got["manufacturer"] == usb_string("Multisonar")
    assert got["product"] == usb_string("Multisonar 24-element sonar")
    assert got["serial"] == usb_string(f"{SERIAL:08X}")
    assert got["interface"] == usb_string(f"Multisonar protocol v{BCD >> 8}")
    bos = got["bos"]
    assert bos[1] == 0x0F and bos[4] == 1
    cap = bos[5:]
    assert cap[1] == 0x10 and cap[2] == 0x05
    assert cap[4:20] == bytes.fromhex("DF60DDD88945C74C9CD2659D9E648A9F"), "MS OS 2.0 platform UUID"
    assert cap[26] == MS_VENDOR_CODE


def check_source(got: dict[str, bytes], ms: bytes) -> None:
    """The device's answers equal multisonar.usb.descriptors with this board's serial."""
    src = multisonar_descriptors(SERIAL)
    assert got["device"] == src.device and got["config"] == src.config and got["bos"] == src.bos
    names = ("str0", "manufacturer", "product", "serial", "interface")
    assert [got[n] for n in names] == list(src.strings)
    assert ms == src.ms_os_20


async def ms_os_descriptor_set(host: UsbHost, bos: bytes) -> bytes:
    total = struct.unpack_from("<H", bos, 5 + 24)[0]
    ms = await host.control_read(ADDR, 0xC0, MS_VENDOR_CODE, 0, 7, total)
    assert len(ms) == total
    return ms


def check_ms_os(ms: bytes) -> None:
    length, dtype, winver, total = struct.unpack_from("<HHIH", ms, 0)
    assert (length, dtype, total) == (10, 0, len(ms)) and winver >= 0x06030000
    off, found = 10, {}
    while off < len(ms):
        length, dtype = struct.unpack_from("<HH", ms, off)
        found[dtype] = ms[off:off + length]
        off += length
    assert off == len(ms)
    compat = found[3]
    assert compat[4:12] == b"WINUSB\0\0"
    reg = found[4]
    ptype, nlen = struct.unpack_from("<HH", reg, 4)
    name = reg[8:8 + nlen].decode("utf-16-le")
    dlen = struct.unpack_from("<H", reg, 8 + nlen)[0]
    data = reg[10 + nlen:10 + nlen + dlen].decode("utf-16-le")
    assert ptype == 7 and name == "DeviceInterfaceGUIDs\0" and data == GUID + "\0\0"


@cocotb.test()
async def test_enumeration(dut):
    host = await start(dut)
    t0, sim0 = time.perf_counter(), get_sim_time("ns")
    got = await enumerate_device(host)
    dut._log.info("wire-level enumeration: %d packets, %.0f us simulated, %.2f s wall",
                  host.packets, (get_sim_time("ns") - sim0) / 1e3, time.perf_counter() - t0)
    check_descriptors(got)
    assert int(dut.configured_o.value) == 1
    ms = await ms_os_descriptor_set(host, got["bos"])
    check_ms_os(ms)
    check_source(got, ms)
    # wLength shorter than the descriptor: exactly wLength bytes, also at a packet boundary
    assert await host.control_read(ADDR, 0xC0, MS_VENDOR_CODE, 0, 7, 128) == ms[:128]
    assert await host.control_read(ADDR, 0x80, 6, 0x0100, 0, 8) == got["device"][:8]
    cfg = await host.control_read(ADDR, 0x80, 8, 0, 0, 1)
    assert cfg == b"\x01"
    st = await host.control_read(ADDR, 0x80, 0, 0, 0, 2)
    assert st == b"\x00\x00"
    assert host.max_delay_bits <= 7.5, f"device answered after {host.max_delay_bits} bit times"
    assert int(dut.collision_o.value) == 0
    dut._log.info("enumeration: %d packets, max response delay %.2f bits, %.2f s wall",
                  host.packets, host.max_delay_bits, time.perf_counter() - t0)


# ---------------------------------------------------------------- helpers for the bulk tests
async def load_in(dut, data: bytes, flush: bool) -> None:
    """Push bytes into EP 0x81 through the testbench source, then optionally flush."""
    dut.src_buf_i.value = int.from_bytes(data, "little") if data else 0
    dut.src_len_i.value = len(data)
    dut.src_flush_i.value = int(flush)
    dut.src_go_i.value = 1
    await ClockCycles(dut.clk_i, 3)
    dut.src_go_i.value = 0
    while int(dut.src_busy_o.value):
        await ClockCycles(dut.clk_i, 64)
    await ClockCycles(dut.clk_i, 2)


def out_entries(dut) -> list[tuple[int, str]]:
    """Entries the application received on EP 0x01: (byte, flags) with flags from
    'l' (out_last: end of USB packet), 'e' (out_end: end of transfer), 'z' (zero-length packet)."""
    n = int(dut.out_count_o.value)
    raw = int(dut.out_log_o.value).to_bytes(len(dut.out_log_o) // 8, "little")[:n]
    flags = [(int(getattr(dut, f"out_{k}_log_o").value), c) for k, c in (("last", "l"), ("end", "e"), ("zlp", "z"))]
    return [(raw[i], "".join(c for v, c in flags if (v >> i) & 1)) for i in range(n)]


def out_log(dut) -> tuple[bytes, list[int]]:
    """Data bytes the application received on EP 0x01 and the indices of bytes flagged last."""
    data = [(b, f) for b, f in out_entries(dut) if "z" not in f]
    return bytes(b for b, _ in data), [i for i, (_, f) in enumerate(data) if "l" in f]


def payload(n: int, seed: int) -> bytes:
    return random.Random(seed).randbytes(n)


async def bulk_out_checks(dut, host: UsbHost) -> None:
    a, b = payload(64, 1), payload(10, 2)
    r = await host.out(ADDR, 1, False, a)
    assert r.pid == PID_ACK, r.name
    assert (await host.sof(0x5A5)).pid is None, "SOF answered"
    r = await host.out(ADDR, 1, True, b)
    assert r.pid == PID_ACK, r.name
    # our ACK "lost": the host re-sends DATA1 -> ACKed again, not delivered twice
    r = await host.out(ADDR, 1, True, b)
    assert r.pid == PID_ACK, r.name
    await ClockCycles(dut.clk_i, 200)
    data, lasts = out_log(dut)
    assert data == a + b, "OUT data delivered wrong"
    assert lasts == [63, 73], f"end-of-packet marks at {lasts}"
    ends = [i for i, (_, f) in enumerate(out_entries(dut)) if "e" in f]
    assert ends == [73], f"end-of-transfer marks at {ends} (only the short packet ends a transfer)"
    r = await host.out(ADDR, 1, False, b"\xAA")  # next toggle is DATA0
    assert r.pid == PID_ACK
    # a transfer of exactly 64 bytes ends with a zero-length packet: one entry flagged zlp
    c = payload(64, 3)
    assert (await host.out(ADDR, 1, True, c)).pid == PID_ACK
    assert (await host.out(ADDR, 1, False, b"")).pid == PID_ACK
    await ClockCycles(dut.clk_i, 50)
    assert out_log(dut)[0] == a + b + b"\xAA" + c
    tail = out_entries(dut)[-2:]
    assert tail == [(c[-1], "l"), (0, "lez")], f"64-byte transfer + ZLP delivered as {tail}"


async def bulk_in_checks(dut, host: UsbHost) -> None:
    r = await host.in_token(ADDR, 1)
    assert r.pid == PID_NAK, f"empty IN endpoint answered {r.name}"
    data = payload(100, 3)
    await load_in(dut, data, flush=True)
    r = await host.in_token(ADDR, 1, ack=False)        # ACK lost
    assert (r.pid, r.payload) == (PID_DATA0, data[:64]), r.name
    assert (await host.sof(0x7FF)).pid is None, "SOF answered"
    r = await host.in_token(ADDR, 1)                   # same data again, same toggle
    assert (r.pid, r.payload) == (PID_DATA0, data[:64]), f"retry: {r.name} {len(r.payload)}"
    r = await host.in_token(ADDR, 1)
    assert (r.pid, r.payload) == (PID_DATA1, data[64:]), r.name
    r = await host.in_token(ADDR, 1)
    assert r.pid == PID_NAK, r.name
    # exact multiple of 64 + flush: two full packets then a zero-length packet
    data = payload(128, 4)
    await load_in(dut, data, flush=True)
    got = [await host.in_token(ADDR, 1) for _ in range(4)]
    assert [(g.pid, g.payload) for g in got] == [(PID_DATA0, data[:64]), (PID_DATA1, data[64:]),
                                                  (PID_DATA0, b""), (PID_NAK, b"")], [g.name for g in got]
    # without flush only full packets go out
    data = payload(70, 5)
    await load_in(dut, data, flush=False)
    r1, r2 = await host.in_token(ADDR, 1), await host.in_token(ADDR, 1)
    assert (r1.pid, r1.payload, r2.pid) == (PID_DATA1, data[:64], PID_NAK), (r1.name, r2.name)
    await load_in(dut, b"", flush=True)
    r = await host.in_token(ADDR, 1)
    assert (r.pid, r.payload) == (PID_DATA0, data[64:]), r.name
    # data queued while a packet waits for its ACK do not change the re-sent packet
    first, more = payload(10, 6), payload(20, 7)
    await load_in(dut, first, flush=True)
    r = await host.in_token(ADDR, 1, ack=False)
    assert (r.pid, r.payload) == (PID_DATA1, first), r.name
    await load_in(dut, more, flush=True)
    r = await host.in_token(ADDR, 1)
    assert (r.pid, r.payload) == (PID_DATA1, first), f"retry after more data: {r.name} {len(r.payload)} bytes"
    r = await host.in_token(ADDR, 1)
    assert (r.pid, r.payload) == (PID_DATA0, more), f"flush during the retry lost: {r.name}"
    assert (await host.in_token(ADDR, 1)).pid == PID_NAK


@cocotb.test()
async def test_bulk_out(dut):
    host = await start(dut)
    await enumerate_device(host)
    await bulk_out_checks(dut, host)
    # NAK while the buffer has no room for a whole packet; no data lost
    dut.out_ready_i.value = 0
    base = out_log(dut)[0]
    sent, toggle, naks = [], True, 0
    for i in range(4):
        p = payload(64, 10 + i)
        r = await host.out(ADDR, 1, toggle, p)
        if r.pid == PID_NAK:
            naks += 1
            break
        assert r.pid == PID_ACK, r.name
        sent.append(p)
        toggle = not toggle
    assert naks == 1 and len(sent) == 2, f"{len(sent)} packets ACKed before NAK (buffer 128 bytes)"
    dut.out_ready_i.value = 1
    await ClockCycles(dut.clk_i, 300)
    p = payload(64, 20)
    r = await host.out(ADDR, 1, toggle, p)   # the NAKed packet is re-sent with the same toggle
    assert r.pid == PID_ACK, r.name
    sent.append(p)
    await ClockCycles(dut.clk_i, 100)
    got = out_log(dut)[0]
    assert got == base + b"".join(sent), f"{len(got)} bytes delivered, expected {len(base) + 64 * len(sent)}"
    # a packet longer than 64 bytes is not acknowledged nor delivered
    r = await host.out(ADDR, 1, not toggle, payload(65, 21))
    assert r.pid is None, r.name
    await ClockCycles(dut.clk_i, 100)
    assert out_log(dut)[0] == base + b"".join(sent)


@cocotb.test()
async def test_bulk_in(dut):
    host = await start(dut)
    await enumerate_device(host)
    await bulk_in_checks(dut, host)


@cocotb.test()
async def test_bulk_in_stream(dut):
    """The application pushes flushed chunks while the host keeps reading: nothing lost or
    duplicated, every packet full except the last of a flush."""
    host = await start(dut)
    await enumerate_device(host)
    rng = random.Random(8)
    chunks = [payload(rng.choice((1, 17, 63, 64, 65, 100, 128, 200)), 100 + i) for i in range(16)]
    want = b"".join(chunks)

    async def producer() -> None:
        for c in chunks:
            await load_in(dut, c, flush=True)
            await ClockCycles(dut.clk_i, rng.choice((0, 500, 3000, 12000)))

    task = cocotb.start_soon(producer())
    got, toggle, naks, shorts = b"", False, 0, 0
    while len(got) < len(want):
        r = await host.in_token(ADDR, 1)
        if r.pid == PID_NAK:
            naks += 1
            assert naks < 2000, f"stream stalled after {len(got)} of {len(want)} bytes"
            continue
        assert r.pid == (PID_DATA1 if toggle else PID_DATA0), f"toggle: {r.name} at byte {len(got)}"
        toggle = not toggle
        shorts += len(r.payload) < 64
        got += r.payload
    await task
    assert got == want, f"stream differs at byte {next(i for i, (a, b) in enumerate(zip(got, want)) if a != b)}"
    assert shorts <= len(chunks)
    dut._log.info("IN stream: %d bytes in %d chunks, %d short packets, %d NAKs", len(want), len(chunks), shorts, naks)


@cocotb.test()
async def test_stall_and_recovery(dut):
    host = await start(dut)
    await enumerate_device(host)
    # unknown requests STALL; the next SETUP works again
    for bm, breq, val, idx, length in ((0x40, 0x99, 0, 0, 0), (0xC0, 0x42, 0, 0, 4), (0x80, 6, 0x0600, 0, 10),
                                       (0x80, 6, 0x0305, 0x409, 255), (0xC0, MS_VENDOR_CODE, 0, 5, 16)):
        try:
            if bm & 0x80:
                await host.control_read(ADDR, bm, breq, val, idx, length)
            else:
                await host.control_nodata(ADDR, bm, breq, val, idx)
        except StallError:
            pass
        else:
            raise AssertionError(f"request {bm:#x}/{breq:#x} value {val:#x} was not stalled")
        assert (await host.control_read(ADDR, 0x80, 8, 0, 0, 1)) == b"\x01"
    # halt EP 0x81 with SET_FEATURE, see STALL and the status bit, clear it: DATA0 again
    await load_in(dut, payload(64, 30), flush=False)
    r = await host.in_token(ADDR, 1)
    assert r.pid == PID_DATA0
    await host.control_nodata(ADDR, 0x02, 3, 0, 0x81)
    assert (await host.in_token(ADDR, 1)).pid == PID_STALL
    assert (await host.control_read(ADDR, 0x82, 0, 0, 0x81, 2)) == b"\x01\x00"
    await host.control_nodata(ADDR, 0x02, 1, 0, 0x81)
    assert (await host.control_read(ADDR, 0x82, 0, 0, 0x81, 2)) == b"\x00\x00"
    data = payload(64, 31)
    await load_in(dut, data, flush=False)
    r = await host.in_token(ADDR, 1)
    assert (r.pid, r.payload) == (PID_DATA0, data), f"after CLEAR_FEATURE: {r.name}"
    # same on EP 0x01
    r = await host.out(ADDR, 1, False, b"x")
    assert r.pid == PID_ACK
    await host.control_nodata(ADDR, 0x02, 3, 0, 0x01)
    assert (await host.out(ADDR, 1, True, b"y")).pid == PID_STALL
    await host.control_nodata(ADDR, 0x02, 1, 0, 0x01)
    r = await host.out(ADDR, 1, False, b"z")
    assert r.pid == PID_ACK
    await ClockCycles(dut.clk_i, 50)
    assert out_log(dut)[0] == b"xz", out_log(dut)
    # halt requests for endpoints that do not exist STALL
    try:
        await host.control_nodata(ADDR, 0x02, 3, 0, 0x82)
    except StallError:
        pass
    else:
        raise AssertionError("SET_FEATURE on EP 0x82 not stalled")


@cocotb.test()
async def test_corrupted_packets(dut):
    host = await start(dut)
    await enumerate_device(host)
    # token with a bad CRC5: ignored (host times out)
    r = await host.send(token_bytes(PID_IN, ADDR, 0, bad_crc=True), listen=True)
    assert r.pid is None, f"bad-CRC5 token answered {r.name}"
    await load_in(dut, payload(64, 40), flush=False)
    r = await host.send(token_bytes(PID_IN, ADDR, 1, bad_crc=True), listen=True)
    assert r.pid is None, r.name
    # token for another address: ignored
    r = await host.send(token_bytes(PID_IN, ADDR + 1, 1), listen=True)
    assert r.pid is None, r.name
    # the data are still there, first toggle
    r = await host.in_token(ADDR, 1)
    assert (r.pid, r.payload) == (PID_DATA0, payload(64, 40))
    # OUT data with a bad CRC16: no handshake, not delivered; re-sent good: delivered once
    r = await host.out(ADDR, 1, False, b"bad", bad_crc=True)
    assert r.pid is None, r.name
    # bit-stuff error inside the data packet (its CRC is right once the bad bit is dropped): dropped
    r = await host.out(ADDR, 1, False, b"\x00\x11\xff\x22", stuff_error_at_byte=2)
    assert r.pid is None, r.name
    # the same packet without the error is fine (the stuff bit inside 0xFF is handled)
    r = await host.out(ADDR, 1, False, b"\x00\x11\xff\x22")
    assert r.pid == PID_ACK, r.name
    r = await host.out(ADDR, 1, True, b"good")
    assert r.pid == PID_ACK
    # SETUP with a bad CRC16 is ignored, the control pipe still works
    r = await host.out(ADDR, 0, False, bytes([0x80, 6, 0, 1, 0, 0, 18, 0]), bad_crc=True, pid=0xD)
    assert r.pid is None, r.name
    assert len(await host.control_read(ADDR, 0x80, 6, 0x0100, 0, 18)) == 18
    await ClockCycles(dut.clk_i, 50)
    assert out_log(dut)[0] == b"\x00\x11\xff\x22good"
    assert int(dut.collision_o.value) == 0


@cocotb.test()
async def test_bus_reset_mid_transfer(dut):
    host = await start(dut)
    await enumerate_device(host)
    data = payload(64, 50)
    await load_in(dut, payload(64, 49), flush=False)
    assert (await host.in_token(ADDR, 1)).pid == PID_DATA0       # toggle now DATA1
    await load_in(dut, data, flush=False)
    r = await host.in_token(ADDR, 1, ack=False)                  # in flight, not ACKed
    assert r.pid == PID_DATA1
    assert (await host.out(ADDR, 1, False, b"1")).pid == PID_ACK  # OUT toggle now DATA1
    # reset in the middle of a control read
    await host.setup(ADDR, bytes([0x80, 6, 0, 2, 0, 0, 32, 0]))
    await host.bus_reset()
    assert int(dut.configured_o.value) == 0, "still configured after bus reset"
    r = await host.in_token(ADDR, 0)
    assert r.pid is None, f"old address answered {r.name} after reset"
    assert len(await host.control_read(0, 0x80, 6, 0x0100, 0, 18)) == 18, "address 0 after reset"
    r = await host.in_token(0, 1)
    assert r.pid is None, "EP1 answered while unconfigured"
    await host.control_nodata(0, 0x00, 5, ADDR, 0)
    await host.control_nodata(ADDR, 0x00, 9, 1, 0)
    assert int(dut.configured_o.value) == 1
    r = await host.in_token(ADDR, 1)
    assert (r.pid, r.payload) == (PID_DATA0, data), f"after reset: {r.name} (toggle restarts at DATA0)"
    assert (await host.out(ADDR, 1, False, b"2")).pid == PID_ACK
    await ClockCycles(dut.clk_i, 50)
    assert out_log(dut)[0] == b"12"


async def clock_error_run(dut, err: float) -> None:
    host = await start(dut, clock_error=err)
    got = await enumerate_device(host)
    check_descriptors(got)
    check_ms_os(await ms_os_descriptor_set(host, got["bos"]))
    await bulk_out_checks(dut, host)
    await bulk_in_checks(dut, host)
    assert host.max_delay_bits <= 7.5
    assert int(dut.collision_o.value) == 0


@cocotb.test()
async def test_host_clock_fast(dut):
    """Host bit clock 0.25 % fast."""
    await clock_error_run(dut, +0.0025)


@cocotb.test()
async def test_host_clock_slow(dut):
    """Host bit clock 0.25 % slow."""
    await clock_error_run(dut, -0.0025)


@cocotb.test()
async def test_line_skew(dut):
    """D- one host clock (a quarter bit) behind D+, host clock 0.25 % slow: short SE0/SE1
    states at every transition must not disturb the receiver."""
    host = await start(dut, clock_error=-0.0025)
    dut.skew_i.value = 1
    check_descriptors(await enumerate_device(host))
    await bulk_out_checks(dut, host)
    await bulk_in_checks(dut, host)


@cocotb.test()
async def test_transaction_level(dut):
    """The wire-less entry point (tl_*): same enumeration, descriptors and bulk behaviour."""
    host = await start(dut, tl=True)
    t0, sim0 = time.perf_counter(), get_sim_time("ns")
    got = await enumerate_device(host)
    dut._log.info("transaction-level enumeration: %d packets, %.0f us simulated, %.2f s wall",
                  host.packets, (get_sim_time("ns") - sim0) / 1e3, time.perf_counter() - t0)
    check_descriptors(got)
    check_ms_os(await ms_os_descriptor_set(host, got["bos"]))
    assert int(dut.configured_o.value) == 1
    await bulk_out_checks(dut, host)
    await bulk_in_checks(dut, host)
    r = await host.out(ADDR, 1, True, b"bad", bad_crc=True)
    assert r.pid is None, f"bad CRC16 answered {r.name} at transaction level"
    r = await host.send(token_bytes(PID_IN, ADDR, 1, bad_crc=True), listen=True)
    assert r.pid is None
    dut._log.info("transaction level: device answers %.0f clocks after the end of the host packet",
                  4 * host.max_delay_bits)
    assert 4 * host.max_delay_bits <= 12
    await host.bus_reset()
    assert int(dut.configured_o.value) == 0
    assert int(dut.dev_drove_o.value) == 0, "the device drove the wire in transaction-level mode"
