"""The scheduler engine's assembler and instruction-set model (multisonar.tools.sched_ucode):
hazard NOPs, refusals that name the problem, and each instruction's result against plain
Python. The RTL is compared with this model in tests/rtl/test_ms_sched_engine.py."""

import pytest

import random

from multisonar.tools.sched_ucode import (CB_OPS, CONDS, OPCODES, Machine, Program, UcodeError,
                                          decode, encode, sv_package)


def run(p: Program, mem=None) -> Machine:
    p.label("halt").jmp("halt")
    img = p.assemble()
    m = Machine(img.words, mem=dict(mem or {}))
    m.run(10_000, stop={img.labels["halt"]})
    return m


def test_neighbour_reading_a_result_gets_a_nop():
    p = Program().add(1, 2, 3).add(4, 1, 1).add(5, 4, 2).add(6, 1, 2)
    img = p.assemble()
    assert img.nops_inserted == 2
    assert [decode(w).op for w in img.words] == ["add", "nop", "add", "nop", "add", "add"]
    with pytest.raises(UcodeError, match=r"\[1\] add: reads what .*\[0\] add produces"):
        p.assemble(strict=True)


def test_loads_stores_and_flags_follow_the_same_rule():
    img = Program().ld(1, 0, 5).st(1, 0, 6).assemble()          # store data from the load
    assert img.nops_inserted == 1
    img = Program(fuse=False).cmpi(1, 3).b("ne", "x").label("x").assemble()  # flags, a branch
    assert img.nops_inserted == 1
    img = Program().cmpi(1, 3).b("al", "x").label("x").assemble()  # always: reads no flags
    assert img.nops_inserted == 0
    img = Program().ld(1, 0, 5).b("eq", "x").label("x").assemble()  # loads set no flags
    assert img.nops_inserted == 0
    img = Program().add(0, 1, 2).add(3, 0, 0).assemble()         # r0 is never a result
    assert img.nops_inserted == 0


def test_a_taken_branch_separates_its_neighbours():
    # the branch itself stands between "add r1" and the target's reader: no NOP needed
    img = Program().add(1, 2, 3).jmp("t").label("t").add(4, 1, 1).assemble()
    assert img.nops_inserted == 0


@pytest.mark.parametrize("build, message", [
    (lambda p: p.jmp("nowhere"), "unknown label 'nowhere'"),
    (lambda p: p.addi(1, 1, 1 << 14), "outside the signed 15-bit range"),
    (lambda p: p.ld(1, 2, -(1 << 14) - 1), "outside the signed 15-bit range"),
    (lambda p: p.lui(1, 1 << 20), "lui immediate"),
    (lambda p: p.add(32, 1, 1), "not a register"),
    (lambda p: p.b("sometimes", "x"), "unknown branch condition"),
    (lambda p: p.rotb(1, 2, 4), "rotb by 4 bytes"),
    (lambda p: p.label("a").label("a"), "label 'a' defined twice"),
])
def test_bad_programs_are_refused_by_name(build, message):
    with pytest.raises(UcodeError, match=message):
        build(Program()).assemble()


def test_a_program_longer_than_the_rom_is_refused():
    p = Program("long")
    for _ in range(9):
        p.nop()
    with pytest.raises(UcodeError, match="long: 9 instructions, the ROM holds 8"):
        p.assemble(depth=8)


@pytest.mark.parametrize("value", [0, 1, -1, 16383, -16384, 16384, 0x1234_5678, 0xFFFF_F000,
                                   0x8000_0000, 0x7FFF_FFFF, 0x0000_0FFF])
def test_li_loads_any_32_bit_value(value):
    m = run(Program().li(7, value))
    assert m.regs[7] == value & 0xFFFF_FFFF


def test_each_instruction_against_python():
    a, b = 0x8765_4321, 0x0F0F_1234
    p = Program().li(1, a).li(2, b).li(3, -3).li(4, 5)
    p.add(10, 1, 2).sub(11, 1, 2).and_(12, 1, 2).or_(13, 1, 2).xor(14, 1, 2).andn(15, 1, 2)
    p.mul(16, 3, 4).mul(17, 1, 2).lsb(18, 2).rotb(19, 1, 1).rotb(20, 1, 3)
    p.addi(21, 1, -5).andi(22, 1, 0x3F0).ori(23, 2, -2).xori(24, 1, 0x155).lui(25, 0xABCDE)
    m = run(p)
    r = m.regs
    sx18 = lambda v: (v & 0x3FFFF) - (1 << 18) if v & 0x20000 else v & 0x3FFFF  # noqa: E731
    assert r[10] == (a + b) & 0xFFFF_FFFF and r[11] == (a - b) & 0xFFFF_FFFF
    assert (r[12], r[13], r[14], r[15]) == (a & b, a | b, a ^ b, a & ~b & 0xFFFF_FFFF)
    assert r[16] == (-15) & 0xFFFF_FFFF
    assert r[17] == (sx18(a) * sx18(b)) & 0xFFFF_FFFF
    assert r[18] == 2                                    # 0x...1234: lowest set bit 2
    assert r[19] == 0x2187_6543 and r[20] == 0x6543_2187
    assert r[21] == a - 5 and r[22] == a & 0x3F0 and r[23] == 0xFFFF_FFFE
    assert r[24] == a ^ 0x155 and r[25] == 0xABCD_E000


def test_flags_and_conditions():
    for x, y in [(5, 5), (4, 5), (5, 4), (0x8000_0000, 1), (0, 0xFFFF_FFFF)]:
        p = Program().li(1, x).li(2, y).cmp(1, 2)
        m = run(p)
        diff = (x - y) & 0xFFFF_FFFF
        assert m.z == (diff == 0) and m.n == bool(diff >> 31)
    m = run(Program().li(1, 0).lsb(2, 1))
    assert m.z and not m.n and m.regs[2] == 0           # lsb of 0: Z, index 0
    m = run(Program().li(1, 1).lsb(2, 1))
    assert not m.z and m.regs[2] == 0                   # lsb of 1: index 0, not Z


def test_calls_return_and_bus_timing():
    p = Program().li(1, 40).call("f").st(1, 0, 3).jmp("end")
    p.label("f").addi(1, 1, 2).ret()
    p.label("end")
    m = run(p, mem={})
    assert m.mem[3] == 42
    st = [op for op in m.trace if op.write]
    assert len(st) == 1 and st[0].addr == 3
    # li (1 clock), call, addi, ret: the store is in the R stage in clock 4, on the bus in 5
    assert st[0].cycle == 5


def test_indexed_store_limit():
    """A bus that decodes its registers from r0-based stores (ms_sched_uc) takes an indexed
    store only below the limit; r0-based stores and loads go anywhere."""
    p = Program().li(1, 0x3F0).nop().st(1, 1, 0xF).ld(2, 1, 0x10).st(1, 0, 0x400)
    p.label("end")
    img = p.assemble()
    m = Machine(img.words, mem={}, indexed_store_limit=0x400)
    m.run(50, stop={img.labels["end"]})
    assert m.mem[0x3FF] == m.mem[0x400] == 0x3F0
    assert [op.absolute for op in m.trace] == [False, False, True]
    p = Program().li(1, 0x3F0).nop().st(1, 1, 0x10)
    m = Machine(p.assemble().words, mem={}, indexed_store_limit=0x400)
    with pytest.raises(UcodeError, match="indexed store must address below 0x400"):
        m.run(50)


def test_model_refuses_an_unassembled_hazard():
    words = [encode(Program().add(1, 2, 3).items[0]), encode(Program().add(4, 1, 1).items[0])]
    with pytest.raises(UcodeError, match="hazard"):
        Machine(words).run(4)


def test_rtl_package_and_rom_image():
    pkg = sv_package()
    for name, (code, _) in OPCODES.items():
        assert f"OP_{name.upper()} = 6'd{code};" in pkg
    for name, code in CONDS.items():
        assert f"CC_{name.upper()} = 4'd{code};" in pkg
    img = Program().li(1, 0x1234_5678).assemble()
    lines = img.hex(depth=4).splitlines()
    assert len(lines) == 4 and all(len(x) == 9 for x in lines) and lines[3] == "000000000"
    assert [decode(int(x, 16)).op for x in lines[:3]] == ["lui", "nop", "ori"]  # ori reads lui


def test_mul_keeps_the_flags():
    m = run(Program().li(1, 5).li(2, 7).cmp(1, 1).mul(3, 1, 2))
    assert m.z and m.regs[3] == 35
    img = Program().cmp(1, 1).mul(3, 1, 2).b("eq", "x").label("x").assemble()
    assert img.nops_inserted == 0   # the branch reads the compare's flags, two instructions back


@pytest.mark.parametrize("value, want", [(-5, 10), (10, 10), (15, 15), (20, 20), (99, 20),
                                         (0x8000_0000, 20)])
def test_clamp(value, want):
    """Modulo compares, as the RTL's ticks: 0x80000000 - 20 is positive, so above the bounds."""
    m = run(Program().li(1, value).li(2, 10).li(3, 20).clamp(1, 2, 3).clamp(1, 2, 3))
    assert m.regs[1] == want


# ------------------------------------------------------------------ compare-and-branch
FUSIBLE = [   # (flag-only compare, the compare-and-branch it fuses into)
    (lambda p: p.cmp(1, 2), "cb"),
    (lambda p: p.tst(1), "cb"),
    (lambda p: p.and_(0, 1, 2), "cbt"),
    (lambda p: p.andi(0, 1, 1 << 9), "cbb"),
    (lambda p: p.cmpi(1, -256), "cbi"),
    (lambda p: p.cmpi(1, 255), "cbi"),
]


@pytest.mark.parametrize("compare, op", FUSIBLE)
def test_a_fused_compare_and_branch_equals_the_pair(compare, op):
    """Fused or not, every register, flag and store is the same for values around the compare's
    edges; the fused one is one word instead of three (compare, hazard NOP, branch)."""
    rng = random.Random(op)
    values = [0, 1, 2, 255, 256, 0x200, 0x7FFF_FFFF, 0x8000_0000, 0xFFFF_FFFF, 0xFFFF_FF00]
    for _ in range(40):
        x, y = rng.choice(values + [rng.getrandbits(32)]), rng.choice(values + [rng.getrandbits(32)])
        for cond in CONDS:
            if cond == "al":
                continue
            got = []
            for fuse in (True, False):
                p = Program(fuse=fuse).li(1, x).li(2, y).nop()
                compare(p).b(cond, "t").li(3, 1).st(3, 0, 9).jmp("e")
                p.label("t").li(3, 2).st(3, 0, 9).label("e")
                img_ops = [decode(w).op for w in p.assemble().words]
                assert (op in img_ops) == fuse
                m = run(p)
                got.append((m.regs[3], m.z, m.n, m.mem[9]))
            assert got[0] == got[1], f"{op} {cond} x={x:#x} y={y:#x}"


def test_compare_and_branch_timing():
    """Not taken: the next instruction in the next clock. Taken: the two behind it are squashed
    and the target is three clocks after the branch."""
    for x, taken in ((5, True), (6, False)):
        p = Program().li(1, x).nop().cbi("eq", 1, 5, "t").st(1, 0, 1).st(1, 0, 2).st(1, 0, 3)
        p.label("t").st(1, 0, 4)
        m = run(p)
        stores = [(op.addr, op.cycle) for op in m.trace if op.write]
        # li, nop, cbi in clocks 0..2: the store after it is on the bus in clock 4
        assert stores == ([(4, 6)] if taken else [(1, 4), (2, 5), (3, 6), (4, 7)])


def test_what_cannot_fuse_stays_a_pair():
    for compare in (lambda p: p.cmp(1, 2).nop(), lambda p: p.sub(3, 1, 2), lambda p: p.andi(0, 1, 6),
                    lambda p: p.cmpi(1, 300), lambda p: p.xor(0, 1, 2), lambda p: p.cmp(1, 2).label("x")):
        p = compare(Program()).b("eq", "y").label("y")
        assert not any(decode(w).op in CB_OPS for w in p.assemble().words)


def test_a_call_right_after_a_compare_and_branch_gets_a_nop():
    """(squashed, it would still set the link register)"""
    p = Program().cb("eq", 1, 2, "x").call("f").label("x").jmp("x").label("f").ret()
    assert [decode(w).op for w in p.assemble().words][:3] == ["cb", "nop", "call"]


@pytest.mark.parametrize("build, message", [
    (lambda p: p.cbi("eq", 1, 256, "x"), "cbi immediate 256"),
    (lambda p: p.cb("al", 1, 2, "x"), "condition other than al"),
])
def test_bad_compare_and_branches_are_refused(build, message):
    with pytest.raises(UcodeError, match=message):
        build(Program()).label("x").assemble()
