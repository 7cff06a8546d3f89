"""Microcode kernels of the scheduler for the engine core (docs/sched_engine.md), with the data
memory layout they assume. Each kernel is checked against the golden model
(multisonar.fastfiring) in tests/test_sched_program.py and timed in clocks by
scripts/bench_sched_engine.py: the figures that say which of the scheduler's loops the
engine can run within the decision lead and which need a fixed stream unit.

Data memory (32-bit words): the tracking state of (sensor s, receiver r) at
``TRK + 2 * (24 s + r)``: word A = tof[23:0] | seq[7:0] << 24, word B = v[23:0] (two's
complement) | flags << 24 (bit 24 tracked, 25 init, 26 vel, 31:28 miss count); the candidate's
predicted T_E of receiver r at ``CAND + r``.
"""

from __future__ import annotations

from .sched_ucode import Program

NUM_RX = 24
TRK = 0x100           # tracking state, 2 words per (sensor, receiver): 0x100..0x27F
CAND = 0x3A0          # candidate T_E per receiver

# register conventions of the kernels
R_MASK24, R_SIGN24 = 28, 29   # constants 0xFFFFFF and 0x800000 (loaded by prologue())


def pack_rx(tracked: bool, tof: int, seq: int, v: int, miss: int = 0, init: bool = False,
            vel: bool = False) -> tuple[int, int]:
    """The two data-memory words of a receiver's tracking state (words A and B above)."""
    flags = int(tracked) | int(init) << 1 | int(vel) << 2 | (miss & 0xF) << 4
    return (tof & 0xFF_FFFF) | (seq & 0xFF) << 24, (v & 0xFF_FFFF) | flags << 24


def cand_clocks(n_rx: int = NUM_RX, seed: int = 1) -> int:
    """Clocks the CAND kernel takes for ``n_rx`` tracked receivers (random states)."""
    import random

    from .sched_ucode import Machine

    rng = random.Random(seed)
    mem = {}
    for r in range(n_rx):
        mem[TRK + 2 * r], mem[TRK + 2 * r + 1] = pack_rx(True, rng.randrange(40_000, 200_000), 7,
                                                         rng.randrange(-500, 501))
    p = prologue(Program("cand_clocks")).li(1, (1 << n_rx) - 1).li(2, TRK).li(3, 8)
    p.li(4, 30_000).li(5, 300_000).label("start")
    cand_kernel(p).label("halt").jmp("halt")
    img = p.assemble()
    m = Machine(img.words, mem=mem)
    m.run(1_000_000, stop={img.labels["halt"]})
    return m.cycle - img.labels["start"]


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
