"""Microcode kernels of the scheduler for the engine core (docs/sched_engine.md), with the data
memory layout they assume. Each kernel is checked against the golden model
(multisonar.fastfiring) in tests/test_sched_program.py and timed in clocks by
scripts/bench_sched_engine.py: the figures that say which of the scheduler's loops the
engine can run within the decision lead and which need a fixed stream unit.

Data memory (32-bit words): the tracking state of (sensor s, receiver r) at
``TRK + 2 * (24 s + r)``: word A = tof[23:0] | seq[7:0] << 24, word B = v[23:0] (two's
complement) | flags << 24 (bit 24 tracked, 25 init, 26 vel, 31:28 miss count); the candidate's
predicted T_E of receiver r at ``CAND + r``; per element tx_until (``TU + e``) and
blank_until (``BU + e``); the candidate's blank interval of element e at ``BA + e``, ``BB + e``;
per sensor s at ``SENS + 32 s``: due (S_DUE), quiet, pulse id (S_SEQ), flags (S_FLAGS:
tracking, in_init, epoch, any receiver tracked), open init windows (S_OPEN), tracking pulses
since the last init ping (S_TRK, saturating at 255), miss limit K (S_K), reinit_every M
(S_REINIT, 0 off), mode (S_MODE: 1 track), the other sensors sharing an element (S_SHARE,
one bit per sensor).

The slot unit (:class:`SlotUnit`, a fixed stream unit the engine drives through I/O
registers) scans the up to 16 reserved windows of one element, one per clock, against the
candidate's blank interval [TA, TB) and window [TWA, TWB) (absolute ticks, written before
SU_GO = element | blank on << 8 | window on << 9) and gives, SU_LATENCY clocks later, SU_X =
the latest retry relative to TA / TWA among the windows it overlaps (end - TA, end - TWA),
SU_FLAGS bit 0 = any overlap, bit 1 = every slot taken (window on), bit 7 = busy, and SU_MINC
= the earliest close tick of the element's windows.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field
from typing import Callable

from ..schedule import min_tof_for_order
from .sched_ucode import MASK32, Machine, Program, UcodeError, sext

NUM_RX = 24
WSLOTS = 16
TRK = 0x100           # tracking state, 2 words per (sensor, receiver): 0x100..0x27F
TU = 0x340            # per element: tx_until (absolute tick)
BU = 0x358            # per element: blank_until (absolute tick)
BA = 0x370            # the candidate's blank interval [a, b) of element e (offsets from t0)
BB = 0x388
CAND = 0x3A0          # candidate T_E per receiver
WV = 0x3B8            # per element: valid reserved-window slots (bit mask)
HC = 0x3D0            # per element: the head's (earliest) close tick
HS = 0x3E8            # per element: the head's slot | 0x100 while there is a head

# the slot unit's I/O registers (bus addresses above the data memory)
SU_TA, SU_TB, SU_TWA, SU_TWB, SU_GO = 0x400, 0x401, 0x402, 0x403, 0x404
SU_X, SU_FLAGS, SU_MINC, SU_VALID = 0x405, 0x406, 0x407, 0x408
SU_CONF, SU_EDGE, SU_HEAD, SU_SENSOR = 0, 1 << 10, 2 << 10, 3 << 10   # SU_GO modes
SU_LATENCY = WSLOTS + 4   # clocks from SU_GO to the results (a slot per clock, four stages)
# outputs of IEL: a window slot written (fields, then the address commits it), a trigger
# (tick, then the element commits it), a head set for the close detector (tick, then element |
# slot << 8 commits it; element | 1 << 16: the element has no head)
W_T0, W_WS, W_WE, W_META, W_ADDR = 0x410, 0x411, 0x412, 0x413, 0x414
TRIG_T, TRIG_EL, HD_T, HD_EL = 0x418, 0x419, 0x41C, 0x41D
EVT_LO, EVT_HI = 0x420, 0x421   # an event word: low half, then the high half commits it
# the divider: DIV_X = dividend (< 2^24), DIV_N = divisor (1..15) starts it; DIV_Q = floor(x / n)
# DIV_LATENCY clocks later (a restoring divider, one quotient bit per clock)
DIV_X, DIV_N, DIV_Q = 0x428, 0x429, 0x42A
DIV_LATENCY = 26

# per-sensor words at SENS + 32 s
SENS = 0x000
S_DUE, S_QUIET, S_SEQ, S_FLAGS, S_OPEN, S_TRK, S_K, S_MODE = 0, 1, 3, 4, 5, 6, 18, 23
S_REINIT, S_SHARE = 22, 24
F_TRACKING, F_IN_INIT, F_EPOCH, F_ANY_TRK = 1, 2, 4, 8    # S_FLAGS bits
MISS_MAX = 15

# register conventions of the kernels
R_MASK24, R_SIGN24 = 28, 29   # constants 0xFFFFFF and 0x800000 (loaded by prologue())


def pack_rx(tracked: bool, tof: int, seq: int, v: int, miss: int = 0, init: bool = False,
            vel: bool = False) -> tuple[int, int]:
    """The two data-memory words of a receiver's tracking state (words A and B above)."""
    flags = int(tracked) | int(init) << 1 | int(vel) << 2 | (miss & 0xF) << 4
    return (tof & 0xFF_FFFF) | (seq & 0xFF) << 24, (v & 0xFF_FFFF) | flags << 24


def cand_clocks(n_rx: int = NUM_RX, seed: int = 1) -> int:
    """Clocks the CAND kernel takes for ``n_rx`` tracked receivers (random states)."""
    rng = random.Random(seed)
    mem = {}
    for r in range(n_rx):
        mem[TRK + 2 * r], mem[TRK + 2 * r + 1] = pack_rx(True, rng.randrange(40_000, 200_000), 7,
                                                         rng.randrange(-500, 501))
    p = prologue(Program("cand_clocks")).li(1, (1 << n_rx) - 1).li(2, TRK).li(3, 8)
    p.li(4, 30_000).li(5, 300_000)
    return run_kernel(p, cand_kernel, mem)[1]


def run_kernel(p: Program, kernel: Callable[[Program], Program], mem: dict[int, int] | None = None,
               slot_unit: "SlotUnit | None" = None, max_cycles: int = 1_000_000) -> tuple["EngineWithUnits", int]:
    """Append ``kernel`` and a halt to ``p`` (the caller's set-up: constants and inputs), run it
    on the engine's model with the unit models; the machine (its memory is ``mem``) and the
    kernel's clocks. A kernel that does not reach its end within ``max_cycles`` is an error."""
    p.label("kernel_start")
    kernel(p).label("kernel_halt").jmp("kernel_halt")
    img = p.assemble()
    m = EngineWithUnits(img.words, mem if mem is not None else {}, slot_unit)
    m.run(max_cycles, stop={img.labels["kernel_halt"]})
    if m.pc != img.labels["kernel_halt"]:
        raise UcodeError(f"{p.name}: {kernel.__name__} did not finish in {max_cycles} clocks")
    return m, m.cycle - img.labels["kernel_start"]


def prologue(p: Program) -> Program:
    """Constants every kernel relies on."""
    return p.li(R_MASK24, 0xFF_FFFF).li(R_SIGN24, 0x80_0000)


def cand_kernel(p: Program) -> Program:
    """CAND for a tracking sensor: for every receiver of the mask in r1 (ascending), if its
    tracking state (base address in r2) is tracked, the prediction for pulse seq r3 (8 bits),
    ``tof + gap * v`` with gap = (r3 - seq) mod 256, clamped to [r4, r5] (the sensor's
    te_limits), stored at CAND + r; r6 / r7 the least / greatest prediction (0x7FFFFFFF / 0
    when none), r8 the receivers that got one (one-hot bits), r9 how many. Model:
    FastFiringModel._predict and the te_min / te_max of _try_issue."""
    p.li(6, 0x7FFF_FFFF).li(7, 0).li(8, 0).li(9, 0)
    p.tst(1).b("eq", "cand_done")
    p.label("cand_loop")
    p.lsb(10, 1).addi(11, 1, -1)
    p.add(12, 10, 10).andn(13, 1, 11)      # 2 r, the receiver's one-hot bit
    p.add(12, 12, 2).and_(1, 1, 11)        # its state's address, the mask without it
    p.ld(14, 12, 0).ld(15, 12, 1)          # words A and B
    p.rotb(16, 15, 3).and_(19, 14, R_MASK24)   # flags byte; tof
    p.andi(16, 16, 1)
    p.b("eq", "cand_next")                 # not tracked: no window
    p.rotb(17, 14, 3).and_(18, 15, R_MASK24)   # seq byte; v (24 bits)
    p.andi(17, 17, 0xFF).xor(18, 18, R_SIGN24)
    p.sub(17, 3, 17).sub(18, 18, R_SIGN24)     # gap; v sign-extended
    p.andi(17, 17, 0xFF)
    p.mul(20, 17, 18)
    p.add(20, 20, 19)                      # prediction
    p.cmp(20, 4).b("ge", "cand_lo").mov(20, 4)           # clamp to [lo, hi]
    p.label("cand_lo").cmp(20, 5).b("le", "cand_hi").mov(20, 5)
    p.label("cand_hi").st(20, 10, CAND)
    p.cmp(20, 6).b("ge", "cand_min").mov(6, 20)           # te_min, te_max
    p.label("cand_min").cmp(20, 7).b("le", "cand_max").mov(7, 20)
    p.label("cand_max")
    p.or_(8, 8, 13).addi(9, 9, 1)
    p.label("cand_next").tst(1).b("ne", "cand_loop")
    p.label("cand_done")
    return p


# ------------------------------------------------------------------ CONF: the conflict scan
@dataclass
class Slot:
    start: int
    end: int
    close: int
    sensor: int = 0


@dataclass
class SlotUnit:
    """Model of the slot unit's contract (module docstring): ``slots[e * WSLOTS + k]`` the
    windows in the WIN memory; the element's valid slots are the SU_VALID mask the engine
    writes before SU_GO. Modes (SU_GO bits 11:10): SU_CONF (above); SU_EDGE, the slot whose
    [start, end) holds tick TA (SU_X, found: bit 0); SU_HEAD, the slot closing first after TA
    (SU_X, its close SU_MINC, found: bit 0); SU_SENSOR, the mask of the slots of sensor TA
    (SU_X)."""
    slots: dict[int, Slot] = field(default_factory=dict)
    regs: dict[int, int] = field(default_factory=dict)
    done_at: int = -1
    x: int = 0
    flags: int = 0
    minc: int = 0

    def write(self, cycle: int, addr: int, data: int) -> None:
        self.regs[addr] = data
        if addr != SU_GO:
            return
        e, bon, won, mode = data & 0xFF, data >> 8 & 1, data >> 9 & 1, data & (3 << 10)
        ta, tb, twa, twb = (self.regs.get(a, 0) for a in (SU_TA, SU_TB, SU_TWA, SU_TWB))
        valid = self.regs.get(SU_VALID, 0)
        ws = [(k, self.slots[e * WSLOTS + k]) for k in range(WSLOTS) if valid >> k & 1]
        self.x = self.flags = self.minc = 0
        if mode == SU_CONF:
            best = None
            for _, w in ws:
                for on, lo, hi in ((bon, ta, tb), (won, twa, twb)):
                    rel = sext(w.end - lo, 32)
                    if on and rel > 0 and sext(w.start - hi, 32) < 0:
                        best = rel if best is None else max(best, rel)
            self.x = (best or 0) & MASK32
            self.flags = int(best is not None) | int(bool(won) and len(ws) >= WSLOTS) << 1
            self.minc = min((w.close for _, w in ws), key=lambda c: sext(c - ta, 32), default=0) & MASK32
        elif mode == SU_EDGE:
            hold = [k for k, w in ws if sext(ta - w.start, 32) >= 0 and sext(ta - w.end, 32) < 0]
            self.x, self.flags = (hold[0], 1) if hold else (0, 0)
        elif mode == SU_HEAD:
            if ws:
                k, w = min(ws, key=lambda kw: sext(kw[1].close - ta, 32))
                self.x, self.minc, self.flags = k, w.close & MASK32, 1
        else:
            self.x = sum(1 << k for k, w in ws if w.sensor == ta)
        self.done_at = cycle + SU_LATENCY

    def read(self, cycle: int, addr: int) -> int:
        busy = cycle < self.done_at
        if addr == SU_FLAGS:
            return 0x80 if busy else self.flags
        if busy:   # results change when the scan completes: a program waits for busy to fall
            return 0xDEAD_BEEF
        return {SU_X: self.x, SU_MINC: self.minc}.get(addr, 0)


@dataclass
class Outputs:
    """What the kernels commit: window slots {address: (t0, ws, we, meta)}, triggers [(tick,
    element)], head sets [(element, slot, close tick)], event words, in order."""
    regs: dict[int, int] = field(default_factory=dict)
    slots: dict[int, tuple[int, int, int, int]] = field(default_factory=dict)
    triggers: list[tuple[int, int]] = field(default_factory=list)
    heads: list[tuple[int, int, int]] = field(default_factory=list)
    events: list[int] = field(default_factory=list)

    def write(self, addr: int, data: int) -> None:
        self.regs[addr] = data
        if addr == W_ADDR:
            self.slots[data] = tuple(self.regs.get(a, 0) for a in (W_T0, W_WS, W_WE, W_META))
        elif addr == TRIG_EL:
            self.triggers.append((self.regs.get(TRIG_T, 0), data))
        elif addr == HD_EL and data >> 16 & 1:   # the element has no head any more
            self.heads.append((data & 0xFF, None, None))
        elif addr == HD_EL:
            self.heads.append((data & 0xFF, data >> 8, self.regs.get(HD_T, 0)))
        elif addr == EVT_HI:
            self.events.append(data << 32 | self.regs.get(EVT_LO, 0))


@dataclass
class DivUnit:
    """Model of the divider's contract (DIV_* above): a read of DIV_Q before the quotient is
    ready returns garbage, so a program waits DIV_LATENCY clocks."""
    x: int = 0
    q: int = 0
    done_at: int = -1

    def write(self, cycle: int, addr: int, data: int) -> None:
        if addr == DIV_X:
            self.x = data & 0xFF_FFFF
        elif addr == DIV_N:
            self.q, self.done_at = self.x // max(1, data & 0xF), cycle + DIV_LATENCY

    def read(self, cycle: int) -> int:
        return self.q if cycle >= self.done_at else 0xDEAD_BEEF


class EngineWithUnits(Machine):
    """The engine's model with its data memory below 0x400, the slot unit and IEL's outputs
    above."""

    def __init__(self, words: list[int], mem: dict[int, int], slot_unit: SlotUnit | None = None,
                 outputs: Outputs | None = None) -> None:
        super().__init__(words, mem=mem)
        self.su = slot_unit if slot_unit is not None else SlotUnit()
        self.out = outputs if outputs is not None else Outputs()
        self.div = DivUnit()

    def read(self, addr: int) -> int:
        if addr == DIV_Q:
            return self.div.read(self.cycle + 1)
        return self.su.read(self.cycle + 1, addr) if addr >= SU_TA else super().read(addr)

    def write(self, addr: int, data: int) -> None:
        if addr in (DIV_X, DIV_N):
            self.div.write(self.cycle + 1, addr, data)
        elif addr >= W_T0:
            self.out.write(addr, data)
        elif addr >= SU_TA:
            self.su.write(self.cycle + 1, addr, data)
        else:
            super().write(addr, data)


def conf_kernel(p: Program) -> Program:
    """CONF: the conflict scan of a candidate pulse at t0 = r1 over the elements of mask r2
    (tx elements r3, elements with a window r4, with a blank interval r9): for a tx element its
    trigger t0 + a against tx_until, for a window element the window start t0 + wa against
    blank_until, then the slot unit over the element's reserved windows. The window of
    receiver e is [te - T_V, te + T_N) with te = CAND + e and T_V / T_N in r5 / r6. Result:
    r7 = 1 when the pulse conflicts, r8 the latest retry t0 (model FastFiringModel._conflict,
    None when r7 = 0)."""
    p.li(7, 0).li(8, 0)                        # r8: the retry relative to t0, while r7 = 1
    p.tst(2).b("eq", "conf_done")
    p.label("conf_loop")
    p.lsb(10, 2).addi(11, 2, -1)
    p.andn(12, 2, 11).and_(2, 2, 11)           # element's one-hot bit; the mask without it
    p.ld(13, 10, BA).ld(14, 10, BB)            # blank interval [a, b)
    p.ld(15, 10, CAND).ld(16, 10, TU)
    p.add(13, 13, 1).add(14, 14, 1)            # t0 + a, t0 + b
    p.sub(17, 15, 5).add(18, 15, 6)            # window offsets te - T_V, te + T_N
    p.st(13, 0, SU_TA).st(14, 0, SU_TB)
    p.add(17, 17, 1).add(18, 18, 1)            # t0 + wa, t0 + wb
    p.st(17, 0, SU_TWA).st(18, 0, SU_TWB)
    p.ld(24, 10, WV).mov(21, 10)
    p.st(24, 0, SU_VALID).and_(20, 12, 9)      # SU_GO: the element; blank on?
    p.b("eq", "conf_noblk").ori(21, 21, 0x100)
    p.label("conf_noblk").and_(20, 12, 4)      # window on?
    p.b("eq", "conf_nowin").ori(21, 21, 0x200)
    p.label("conf_nowin").and_(19, 12, 3)      # tx element?
    p.st(21, 0, SU_GO)                         # the slot unit scans while the rules below run
    p.tst(19).b("eq", "conf_notx")
    p.sub(22, 16, 13).b("le", "conf_notx")     # tx_until - (t0 + a) > 0: retry
    p.call("conf_fold")
    p.label("conf_notx").tst(20).b("eq", "conf_wait")
    p.ld(16, 10, BU).nop().nop()
    p.sub(22, 16, 17).b("le", "conf_wait")     # blank_until - (t0 + wa) > 0: retry
    p.call("conf_fold")
    p.label("conf_wait").ld(23, 0, SU_FLAGS).nop().nop()
    p.andi(0, 23, 0x80).b("ne", "conf_wait")
    p.andi(0, 23, 1).b("eq", "conf_full")
    p.ld(22, 0, SU_X).nop().nop()
    p.call("conf_fold")
    p.label("conf_full").andi(0, 23, 2).b("eq", "conf_next")
    p.ld(22, 0, SU_MINC).nop().nop()
    p.sub(22, 22, 1)                           # the earliest close, relative to t0
    p.call("conf_fold")
    p.label("conf_next").tst(2).b("ne", "conf_loop")
    p.jmp("conf_done")
    # r8 = max(r8, r22) with r7 = 1 (a retry relative to t0)
    p.label("conf_fold").tst(7).b("eq", "conf_take")
    p.cmp(22, 8).b("le", "conf_keep")
    p.label("conf_take").mov(8, 22).li(7, 1)
    p.label("conf_keep").ret()
    p.label("conf_done").add(8, 8, 1)          # the retry as a t0
    return p


def conf_clocks(n_el: int = NUM_RX, n_tx: int = 3, slots: int = WSLOTS) -> int:
    """Clocks the CONF kernel takes for a candidate touching ``n_el`` elements, all with a
    window, the first ``n_tx`` also tx elements, each holding ``slots`` reserved windows that
    it does not overlap (every rule checked, no conflict found)."""
    t, tv, tn = 1 << 24, 24_000, 24_000
    mem: dict[int, int] = {}
    su = SlotUnit()
    for e in range(n_el):
        mem[TU + e] = mem[BU + e] = t - 1000
        mem[CAND + e] = 200_000
        mem[BA + e], mem[BB + e] = 100 * e, 100 * e + 50_000
        for k in range(slots):
            su.slots[e * WSLOTS + k] = Slot(t - 10_000 * (k + 2), t - 10_000 * (k + 1), t)
        mem[WV + e] = (1 << slots) - 1
    allm, txm = (1 << n_el) - 1, (1 << n_tx) - 1
    p = prologue(Program("conf_clocks")).li(1, t).li(2, allm).li(3, txm).li(4, allm).li(5, tv)
    p.li(6, tn).li(9, txm)
    m, clocks = run_kernel(p, conf_kernel, mem, su, max_cycles=1_000_000)
    assert m.regs[7] == int(slots >= WSLOTS)   # only a full element can defer it
    return clocks


# ------------------------------------------------------------------ IEL: the issue's writes
def iel_kernel(p: Program) -> Program:
    """IEL, the writes of a pulse issued at t0 = r1 over the elements of mask r2 (tx r3, with a
    window r4, with a blank interval r9; T_V / T_N in r5 / r6, the window of element e being
    [te - T_V, te + T_N) with te = CAND + e; an init ping uses te = 0, T_V = -D, T_N = R):
    blank_until and (tx) tx_until = max(, t0 + b); a trigger at t0 + a per tx element; the
    window in the element's lowest free slot (WV), its fields from r1, the offsets and the
    meta word r24; the head (HC / HS and the close detector) when the new window closes first.
    Close tick = t0 + we + r25 (r25 = L - 1). Model: the issue part of _try_issue."""
    p.li(26, 16).li(27, 256)
    p.tst(2).b("eq", "iel_done")
    p.label("iel_loop")
    p.lsb(10, 2).addi(11, 2, -1)
    p.andn(12, 2, 11).and_(2, 2, 11)
    p.ld(13, 10, BB).ld(16, 10, BU)
    p.and_(20, 12, 9)
    p.b("eq", "iel_notx")                    # no blank interval: no tx either
    p.add(14, 13, 1)                         # t0 + b
    p.sub(0, 14, 16).b("le", "iel_bu")       # later than blank_until?
    p.st(14, 10, BU)
    p.label("iel_bu").and_(20, 12, 3)
    p.b("eq", "iel_notx")
    p.ld(16, 10, TU).ld(13, 10, BA).nop()
    p.add(15, 13, 1)                         # the trigger tick t0 + a
    p.sub(0, 14, 16).b("le", "iel_tu")       # later than tx_until?
    p.st(14, 10, TU)
    p.label("iel_tu").st(15, 0, TRIG_T).st(10, 0, TRIG_EL)
    p.label("iel_notx").and_(20, 12, 4)
    p.b("eq", "iel_next")
    p.ld(15, 10, CAND).ld(17, 10, WV)
    p.mul(28, 10, 26)                        # the element's first slot address, e * 16
    p.sub(18, 15, 5).add(19, 15, 6)          # ws, we
    p.xori(21, 17, -1)                       # free slots
    p.lsb(22, 21).addi(23, 21, -1)           # the lowest; its one-hot bit below
    p.andn(23, 21, 23).add(28, 28, 22)
    p.or_(17, 17, 23).add(30, 1, 19)
    p.st(17, 10, WV).st(1, 0, W_T0).st(18, 0, W_WS).st(19, 0, W_WE).st(24, 0, W_META)
    p.st(28, 0, W_ADDR).add(30, 30, 25)      # the window's close tick t0 + we - 1 + L
    p.ld(16, 10, HS).ld(13, 10, HC).nop()
    p.andi(0, 16, 0x100).b("eq", "iel_head")
    p.sub(0, 30, 13).b("ge", "iel_next")     # the head closes first: keep it
    p.label("iel_head").mul(29, 22, 27).st(30, 10, HC)
    p.ori(16, 22, 0x100).st(30, 0, HD_T)
    p.st(16, 10, HS).or_(29, 29, 10)
    p.st(29, 0, HD_EL)
    p.label("iel_next").tst(2).b("ne", "iel_loop")
    p.label("iel_done")
    return p


def iel_clocks(n_el: int = NUM_RX, n_tx: int = 3) -> int:
    """Clocks the IEL kernel takes for a pulse on ``n_el`` elements, all with a window (each
    element's head kept: its windows close earlier), the first ``n_tx`` also tx elements."""
    t = 1 << 24
    mem: dict[int, int] = {}
    for e in range(n_el):
        mem[TU + e] = mem[BU + e] = t - 1000
        mem[CAND + e] = 200_000
        mem[BA + e], mem[BB + e] = 100 * e, 100 * e + 50_000
        mem[WV + e], mem[HC + e], mem[HS + e] = 0b111, t + 10, 0x100
    allm, txm = (1 << n_el) - 1, (1 << n_tx) - 1
    p = prologue(Program("iel_clocks")).li(1, t).li(2, allm).li(3, txm).li(4, allm).li(9, txm)
    p.li(5, 24_000).li(6, 24_000).li(24, 0).li(25, 2)
    m, clocks = run_kernel(p, iel_kernel, mem, max_cycles=1_000_000)
    assert len(m.out.slots) == n_el and len(m.out.triggers) == n_tx
    return clocks


# ------------------------------------------------------------------ HIT: an echo in a window
def hit_kernel(p: Program) -> Program:
    """HIT, an edge at tick r1 in a window (t0 r2, pulse seq r3 (8 bits), flags r4: bit 0 init
    ping, bit 1 of the sensor's current epoch, bit 2 the window saw an echo before) of receiver
    r6 of sensor r7, tracking state at r5 (words A, B); gate r8 (0 off), v_max r9, T_E limits
    r10 / r11. The first echo writes its event word (docs/fast_firing.md section 6) and, for a
    window of the current epoch, updates the tracking state (an init ping's first echo starts
    the track; a tracking window's first echo is a sample if the pulse gap is 1..127, with
    velocity when the gap is 1 after a tracking sample) unless the gated miss rule rejects it
    (r12 = 1: then the window counts as a miss). A later echo does nothing. Model:
    FastFiringModel._rise and _sample (max_echoes_per_window = 1)."""
    p.li(12, 0).li(30, -0x2000_0000).li(17, 32)           # r30 = 0xE0000000
    p.andi(0, 4, 4).b("ne", "hit_done")                  # not the first echo: no event
    p.sub(14, 1, 2).andi(16, 3, 0xFF)
    p.and_(14, 14, R_MASK24).mul(16, 16, 17)             # tof; seq << 5
    p.rotb(15, 6, 1).rotb(16, 16, 1)                     # rx << 24; seq << 29 (bits 2:0 low, 7:3 high)
    p.and_(18, 16, 30).mul(20, 7, 17)                    # seq bits of the low half; sensor << 5
    p.or_(15, 15, 18).andi(19, 16, 0x1F)
    p.or_(15, 15, 14).or_(19, 19, 20)                    # low half; high half: seq, sensor
    p.andi(21, 4, 1).li(22, 2048)
    p.mul(21, 21, 22)                                    # init_ping << 11 (bit 43)
    p.ori(19, 19, 0x300)                                 # in_window, first_echo (bits 40, 41)
    p.or_(19, 19, 21)
    p.st(15, 0, EVT_LO).st(19, 0, EVT_HI)
    p.andi(0, 4, 2).b("eq", "hit_done")                  # an earlier epoch's window: no sample
    p.ld(23, 5, 0).ld(24, 5, 1)
    p.andi(0, 4, 1).b("ne", "hit_init")
    p.rotb(25, 24, 3).rotb(26, 23, 3)                    # flags byte; seq byte of the state
    p.andi(0, 25, 1).b("eq", "hit_done")                 # not tracked: no sample, no gate
    p.andi(26, 26, 0xFF).and_(18, 24, R_MASK24)
    p.sub(27, 3, 26).xor(18, 18, R_SIGN24)
    p.andi(27, 27, 0xFF).sub(18, 18, R_SIGN24)           # gap (8 bits); v
    p.and_(20, 23, R_MASK24)                             # the state's tof
    p.tst(8).b("eq", "hit_sample")                       # gate off
    p.andi(0, 25, 4).b("eq", "hit_sample")               # velocity not measured: no gate
    p.xori(21, 27, 0x80)
    p.addi(21, 21, -128)                                 # the gap, signed
    p.mul(22, 21, 18)
    p.add(22, 22, 20)                                    # prediction, then its clamp
    p.cmp(22, 10).b("ge", "hit_lo").mov(22, 10)
    p.label("hit_lo").cmp(22, 11).b("le", "hit_hi").mov(22, 11)
    p.label("hit_hi").sub(22, 14, 22).b("ge", "hit_abs").sub(22, 0, 22)
    p.label("hit_abs").cmp(22, 8).b("le", "hit_sample")
    p.li(12, 1).jmp("hit_done")                          # rejected: counts as a miss at close
    p.label("hit_sample").tst(27).b("eq", "hit_done")    # gap 0: no sample
    p.andi(0, 27, 0x80).b("ne", "hit_done")              # gap 128..255 (negative): no sample
    p.li(26, 0).li(21, 1)                                # v, flags: tracked
    p.cmpi(27, 1).b("ne", "hit_write")
    p.andi(0, 25, 2).b("ne", "hit_write")                # after the init ping's sample: no v
    p.sub(26, 14, 20).sub(22, 0, 9)                      # v = tof - last tof, within +-v_max
    p.cmp(26, 9).b("le", "hit_vhi").mov(26, 9)
    p.label("hit_vhi").cmp(26, 22).b("ge", "hit_vlo").mov(26, 22)
    p.label("hit_vlo").li(21, 5)                         # tracked, vel
    p.label("hit_write").andi(16, 3, 0xFF).and_(26, 26, R_MASK24)
    p.rotb(16, 16, 1).rotb(21, 21, 1)
    p.or_(23, 14, 16).or_(24, 26, 21)
    p.st(23, 5, 0).st(24, 5, 1).jmp("hit_done")
    p.label("hit_init").andi(16, 3, 0xFF).li(21, 3)      # an init ping's echo: tracked, init
    p.rotb(16, 16, 1).rotb(21, 21, 1)
    p.or_(23, 14, 16)
    p.st(23, 5, 0).st(21, 5, 1)
    p.label("hit_done")
    return p


def hit_clocks() -> int:
    """Clocks the HIT kernel takes for the longest common path: a tracking window's first
    echo, velocity measured, checked by the gate and taken as a sample with velocity."""
    t0, k = 1 << 24, 500
    a, b = pack_rx(True, 100_000, k - 1, 40, vel=True)
    mem = {TRK: a, TRK + 1: b}
    p = prologue(Program("hit_clocks")).li(1, t0 + 100_100).li(2, t0).li(3, k & 0xFF).li(4, 2)
    p.li(5, TRK).li(6, 0).li(7, 0).li(8, 2400).li(9, 24_000).li(10, 30_000).li(11, 300_000)
    p
    m, clocks = run_kernel(p, hit_kernel, mem, max_cycles=10_000)
    assert len(m.out.events) == 1 and m.regs[12] == 0 and m.mem[TRK + 1] >> 24 == 5
    return clocks


# ------------------------------------------------------------------ CLOSE: a window's result
def close_kernel(p: Program) -> Program:
    """CLOSE of the head window of receiver r6 at tick r1: window t0 r2, end offset r3, pulse
    seq r4 (8 bits), flags r5 (bit 0 init ping, bit 1 saw an echo, bit 2 that echo was
    rejected by the gate, bit 3 the window's epoch), sensor r7 (its words at r8 = SENS + 32 s),
    tracking state at r9. An empty window writes its event word; an empty or rejected tracking
    window of the current epoch counts a miss, and K misses while tracking end the tracking
    (due = min(due, now); r10 = 1: the caller cancels the sensor's windows); the last open
    window of an init ping ends the init phase (tracking if the mode is track and a receiver
    got an echo). Model: FastFiringModel._on_close."""
    p.li(10, 0).li(17, 32).li(22, 2048)
    p.ld(11, 8, S_FLAGS).andi(0, 5, 2)
    p.b("ne", "close_hit")                              # an echo came: no event
    p.andi(14, 4, 0xFF).andi(15, 5, 1)                  # the empty window's event word
    p.mul(14, 14, 17).mul(15, 15, 22)                   # seq << 5; init_ping << 11
    p.and_(12, 3, R_MASK24).rotb(13, 6, 1)              # tof = end - t0; rx << 24
    p.rotb(14, 14, 1).mul(16, 7, 17)                    # seq << 29; sensor << 5
    p.or_(12, 12, 13).li(13, -0x2000_0000)
    p.and_(13, 14, 13).andi(14, 14, 0x1F)
    p.or_(12, 12, 13).or_(14, 14, 16)
    p.ori(14, 14, 0x400).or_(14, 14, 15)                # window_empty (bit 42), init_ping
    p.st(12, 0, EVT_LO).st(14, 0, EVT_HI)
    p.jmp("close_miss")
    p.label("close_hit").andi(0, 5, 4).b("eq", "close_init")   # a sample: no miss
    p.label("close_miss").andi(0, 5, 1).b("ne", "close_init")  # init pings count no misses
    p.andi(12, 11, F_EPOCH).andi(13, 5, 8)
    p.add(12, 12, 12)                                   # the sensor's epoch at bit 3
    p.xor(0, 12, 13).b("ne", "close_done")              # an earlier epoch's window
    p.ld(12, 9, 1).ld(14, 8, S_K).nop()
    p.rotb(13, 12, 3)
    p.andi(15, 13, 0xF0)                                # miss count << 4 (flags byte)
    p.cmpi(15, 0xF0).b("eq", "close_sat")               # saturated at 15
    p.addi(15, 15, 0x10).li(16, 0x1000_0000)
    p.add(12, 12, 16)                                   # miss + 1 in word B (bits 31:28)
    p.st(12, 9, 1)
    p.label("close_sat").add(14, 14, 14)
    p.add(14, 14, 14).andi(0, 11, F_TRACKING)
    p.b("eq", "close_done")                             # not tracking: no safety
    p.add(14, 14, 14)
    p.add(14, 14, 14)                                   # K << 4
    p.sub(0, 15, 14).b("lt", "close_done")              # fewer than K misses
    p.andi(11, 11, ~F_TRACKING).li(10, 1)      # safety: re-initialise now
    p.ld(12, 8, S_DUE).st(11, 8, S_FLAGS).nop()
    p.sub(0, 1, 12).b("ge", "close_done")
    p.st(1, 8, S_DUE).jmp("close_done")                 # due = min(due, now)
    p.label("close_init").andi(0, 5, 1).b("eq", "close_done")
    p.andi(12, 11, F_EPOCH).andi(13, 5, 8)
    p.add(12, 12, 12)
    p.xor(0, 12, 13).b("ne", "close_done")              # an earlier epoch's init ping
    p.ld(12, 8, S_OPEN).nop().nop()
    p.addi(12, 12, -1)
    p.st(12, 8, S_OPEN).b("ne", "close_done")           # windows of the init ping still open
    p.ld(13, 8, S_MODE).andi(11, 11, ~(F_IN_INIT | F_TRACKING))
    p.andi(14, 11, F_ANY_TRK)
    p.b("eq", "close_flags")
    p.cmpi(13, 1).b("ne", "close_flags")
    p.ori(11, 11, F_TRACKING)                           # track mode and an echo: tracking
    p.label("close_flags").st(11, 8, S_FLAGS)
    p.label("close_done")
    return p


def close_clocks() -> int:
    """Clocks the CLOSE kernel takes for its longest path: an empty tracking window whose
    miss reaches K (event word, miss count, safety, due)."""
    now, k = 1 << 24, 3
    a, b = pack_rx(True, 100_000, 7, 0, miss=k - 1)
    mem = {TRK: a, TRK + 1: b, SENS + S_DUE: now + 10, SENS + S_FLAGS: F_TRACKING, SENS + S_K: k,
           SENS + S_MODE: 1}
    p = prologue(Program("close_clocks")).li(1, now).li(2, now - 150_000).li(3, 124_000).li(4, 7)
    p.li(5, 0).li(6, 0).li(7, 0).li(8, SENS).li(9, TRK)
    m, clocks = run_kernel(p, close_kernel, mem, max_cycles=10_000)
    assert len(m.out.events) == 1 and m.regs[10] == 1 and m.mem[SENS + S_DUE] == now
    return clocks


# ------------------------------------------------------------------ ISSUE: the sensor's state
def issue_kernel(p: Program) -> Program:
    """ISSUE, the sensor's side of a pulse issued at t0 = r1 by sensor r7 (words at r8): the
    pulse record (docs/fast_firing.md section 6; n_win r3, init ping r4 = 1), then pulse id + 1;
    an init ping flips the epoch, starts the init phase with r3 open windows, clears the
    tracking pulse count and the tracking states of the receivers in mask r6 (at r9 + 2 r);
    a tracking pulse counts (saturating at 255); due = t0 + period r2, quiet = t0 + r5 (max
    ToF - D). Model: the issue part of FastFiringModel._try_issue."""
    p.ld(10, 8, S_SEQ).ld(11, 8, S_FLAGS).li(17, 32)
    p.li(12, 2048).li(13, 8192)
    p.mul(14, 7, 17).mul(15, 4, 12)                     # sensor << 5; init_ping << 11
    p.mul(16, 10, 13).or_(14, 14, 3)                    # pulse id << 13; n_win
    p.or_(14, 14, 15).lui(18, 0x40000)                  # bit 62 of the word: bit 30 of the high half
    p.or_(14, 14, 16)
    p.or_(14, 14, 18)
    p.st(1, 0, EVT_LO).st(14, 0, EVT_HI)
    p.addi(10, 10, 1).li(19, 0xFFFF)
    p.add(12, 1, 2).add(13, 1, 5)                       # due, quiet
    p.and_(10, 10, 19)                                  # the pulse id wraps at 2^16
    p.st(10, 8, S_SEQ).st(12, 8, S_DUE).st(13, 8, S_QUIET)
    p.tst(4).b("eq", "issue_track")
    p.xori(11, 11, F_EPOCH)
    p.andi(11, 11, ~(F_TRACKING | F_ANY_TRK))
    p.ori(11, 11, F_IN_INIT)
    p.st(11, 8, S_FLAGS).st(3, 8, S_OPEN).st(0, 8, S_TRK)
    p.tst(6).b("eq", "issue_done")
    p.label("issue_rx").lsb(10, 6).addi(11, 6, -1)
    p.add(12, 10, 10)
    p.add(12, 12, 9).and_(6, 6, 11)                     # the state's address; the mask without r
    p.st(0, 12, 0).st(0, 12, 1).b("ne", "issue_rx")     # (flags of the mask's and)
    p.jmp("issue_done")
    p.label("issue_track").ld(10, 8, S_TRK).nop().nop()
    p.cmpi(10, 255).b("eq", "issue_done")
    p.addi(10, 10, 1)
    p.st(10, 8, S_TRK)
    p.label("issue_done")
    return p


# ------------------------------------------------------------------ SCHED: may the sensor decide?
SCHED_NOT_YET, SCHED_QUIET, SCHED_HOLD, SCHED_GO = 0, 1, 2, 3


def sched_kernel(p: Program) -> Program:
    """SCHED, whether sensor r7 (words at r8) decides at tick r1 for t0 = r1 + P (P in r2):
    r10 = SCHED_NOT_YET (in its init phase, or not due by t0), SCHED_QUIET (an init ping
    before its quiet tick: r11 = the quiet tick, the retry t0), SCHED_HOLD (a sensor sharing an
    element is eligible with an earlier (due, id)) or SCHED_GO (on to the candidate; r12 = 1
    for an init ping). A tracking sensor with M = reinit_every tracking pulses since its init
    ping stops tracking first (r13 = 1: the caller cancels its windows). Model: the part of
    FastFiringModel._try_issue before the candidate, with _eligible."""
    p.li(10, SCHED_NOT_YET).li(13, 0).li(12, 0)
    p.add(14, 1, 2).ld(11, 8, S_FLAGS).ld(20, 8, S_DUE)   # t0 = now + P
    p.nop()
    p.andi(0, 11, F_IN_INIT).b("ne", "sched_done")
    p.sub(0, 14, 20).b("lt", "sched_done")                # not due by t0
    p.andi(0, 11, F_TRACKING).b("eq", "sched_init")
    p.ld(15, 8, S_REINIT).ld(16, 8, S_TRK).nop()
    p.tst(15).b("eq", "sched_edf")                        # reinit_every off
    p.sub(0, 16, 15).b("lt", "sched_edf")
    p.andi(11, 11, ~F_TRACKING).li(13, 1)                 # forced re-initialisation
    p.st(11, 8, S_FLAGS)
    p.label("sched_init").ld(15, 8, S_QUIET).li(12, 1).nop()
    p.sub(0, 14, 15).b("ge", "sched_edf")
    p.li(10, SCHED_QUIET).mov(11, 15).jmp("sched_done")
    p.label("sched_edf").ld(16, 8, S_SHARE).li(17, 32)
    p.label("sched_o").tst(16).b("eq", "sched_go")
    p.lsb(18, 16).addi(19, 16, -1)
    p.mul(21, 18, 17).and_(16, 16, 19)                    # o's words; the mask without o
    p.ld(22, 21, SENS + S_FLAGS).ld(23, 21, SENS + S_DUE).ld(24, 21, SENS + S_QUIET)
    p.andi(0, 22, F_IN_INIT).b("ne", "sched_o")           # o waits for its init result
    p.sub(0, 14, 23).b("lt", "sched_o")                   # o not due by t0
    p.andi(0, 22, F_TRACKING).b("ne", "sched_elig")
    p.sub(0, 14, 24).b("lt", "sched_o")                   # o's init ping still quiet
    p.label("sched_elig").sub(0, 23, 20).b("lt", "sched_hold")   # o due earlier
    p.b("ne", "sched_o")
    p.sub(0, 18, 7).b("ge", "sched_o")                    # the same due: the lower id first
    p.label("sched_hold").li(10, SCHED_HOLD).jmp("sched_done")
    p.label("sched_go").li(10, SCHED_GO)
    p.label("sched_done")
    return p


# ------------------------------------------------------------------ ORDER: the effective order
def order_kernel(p: Program) -> Program:
    """ORDER, the largest n <= order r1 whose interlacing is feasible for predictions te_min r2
    .. te_max r3 (T_V r4, T_N r5, blanking D r6): T_s = floor((te_min - T_V - D) / n) > 0 and
    (n + 1) T_s >= te_max + T_N, tried from n = order down (the divider gives each T_s). Result:
    r7 = n (0: none), r8 = the period (T_s, or te_max + T_N for n = 0). Model:
    schedule.effective_order and pulse_period."""
    p.sub(9, 2, 4).add(10, 3, 5)                   # te_min - T_V; te_max + T_N
    p.mov(7, 1).mov(8, 10)                         # n = order
    p.sub(9, 9, 6).b("le", "order_none")           # x = te_min - T_V - D <= 0: no T_s > 0
    p.st(9, 0, DIV_X)
    p.label("order_try").tst(7).b("eq", "order_none")
    p.st(7, 0, DIV_N).li(11, DIV_LATENCY // 3)
    p.label("order_wait").addi(11, 11, -1).nop().b("gt", "order_wait")
    p.ld(12, 0, DIV_Q).mov(13, 7).li(14, 0)
    p.label("order_mul").add(14, 14, 12).addi(13, 13, -1)   # (n + 1) T_s by n + 1 additions
    p.b("ge", "order_mul")
    p.tst(12).b("eq", "order_next")                # T_s = 0: infeasible
    p.sub(0, 14, 10).b("lt", "order_next")
    p.mov(8, 12).jmp("order_done")
    p.label("order_next").addi(7, 7, -1).jmp("order_try")
    p.label("order_none").li(7, 0).mov(8, 10)
    p.label("order_done")
    return p


def order_clocks(tries: int = 1) -> int:
    """Clocks the ORDER kernel takes when the ``tries``-th order it tries (from 8 down) is the
    first feasible one."""
    tv = tn = d = 10_000
    n = 9 - tries
    te = min_tof_for_order(n, tv, tn, d)
    p = prologue(Program("order_clocks")).li(1, 8).li(2, te).li(3, te).li(4, tv).li(5, tn).li(6, d)
    p
    m, clocks = run_kernel(p, order_kernel, {}, max_cycles=100_000)
    assert m.regs[7] == n
    return clocks


# ------------------------------------------------------------------ the slot unit's other scans
def _su_scan(p: Program, tag: str, el: int, ta: int, mode: int) -> Program:
    """Start the slot unit on element register ``el`` (its valid slots from WV) with TA from
    register ``ta`` in ``mode``, and wait for it; r23 = SU_FLAGS. Uses r20, r21."""
    p.ld(20, el, WV).ori(21, el, mode)
    p.st(20, 0, SU_VALID).st(ta, 0, SU_TA).st(21, 0, SU_GO)
    p.label(f"{tag}_wait").ld(23, 0, SU_FLAGS).nop().nop()
    p.andi(0, 23, 0x80).b("ne", f"{tag}_wait")
    return p


def edge_kernel(p: Program) -> Program:
    """EDGE, the window of receiver r6 holding the edge timestamp r1: r10 = its slot, or -1
    outside every window (the edge is gated). Model: the window search of FastFiringModel._rise."""
    _su_scan(p, "edge", 6, 1, SU_EDGE)
    p.li(10, -1).andi(0, 23, 1)
    p.b("eq", "edge_done")
    p.ld(10, 0, SU_X)
    p.label("edge_done")
    return p


def _head_rescan(p: Program, tag: str) -> Program:
    """Element r6's head after its windows changed: the slot closing first after tick r1, into
    HC / HS and to the close detector, or no head. Uses r20-r23, r25, r26."""
    _su_scan(p, tag, 6, 1, SU_HEAD)
    p.andi(0, 23, 1).b("eq", f"{tag}_none")
    p.ld(25, 0, SU_X).ld(26, 0, SU_MINC).li(21, 256)
    p.ori(20, 25, 0x100).mul(21, 25, 21)
    p.st(26, 6, HC).st(20, 6, HS).or_(21, 21, 6)
    p.st(26, 0, HD_T).st(21, 0, HD_EL).jmp(f"{tag}_done")
    p.label(f"{tag}_none").lui(21, 0x10).st(0, 6, HS)       # 1 << 16: no head
    p.or_(21, 21, 6)
    p.st(21, 0, HD_EL)
    p.label(f"{tag}_done")
    return p


def head_kernel(p: Program) -> Program:
    """HEAD, element r6's next window to close (after its head closed at tick r1, its slot
    cleared from WV): the earliest close of its remaining windows, or none. Model: the
    element's windows after FastFiringModel._on_close removes one."""
    return _head_rescan(p, "head")


def safe_kernel(p: Program) -> Program:
    """SAFE, the cancel of sensor r7 at tick r1: the cancel record (docs/fast_firing.md section
    6), then on every element the sensor's windows leave WV. Heads stay as they are (as in
    ms_scheduler): a cancelled head still reaches its close tick, where the caller finds its
    slot no longer valid, writes nothing for it and runs HEAD. Model: FastFiringModel._cancel."""
    p.li(17, 32).lui(18, 0x60000)                           # bits 62, 61: bits 30, 29 of the high half
    p.mul(19, 7, 17)
    p.or_(19, 19, 18)                                       # sensor << 5 (bit 37)
    p.st(1, 0, EVT_LO).st(19, 0, EVT_HI)
    p.li(6, NUM_RX - 1)
    p.label("safe_el")
    _su_scan(p, "safe_scan", 6, 7, SU_SENSOR)
    p.ld(22, 0, SU_X).ld(24, 6, WV).nop()
    p.andn(24, 24, 22)
    p.st(24, 6, WV).addi(6, 6, -1).nop().b("ge", "safe_el")
    return p


def scan_clocks() -> dict[str, int]:
    """Clocks of EDGE (an edge in a window), HEAD (a new head found) and SAFE (24 elements,
    every one holding windows of the cancelled sensor)."""
    t = 1 << 24
    su, mem = SlotUnit(), {}
    for e in range(NUM_RX):
        for k in range(4):
            su.slots[e * WSLOTS + k] = Slot(t + 1000 * k, t + 1000 * k + 500, t + 1000 * k + 502, k % 2)
        mem[WV + e], mem[HS + e], mem[HC + e] = 0b1111, 0x100 | (e % 2), t + 1000 * (e % 2) + 502
    out = {}
    p = prologue(Program("edge_clocks")).li(1, t + 2100).li(6, 0)
    m, out["edge"] = run_kernel(p, edge_kernel, dict(mem), su)
    assert m.regs[10] == 2
    p = prologue(Program("head_clocks")).li(1, t).li(6, 0)
    m, out["head"] = run_kernel(p, head_kernel, dict(mem), su)
    assert m.mem[HS] == 0x100
    p = prologue(Program("safe_clocks")).li(1, t).li(7, 1)
    m, out["safe"] = run_kernel(p, safe_kernel, dict(mem), su)
    assert all(m.mem[WV + e] == 0b0101 for e in range(NUM_RX))
    return out
