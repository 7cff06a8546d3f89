"""The firmware's table check and load (firmware/app/sonar/sched_table.c) against the Python
reference: the verdict of multisonar.simdevice.decode_vs_table (code and entry) and, for an
accepted table, the words of multisonar.tools.sched_program.system.load_image, address by
address. `make -C firmware host-sched` builds the C for the host (ctypes)."""

from __future__ import annotations

import ctypes
import random
import subprocess
from pathlib import Path
from types import SimpleNamespace

import pytest

from multisonar import protocol as P
from multisonar.constants import DEVICE_DECISION_LEAD
from multisonar.generated import sonar_regs as R
from multisonar.simdevice import _CfgErr, decode_vs_table
from multisonar.tools.sched_program.system import load_image

from vs_tables import random_table  # tests/rtl (on sys.path, tests/conftest.py)

ROOT = Path(__file__).resolve().parents[1]
LIB = ROOT / "build/fw/host/libmssched.so"
VS_WORDS = ("VS_TX_MASK", "VS_RX_MASK", "VS_MODE", "VS_WINDOW", "VS_T_DEAD", "VS_MAX_TOF", "VS_XTALK",
            "VS_TRACK", "VS_PHASE")
U32 = ctypes.c_uint32
PUT = ctypes.CFUNCTYPE(None, ctypes.c_void_p, U32, U32)


class Src(ctypes.Structure):
    _fields_ = [("vs", ctypes.POINTER(U32)), ("delay", ctypes.POINTER(U32)), ("delay_over", U32 * 8),
                ("burst_half_period", U32), ("lead", U32), ("glitch_min", U32), ("miss_gate", U32),
                ("miss_hold", U32)]


@pytest.fixture(scope="module")
def lib():
    r = subprocess.run(["make", "-s", "-C", str(ROOT / "firmware"), "host-sched"], capture_output=True, text=True)
    assert r.returncode == 0, f"make -C firmware host-sched failed:\n{r.stdout}\n{r.stderr}"
    L = ctypes.CDLL(str(LIB))
    L.ms_table_check.argtypes = [ctypes.POINTER(Src), ctypes.POINTER(U32)]
    L.ms_table_check.restype = U32
    L.ms_table_load.argtypes = [ctypes.POINTER(Src), PUT, ctypes.c_void_p]
    L.ms_table_load.restype = U32
    return L


def source(regs, *, glitch_min: int, miss_gate: int, miss_hold: int = 1) -> tuple[Src, list]:
    """The C view of a RegisterFile: VS words at the register map's stride, the DELAY memory."""
    stride = R.REGISTERS["VS_TX_MASK"].addr(1) - R.REGISTERS["VS_TX_MASK"].addr(0)
    assert stride == 64, "sched_table.c reads 16 words per entry"
    vs = (U32 * (16 * 8))()
    for i in range(8):
        for r, name in enumerate(VS_WORDS):
            assert R.REGISTERS[name].addr(i) == R.REGISTERS["VS_TX_MASK"].addr(i) + 4 * r
            vs[16 * i + r] = regs.get(name, i)
    mem = R.MEMORIES["DELAY"]
    delay = (U32 * 256)(*[regs.values[mem.address + i * mem.stride] for i in range(256)])
    over = [0] * 8
    for a in regs.over_width:
        i = (a - mem.address) // mem.stride
        over[i // 32] |= 1 << (i % 32)
    src = Src(ctypes.cast(vs, ctypes.POINTER(U32)), ctypes.cast(delay, ctypes.POINTER(U32)), (U32 * 8)(*over),
              regs.field("BURST", "HALF_PERIOD"), DEVICE_DECISION_LEAD, glitch_min, miss_gate, miss_hold)
    return src, [vs, delay]   # the arrays stay alive with the structure


def c_load(lib, src: Src) -> tuple[int, dict[int, int]]:
    words: dict[int, int] = {}
    dup: list[int] = []

    def put(_ctx, addr, word):
        if addr in words:
            dup.append(addr)
        words[addr] = word

    cb = PUT(put)
    act = lib.ms_table_load(ctypes.byref(src), cb, None)
    assert not dup, f"the load writes addresses {dup[:5]} twice"
    return act, words


def test_random_tables_match_the_reference(lib):
    """2,000 random tables (half of them with a field pushed to a refusal, some empty, some
    with over-wide DELAY words): the same verdict; every accepted table's load image equal."""
    rng = random.Random(20261202)
    layout = SimpleNamespace(n=24)
    codes: dict[int, int] = {}
    accepted = 0
    for t in range(2000):
        half = rng.choice([1, 300, 600])
        regs = random_table(rng, half, p_off=1.0 if t % 50 == 7 else 0.2)
        if rng.random() < 0.05:    # an over-wide DELAY word (the firmware's own refusal)
            mem = R.MEMORIES["DELAY"]
            regs.over_width.add(mem.address + rng.randrange(256) * mem.stride)
        glitch, gate = rng.choice([0, 1, 24, 255]), rng.choice([0, 2400, 65535])
        src, keep = source(regs, glitch_min=glitch, miss_gate=gate)
        entry = U32(99)
        code = lib.ms_table_check(ctypes.byref(src), ctypes.byref(entry))
        try:
            cfg = decode_vs_table(regs, layout)
            want = (0, 0)
        except _CfgErr as e:
            cfg, want = None, (int(e.code), e.vs)
        assert (code, entry.value) == want, f"table {t}: C says {P.CfgError(code).name} at entry {entry.value}, " \
                                            f"decode_vs_table {P.CfgError(want[0]).name} at entry {want[1]}"
        codes[code] = codes.get(code, 0) + 1
        if cfg is None:
            continue
        accepted += 1
        act, words = c_load(lib, src)
        assert act == sum(1 << c.id for c in cfg)
        ref = load_image(cfg, lead=DEVICE_DECISION_LEAD, glitch_min=glitch, miss_gate=gate)
        assert words.keys() == ref.keys(), f"table {t}: addresses only in C " \
            f"{sorted(words.keys() - ref.keys())[:5]}, only in Python {sorted(ref.keys() - words.keys())[:5]}"
        bad = [(hex(a), words[a], ref[a]) for a in sorted(ref) if words[a] != ref[a]]
        assert not bad, f"table {t}: (address, C, Python) differ: {bad[:5]}"
        del keep
    assert accepted >= 400, f"only {accepted} accepted tables"
    missing = {int(c) for c in P.CfgError} - set(codes)
    assert not missing, f"no table was refused with {[P.CfgError(c).name for c in missing]}"


def test_the_table_code_builds_for_the_soft_core():
    """sched_table.c compiles for the soft-core as the firmware's flags do (rv32im, -Werror)."""
    r = subprocess.run(["riscv64-unknown-elf-gcc", "-std=c11", "-march=rv32im", "-mabi=ilp32", "-Os",
                        "--specs=picolibc.specs", "-Wall", "-Wextra", "-Werror", f"-I{ROOT / 'build/gen/firmware'}",
                        "-c", str(ROOT / "firmware/app/sonar/sched_table.c"), "-o", "/dev/null"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def one_entry(**f) -> "RegisterFile":
    """A table whose entry 0 has the given fields (the rest: a valid 3-element track sensor)."""
    from multisonar.simdevice import RegisterFile

    v = dict(mode=1, order=2, k=3, tx=0b111, rx=0b11111, nb=1, burst=8, t_dead=40000, t_xt=40000,
             t_v=24000, t_n=24000, max_tof=400000, vmax=100, half=300, delays=(0, 17, 5))
    v.update(f)
    regs = RegisterFile()

    def put(name: str, **fields) -> None:
        reg, w = R.REGISTERS[name], 0
        for k, x in fields.items():
            w = reg.fields[k].put(w, x)
        regs.set_hw(name, w, 0)

    put("VS_TX_MASK", MASK=v["tx"])
    put("VS_RX_MASK", MASK=v["rx"])
    put("VS_MODE", MODE=v["mode"], ORDER=v["order"], MISS_LIMIT=v["k"], REINIT_EVERY=0)
    put("VS_WINDOW", T_V=v["t_v"], T_N=v["t_n"])
    put("VS_T_DEAD", TICKS=v["t_dead"])
    put("VS_MAX_TOF", TICKS=v["max_tof"])
    put("VS_XTALK", T_XTALK=v["t_xt"], NB=v["nb"])
    put("VS_TRACK", VMAX=v["vmax"], BURST_CYCLES=v["burst"])
    for i in range(1, 8):
        regs.set_hw("VS_MODE", 0, i)
    mem = R.MEMORIES["DELAY"]
    for e, d in zip((e for e in range(24) if v["tx"] >> e & 1), v["delays"]):
        regs.values[mem.address + e * mem.stride] = d
    regs.set_hw("BURST", R.REGISTERS["BURST"].fields["HALF_PERIOD"].put(R.REGISTERS["BURST"].reset, v["half"]))
    return regs


P_LEAD = DEVICE_DECISION_LEAD
EDGES = [  # (fields, expected code): each refusal's boundary, accepted on one side, refused on the other
    (dict(t_dead=P_LEAD - 17, t_xt=1), P.CfgError.LEAD),            # D = P exactly
    (dict(t_dead=P_LEAD - 16, t_xt=1), P.CfgError.OK),              # D = P + 1
    (dict(t_v=P_LEAD // 4, t_n=P_LEAD // 4), P.CfgError.WINDOW_SHORT),  # T_V + T_N = P / 2
    (dict(t_v=P_LEAD // 4, t_n=P_LEAD // 4 + 1), P.CfgError.OK),
    (dict(max_tof=40017 + 2 * 24000 - 1), P.CfgError.MAX_TOF),     # R - T_N = D + T_V - 1
    (dict(max_tof=40017 + 2 * 24000), P.CfgError.OK),              # R - T_N = D + T_V
    (dict(t_dead=8 * 2 * 300 - 1, t_xt=P_LEAD + 1), P.CfgError.WINDOW),  # T_dead one tick short of the burst
    (dict(t_dead=8 * 2 * 300, t_xt=P_LEAD + 1), P.CfgError.OK),
    (dict(tx=(1 << 23) | 1, delays=(0, 0)), P.CfgError.OK),         # a run across the ring's wrap
    (dict(tx=(1 << 23) | 2, delays=(0, 0)), P.CfgError.TX_MASK),
    (dict(tx=(1 << 24) - 1, delays=(0,) * 24, nb=3), P.CfgError.OK),  # every element: no neighbours
    (dict(order=8), P.CfgError.OK),
    (dict(order=9), P.CfgError.ORDER),
    (dict(mode=3), P.CfgError.BAD_MODE),
    (dict(k=0), P.CfgError.MISS_LIMIT),
    (dict(burst=0), P.CfgError.BURST),
    (dict(mode=0), P.CfgError.EMPTY_TABLE),
]


@pytest.mark.parametrize("fields,code", EDGES, ids=[f"{c.name}-{i}" for i, (_, c) in enumerate(EDGES)])
def test_refusal_boundaries(lib, fields, code):
    """Each refusal at its boundary tick: the C verdict, the reference's, the expected one."""
    regs = one_entry(**fields)
    src, keep = source(regs, glitch_min=24, miss_gate=2400)
    entry = U32(99)
    got = lib.ms_table_check(ctypes.byref(src), ctypes.byref(entry))
    try:
        cfg = decode_vs_table(regs, SimpleNamespace(n=24))
        ref = P.CfgError.OK
    except _CfgErr as e:
        cfg, ref = None, e.code
    assert (P.CfgError(got), P.CfgError(ref)) == (code, code)
    if cfg is not None:
        _, words = c_load(lib, src)
        assert words == load_image(cfg, lead=P_LEAD, glitch_min=24, miss_gate=2400)
    del keep
