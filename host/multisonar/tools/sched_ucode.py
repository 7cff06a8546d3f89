"""The scheduler engine's microcode: instruction set, assembler and instruction-set simulator.

One source for the engine's instruction set (docs/sched_engine.md): the RTL decoder
(rtl/core/ms_sched_engine.sv) reads the opcodes from the SystemVerilog package this module
writes in the ``make`` gen step, programs are built with :class:`Program` and assembled into
the ``$readmemh`` image of the engine's microcode ROM, and :class:`Machine` runs an image
clock by clock as the RTL does (the engine's scoreboard compares the two).

    python -m multisonar.tools.sched_ucode --pkg build/gen/rtl/ms_ucode_pkg.sv

Instruction word (36 bits, one DP16KD word): op[35:30] rd[29:25] ra[24:20] rb[19:15]
imm[14:0]. 32 registers of 32 bits, r0 reads 0 and ignores writes. One instruction per clock,
no interlocks: a result (ALU or load) and the flags are usable from the second instruction
after the one producing them; :meth:`Program.assemble` inserts a NOP where the next
instruction would read too early (only neighbours in address order can: a taken branch puts
itself between its predecessor and the target). ``b`` resolves in one clock on the flags, no
delay slot. The compare-and-branch instructions (``cb``, ``cbi``, ``cbb``, ``cbt``) set the
flags as their ALU operation would and resolve two clocks later: when taken, the two
instructions after them in address order are squashed (no effect at all) and the target
follows three clocks after the branch; not taken, they cost one clock. :meth:`Program.b`
fuses a flag-only compare right before it into one of them (a ``sub``, ``tst``, ``cmpi`` with
a small immediate, single-bit ``andi`` or ``and`` with rd = r0: the same flags, one word
instead of three with the hazard NOP).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable

WORD_BITS = 36
NREGS = 32
IMM_BITS = 15
MASK32 = 0xFFFF_FFFF

# opcode -> (code, format). Formats: "r" rd = ra op rb; "i" rd = ra op sext(imm15);
# "u" rd = imm20 << 12 (imm20 = {rb, imm}); "x" rd = ra rotated right by imm[1:0] bytes;
# "l" rd = bus[ra + sext(imm)]; "s" bus[ra + sext(imm)] = rb; "b" branch (rd = condition,
# imm = target); "c" call (imm = target); "n" no operands; compare-and-branch (rd = condition,
# imm[10:0] = target): "cb" flags of ra - rb, "ci" flags of ra - k (k: signed 9 bits, {rb,
# imm[14:11]}), "cq" flags of ra & (1 << rb), "ct" flags of ra & rb.
OPCODES: dict[str, tuple[int, str]] = {
    "nop":  (0, "n"),
    "add":  (1, "r"), "sub": (2, "r"), "and": (3, "r"), "or": (4, "r"), "xor": (5, "r"),
    "andn": (6, "r"),   # ra & ~rb
    "mul":  (7, "r"),   # low 32 bits of signed ra[17:0] * signed rb[17:0]
    "addi": (8, "i"), "andi": (9, "i"), "ori": (10, "i"), "xori": (11, "i"),
    "lui":  (12, "u"),
    "lsb":  (13, "r"),  # index of ra's lowest set bit (0 when none; Z = ra == 0)
    "rotb": (14, "x"),  # ra rotated right by 0-3 bytes
    "ld":   (16, "l"), "st": (17, "s"),
    "b":    (20, "b"), "call": (21, "c"), "ret": (22, "n"),
    "cb":   (23, "cb"), "cbi": (24, "ci"), "cbb": (25, "cq"), "cbt": (26, "ct"),
}
CB_OPS = frozenset({"cb", "cbi", "cbb", "cbt"})   # compare-and-branch
TARGET_BITS = 11       # a compare-and-branch's target: imm[10:0]
CBI_MIN, CBI_MAX = -256, 255
# operations that write the flags Z (result == 0) and N (result bit 31); lsb: Z = ra == 0, N = 0.
# mul keeps them: its product would otherwise run on into the flags' zero test (57 -> 61 MHz)
FLAG_OPS = frozenset({"add", "sub", "and", "or", "xor", "andn", "addi", "andi", "ori",
                      "xori", "lui", "lsb", "rotb"}) | CB_OPS
WRITE_OPS = (FLAG_OPS - CB_OPS) | {"ld", "mul"}  # operations that write rd
CONDS = {"al": 0, "eq": 1, "ne": 2, "lt": 3, "ge": 4, "le": 5, "gt": 6}


class UcodeError(ValueError):
    """A program the engine cannot run as written (the message names the instruction)."""


def sext(value: int, bits: int) -> int:
    value &= (1 << bits) - 1
    return value - (1 << bits) if value >> (bits - 1) else value


def cond_holds(cond: int, z: bool, n: bool) -> bool:
    return {0: True, 1: z, 2: not z, 3: n, 4: not n, 5: n or z, 6: not n and not z}[cond]


@dataclass
class Insn:
    op: str
    rd: int = 0
    ra: int = 0
    rb: int = 0
    imm: int = 0
    target: str | None = None   # branch / call label, resolved by assemble()
    where: str = ""             # for messages: the builder's line or a caller's note
    k: int = 0                  # cbi's compare immediate

    def reads(self) -> set[int]:
        fmt = OPCODES[self.op][1]
        if fmt in ("cb", "ct"):
            return {self.ra, self.rb} - {0}
        if fmt in ("ci", "cq"):
            return {self.ra} - {0}
        if fmt == "r":
            return {self.ra, self.rb} - {0} if self.op != "lsb" else {self.ra} - {0}
        if fmt in ("i", "x", "l"):
            return {self.ra} - {0}
        if fmt == "s":
            return {self.ra, self.rb} - {0}
        return set()

    def writes(self) -> int:
        return self.rd if self.op in WRITE_OPS else 0


def encode(insn: Insn, target: int = 0) -> int:
    code, fmt = OPCODES[insn.op]
    rd, ra, rb, imm = insn.rd, insn.ra, insn.rb, insn.imm
    if fmt in ("cb", "ci", "cq", "ct"):
        if not 0 <= target < (1 << TARGET_BITS):
            raise UcodeError(f"{insn.where}: {insn.op} target {target} beyond {TARGET_BITS} bits")
        imm = target
        if fmt == "ci":
            if not CBI_MIN <= insn.k <= CBI_MAX:
                raise UcodeError(f"{insn.where}: cbi immediate {insn.k} outside {CBI_MIN}..{CBI_MAX}")
            rb, imm = (insn.k >> 4) & 0x1F, imm | (insn.k & 0xF) << TARGET_BITS
    elif fmt in ("b", "c"):
        imm, rb, ra = target, 0, 0
        if fmt == "c":
            rd = 0
    elif fmt == "u":
        rb, imm, ra = (imm >> IMM_BITS) & 0x1F, imm & ((1 << IMM_BITS) - 1), 0
    elif fmt == "n":
        rd = ra = rb = imm = 0
    for name, val in (("rd", rd), ("ra", ra), ("rb", rb)):
        if not 0 <= val < NREGS:
            raise UcodeError(f"{insn.where}: {insn.op} {name} = {val} is not a register 0..31")
    return (code << 30) | (rd << 25) | (ra << 20) | (rb << 15) | (imm & ((1 << IMM_BITS) - 1))


_OP_NAMES = {c: n for n, (c, _) in OPCODES.items()}


def decode(word: int) -> Insn:
    code = (word >> 30) & 0x3F
    op = _OP_NAMES.get(code, "nop")
    fmt = OPCODES[op][1]
    rd, ra, rb, imm = (word >> 25) & 0x1F, (word >> 20) & 0x1F, (word >> 15) & 0x1F, word & 0x7FFF
    if fmt in ("i", "l", "s"):
        imm = sext(imm, IMM_BITS)
    elif fmt == "u":
        imm = (rb << IMM_BITS) | imm
    elif fmt == "ci":
        return Insn(op, rd, ra, 0, imm & ((1 << TARGET_BITS) - 1),
                    k=sext(rb << 4 | imm >> TARGET_BITS, 9))
    elif fmt in ("cb", "cq", "ct"):
        imm &= (1 << TARGET_BITS) - 1
    return Insn(op, rd, ra, rb, imm)


@dataclass
class Image:
    """An assembled program: ROM words, label addresses, how many hazard NOPs were added."""
    words: list[int]
    labels: dict[str, int]
    listing: list[str]
    nops_inserted: int

    def hex(self, depth: int | None = None) -> str:
        """``$readmemh`` text, one 9-digit word per line, padded with NOPs to ``depth``."""
        words = list(self.words) + [0] * max(0, (depth or 0) - len(self.words))
        return "".join(f"{w:09x}\n" for w in words)


class Program:
    """Builds a program instruction by instruction: ``p.add(3, 1, 2)``, ``p.label("loop")``,
    ``p.b("ne", "loop")``. Pseudo-instructions: ``li``, ``mov``, ``cmp``, ``cmpi``, ``tst``,
    ``clamp``, ``jmp``."""

    def __init__(self, name: str = "program", fuse: bool = True) -> None:
        self.name = name
        self.fuse = fuse                     # b() fuses a flag-only compare before it
        self.items: list[Insn | str] = []   # instructions and labels (str) in order
        self._count = 0                      # instructions among the items

    # ---- raw instructions
    def _emit(self, insn: Insn) -> "Program":
        if not insn.where:
            insn.where = f"{self.name}[{self._count}] {insn.op}"
        self._count += 1
        self.items.append(insn)
        return self

    def _imm15(self, op: str, value: int, what: str) -> None:
        if not -(1 << (IMM_BITS - 1)) <= value < (1 << (IMM_BITS - 1)):
            raise UcodeError(f"{self.name}: {op} {what} {value} outside the signed 15-bit range")

    def label(self, name: str) -> "Program":
        if name in self.items:
            raise UcodeError(f"{self.name}: label {name!r} defined twice")
        self.items.append(name)
        return self

    def nop(self) -> "Program":
        return self._emit(Insn("nop"))

    def _r(op: str) -> Callable:  # noqa: N805 (a builder factory used in the class body)
        def f(self: "Program", rd: int, ra: int, rb: int) -> "Program":
            return self._emit(Insn(op, rd, ra, rb))
        f.__name__ = op
        return f

    def _i(op: str) -> Callable:  # noqa: N805
        def f(self: "Program", rd: int, ra: int, imm: int) -> "Program":
            self._imm15(op, imm, "immediate")
            return self._emit(Insn(op, rd, ra, 0, imm))
        f.__name__ = op
        return f

    add, sub, and_, or_, xor = _r("add"), _r("sub"), _r("and"), _r("or"), _r("xor")
    andn, mul = _r("andn"), _r("mul")
    addi, andi, ori, xori = _i("addi"), _i("andi"), _i("ori"), _i("xori")

    def lui(self, rd: int, imm20: int) -> "Program":
        if not 0 <= imm20 < (1 << 20):
            raise UcodeError(f"{self.name}: lui immediate {imm20} outside 0..2^20-1")
        return self._emit(Insn("lui", rd, 0, 0, imm20))

    def lsb(self, rd: int, ra: int) -> "Program":
        return self._emit(Insn("lsb", rd, ra))

    def rotb(self, rd: int, ra: int, nbytes: int) -> "Program":
        """rd = ra rotated right by ``nbytes`` bytes (0-3)"""
        if not 0 <= nbytes <= 3:
            raise UcodeError(f"{self.name}: rotb by {nbytes} bytes, the rotator takes 0..3")
        return self._emit(Insn("rotb", rd, ra, 0, nbytes))

    def ld(self, rd: int, ra: int, off: int = 0) -> "Program":
        """rd = bus[ra + off]"""
        return self._mem("ld", rd, ra, 0, off)

    def st(self, rb: int, ra: int, off: int = 0) -> "Program":
        """bus[ra + off] = rb"""
        return self._mem("st", 0, ra, rb, off)

    def _mem(self, op: str, rd: int, ra: int, rb: int, off: int) -> "Program":
        self._imm15(op, off, "offset")
        return self._emit(Insn(op, rd, ra, rb, off))

    def b(self, cond: str, target: str) -> "Program":
        """Branch on the flags; fused with a flag-only compare right before it (no label
        between) into a compare-and-branch when one has the same flags."""
        if cond not in CONDS:
            raise UcodeError(f"{self.name}: unknown branch condition {cond!r} (one of {sorted(CONDS)})")
        last = self.items[-1] if self.items else None
        if self.fuse and cond != "al" and isinstance(last, Insn):
            fused = _fused(last, CONDS[cond], target)
            if fused is not None:
                self.items[-1] = fused
                return self
        return self._emit(Insn("b", CONDS[cond], target=target))

    def _cbranch(self, op: str, cond: str, ra: int, rb: int, target: str, k: int = 0) -> "Program":
        if cond not in CONDS or cond == "al":
            raise UcodeError(f"{self.name}: {op} takes a condition other than al, not {cond!r}")
        return self._emit(Insn(op, CONDS[cond], ra, rb, target=target, k=k))

    def cb(self, cond: str, ra: int, rb: int, target: str) -> "Program":
        """branch to ``target`` if ``cond`` holds for ra - rb (the flags of cmp)"""
        return self._cbranch("cb", cond, ra, rb, target)

    def cbi(self, cond: str, ra: int, k: int, target: str) -> "Program":
        """branch if ``cond`` holds for ra - k, k in -256..255 (the flags of cmpi)"""
        if not CBI_MIN <= k <= CBI_MAX:
            raise UcodeError(f"{self.name}: cbi immediate {k} outside {CBI_MIN}..{CBI_MAX}")
        return self._cbranch("cbi", cond, ra, 0, target, k)

    def cbb(self, cond: str, ra: int, bit: int, target: str) -> "Program":
        """branch if ``cond`` holds for ra & (1 << bit) (eq: the bit is clear)"""
        return self._cbranch("cbb", cond, ra, bit, target)

    def cbt(self, cond: str, ra: int, rb: int, target: str) -> "Program":
        """branch if ``cond`` holds for ra & rb"""
        return self._cbranch("cbt", cond, ra, rb, target)

    def jmp(self, target: str) -> "Program":
        return self.b("al", target)

    def call(self, target: str) -> "Program":
        return self._emit(Insn("call", target=target))

    def ret(self) -> "Program":
        return self._emit(Insn("ret"))

    # ---- pseudo-instructions
    def li(self, rd: int, value: int) -> "Program":
        """rd = value (any 32-bit value: one instruction when it fits 15 signed bits, else two)"""
        value &= MASK32
        if sext(value, 32) == sext(value, IMM_BITS):
            return self.addi(rd, 0, sext(value, IMM_BITS))
        self.lui(rd, value >> 12)
        return self.ori(rd, rd, value & 0xFFF) if value & 0xFFF else self

    def mov(self, rd: int, ra: int) -> "Program":
        return self.or_(rd, ra, 0)

    def cmp(self, ra: int, rb: int) -> "Program":
        """flags of ra - rb (modulo 2^32, as the RTL's $signed(a - b) compares)"""
        return self.sub(0, ra, rb)

    def cmpi(self, ra: int, imm: int) -> "Program":
        return self.addi(0, ra, -imm)

    def tst(self, ra: int) -> "Program":
        return self.or_(0, ra, 0)

    def clamp(self, rd: int, lo: int, hi: int) -> "Program":
        """rd = min(max(rd, lo), hi) with the modulo compares (signed rd - lo, rd - hi)"""
        tag = f"__clamp{self._count}"
        self.cmp(rd, lo).b("ge", f"{tag}_lo").mov(rd, lo)
        return self.label(f"{tag}_lo").cmp(rd, hi).b("le", f"{tag}_hi").mov(rd, hi).label(f"{tag}_hi")

    # ---- assembly
    def assemble(self, depth: int = 512, strict: bool = False, schedule: bool = True) -> Image:
        """Resolve labels, reorder each basic block so that fewer neighbours depend on each
        other (``schedule``, see :func:`schedule_block`), insert a NOP wherever an instruction
        reads a register or the flags its neighbour before it produces (``strict``: refuse
        instead), encode. Errors name the instruction: unknown label, program longer than
        ``depth``."""
        out: list[Insn | str] = []
        prev: Insn | None = None
        nops = 0
        for item in (self._scheduled() if schedule else self.items):
            if isinstance(item, str):
                out.append(item)
                continue
            if prev is not None and hazard(prev, item):
                if strict:
                    raise UcodeError(f"{item.where}: reads what {prev.where} produces in the clock "
                                     "before (one instruction must come between)")
                out.append(Insn("nop", where=f"{item.where} (hazard nop)"))
                nops += 1
            out.append(item)
            prev = item
        labels: dict[str, int] = {}
        addr = 0
        for item in out:
            if isinstance(item, str):
                labels[item] = addr
            else:
                addr += 1
        if addr > depth:
            raise UcodeError(f"{self.name}: {addr} instructions, the ROM holds {depth}")
        words, listing = [], []
        for item in out:
            if isinstance(item, str):
                listing.append(f"{item}:")
                continue
            tgt = 0
            if item.target is not None:
                if item.target not in labels:
                    raise UcodeError(f"{item.where}: unknown label {item.target!r}")
                tgt = labels[item.target]
            listing.append(f"  {len(words):4d}  {item.op} rd={item.rd} ra={item.ra} rb={item.rb} "
                           f"imm={item.k if item.op == 'cbi' else item.imm}"
                           f"{' -> ' + item.target if item.target else ''}")
            words.append(encode(item, tgt))
        return Image(words, labels, listing, nops)


    def _scheduled(self) -> list[Insn | str]:
        """The items with each basic block scheduled. A block ends at a label, a branch, call
        or ret (kept last); an explicit ``nop`` is a barrier nothing moves across."""
        out: list[Insn | str] = []
        block: list[Insn] = []
        for item in self.items:
            if isinstance(item, str) or item.op == "nop":
                out += schedule_block(block)
                block = []
                out.append(item)
            elif item.op in CONTROL_OPS:
                out += schedule_block(block + [item])
                block = []
            else:
                block.append(item)
        return out + schedule_block(block)


CONTROL_OPS = frozenset({"b", "call", "ret"}) | CB_OPS
_FLAGS = NREGS   # the flags, as one more register for the dependences


def _uses(insn: Insn) -> tuple[set[int], set[int]]:
    """(what ``insn`` reads, what it writes): registers, and the flags as register _FLAGS."""
    reads, writes = insn.reads(), {insn.writes()} - {0}
    if insn.op == "b" and insn.rd != CONDS["al"]:
        reads = reads | {_FLAGS}
    if insn.op in FLAG_OPS:
        writes.add(_FLAGS)
    return reads, writes


def schedule_block(block: list[Insn]) -> list[Insn]:
    """A basic block in an order with fewer hazards between neighbours: a greedy list
    scheduler over the block's dependences (register and flag reads / writes in either order,
    and every bus access kept in program order: I/O has side effects and the WIN port and the
    units count clocks between accesses, which only grow). The block's control instruction
    stays last. Each step takes, among the instructions whose predecessors are placed, one
    that does not read what the last placed one produces, the one heading the longest chain
    first (ties: program order). Every register and the flags end as in program order."""
    n = len(block)
    if n < 3:
        return list(block)
    uses = [_uses(i) for i in block]
    preds: list[set[int]] = [set() for _ in range(n)]
    for j in range(n):
        rj, wj = uses[j]
        for i in range(j):
            ri, wi = uses[i]
            if (wi & rj or ri & wj or wi & wj or (block[i].op in ("ld", "st") and block[j].op in ("ld", "st"))
                    or block[j].op in CONTROL_OPS):
                preds[j].add(i)
    height = [1] * n
    for j in reversed(range(n)):
        for i in preds[j]:
            height[i] = max(height[i], height[j] + 1)
    placed: list[int] = []
    done: set[int] = set()
    while len(placed) < n:
        ready = [j for j in range(n) if j not in done and preds[j] <= done]
        last = block[placed[-1]] if placed else None
        calm = [j for j in ready if last is None or not hazard(last, block[j])]
        pick = max(calm or ready, key=lambda j: (height[j], -j))
        placed.append(pick)
        done.add(pick)
    return [block[j] for j in placed]


def _fused(flag_op: Insn, cond: int, target: str) -> Insn | None:
    """The compare-and-branch with the flags of ``flag_op`` (which writes only the flags)
    followed by ``b cond``, or None."""
    op, ra, rb, imm = flag_op.op, flag_op.ra, flag_op.rb, flag_op.imm
    if flag_op.rd != 0:
        return None
    where = f"{flag_op.where} + b"
    if op == "sub":
        return Insn("cb", cond, ra, rb, target=target, where=where)
    if op == "or" and 0 in (ra, rb):                    # tst: the flags of the register
        return Insn("cb", cond, ra or rb, 0, target=target, where=where)
    if op == "and":
        return Insn("cbt", cond, ra, rb, target=target, where=where)
    if op == "andi" and imm > 0 and imm & (imm - 1) == 0:   # a single bit: N = 0 either way
        return Insn("cbb", cond, ra, imm.bit_length() - 1, target=target, where=where)
    if op == "addi" and CBI_MIN <= -imm <= CBI_MAX:     # ra + imm = ra - (-imm)
        return Insn("cbi", cond, ra, 0, target=target, where=where, k=-imm)
    return None


def hazard(first: Insn, second: Insn) -> bool:
    """``second`` executes right after ``first`` and reads its result or flags too early
    (branches, call and ret write neither), or is a call right after a compare-and-branch
    (squashed, it would still set the link register)."""
    w = first.writes()
    if w and w in second.reads():
        return True
    if first.op in CB_OPS and second.op == "call":
        return True
    return first.op in FLAG_OPS and second.op == "b" and second.rd != CONDS["al"]


def random_program(seed: int, base: int = 0x100, words: int = 64, length: int | None = None,
                   name: str | None = None) -> Program:
    """A seeded stress program: every instruction on random registers and immediates, loads and
    stores in ``words`` words from ``base`` (r31 holds the base, r30 counts loops), forward
    branches on every condition and a few counted loops; it ends without a halt (callers add
    theirs). Used by the engine's scoreboard and, as a representative ROM, its area bench."""
    import random

    rng = random.Random(seed)
    p = Program(name or f"random{seed}")
    for r in range(1, 32):
        p.li(r, rng.getrandbits(32) if r != 31 else base)
    rops = (p.add, p.sub, p.and_, p.or_, p.xor, p.andn, p.mul)
    iops = (p.addi, p.andi, p.ori, p.xori)
    nlabel = loops = 0
    for _ in range(length if length is not None else rng.randrange(150, 300)):
        def r() -> int:
            return rng.randrange(1, 30)
        kind = rng.random()
        if kind < 0.35:
            rng.choice(rops)(r(), r(), r())
        elif kind < 0.55:
            rng.choice(iops)(r(), r(), rng.randrange(-16384, 16384))
        elif kind < 0.62:
            p.lsb(r(), r()) if rng.random() < 0.5 else p.rotb(r(), r(), rng.randrange(4))
        elif kind < 0.65:
            p.lui(r(), rng.getrandbits(20))
        elif kind < 0.75:
            p.ld(r(), 31, rng.randrange(words))
        elif kind < 0.85:
            p.st(r(), 31, rng.randrange(words))
        elif kind < 0.95:   # a forward branch over a few instructions, half of them fused
            nlabel += 1        # with a compare into a compare-and-branch
            cond = rng.choice(list(CONDS))
            if cond != "al" and rng.random() < 0.5:
                rng.choice((lambda: p.cmp(r(), r()), lambda: p.tst(r()), lambda: p.and_(0, r(), r()),
                            lambda: p.cmpi(r(), rng.randrange(CBI_MIN, CBI_MAX + 1)),
                            lambda: p.andi(0, r(), 1 << rng.randrange(14))))()
            p.b(cond, f"f{nlabel}")
            for _ in range(rng.randrange(1, 4)):
                p.xor(r(), r(), r())
            p.label(f"f{nlabel}")
        elif loops < 3:     # a counted loop: r30 counts down, the body adds and stores
            loops += 1
            p.li(30, rng.randrange(2, 6)).label(f"loop{loops}")
            p.add(r(), r(), r()).st(rng.randrange(1, 30), 31, rng.randrange(words))
            p.addi(30, 30, -1).nop().b("ne", f"loop{loops}")
            p.call(f"sub{loops}").jmp(f"after{loops}")
            p.label(f"sub{loops}").add(r(), r(), r()).ret()
            p.label(f"after{loops}")
    p.li(2, rng.getrandbits(14))
    return p


# ------------------------------------------------------------------ instruction-set simulator
@dataclass
class BusOp:
    cycle: int     # clock of the bus access (the instruction's X stage), counted from reset release
    write: bool
    addr: int
    data: int      # written data, or the data read
    absolute: bool = False   # ra is r0: the immediate is the address


@dataclass
class Machine:
    """Runs an image one instruction per clock, with the RTL's timing: the instruction in the
    R stage at clock k accesses the bus in clock k + 1. ``read(addr)`` and ``write(addr,
    data)`` model the bus (default: a dict memory). Hazards the assembler would have removed
    raise :class:`UcodeError` (the RTL would read a stale value)."""
    words: list[int]
    addr_bits: int = 12
    # a store whose ra is not r0 must address below this (None: anywhere). A bus with many
    # targets decodes them from the immediate of an r0-based store, a register in the X stage
    # (ms_sched_engine's bus_abs_o / bus_imm_o), and takes an indexed store as a memory write
    indexed_store_limit: int | None = None
    mem: dict[int, int] = field(default_factory=dict)
    regs: list[int] = field(default_factory=lambda: [0] * NREGS)
    z: bool = False
    n: bool = False
    pc: int = 0
    lr: int = 0
    cycle: int = 0
    trace: list[BusOp] = field(default_factory=list)

    def read(self, addr: int) -> int:
        return self.mem.get(addr, 0)

    def write(self, addr: int, data: int) -> None:
        self.mem[addr] = data

    def run(self, max_cycles: int, stop: Iterable[int] = ()) -> int:
        """Execute until the pc reaches an address of ``stop`` or ``max_cycles`` clocks."""
        stops = set(stop)
        code = [decode(w) for w in self.words]   # each word decoded once, not per clock
        nop = decode(0)
        prev: Insn | None = None
        while self.cycle < max_cycles and self.pc not in stops:
            insn = code[self.pc] if self.pc < len(code) else nop
            if prev is not None and hazard(prev, insn):
                raise UcodeError(f"pc {self.pc}: hazard with the instruction before ({prev.op})")
            before = self.cycle
            self.step(insn)
            prev = insn if self.cycle == before + 1 else None   # a taken cb: two squashed clocks
        return self.cycle

    def step(self, insn: Insn) -> None:
        op, r = insn.op, self.regs
        a, bv = r[insn.ra], r[insn.rb]
        nxt = self.pc + 1
        res: int | None = None
        z_override: bool | None = None
        if op == "add":
            res = a + bv
        elif op == "sub":
            res = a - bv
        elif op == "and":
            res = a & bv
        elif op == "or":
            res = a | bv
        elif op == "xor":
            res = a ^ bv
        elif op == "andn":
            res = a & ~bv
        elif op == "mul":
            res = sext(a, 18) * sext(bv, 18)
        elif op == "addi":
            res = a + insn.imm
        elif op == "andi":
            res = a & insn.imm
        elif op == "ori":
            res = a | insn.imm
        elif op == "xori":
            res = a ^ insn.imm
        elif op == "lui":
            res = insn.imm << 12
        elif op == "lsb":
            res = ((a & -a).bit_length() - 1) if a else 0
            z_override = a == 0
        elif op == "rotb":
            k = 8 * (insn.imm & 3)
            res = (a >> k) | (a << (32 - k))
        elif op in ("ld", "st"):
            addr = (a + insn.imm) & ((1 << self.addr_bits) - 1)
            if op == "ld":
                data = self.read(addr) & MASK32
                self.trace.append(BusOp(self.cycle + 1, False, addr, data, insn.ra == 0))
                if insn.rd:
                    r[insn.rd] = data
            else:
                lim = self.indexed_store_limit
                if insn.ra and lim is not None and addr >= lim:
                    raise UcodeError(f"pc {self.pc}: st to {addr:#x} through r{insn.ra}: an "
                                     f"indexed store must address below {lim:#x}")
                self.trace.append(BusOp(self.cycle + 1, True, addr, bv, insn.ra == 0))
                self.write(addr, bv)
        elif op in CB_OPS:              # the flags below, then the decision
            bv = {"cbi": insn.k, "cbb": 1 << insn.rb}.get(op, bv)
            res = (a - bv) if op in ("cb", "cbi") else (a & bv)
        elif op == "b":
            if cond_holds(insn.rd, self.z, self.n):
                nxt = insn.imm
        elif op == "call":
            self.lr, nxt = self.pc + 1, insn.imm
        elif op == "ret":
            nxt = self.lr
        if res is not None:
            res &= MASK32
            if insn.rd and op in WRITE_OPS:
                r[insn.rd] = res
            if op in FLAG_OPS:
                self.z = (res == 0) if z_override is None else z_override
                self.n = bool(res >> 31)
        if op in CB_OPS and cond_holds(insn.rd, self.z, self.n):
            nxt = insn.imm
            self.cycle += 2              # the two instructions after it are squashed
        self.pc = nxt
        self.cycle += 1


# ------------------------------------------------------------------ generated RTL package
def sv_package() -> str:
    lines = ["// Generated by multisonar.tools.sched_ucode (the scheduler engine's instruction set).",
             "// Do not edit: docs/sched_engine.md describes it, the Python module is its source.",
             "package ms_ucode_pkg;",
             f"  localparam int UC_WORD_BITS = {WORD_BITS};"]
    for name, (code, _) in OPCODES.items():
        lines.append(f"  localparam logic [5:0] OP_{name.upper()} = 6'd{code};")
    for name, code in CONDS.items():
        lines.append(f"  localparam logic [3:0] CC_{name.upper()} = 4'd{code};")
    lines.append("endpackage")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pkg", type=Path, required=True, help="write the opcode package here")
    args = ap.parse_args(argv)
    args.pkg.parent.mkdir(parents=True, exist_ok=True)
    args.pkg.write_text(sv_package())


if __name__ == "__main__":
    main()
