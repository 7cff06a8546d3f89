"""Clocks of the kernels on representative loads, the figures of scripts/bench_sched_engine.py
(each checks its own result)."""

from __future__ import annotations

import random

from ...schedule import min_tof_for_order
from ..sched_ucode import Program
from .layout import (BA, BB, BU, CAND, F_TRACKING, HC, HS, NUM_RX, SENS, S_DUE, S_FLAGS, S_K,
                     S_MODE, TRK, TU, WSLOTS, WV, pack_rx, prologue)
from .units import Slot, SlotUnit, run_kernel
from .decision import cand_kernel, conf_kernel, iel_kernel, order_kernel
from .events import close_kernel, edge_kernel, head_kernel, hit_kernel, safe_kernel


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


def _candidate_elements(mem: dict[int, int], n_el: int, t: int) -> None:
    """Elements 0..n_el-1 of a candidate at t0 = t: reservations over before it, T_E 200,000,
    blank intervals [100 e, 100 e + 50,000)."""
    for e in range(n_el):
        mem[TU + e] = mem[BU + e] = t - 1000
        mem[CAND + e] = 200_000
        mem[BA + e], mem[BB + e] = 100 * e, 100 * e + 50_000


def conf_clocks(n_el: int = NUM_RX, n_tx: int = 3, slots: int = WSLOTS) -> int:
    """Clocks the CONF kernel takes for a candidate touching ``n_el`` elements, all with a
    window, the first ``n_tx`` also tx elements, each holding ``slots`` reserved windows that
    it does not overlap (every rule checked, no conflict found)."""
    t, tv, tn = 1 << 24, 24_000, 24_000
    mem: dict[int, int] = {}
    su = SlotUnit()
    _candidate_elements(mem, n_el, t)
    for e in range(n_el):
        for k in range(slots):
            su.slots[e * WSLOTS + k] = Slot(t - 10_000 * (k + 2), t - 10_000 * (k + 1), t)
        mem[WV + e] = (1 << slots) - 1
    allm, txm = (1 << n_el) - 1, (1 << n_tx) - 1
    p = prologue(Program("conf_clocks")).li(1, t).li(2, allm).li(3, txm).li(4, allm).li(5, tv)
    p.li(6, tn).li(9, txm)
    m, clocks = run_kernel(p, conf_kernel, mem, su)
    assert m.regs[7] == int(slots >= WSLOTS)   # only a full element can defer it
    return clocks


def iel_clocks(n_el: int = NUM_RX, n_tx: int = 3) -> int:
    """Clocks the IEL kernel takes for a pulse on ``n_el`` elements, all with a window (each
    element's head kept: its windows close earlier), the first ``n_tx`` also tx elements."""
    t = 1 << 24
    mem: dict[int, int] = {}
    _candidate_elements(mem, n_el, t)
    for e in range(n_el):
        mem[WV + e], mem[HC + e], mem[HS + e] = 0b111, t + 10, 0x100
    allm, txm = (1 << n_el) - 1, (1 << n_tx) - 1
    p = prologue(Program("iel_clocks")).li(1, t).li(2, allm).li(3, txm).li(4, allm).li(9, txm)
    p.li(5, 24_000).li(6, 24_000).li(24, 0).li(25, 2)
    m, clocks = run_kernel(p, iel_kernel, mem)
    assert len(m.out.slots) == n_el and len(m.out.triggers) == n_tx
    return clocks


def hit_clocks() -> int:
    """Clocks the HIT kernel takes for the longest common path: a tracking window's first
    echo, velocity measured, checked by the gate and taken as a sample with velocity."""
    t0, k = 1 << 24, 500
    a, b = pack_rx(True, 100_000, k - 1, 40, vel=True)
    mem = {TRK: a, TRK + 1: b}
    p = prologue(Program("hit_clocks")).li(1, t0 + 100_100).li(2, t0).li(3, k & 0xFF).li(4, 2)
    p.li(5, TRK).li(6, 0).li(7, 0).li(8, 2400).li(9, 24_000).li(10, 30_000).li(11, 300_000)
    m, clocks = run_kernel(p, hit_kernel, mem, max_cycles=10_000)
    assert len(m.out.events) == 1 and m.regs[12] == 0 and m.mem[TRK + 1] >> 24 == 5
    return clocks


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


def order_clocks(tries: int = 1) -> int:
    """Clocks the ORDER kernel takes when the ``tries``-th order it tries (from 8 down) is the
    first feasible one."""
    tv = tn = d = 10_000
    n = 9 - tries
    te = min_tof_for_order(n, tv, tn, d)
    p = prologue(Program("order_clocks")).li(1, 8).li(2, te).li(3, te).li(4, tv).li(5, tn).li(6, d)
    m, clocks = run_kernel(p, order_kernel, {}, max_cycles=100_000)
    assert m.regs[7] == n
    return clocks


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
