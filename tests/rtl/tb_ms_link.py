"""cocotb unit test of the host link (rtl/link/ms_link.sv): command receive buffer, reply and
frame queues with commit / roll-back, packer (CRC-32 appended, one transfer per packet,
replies first at packet boundaries), drops counted, discard at a boundary."""

from __future__ import annotations

import random
import struct
import zlib

import cocotb
from cocotb.triggers import FallingEdge, RisingEdge

from multisonar import protocol as P
from tbutil import reset, start_clock


def packet_words(magic: bytes, typ: int, seq: int, payload: bytes) -> list[int]:
    """Header + payload as the firmware writes them (no CRC, last word zero-padded)."""
    b = magic + bytes([1, typ, 0, 0]) + struct.pack("<HI", len(payload), seq) + payload
    b += bytes(-len(b) % 4)
    return list(struct.unpack(f"<{len(b) // 4}I", b))


class Link:
    def __init__(self, dut) -> None:
        self.dut = dut
        self.transfers: list[bytes] = []
        self._buf = bytearray()
        for s in ("out_valid_i", "out_data_i", "out_end_i", "out_zlp_i", "cmd_rd_i", "cmd_next_i", "rep_wr_i",
                  "rep_wdata_i", "rep_end_i", "frm_wr_i", "frm_wdata_i", "frm_end_i", "frm_discard_i", "clear_i",
                  "in_ready_i"):
            getattr(dut, s).value = 0

    async def write(self, which: str, words: list[int], commit: bool = True) -> None:
        d = self.dut
        for w in words:
            await FallingEdge(d.clk_i)
            getattr(d, f"{which}_wr_i").value = 1
            getattr(d, f"{which}_wdata_i").value = w
        await FallingEdge(d.clk_i)
        getattr(d, f"{which}_wr_i").value = 0
        if commit:
            await self.strobe(f"{which}_end_i")

    async def strobe(self, name: str) -> None:
        await FallingEdge(self.dut.clk_i)
        getattr(self.dut, name).value = 1
        await FallingEdge(self.dut.clk_i)
        getattr(self.dut, name).value = 0

    async def drain(self, clocks: int) -> None:
        """in_ready high for `clocks` clocks, collecting bytes and flushes."""
        d = self.dut
        await FallingEdge(d.clk_i)
        d.in_ready_i.value = 1
        for k in range(clocks):
            if k:
                await FallingEdge(d.clk_i)
            if int(d.in_valid_o.value):
                self._buf.append(int(d.in_data_o.value))
            if int(d.in_flush_o.value):
                self.transfers.append(bytes(self._buf))
                self._buf.clear()
        d.in_ready_i.value = 0

    def packets(self) -> list[P.Packet]:
        out = []
        for t in self.transfers:
            sp = P.StreamParser()
            got = sp.feed(t)
            assert len(got) == 1 and sp.bad_crc == 0 and len(t) == 16 + len(got[0].payload), t.hex()
            out += got
        return out

    async def send_cmd(self, data: bytes, zlp: bool = False) -> None:
        d = self.dut
        entries = [(b, i == len(data) - 1 and not zlp, 0) for i, b in enumerate(data)]
        if zlp or not data:
            entries.append((0, 1, 1))
        i = 0
        while i < len(entries):
            await FallingEdge(d.clk_i)
            b, end, z = entries[i]
            d.out_valid_i.value, d.out_data_i.value, d.out_end_i.value, d.out_zlp_i.value = 1, b, int(end), z
            if int(d.out_ready_o.value):
                i += 1
        await FallingEdge(d.clk_i)
        d.out_valid_i.value = d.out_end_i.value = d.out_zlp_i.value = 0

    async def read_cmd(self) -> tuple[int, bool, bool, bytes]:
        d = self.dut
        await FallingEdge(d.clk_i)
        assert int(d.cmd_avail_o.value), "no command transfer available"
        n, ok, ovl = int(d.cmd_bytes_o.value), bool(int(d.cmd_crc_ok_o.value)), bool(int(d.cmd_overlong_o.value))
        words = []
        for _ in range((min(n, 1088) + 3) // 4 + 1):  # one read past the end: 0
            d.cmd_rd_i.value = 1
            await FallingEdge(d.clk_i)  # the pop was taken at the rising edge between
            d.cmd_rd_i.value = 0
            assert int(d.cmd_rd_ack_o.value) == 1
            words.append(int(d.cmd_rd_data_o.value))
        assert words[-1] == 0, "read past the transfer's end is not 0"
        await self.strobe("cmd_next_i")
        return n, ok, ovl, b"".join(struct.pack("<I", w) for w in words[:-1])


@cocotb.test(timeout_time=50, timeout_unit="ms")
async def packets_priority_drops_discard(dut):
    start_clock(dut.clk_i)
    link = Link(dut)
    await reset(dut.clk_i, dut.rst_i)
    rng = random.Random(5)
    # 1. two frames and a reply while the endpoint is busy: frame 0 (already started), the
    #    reply, then frame 1; CRCs appended; odd reply lengths (the CRC right after the payload)
    f0 = packet_words(b"MF", 0x40, 0, bytes(rng.randrange(256) for _ in range(36)))
    f1 = packet_words(b"MF", 0x40, 1, bytes(rng.randrange(256) for _ in range(20)))
    r0 = packet_words(b"MR", 0x8A, 9, b"abcde")
    await link.write("frm", f0)
    await link.write("frm", f1)
    await link.write("rep", r0)
    await link.drain(2000)
    ps = link.packets()
    assert [(p.magic, p.seq) for p in ps] == [(P.MAGIC_FRAME, 0), (P.MAGIC_REPLY, 9), (P.MAGIC_FRAME, 1)], ps
    assert ps[1].payload == b"abcde"
    assert int(dut.frames_sent_o.value) == 2 and int(dut.frames_dropped_o.value) == 0
    # 2. the frame queue fills (endpoint not read): the frame that does not fit is dropped
    #    whole and counted; malformed frames (length and word count disagree) too
    link.transfers.clear()
    sent, seq = [], 10
    for k in range(12):  # 12 x 268 bytes > 512 words
        pl = bytes(rng.randrange(256) for _ in range(256))
        await link.write("frm", packet_words(b"MF", 0x40, seq, pl))
        sent.append((seq, pl))
        seq += 1
    bad = packet_words(b"MF", 0x40, 99, bytes(8))[:-1]  # one word short
    await link.write("frm", bad)
    for _ in range(3):  # the counter follows the commit by two clocks
        await FallingEdge(dut.clk_i)
    dropped = int(dut.frames_dropped_o.value)
    # 66 words of frame 10 wait (its first word is in the packer), then 6 more frames of 67
    # words fit in 512: frames 17..21 and the malformed one are dropped
    assert dropped == 6, f"frames_dropped {dropped}"
    await link.drain(40000)
    ps = link.packets()
    got = [(p.seq, p.payload) for p in ps]
    assert len(got) == 12 + 1 - dropped, (len(got), dropped)
    assert all(g in sent for g in got) and [g[0] for g in got] == sorted(g[0] for g in got)
    assert all(p.seq != 99 for p in ps)
    # 3. discard: frames committed before the request are dropped (counted) at the next
    #    boundary; the frame in flight finishes; later frames stay
    link.transfers.clear()
    await link.strobe("clear_i")
    for s in (20, 21, 22):
        await link.write("frm", packet_words(b"MF", 0x40, s, bytes(100)))
    await link.drain(10)  # frame 20 starts
    await link.strobe("frm_discard_i")
    await link.write("frm", packet_words(b"MF", 0x40, 23, bytes(4)))
    await link.drain(5000)
    for _ in range(3):
        await FallingEdge(dut.clk_i)
    assert [p.seq for p in link.packets()] == [20, 23]
    assert int(dut.frames_dropped_o.value) == 2 and int(dut.frames_sent_o.value) == 2


@cocotb.test(timeout_time=50, timeout_unit="ms")
async def command_transfers(dut):
    start_clock(dut.clk_i)
    link = Link(dut)
    await reset(dut.clk_i, dut.rst_i)
    good = P.encode_command(P.Opcode.ECHO, b"hello", seq=3)           # 21 bytes, short packet
    big = P.encode_command(P.Opcode.ECHO, bytes(range(48)), seq=4)      # 64 bytes + ZLP
    huge = bytes(1200)                                                   # longer than the buffer
    await link.send_cmd(good)
    await link.send_cmd(big, zlp=True)
    await link.send_cmd(good[:-1] + bytes([good[-1] ^ 0x40]))
    n, ok, ovl, data = await link.read_cmd()
    assert (n, ok, ovl, data[:n]) == (len(good), True, False, good) and data[n:] == bytes(-n % 4)
    n, ok, ovl, data = await link.read_cmd()
    assert (n, ok, ovl, data) == (64, True, False, big)
    n, ok, ovl, _ = await link.read_cmd()
    assert (n, ok, ovl) == (len(good), False, False)
    await link.send_cmd(huge)
    await link.send_cmd(b"", zlp=True)
    n, ok, ovl, data = await link.read_cmd()
    assert (n, ovl, len(data)) == (1200, True, 1088) and data == bytes(1088)
    n, ok, ovl, data = await link.read_cmd()
    assert (n, ovl, data) == (0, False, b"")
    # release without reading: the next transfer starts clean
    await link.send_cmd(good)
    await link.send_cmd(big, zlp=True)
    await link.strobe("cmd_next_i")
    n, ok, ovl, data = await link.read_cmd()
    assert (n, ok, data) == (64, True, big)
    assert zlib.crc32(big[:-4]) == struct.unpack("<I", big[-4:])[0]
    await FallingEdge(dut.clk_i)
    assert not int(dut.cmd_avail_o.value)
    await RisingEdge(dut.clk_i)
