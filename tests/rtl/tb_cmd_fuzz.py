"""cocotb tests of the command path under fuzzing and of the firmware watchdog, on the RTL
(cmd_fuzz_tb: ms_system = SoC running firmware/app/sonar + sonar core + host link).

The USB endpoint is replaced by an SV-side feeder and capture (cmd_fuzz_tb.sv): Python hands a
whole transfer over in one write, the SV feeds it byte by byte as the bulk OUT endpoint would
(short packet / ZLP ends it) and appends every packet of the bulk IN byte stream to a file.

``cmd_fuzz``: CMD_FUZZ_N (default 10000) command transfers, ~35 % valid packets of every opcode
of multisonar.protocol and ~65 % mutations (bit flips, truncation, extension, wrong magic /
version / length / CRC, unknown opcodes, wrong payload size for the opcode, random bytes,
oversize > 1088 bytes), fed in batches. Reference: a model of docs/protocol.md sections 3/4
built from multisonar.simdevice (RegisterFile for the address checks and the write masks,
decode_vs_table for START's verdict, protocol.PARAM_RANGE). Checked: exactly one reply
per transfer, in order, each with the model's type, status and seq (payloads where they are
determined: ECHO, WRITE_REGS count, BAD_ADDRESS, BAD_VERSION, SET/GET_PARAM, DEVICE_INFO,
READ_REGS of the table, bad_commands of READ_COUNTERS); each reply within HANG_CYCLES of its
transfer's end (no hang); every packet's CRC; the table the sonar core holds at the end (read
from the hardware: ms_csr flip-flops, delay RAM) equals the one before with the accepted
WRITE_REGS applied (configuration intact); then the original table written back, a
short-range table STARTed, and frames streamed with consecutive sequence numbers.
READ_REGS values of the table must be exact (CMD_FUZZ_STRICT=0 would tolerate and count stale
values, the symptom of firmware reading the registers through VexRiscv's data cache, fixed).

``watchdog_recovers_hang``: the firmware is made to hang while the sonar runs, by a cocotb
deposit on an internal signal: the SoC's peripheral bus bridge (u_soc.u_soc_bridge.state_q) is
put into WAIT_ACK with no request outstanding, so the CPU's next SoC-register access (timer,
watchdog kick, command status: every pass of the main loop) never completes — a lost bus
acknowledge. The bridge is reset with the CPU only, so the watchdog's CPU reset is the only way
out. To keep the test short, the watchdog counter (u_soc.wdt_cnt_q, 1 s = 48 M clocks with
sonar_app's WDT_CYCLES) is preset once the hang is established so that WDT_MARGIN clocks of
the timeout remain; the compare / reset / count logic is the real one. Checked: while hung no
reply and no new frame; the sonar core keeps firing (drive bursts counted); the CPU reset
happens; the firmware reboots reporting WDT_RESETS = 1 (boot mailbox word), finds the sonar
running and keeps it running, answers the command sent during the hang and new ones, and
frames flow again (sequence numbers restart at 0, docs/protocol.md section 8).
"""

from __future__ import annotations

import json
import os
import random
import struct
import time
from collections import Counter
from pathlib import Path

import cocotb
from cocotb.triggers import ClockCycles, FallingEdge, First, ReadOnly, RisingEdge, Timer

from multisonar import protocol as P
from multisonar.generated import sonar_regs as R
from multisonar.layout import load_layout
from multisonar.regmap import schedule_writes
from multisonar.schedule import Schedule, VirtualSensor
from multisonar.simdevice import RegisterFile, _CfgErr, decode_vs_table
from tbutil import CLK_PERIOD_PS, reset

OUT_DIR = Path(os.environ.get("CMD_FUZZ_DIR", "."))
HANG_CYCLES = 2_000_000      # a reply must start within this many clocks of its transfer's end
BATCH = 48                   # transfers fed back to back before the replies are checked
LAYOUT = load_layout()
EVT = {R.REGISTERS["EVT_LO"].addr(), R.REGISTERS["EVT_HI"].addr()}
ERR = P.ERROR_REPLY_TYPE
# Known firmware bug (report of issue #9): the firmware reaches the table for WRITE_REGS /
# READ_REGS through SONAR_AT / DELAY_ENTRY at 0x1000_0000 + offset, the *cached* alias
# (ms_hw.h's MS_REG uses MS_IO_UNCACHED), so VexRiscv's write-through data cache answers READ_REGS
# with stale values (a value written unmasked, or one the firmware changed through the uncached
# alias since: SET_PARAM GLITCH_MIN). While True, a READ_REGS value of a table register may be
# any value that register held or was written with (counted: stale_reads); the 'configuration
# intact' check reads the hardware itself. The firmware reads through the uncached alias now, so
# the default is strict; CMD_FUZZ_STRICT=0 brings the tolerance back for diagnosis.
FW_READS_CACHED = os.environ.get("CMD_FUZZ_STRICT", "1") != "1"


def fast_table() -> list[tuple[int, int]]:
    """WRITE_REGS of a short-range sensor (as tests/rtl/tb_usb_link.py): with no echoes it
    fires an initialisation ping every ~4 ms instead of the compiled-in table's ~25 ms."""
    s = Schedule(LAYOUT, [VirtualSensor("front", tx=[0], rx=[23, 0, 1], order=1, max_range_m=0.6,
                                        t_dead=0.8e-3, t_v=0.2e-3, t_n=0.2e-3)], temperature_c=20.0)
    return schedule_writes(s)


def us(cycles: int) -> float:
    return cycles * CLK_PERIOD_PS / 1e6


class Bench:
    """Feeder / capture of cmd_fuzz_tb; packets read back from the capture files."""

    def __init__(self, dut) -> None:
        self.dut = dut
        self.cap_buf = ""
        self.cmd_buf = ""
        self.sent = 0
        self.mail: list[int] = []

    async def start(self) -> None:
        dut = self.dut
        await FallingEdge(dut.clk_i)  # the wrapper's own clock (cmd_fuzz_tb.sv)
        dut.echo_i.value = 0
        dut.go_i.value = 0
        dut.tx_len_i.value = 0
        await reset(dut.clk_i, dut.rst_i)
        # opened once the simulation has created them; an earlier test's lines are skipped
        self.cap = open(OUT_DIR / "cap.txt")  # noqa: SIM115 - read incrementally
        self.cmd = open(OUT_DIR / "cmd.txt")  # noqa: SIM115
        self.cap.read()
        self.cmd.read()
        cocotb.start_soon(self._mailbox())

    async def _mailbox(self) -> None:
        while True:
            await RisingEdge(self.dut.sim_out_strobe_o)
            await ReadOnly()
            self.mail.append(int(self.dut.sim_out_o.value))

    async def send(self, pkt: bytes, limit: int = HANG_CYCLES) -> None:
        """Hand one transfer to the feeder (waits while it is busy with the previous one)."""
        dut = self.dut
        if int(dut.busy_o.value):
            t = await First(FallingEdge(dut.busy_o), Timer(us(limit), unit="us"))
            assert not isinstance(t, Timer), f"the device took no command byte for {limit} clocks (hang)"
        await FallingEdge(dut.clk_i)
        dut.tx_bytes_i.value = int.from_bytes(pkt, "little")
        dut.tx_len_i.value = len(pkt)
        dut.go_i.value = 1
        await RisingEdge(dut.clk_i)
        await FallingEdge(dut.clk_i)
        dut.go_i.value = 0
        self.sent += 1

    async def wait_replies(self, n: int, limit: int = HANG_CYCLES, poll_us: float = 40.0) -> None:
        """Until n replies were captured; fails if none arrives for `limit` clocks."""
        dut = self.dut
        last, still = int(dut.n_replies_o.value), 0
        while last < n:
            await Timer(poll_us, unit="us")
            now = int(dut.n_replies_o.value)
            still = 0 if now != last else still + poll_us
            last = now
            assert still < us(limit), f"{n - now} replies missing after {limit} clocks without one (hang)"

    def _lines(self, fh, attr: str) -> list[str]:
        buf = getattr(self, attr) + fh.read()
        *lines, rest = buf.split("\n")
        setattr(self, attr, rest)
        return lines

    def packets(self) -> list[tuple[int, bytes]]:
        """New bulk IN packets: (cycle of the first byte, bytes incl. CRC)."""
        out = []
        for ln in self._lines(self.cap, "cap_buf"):
            c, h = ln.split()
            out.append((int(c), bytes.fromhex(h)))
        return out

    def close(self) -> None:
        self.cap.close()
        self.cmd.close()

    def cmd_ends(self) -> list[int]:
        return [int(x) for x in self._lines(self.cmd, "cmd_buf")]


class Model:
    """docs/protocol.md sections 3/4 for the fuzzer: the expected reply of each transfer."""

    def __init__(self, table: dict[int, int], params: dict[int, int], info: bytes) -> None:
        self.regs = RegisterFile()
        self.regs.values.update(table)
        # the RTL keeps DELAY_W = 16 bits per phasing delay (docs/protocol.md section 5: "the
        # delay field is 16 bits"); the register map declares 32
        for i in range(R.MEMORIES["DELAY"].entries):
            self.regs.writable_mask[R.MEMORIES["DELAY"].address + 4 * i] = 0xFFFF
        self.params = dict(params)
        self.info = info
        self.running = False
        self.bad = 0
        self.n = 0
        self.log: dict[int, list] = {}
        self.stale_reads = 0
        #: every value a table register has held or was written with (unmasked): what a stale
        #: cached read can return (FW_READS_CACHED)
        self.history: dict[int, set[int]] = {a: {v} for a, v in table.items()}

    def expect(self, data: bytes):
        """(type, status, seq, payload or None when not determined)."""
        self.n += 1
        if len(data) < 16:
            return self._bad(ERR, P.Status.BAD_LENGTH, 0, b"")
        magic, ver, op, _fl, _st, length, seq = P.HEADER.unpack_from(data, 0)
        if magic != P.MAGIC_COMMAND:
            return self._bad(ERR, P.Status.BAD_MAGIC, seq, b"")
        if ver != 1:
            return self._bad(ERR, P.Status.BAD_VERSION, seq, b"\x01")
        rop = (op | 0x80) & 0xFF
        if length > P.MAX_PAYLOAD or len(data) != 16 + length:
            return self._bad(rop, P.Status.BAD_LENGTH, seq, b"")
        if struct.unpack_from("<I", data, 12 + length)[0] != P.crc32(data[:12 + length]):
            return self._bad(rop, P.Status.BAD_CRC, seq, b"")
        if op not in P.Opcode._value2member_map_:
            return self._bad(rop, P.Status.UNKNOWN_OPCODE, seq, b"")
        st, pl = getattr(self, "_" + P.Opcode(op).name.lower())(data[12:12 + length])
        if st != P.Status.OK:
            self.bad += 1
        return rop, st, seq, pl

    def _bad(self, t, st, seq, pl):
        self.bad += 1
        return t, st, seq, pl

    def _device_info(self, pl):
        return (P.Status.BAD_LENGTH, b"") if pl else (P.Status.OK, self.info)

    def _write_regs(self, pl):
        if len(pl) % 8:
            return P.Status.BAD_LENGTH, b""
        if self.running:
            return P.Status.BUSY, b""
        for i, (a, v) in enumerate(P.parse_write_regs(pl)):
            if not self.regs.writable(a):
                return P.Status.BAD_ADDRESS, struct.pack("<HHI", i, 0, a)
            self.regs.write(a, v)  # an over-wide DELAY word is remembered: START refuses it
            self.log.setdefault(a, []).append(("write", self.n, v))
            self.history[a] |= {v, self.regs.values[a]}
        return P.Status.OK, struct.pack("<H", len(pl) // 8)

    def _read_regs(self, pl):
        if len(pl) % 4:
            return P.Status.BAD_LENGTH, b""
        addrs = P.parse_read_regs(pl)
        for i, a in enumerate(addrs):
            if not self.regs.readable(a):
                return P.Status.BAD_ADDRESS, struct.pack("<HHI", i, 0, a)
        # table registers must read back as the model has them; live ones are not determined
        # snapshot now: the expectations of a whole batch are computed before it is fed
        return P.Status.OK, [(a, self.regs.values[a], frozenset(self.history[a])) if self.regs.writable(a) else None
                             for a in addrs]

    def _start(self, pl):
        if pl:
            return P.Status.BAD_LENGTH, b""
        if self.running:
            return P.Status.BUSY, b""
        try:
            decode_vs_table(self.regs, LAYOUT)
        except _CfgErr as e:
            return P.Status.CFG_REJECTED, bytes([int(e.code), e.vs])
        self.running = True
        return P.Status.OK, None

    def _stop(self, pl):
        if pl:
            return P.Status.BAD_LENGTH, b""
        self.running = False
        return P.Status.OK, None

    def _read_counters(self, pl):
        return (P.Status.BAD_LENGTH, b"") if pl else (P.Status.OK, ("bad", self.bad))

    def _clear_counters(self, pl):
        if pl:
            return P.Status.BAD_LENGTH, b""
        self.bad = 0
        return P.Status.OK, b""

    def _set_param(self, pl):
        if len(pl) != 8:
            return P.Status.BAD_LENGTH, b""
        pid, value = P.parse_set_param(pl)
        if pid not in self.params:
            return P.Status.BAD_PARAM, pl
        lo, hi = P.PARAM_RANGE[P.Param(pid)]
        if not lo <= value <= hi:
            return P.Status.BAD_PARAM, pl
        if self.running and pid in P.PARAM_BUSY_WHILE_RUNNING:
            return P.Status.BUSY, pl
        self.params[pid] = value
        if pid == P.Param.GLITCH_MIN:
            f = R.REGISTERS["RX_FILTER"].fields["GLITCH_MIN"]
            self.regs.set_hw("RX_FILTER", f.put(self.regs.get("RX_FILTER"), value))
            self.log.setdefault(R.REGISTERS["RX_FILTER"].addr(), []).append(("glitch", self.n, value))
            self.history[R.REGISTERS["RX_FILTER"].addr()].add(self.regs.get("RX_FILTER"))
        return P.Status.OK, pl

    def _get_param(self, pl):
        if len(pl) != 2:
            return P.Status.BAD_LENGTH, b""
        pid = P.parse_get_param(pl)
        if pid not in self.params:
            return P.Status.BAD_PARAM, pl
        if pid == P.Param.GLITCH_MIN:  # the register itself (WRITE_REGS of RX_FILTER changes it too)
            return P.Status.OK, P.set_param_payload(pid, self.regs.field("RX_FILTER", "GLITCH_MIN"))
        return P.Status.OK, P.set_param_payload(pid, self.params[pid])

    def _echo(self, pl):
        return P.Status.OK, pl

    def _fw_stats(self, pl):
        return (P.Status.BAD_LENGTH, b"") if pl else (P.Status.OK, ("fw_stats",))


class Fuzzer:
    """Valid packets of every opcode and their mutations."""

    MUTATIONS = ("bitflip", "truncate", "extend", "magic", "version", "length", "crc", "opcode", "payload_size",
                 "random", "oversize", "short")

    def __init__(self, rng: random.Random, table: dict[int, int]) -> None:
        self.rng = rng
        self.table = table
        self.regs = RegisterFile()
        self.writable = sorted(self.regs.writable_mask)
        self.readable = [a for a in sorted(self.regs.values) if self.regs.readable(a)]
        used = set(self.readable)
        self.bad_addrs = [a for a in range(0, 0x800, 4) if a not in used] + [R.REGISTERS["CTRL"].addr()]
        self.kinds: Counter = Counter()

    def _addr_bad(self) -> int:
        r = self.rng
        return r.choice([r.choice(self.bad_addrs), r.choice(self.readable) | r.randint(1, 3),
                         r.getrandbits(32), r.choice([R.REGISTERS[n].addr() for n in ("ID", "STATUS", "CTRL", "CAPS")])])

    def _value(self, a: int) -> int:
        r, x = self.rng, self.rng.random()
        if x < 0.55:
            return self.table.get(a, 0)
        if x < 0.75:
            return self.table.get(a, 0) ^ (1 << r.randrange(32))
        return r.getrandbits(32)

    def valid(self) -> bytes:
        r = self.rng
        op = r.choices(list(P.Opcode), weights=[3, 10, 10, 3, 4, 4, 2, 8, 5, 10, 3])[0]
        pl = b""
        if op == P.Opcode.WRITE_REGS:
            pairs = []
            for _ in range(r.randint(1, 6)):
                a = r.choice(self.writable) if r.random() < 0.93 else self._addr_bad()
                pairs.append((a, self._value(a)))
            pl = P.write_regs_payload(pairs)
        elif op == P.Opcode.READ_REGS:
            n = r.randint(1, 12) if r.random() < 0.98 else r.randint(1, 256)
            pl = P.read_regs_payload([r.choice(self.readable) if r.random() < 0.97 else self._addr_bad()
                                      for _ in range(n)])
        elif op == P.Opcode.ECHO:
            x = r.random()
            n = r.randint(0, 64) if x < 0.8 else r.randint(0, 300) if x < 0.99 else r.randint(0, 1024)
            pl = r.randbytes(n)
        elif op == P.Opcode.SET_PARAM:
            pid = r.choice([1, 1, 2, 3, 4, 5, 5, 0, 6, r.getrandbits(16)])
            lo, hi = P.PARAM_RANGE.get(pid, (0, 10)) if pid in P.Param._value2member_map_ else (0, 10)
            v = r.randint(lo, hi) if r.random() < 0.7 else r.choice([lo - 1, hi + 1, -2**31, 2**31 - 1,
                                                                     r.randint(-2**31, 2**31 - 1)])
            pl = P.set_param_payload(pid, v)
        elif op == P.Opcode.GET_PARAM:
            pl = struct.pack("<H", r.choice([1, 2, 3, 4, 5, 0, 6, r.getrandbits(16)]))
        self.kinds["valid_" + op.name] += 1
        return P.encode_command(op, pl, seq=r.getrandbits(32))

    def mutated(self) -> bytes:
        r = self.rng
        kind = r.choices(self.MUTATIONS, weights=[4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 1, 4])[0]  # oversize: 1/45
        self.kinds[kind] += 1
        p = bytearray(self.valid())
        self.kinds[f"valid_{P.Opcode(p[3]).name}"] -= 1

        def recrc(b: bytearray) -> bytes:
            return bytes(b[:-4]) + struct.pack("<I", P.crc32(bytes(b[:-4])))

        if kind == "bitflip":
            for _ in range(r.randint(1, 3)):
                i = r.randrange(len(p) * 8)
                p[i // 8] ^= 1 << (i % 8)
            return bytes(p)
        if kind == "truncate":
            return bytes(p[:r.randrange(len(p))])
        if kind == "extend":
            return bytes(p) + r.randbytes(r.randint(1, 40))
        if kind == "magic":
            m = r.randbytes(2)
            p[0:2] = m if m != b"MC" else b"MR"
            return recrc(p) if r.random() < 0.5 else bytes(p)
        if kind == "version":
            p[2] = r.choice([0, 2, 255, r.randrange(2, 256)])
            return recrc(p)
        if kind == "length":
            struct.pack_into("<H", p, 6, r.choice([r.getrandbits(16), (len(p) - 16 + r.choice([-1, 1, 4])) & 0xFFFF,
                                                   1025, 0xFFFF]))
            return recrc(p)
        if kind == "crc":
            p[-1 - r.randrange(4)] ^= 1 << r.randrange(8)
            return bytes(p)
        if kind == "opcode":
            p[3] = r.choice([0, 11, 0x40, 0x7F, 0x80, 0x8A, 0xFF, r.randrange(11, 256)])
            return recrc(p)
        if kind == "payload_size":
            op = r.choice([P.Opcode.DEVICE_INFO, P.Opcode.START, P.Opcode.STOP, P.Opcode.READ_COUNTERS,
                           P.Opcode.CLEAR_COUNTERS, P.Opcode.SET_PARAM, P.Opcode.GET_PARAM, P.Opcode.WRITE_REGS,
                           P.Opcode.READ_REGS])
            n = r.choice([1, 2, 3, 5, 7, 9, 12, 13])
            if op == P.Opcode.GET_PARAM and n == 2:
                n = 3
            if op == P.Opcode.SET_PARAM and n == 8:
                n = 9
            return P.encode_command(op, r.randbytes(n), seq=r.getrandbits(32))
        if kind == "random":
            return r.randbytes(r.randint(0, 96))
        if kind == "short":
            return bytes(p[:r.randint(0, 15)])
        # oversize: more than a maximal packet, sometimes more than the 1088 bytes the link keeps
        n = r.randint(1041, 1200)
        body = P.HEADER.pack(b"MC", 1, P.Opcode.ECHO, 0, 0, r.choice([1024, n - 16, (n - 16) & 0xFFFF, 0]),
                             r.getrandbits(32)) + r.randbytes(n - 16)
        return body + struct.pack("<I", P.crc32(body))

    def packet(self) -> bytes:
        return self.valid() if self.rng.random() < 0.35 else self.mutated()


def decode(raw: bytes) -> P.Packet:
    return P.decode_packet(raw)  # raises on a bad CRC / header: every packet must be well formed


async def roundtrip(b: Bench, op, payload: bytes = b"", seq: int = 1) -> tuple[P.Packet, list[P.Packet]]:
    """One command, lock-step: its reply and the frames captured meanwhile."""
    n = int(b.dut.n_replies_o.value)
    await b.send(P.encode_command(op, payload, seq=seq))
    await b.wait_replies(n + 1)
    pk = [decode(raw) for _, raw in b.packets()]
    b.cmd_ends()
    reps = [p for p in pk if p.is_reply]
    assert len(reps) == 1, reps
    assert reps[0].seq == seq and reps[0].type == (op | 0x80), reps[0]
    return reps[0], [p for p in pk if p.is_frame]


def table_addrs() -> list[int]:
    return sorted(RegisterFile().writable_mask)


async def read_table(b: Bench) -> dict[int, int]:
    out = {}
    addrs = table_addrs()
    for i in range(0, len(addrs), 200):
        chunk = addrs[i:i + 200]
        rep, _ = await roundtrip(b, P.Opcode.READ_REGS, P.read_regs_payload(chunk), seq=900 + i)
        assert rep.status == P.Status.OK, rep
        out.update(zip(chunk, struct.unpack(f"<{len(chunk)}I", rep.payload)))
    return out


async def hw_table(dut) -> dict[int, int]:
    """The table as the sonar core holds it (ms_csr's VS RAM, delay RAM, regblock outputs):
    ground truth for 'configuration intact', independent of the firmware's READ_REGS."""
    await ReadOnly()
    csr = dut.u_sys.u_sonar.u_csr
    vs_mem = csr.vs_m  # word entry * 9 + register
    out = {}
    names = ["VS_TX_MASK", "VS_RX_MASK", "VS_MODE", "VS_WINDOW", "VS_T_DEAD", "VS_MAX_TOF", "VS_XTALK", "VS_TRACK",
             "VS_PHASE"]
    for v in range(8):
        for r, n in enumerate(names):
            out[R.REGISTERS[n].addr(v)] = int(vs_mem[9 * v + r].value)
    mem = csr.delay_m
    for i in range(R.MEMORIES["DELAY"].entries):
        out[R.MEMORIES["DELAY"].address + 4 * i] = int(mem[i].value)
    out[R.REGISTERS["BURST"].addr()] = int(csr.burst_half_period_o.value) | int(csr.burst_cycles_o.value) << 16
    out[R.REGISTERS["RX_FILTER"].addr()] = (int(csr.glitch_min_o.value) | int(csr.miss_hold.value) << 8
                                            | int(csr.miss_gate.value) << 16)
    await Timer(1, unit="ns")
    assert set(out) == set(table_addrs())
    return out


async def boot(b: Bench) -> None:
    await b.start()
    for _ in range(2000):
        if any(w >> 28 == 1 for w in b.mail):
            return
        await Timer(20, unit="us")
    raise AssertionError("the firmware did not boot")


@cocotb.test(timeout_time=3_000_000, timeout_unit="ms")
async def cmd_fuzz(dut):
    n_total = int(os.environ.get("CMD_FUZZ_N", "10000"))
    seed = int(os.environ.get("CMD_FUZZ_SEED", "9"))
    rng = random.Random(seed)
    wall0 = time.monotonic()
    b = Bench(dut)
    await boot(b)
    info, _ = await roundtrip(b, P.Opcode.DEVICE_INFO)
    assert info.status == P.Status.OK and len(info.payload) == 24
    params = {}
    for pid in P.Param:
        rep, _ = await roundtrip(b, P.Opcode.GET_PARAM, struct.pack("<H", pid), seq=100 + pid)
        assert rep.status == P.Status.OK, rep
        params[int(pid)] = struct.unpack("<HHi", rep.payload)[2]
    rep, _ = await roundtrip(b, P.Opcode.CLEAR_COUNTERS, seq=3)
    # a short-range table, so that the runs the fuzzer STARTs produce frames meanwhile
    rep, _ = await roundtrip(b, P.Opcode.WRITE_REGS, P.write_regs_payload(fast_table()), seq=4)
    assert rep.status == P.Status.OK, rep
    table0 = await hw_table(dut)
    assert await read_table(b) == table0, "READ_REGS of the table after boot differs from the hardware"
    model = Model(table0, params, info.payload)
    fuzz = Fuzzer(rng, table0)
    sim0 = int(dut.cycle_o.value)
    wall_f0 = time.monotonic()

    statuses: Counter = Counter()
    stats = {"packets": 0, "replies": 0, "frames": 0, "hangs": 0, "max_latency": 0, "bytes": 0}
    lat_sum = 0
    while stats["packets"] < n_total:
        k = min(BATCH, n_total - stats["packets"])
        batch = [fuzz.packet() for _ in range(k)]
        want = [model.expect(p) for p in batch]
        n0 = int(dut.n_replies_o.value)
        for p in batch:
            await b.send(p)
        await b.wait_replies(n0 + k)
        await ClockCycles(dut.clk_i, 64)  # let a reply still in flight appear (there must be none)
        got = [(c, decode(raw)) for c, raw in b.packets()]
        ends = b.cmd_ends()
        reps = [(c, p) for c, p in got if p.is_reply]
        stats["frames"] += len(got) - len(reps)
        assert len(ends) == k, (len(ends), k)
        assert len(reps) == k, f"{len(reps)} replies to {k} command transfers"
        for i, ((c, rep), end, pkt, (t, st, seq, pl)) in enumerate(zip(reps, ends, batch, want)):
            where = f"packet {stats['packets'] + i} {pkt[:24].hex()}..({len(pkt)} B): reply {rep}"
            assert (rep.type, rep.status, rep.seq) == (t, st, seq), f"{where}; expected {(t, st.name, seq)}"
            lat = c - end
            assert 0 < lat < HANG_CYCLES, f"{where}: latency {lat} clocks"
            stats["max_latency"] = max(stats["max_latency"], lat)
            lat_sum += lat
            if isinstance(pl, bytes):
                assert rep.payload == pl, f"{where}: payload, expected {pl.hex()}"
            elif isinstance(pl, list):
                vals = struct.unpack(f"<{len(pl)}I", rep.payload)
                for v, e in zip(vals, pl):
                    if e is None:
                        continue
                    a, w, hist = e
                    if v != w and FW_READS_CACHED and v in hist:
                        model.stale_reads += 1  # the firmware's cached read (see FW_READS_CACHED)
                        continue
                    assert v == w, f"{where}: register 0x{a:X} reads 0x{v:08X}, model 0x{w:08X} ({model.log.get(a)})"
            elif isinstance(pl, tuple) and pl[0] == "fw_stats":  # the firmware's counts: their size
                assert len(P.decode_fw_stats(rep.payload)) == len(P.FW_STATS_FIELDS), where
            elif isinstance(pl, tuple):  # READ_COUNTERS: bad_commands since CLEAR_COUNTERS
                c_ = P.decode_counters(rep.payload)
                assert c_["bad_commands"] == pl[1], f"{where}: bad_commands {c_['bad_commands']}, model {pl[1]}"
            elif st == P.Status.OK:  # START / STOP: the frame sequence number
                assert len(rep.payload) == 4, where
            statuses[P.Status(rep.status).name] += 1
            stats["bytes"] += len(pkt)
        stats["packets"] += k
        stats["replies"] += len(reps)
        assert not int(dut.trap_o.value), "CPU trap"

    # configuration intact: the table is the one before with the accepted writes applied
    if model.running:
        rep, _ = await roundtrip(b, P.Opcode.STOP, seq=7)
        assert rep.status == P.Status.OK
        model.running = False
    got_table = await hw_table(dut)
    diff = {a: (got_table[a], model.regs.values[a]) for a in got_table if got_table[a] != model.regs.values[a]}
    assert not diff, f"table differs from the model: {diff} {[(a, model.log.get(a)) for a in diff]}"
    changed = sum(1 for a in table0 if table0[a] != got_table[a])
    sim1 = int(dut.cycle_o.value)
    wall_fuzz = time.monotonic() - wall_f0
    # still streams: the original table back, START, frames with consecutive sequence numbers
    rep, _ = await roundtrip(b, P.Opcode.WRITE_REGS, P.write_regs_payload(sorted(table0.items())[:128]), seq=11)
    assert rep.status == P.Status.OK, rep
    rep, _ = await roundtrip(b, P.Opcode.WRITE_REGS, P.write_regs_payload(sorted(table0.items())[128:256]), seq=12)
    assert rep.status == P.Status.OK, rep
    rep, _ = await roundtrip(b, P.Opcode.WRITE_REGS, P.write_regs_payload(sorted(table0.items())[256:]), seq=13)
    assert rep.status == P.Status.OK, rep
    assert await hw_table(dut) == table0
    rep, _ = await roundtrip(b, P.Opcode.WRITE_REGS, P.write_regs_payload(fast_table()), seq=16)
    assert rep.status == P.Status.OK, rep
    rep, _ = await roundtrip(b, P.Opcode.START, seq=14)
    assert rep.status == P.Status.OK, rep
    first = struct.unpack("<I", rep.payload)[0]
    frames: list[P.Packet] = []
    for _ in range(5000):
        await Timer(100, unit="us")
        frames += [decode(raw) for _, raw in b.packets()]
        if len(frames) >= 3:
            break
    assert len(frames) >= 3 and all(f.is_frame for f in frames), f"{len(frames)} frames after START"
    assert [f.seq for f in frames] == list(range(first, first + len(frames))), [f.seq for f in frames]
    for f in frames:
        P.decode_frame(f)
    rep, _ = await roundtrip(b, P.Opcode.STOP, seq=15)
    assert rep.status == P.Status.OK
    wall = time.monotonic() - wall0
    res = {"packets": stats["packets"], "replies": stats["replies"], "hangs": 0, "frames_during_fuzz": stats["frames"],
           "statuses": dict(statuses), "kinds": dict(fuzz.kinds), "bytes": stats["bytes"],
           "max_latency_clk": stats["max_latency"], "mean_latency_clk": lat_sum / max(stats["replies"], 1),
           "sim_s": (sim1 - sim0) / 48e6, "wall_s": wall, "fuzz_wall_s": wall_fuzz,
           "packets_per_s": stats["packets"] / max(wall_fuzz, 1e-9), "fuzz_clk_per_s": (sim1 - sim0) / max(wall_fuzz, 1e-9),
           "table_regs_changed": changed, "frames_after": len(frames), "seed": seed,
           "stale_reads": model.stale_reads}
    dut._log.info("fuzz: %s", json.dumps(res))
    if os.environ.get("CMD_FUZZ_JSON"):
        Path(os.environ["CMD_FUZZ_JSON"]).write_text(json.dumps(res, indent=1))
    b.close()
    assert statuses["OK"] > 0 and len(statuses) >= 8, statuses


WDT_MARGIN = 600_000     # clocks of the watchdog timeout left when the hang is established
WDT_CYCLES = 48_000_000  # firmware/app/sonar/app.h WDT_CYCLES (WDT_TIMEOUT written at boot)
BRIDGE_WAIT_ACK = 2        # ms_pico_bridge state_e: IDLE, REQ, WAIT_ACK, DONE


@cocotb.test(timeout_time=600_000, timeout_unit="ms")
async def watchdog_recovers_hang(dut):
    b = Bench(dut)
    await boot(b)
    soc = dut.u_sys.u_soc
    boots0 = [w for w in b.mail if w >> 28 == 1]
    assert boots0 and boots0[-1] & 0xFFFF == 0, boots0
    rep, _ = await roundtrip(b, P.Opcode.WRITE_REGS, P.write_regs_payload(fast_table()), seq=20)
    assert rep.status == P.Status.OK, rep
    rep, _ = await roundtrip(b, P.Opcode.START, seq=21)
    assert rep.status == P.Status.OK, rep
    first = struct.unpack("<I", rep.payload)[0]
    frames = []
    while len(frames) < 3:
        await Timer(200, unit="us")
        frames += [decode(raw) for _, raw in b.packets() if raw[:2] == b"MF"]
    assert [f.seq for f in frames] == list(range(first, first + len(frames)))
    rep, _ = await roundtrip(b, P.Opcode.READ_COUNTERS, seq=22)
    c0 = P.decode_counters(rep.payload)

    # --- inject: the SoC bridge waits for an acknowledge that never comes
    while True:
        await FallingEdge(dut.clk_i)
        if int(soc.u_soc_bridge.state_q.value) == 0 and not int(soc.cpu_rst_q.value):
            soc.u_soc_bridge.state_q.value = BRIDGE_WAIT_ACK  # no request outstanding
            break
    t_hang = int(dut.cycle_o.value)
    drive0 = int(dut.drive_edges_o.value)
    pulses: list[int] = []
    sched = dut.u_sys.u_sonar.u_sched

    async def count_pulses():
        while True:
            await RisingEdge(sched.pulse_o)
            pulses.append(int(dut.cycle_o.value))

    counter = cocotb.start_soon(count_pulses())
    await ClockCycles(dut.clk_i, 20_000)  # frames already queued drain
    b.packets()
    frames_hung0, mail0 = int(dut.n_frames_o.value), len(b.mail)
    assert int(soc.u_soc_bridge.state_q.value) == BRIDGE_WAIT_ACK, "the hang did not take"
    # a command sent during the hang: it must not be answered before the recovery
    n_rep = int(dut.n_replies_o.value)
    echo = P.encode_command(P.Opcode.ECHO, b"during the hang", seq=23)
    await b.send(echo)
    await ClockCycles(dut.clk_i, 100_000)
    assert int(dut.n_replies_o.value) == n_rep, "a reply while the CPU is hung"
    assert int(dut.n_frames_o.value) == frames_hung0 and len(b.mail) == mail0, "the CPU is not hung"
    assert int(soc.cpu_rst_q.value) == 0
    # shorten the wait: WDT_MARGIN clocks of the 1 s timeout remain (the counter is not kicked)
    cnt, t_preset = int(soc.wdt_cnt_q.value), int(dut.cycle_o.value)
    assert cnt >= t_preset - t_hang - 1000, f"watchdog counter {cnt}: it is being kicked"
    soc.wdt_cnt_q.value = WDT_CYCLES - WDT_MARGIN
    t = await First(RisingEdge(soc.cpu_rst_q), Timer(us(2 * WDT_MARGIN), unit="us"))
    assert not isinstance(t, Timer), "no watchdog reset"
    t_rst = int(dut.cycle_o.value)
    assert abs(t_rst - t_preset - WDT_MARGIN) <= 4, t_rst - t_preset
    drive_hang = int(dut.drive_edges_o.value) - drive0
    pulses_hang = len(pulses)
    # --- recovery: reboot, the pending ECHO answered, frames again (seq restarts at 0)
    await b.wait_replies(n_rep + 1)
    t_ans = int(dut.cycle_o.value)
    pk = [decode(raw) for _, raw in b.packets()]
    reps = [p for p in pk if p.is_reply]
    assert len(reps) == 1 and (reps[0].seq, reps[0].status, reps[0].payload) == (23, 0, b"during the hang"), reps
    boots = [w for w in b.mail if w >> 28 == 1]
    assert len(boots) == 2 and boots[-1] & 0xFFFF == 1, [hex(w) for w in boots]  # WDT_RESETS = 1
    frames = [p for p in pk if p.is_frame]
    while len(frames) < 3:
        await Timer(200, unit="us")
        frames += [decode(raw) for _, raw in b.packets() if raw[:2] == b"MF"]
    assert [f.seq for f in frames] == list(range(len(frames))), [f.seq for f in frames]
    heads = [P.decode_frame(f) for f in frames]
    rep, _ = await roundtrip(b, P.Opcode.READ_COUNTERS, seq=24)
    c1 = P.decode_counters(rep.payload)
    rep, _ = await roundtrip(b, P.Opcode.ECHO, b"after", seq=25)
    assert rep.payload == b"after"
    hung_cycles = t_rst - t_hang
    # the sonar kept firing through the hang: bursts at its pulse rate, PULSES counted them
    counter.cancel()
    assert pulses_hang >= 3 and drive_hang >= pulses_hang, \
        f"{pulses_hang} pulses, {drive_hang} drive edges during {hung_cycles} hung clocks"
    gaps = [b_ - a_ for a_, b_ in zip(pulses, pulses[1:])]
    assert max(gaps + [pulses[0] - t_hang]) < hung_cycles // 2, gaps  # firing kept its pace
    assert c1["pulses"] - c0["pulses"] >= pulses_hang, (c0, c1, pulses_hang)
    rep, _ = await roundtrip(b, P.Opcode.STOP, seq=26)
    assert rep.status == P.Status.OK
    assert not int(dut.trap_o.value)
    b.close()
    if not FW_READS_CACHED:  # strict mode: also the host-visible count (firmware fix in the report)
        assert c1["watchdog"] == 1 and all(int(h.head["watchdog"]) == 1 for h in heads), (c1, heads)
    dut._log.info("watchdog: hung %d clocks (timeout shortened), %d pulses / %d drive edges during the hang, reset -> "
                  "pending ECHO answered after %d clocks; boot word 0x%08X; READ_COUNTERS.watchdog after: %d; "
                  "frame head watchdog field: %s; pulses %d -> %d",
                  hung_cycles, pulses_hang, drive_hang, t_ans - t_rst, boots[-1], c1["watchdog"],
                  [int(h.head["watchdog"]) for h in heads][:3],
                  c0["pulses"], c1["pulses"])
    if os.environ.get("CMD_FUZZ_JSON"):
        p = Path(os.environ["CMD_FUZZ_JSON"]).with_suffix(".wdt.json")
        p.write_text(json.dumps({"hung_clk": hung_cycles, "pulses_during_hang": pulses_hang, "drive_edges_during_hang": drive_hang,
                                 "answer_after_reset_clk": t_ans - t_rst, "wdt_resets_at_boot": boots[-1] & 0xFFFF,
                                 "read_counters_watchdog": c1["watchdog"]}))
