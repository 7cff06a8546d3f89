"""cocotb tests of ms_sched_engine (the scheduler's microcoded engine core) against its golden
model, multisonar.tools.sched_ucode.Machine: every bus access (clock, read or write, address,
written data) of a program must be the model's, clock for clock. Programs end by storing every
register and the flags (through branches) to the bus, so a wrong result always shows.

Programs: every instruction on edge values, the shortest forwarding distance, all branch
conditions, call / return, compare-and-branch with stores, loads and branches in its shadow;
random programs (seeded) with forward branches, counted loops and
calls;
a lowest-set-bit loop over masks, the engine's typical scan.
"""

from __future__ import annotations

import random

import cocotb
from cocotb.triggers import ClockCycles, FallingEdge, RisingEdge

from multisonar.tools.sched_ucode import CONDS, Image, Machine, Program, random_program
from tbutil import start_clock

AW = 12
ROM = 1024          # the testbench's UCODE_WORDS
DUMP = 0xF00        # registers r1..r31 are stored at DUMP + r, flag markers at DUMP + 32..
DATA = 0x100        # the window of the RAM random programs read and write
DATA_WORDS = 64


def finish(p: Program) -> Program:
    """Store every register and, per branch condition, whether it holds; then halt."""
    p.nop().nop()   # results of the program's last instructions are written
    for r in range(1, 32):
        p.st(r, 0, DUMP + r)
    for i, cond in enumerate(CONDS):
        p.b(cond, f"__taken_{cond}")
        p.li(1, 0x100 + i).st(1, 0, DUMP + 32 + i).jmp(f"__next_{cond}")
        p.label(f"__taken_{cond}")
        p.li(1, 0x200 + i).st(1, 0, DUMP + 32 + i)
        p.label(f"__next_{cond}")
        p.cmpi(2, 7 * i)  # new flags for the next condition (r2 holds the program's last value)
        p.nop()
    p.label("__halt").jmp("__halt")
    return p


async def run_image(dut, image: Image, mem: dict[int, int], max_cycles: int = 20000):
    """Load ROM and RAM, reset, run until the model halts; return (rtl trace, model trace)."""
    model = Machine(image.words, addr_bits=AW, mem=dict(mem))
    cycles = model.run(max_cycles, stop={image.labels["__halt"]})
    assert cycles < max_cycles, "the program did not halt in the model"
    for i in range(ROM):
        dut.u_eng.rom_q[i].value = image.words[i] if i < len(image.words) else 0
    for a in range(2 ** AW):
        dut.mem_q[a].value = mem.get(a, 0)
    for r in range(32):          # the power-up state (a reset does not clear registers)
        dut.u_eng.rf_q[r].value = 0
    dut.rst_i.value = 1
    await ClockCycles(dut.clk_i, 3)
    dut.rst_i.value = 0          # right after a rising edge: the clock that follows is clock 0
    trace = []
    for cyc in range(cycles + 4):
        await FallingEdge(dut.clk_i)
        # an r0-based access (bus_abs_o) shows its address on bus_imm_o too
        absolute = bool(int(dut.bus_abs_o.value))
        if absolute:
            absolute = int(dut.bus_imm_o.value) == int(dut.bus_addr_o.value)
        if int(dut.bus_we_o.value):
            trace.append((cyc, True, int(dut.bus_addr_o.value), int(dut.bus_wdata_o.value),
                          absolute))
        elif int(dut.bus_re_o.value):
            trace.append((cyc, False, int(dut.bus_addr_o.value), None, absolute))
    expect = [(op.cycle, op.write, op.addr, op.data if op.write else None, op.absolute)
              for op in model.trace]
    return trace, expect, model


def compare(trace, expect, what: str) -> None:
    for i, (got, exp) in enumerate(zip(trace, expect)):
        assert got == exp, f"{what}: bus access {i}: RTL {got}, model {exp}"
    assert len(trace) == len(expect), f"{what}: {len(trace)} bus accesses, model {len(expect)}"


async def setup(dut) -> None:
    start_clock(dut.clk_i)
    dut.rst_i.value = 1
    await RisingEdge(dut.clk_i)


def directed_program() -> Program:
    p = Program("directed")
    edge = [0, 1, 0x7FFF_FFFF, 0x8000_0000, 0xFFFF_FFFF, 0x1234_5678, 0x0002_0000, 0xFFFE_0001]
    for k, v in enumerate(edge):
        p.li(3 + k, v)        # r3..r10
    p.nop()
    out = 11
    for rb in range(3, 11):
        for op in ("add", "sub", "and_", "or_", "xor", "andn", "mul"):
            getattr(p, op)(out, 3 + (rb * 5) % 8, rb)
            p.st(out, 0, 0x200 + out)   # distance 2 from the next writer of out: forwarded
            out = 11 if out == 30 else out + 1
    for k in range(3, 11):
        p.lsb(12, k).addi(13, k, -1).rotb(14, k, k % 4).xori(15, k, -2)
        p.st(12, 0, 0x300 + k).st(13, 0, 0x310 + k).st(14, 0, 0x320 + k).st(15, 0, 0x330 + k)
        p.andi(16, k, 0x3FFF).ori(17, k, -16384).lui(18, (k * 0x1357) & 0xFFFFF)
        p.st(16, 0, 0x340 + k).st(17, 0, 0x350 + k).st(18, 0, 0x360 + k)
    # loads: base + negative offset, the loaded value used at distance 2 (forwarded) and 1 (nop)
    p.li(20, 0x410).st(5, 20, -16).ld(21, 20, -16).nop().add(22, 21, 21).ld(23, 0, 0x400)
    p.add(24, 23, 3).st(24, 0, 0x401)
    # r0 ignores writes
    p.addi(0, 3, 99).add(25, 0, 0).st(25, 0, 0x402)
    # call / return, twice
    p.li(26, 0).call("sub1").addi(26, 26, 1).call("sub1").jmp("after")
    p.label("sub1").addi(26, 26, 5).ret()
    p.label("after").st(26, 0, 0x403)
    # mul keeps the flags: Z from the compare survives a non-zero product
    p.li(28, 0x77).li(1, 5).li(2, 7).nop().cmp(1, 1).mul(3, 1, 2).b("eq", "mul_kept").li(28, 1)
    p.label("mul_kept").st(28, 0, 0x404).st(3, 0, 0x405)
    # every condition after a subtraction: taken and not taken
    for i, (a, b) in enumerate([(5, 5), (4, 5), (5, 4), (0x8000_0000, 1), (1, 0x8000_0000)]):
        p.li(1, a).li(2, b).nop().cmp(1, 2).nop()
        for cond in CONDS:
            p.li(27, 0).b(cond, f"t{i}{cond}").li(27, 1)
            p.label(f"t{i}{cond}").st(27, 0, 0x500 + 8 * i + CONDS[cond])
    # compare-and-branch, each kind taken and not taken, with a store, a load, a branch and
    # another compare-and-branch in its shadow (squashed when it is taken)
    p.li(1, 0x100).li(2, 0x100).li(4, 0x8000_0005).nop()
    shadows = (lambda q, i: q.st(4, 0, 0x600 + i).st(4, 0, 0x640 + i),
               lambda q, i: q.ld(29, 0, 0x405).addi(30, 30, 1),
               lambda q, i: q.jmp(f"c{i}").st(4, 0, 0x680 + i),
               lambda q, i: q.cb("ne", 1, 2, f"c{i}").st(4, 0, 0x6C0 + i))
    kinds = (lambda q, i, c: q.cb(c, 1, 2, f"c{i}"), lambda q, i, c: q.cb(c, 4, 0, f"c{i}"),
             lambda q, i, c: q.cbi(c, 1, 255, f"c{i}"), lambda q, i, c: q.cbi(c, 4, -256, f"c{i}"),
             lambda q, i, c: q.cbb(c, 1, 8, f"c{i}"), lambda q, i, c: q.cbb(c, 4, 31, f"c{i}"),
             lambda q, i, c: q.cbt(c, 1, 4, f"c{i}"))
    p.li(30, 0)
    i = 0
    for kind in kinds:
        for cond in ("eq", "ne", "lt", "ge", "le", "gt"):
            kind(p, i, cond)
            shadows[i % len(shadows)](p, i)
            p.st(4, 0, 0x700 + i).label(f"c{i}").st(30, 0, 0x780 + i)
            i += 1
    p.li(2, 3)
    return finish(p)


@cocotb.test(timeout_time=50, timeout_unit="ms")
async def every_instruction_matches_the_model(dut):
    """Each instruction on edge values, forwarding at distance 2, r0, call / return and every
    branch condition taken and not taken: the RTL's bus accesses are the model's."""
    await setup(dut)
    image = directed_program().assemble(ROM)
    trace, expect, model = await run_image(dut, image, {})
    compare(trace, expect, "directed program")
    # the model itself against plain Python on a few results (the model is the reference)
    assert model.mem[0x402] == 0 and model.mem[0x403] == 11
    assert model.mem[0x401] == (0x7FFF_FFFF + 0) & 0xFFFF_FFFF  # ld of 0x400 (r5) + r3 (0)
    assert model.mem[0x300 + 6] == 31 and model.mem[0x300 + 3] == 0  # lsb(0x8000_0000), lsb(0)


def random_case(seed: int) -> tuple[Program, dict[int, int]]:
    rng = random.Random(10_000 + seed)
    mem = {DATA + i: rng.getrandbits(32) for i in range(DATA_WORDS)}
    return finish(random_program(seed, base=DATA, words=DATA_WORDS)), mem


@cocotb.test(timeout_time=500, timeout_unit="ms")
async def random_programs_match_the_model(dut):
    """Twenty seeded random programs (ALU, loads, stores, forward branches, loops; hazards
    resolved by the assembler): every bus access equal to the model's."""
    await setup(dut)
    for seed in range(20):
        prog, mem = random_case(seed)
        image = prog.assemble(ROM)
        trace, expect, _ = await run_image(dut, image, mem)
        compare(trace, expect, f"random program {seed}")


@cocotb.test(timeout_time=100, timeout_unit="ms")
async def set_bit_scan_lists_every_bit(dut):
    """The engine's mask scan (lowest set bit, then clear it: m & (m - 1)) over masks from
    memory stores the index of every set bit in order and a terminator, as Python lists them."""
    await setup(dut)
    rng = random.Random(7)
    masks = [0, 1, 0x8000_0000, 0xFFFF_FFFF, 0x00FF_FF00] + [rng.getrandbits(24) for _ in range(5)]
    mem = {DATA + i: m for i, m in enumerate(masks)}
    p = Program("scan")
    p.li(5, 0x800)                       # output pointer
    p.li(6, len(masks)).li(7, DATA)
    p.label("next_mask").ld(1, 7, 0).nop().nop()
    p.label("bit").addi(3, 1, -1).lsb(2, 1)   # the flags of lsb: Z when the mask is empty
    p.b("eq", "done").and_(1, 1, 3).st(2, 5, 0).addi(5, 5, 1).jmp("bit")
    p.label("done").li(4, 99).st(4, 5, 0).addi(5, 5, 1)
    p.addi(7, 7, 1).addi(6, 6, -1).nop().b("ne", "next_mask")
    p.li(2, 0)
    image = finish(p).assemble(ROM)
    trace, expect, model = await run_image(dut, image, mem)
    compare(trace, expect, "set-bit scan")
    want = []
    for m in masks:
        want += [i for i in range(32) if m >> i & 1] + [99]
    got = [model.mem[0x800 + i] for i in range(len(want))]
    assert got == want
