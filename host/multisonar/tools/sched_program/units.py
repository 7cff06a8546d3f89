"""Models of the fixed units and outputs the kernels drive through I/O registers (the slot
unit, the divider, the output strobes), the engine's model with them, and run_kernel.

The slot unit (:class:`SlotUnit`, a fixed stream unit the engine drives through I/O
registers) scans the valid ones of the up to 16 reserved windows of one element, one per
clock (results five clocks after the last; SU_LATENCY with every slot valid), against the
candidate's blank interval [TA, TB) and window [TWA, TWB) (absolute ticks, written before
SU_GO = element | blank on << 8 | window on << 9) and gives, when busy falls, SU_X =
the latest retry relative to TA / TWA among the windows it overlaps (end - TA, end - TWA),
SU_FLAGS bit 0 = any overlap, bit 1 = every slot taken (window on), bit 7 = busy, and SU_MINC
= the earliest close tick of the element's windows.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from ..sched_ucode import MASK32, Machine, Program, UcodeError, sext
from .layout import (DIV_LATENCY, DIV_N, DIV_Q, DIV_STAT, DIV_X, EVT_HI, EVT_LO, HD_EL, HD_T,
                     SU_CONF, SU_EDGE, SU_FLAGS, SU_GO, SU_HEAD, SU_LATENCY, SU_MINC, SU_TA, SU_TB,
                     SU_TWA, SU_TWB, SU_VALID, SU_X, TRIG_EL, TRIG_T, WSLOTS, W_ADDR, W_META, W_T0,
                     W_WE)


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
        self.done_at = cycle + len(ws) + SU_LATENCY - WSLOTS   # a valid slot per clock

    def read(self, cycle: int, addr: int) -> int:
        busy = cycle < self.done_at
        if addr == SU_FLAGS:
            return 0x80 if busy else self.flags
        if busy:   # results change when the scan completes: a program waits for busy to fall
            return 0xDEAD_BEEF
        return {SU_X: self.x, SU_MINC: self.minc}.get(addr, 0)


@dataclass
class Outputs:
    """What the kernels commit: window slots {address: (t0, we, meta)}, triggers [(tick,
    element)], head sets [(element, slot, close tick)], event words, in order."""
    regs: dict[int, int] = field(default_factory=dict)
    slots: dict[int, tuple[int, int, int]] = field(default_factory=dict)
    triggers: list[tuple[int, int]] = field(default_factory=list)
    heads: list[tuple[int, int, int]] = field(default_factory=list)
    events: list[int] = field(default_factory=list)

    def write(self, addr: int, data: int) -> None:
        self.regs[addr] = data
        if addr == W_ADDR:
            self.slots[data] = tuple(self.regs.get(a, 0) for a in (W_T0, W_WE, W_META))
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
    """Model of the divider's contract (DIV_* above): DIV_STAT reads 0x80 (busy) for
    DIV_LATENCY clocks after a start, and a read of DIV_Q before then returns garbage."""
    x: int = 0
    q: int = 0
    done_at: int = -1

    def write(self, cycle: int, addr: int, data: int) -> None:
        if addr == DIV_X:
            self.x = data & 0xFF_FFFF
        elif addr == DIV_N:
            self.q, self.done_at = self.x // max(1, data & 0xF), cycle + DIV_LATENCY

    def read(self, cycle: int, addr: int = DIV_Q) -> int:
        if addr == DIV_STAT:
            return 0x80 if cycle < self.done_at else 0
        return self.q if cycle >= self.done_at else 0xDEAD_BEEF


class EngineWithUnits(Machine):
    """The engine's model with its data memory below 0x400, the slot unit and IEL's outputs
    above."""

    def __init__(self, words: list[int], mem: dict[int, int], slot_unit: SlotUnit | None = None,
                 outputs: Outputs | None = None) -> None:
        super().__init__(words, mem=mem, indexed_store_limit=SU_TA)
        self.su = slot_unit if slot_unit is not None else SlotUnit()
        self.out = outputs if outputs is not None else Outputs()
        self.div = DivUnit()

    def read(self, addr: int) -> int:
        if addr in (DIV_Q, DIV_STAT):
            return self.div.read(self.cycle + 1, addr)
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
