"""cocotb tests of ms_sched_cfg (the scheduler's configuration check and load) against the
simulated device's decoder of the same registers, multisonar.simdevice.decode_vs_table.

Random tables: valid schedules with entries switched off, and single fields pushed to each
refusal. For every table the check's code and entry equal the decoder's; for an accepted table
the load writes every entry's record once, with the decoder's blanking, crosstalk neighbours
and their first / last delays, every element's blank interval and the share matrix.
"""

from __future__ import annotations

import os
import random
from types import SimpleNamespace

import cocotb
import numpy as np
from cocotb.triggers import ClockCycles, RisingEdge

from multisonar import protocol as P
from multisonar.generated import sonar_regs as R
from multisonar.schedule import _xtalk
from multisonar.simdevice import RegisterFile, _CfgErr, decode_vs_table
from tbutil import reset, start_clock
from vs_tables import random_table

NUM_CH = 24
NUM_VS = int(os.environ.get("CFG_NUM_VS", "8"))
TABLES = int(os.environ.get("CFG_TABLES", "200"))
WORDS = ("VS_TX_MASK", "VS_RX_MASK", "VS_MODE", "VS_WINDOW", "VS_T_DEAD", "VS_MAX_TOF", "VS_XTALK",
         "VS_TRACK", "VS_PHASE")
# the record's fields, most significant first (ms_sched_cfg_tb.sv)
REC = (("tx", 24), ("rx", 24), ("xt", 24), ("use", 24), ("act", 1), ("track", 1), ("order", 4),
       ("k", 4), ("reinit", 8), ("tv", 16), ("tn", 16), ("vmax", 16), ("rmax", 24), ("phase", 24),
       ("dbl", 24), ("lo", 24), ("hi", 24), ("burst", 8))
REC_W = sum(w for _, w in REC)
LAYOUT = SimpleNamespace(n=NUM_CH)
MASK24 = (1 << 24) - 1


def table_words(regs: RegisterFile) -> tuple[int, int]:
    dmem = R.MEMORIES["DELAY"]
    table = 0
    for vs in range(8):
        for r, name in enumerate(WORDS):
            table |= regs.get(name, vs) << ((vs * 9 + r) * 32)
    delays = 0
    for i in range(256):
        delays |= (regs.values[dmem.address + i * dmem.stride] & 0xFFFF) << (i * 16)
    return table, delays


def expected_load(regs: RegisterFile) -> tuple[list[dict], dict[int, tuple[int, int]], int]:
    """Records, blank intervals {(entry << 5) | element: (a, b)} and share bits as the load
    writes them (every entry, enabled or not)."""
    dmem = R.MEMORIES["DELAY"]
    recs, blk, use = [], {}, []
    for vs in range(NUM_VS):
        def fld(reg: str, f: str) -> int:
            return regs.field(reg, f, vs)
        tx, rx = fld("VS_TX_MASK", "MASK"), fld("VS_RX_MASK", "MASK")
        nb, mode = fld("VS_XTALK", "NB"), fld("VS_MODE", "MODE")
        dead, xtk = fld("VS_T_DEAD", "TICKS"), fld("VS_XTALK", "T_XTALK")
        d = [regs.values[dmem.address + (vs * 32 + e) * dmem.stride] for e in range(NUM_CH)]
        dmax = max([d[e] for e in range(NUM_CH) if tx >> e & 1], default=0)
        dbl = (max(dead, xtk) + dmax) & MASK24
        tv, tn, tmax = fld("VS_WINDOW", "T_V"), fld("VS_WINDOW", "T_N"), fld("VS_MAX_TOF", "TICKS")
        # crosstalk neighbours and their first / last tx delay: the model's own rule
        tx_el = np.array([e for e in range(NUM_CH) if tx >> e & 1], dtype=np.int64)
        xt_el, xt_d = _xtalk(tx_el, np.array([d[e] for e in tx_el], dtype=np.int64), nb, NUM_CH)
        xt = sum(1 << int(e) for e in xt_el)
        recs.append(dict(
            tx=tx, rx=rx, xt=xt, use=tx | rx | xt, act=int(mode != 0), track=int(mode == 1),
            order=fld("VS_MODE", "ORDER"), k=fld("VS_MODE", "MISS_LIMIT"), reinit=fld("VS_MODE", "REINIT_EVERY"),
            tv=tv, tn=tn, vmax=fld("VS_TRACK", "VMAX"), rmax=tmax, phase=fld("VS_PHASE", "TICKS"),
            dbl=dbl, lo=(dbl + tv) & MASK24, hi=(tmax - tn) & MASK24, burst=fld("VS_TRACK", "BURST_CYCLES")))
        use.append(tx | rx | xt)
        for e in range(NUM_CH):
            blk[(vs << 5) | e] = (d[e], d[e] + dead) if tx >> e & 1 else (0, 0)
        for e, (first, last) in zip(xt_el, xt_d):
            blk[(vs << 5) | int(e)] = (int(first), int(last) + xtk)
    share = 0
    for a in range(NUM_VS):
        for b in range(NUM_VS):
            if use[a] & use[b]:
                share |= 1 << (a * 8 + b)
    return recs, blk, share


def decoded(regs: RegisterFile) -> tuple[tuple[int, int], dict]:
    """The decoder's verdict as (cfg_error code, entry), (0, 0) when accepted, and its resolved
    sensors by entry."""
    try:
        return (0, 0), {s.id: s for s in decode_vs_table(regs, LAYOUT)}
    except _CfgErr as e:
        return (int(e.code), e.vs), {}


def decode_records(word: int) -> list[dict]:
    out = []
    for vs in range(NUM_VS):
        v = word >> (vs * REC_W) & ((1 << REC_W) - 1)
        rec, pos = {}, REC_W
        for name, w in REC:
            pos -= w
            rec[name] = v >> pos & ((1 << w) - 1)
        out.append(rec)
    return out


async def run_op(dut, op: str, limit: int = 20000) -> int:
    getattr(dut, op + "_i").value = 1
    await RisingEdge(dut.clk_i)
    getattr(dut, op + "_i").value = 0
    for _ in range(limit // 64):
        await ClockCycles(dut.clk_i, 64)
        if not int(dut.busy_o.value):
            return int(dut.clocks_o.value)
    raise AssertionError(f"{op} did not finish within {limit} clocks")


async def start(dut) -> None:
    start_clock(dut.clk_i)
    for s in ("check_i", "load_i", "abort_i"):
        getattr(dut, s).value = 0
    dut.burst_half_period_i.value = 0
    dut.table_i.value = 0
    dut.delays_i.value = 0
    await reset(dut.clk_i, dut.rst_i)


@cocotb.test()
async def random_tables_against_the_decoder(dut):
    await start(dut)
    rng = random.Random(2711)
    codes: dict[int, int] = {}
    clocks = {"check": [], "load": []}
    for t in range(TABLES):
        half = rng.choice([1, 300, 600])
        regs = random_table(rng, half, p_off=1.0 if t % 50 == 7 else 0.2, num_vs=NUM_VS)  # some empty tables
        table, delays = table_words(regs)
        dut.table_i.value = table
        dut.delays_i.value = delays
        dut.burst_half_period_i.value = half
        clocks["check"].append(await run_op(dut, "check"))
        err, err_vs = int(dut.err_o.value), int(dut.err_vs_o.value)
        want, resolved = decoded(regs)
        assert (err, err_vs) == want, f"table {t}: check says code {err} entry {err_vs}, decoder {want}"
        codes[err] = codes.get(err, 0) + 1
        if err:
            continue
        clocks["load"].append(await run_op(dut, "load"))
        recs, blk, share = expected_load(regs)
        got = decode_records(int(dut.records_o.value))
        counts = int(dut.ld_count_o.value)
        for vs in range(NUM_VS):
            assert counts >> (vs * 8) & 0xFF == 1, f"table {t}: entry {vs} written {counts >> (vs * 8) & 0xFF} times"
            assert got[vs] == recs[vs], f"table {t} entry {vs}: record {got[vs]}, expected {recs[vs]}"
            if vs in resolved:  # the decoder's own figures
                s = resolved[vs]
                assert got[vs]["dbl"] == s.blank, f"table {t} entry {vs}: blanking"
                assert sorted(int(e) for e in s.xtalk_elements) == [e for e in range(NUM_CH) if got[vs]["xt"] >> e & 1]
                for e, (first, last) in zip(s.xtalk_elements, s.xtalk_delays):
                    assert blk[(vs << 5) | int(e)] == (int(first), int(last) + s.t_xtalk)
                for e, dl in zip(s.tx, s.delays):
                    assert blk[(vs << 5) | int(e)] == (int(dl), int(dl) + s.t_dead)
        words = int(dut.blk_o.value)
        written = int(dut.blk_written_o.value)
        assert int(dut.blk_count_o.value) == NUM_VS * NUM_CH, f"table {t}: blank interval writes"
        for key, (a, b) in blk.items():
            assert written >> key & 1, f"table {t}: blank interval {key >> 5}/{key & 31} not written"
            w = words >> (key * 36) & ((1 << 36) - 1)
            assert (w >> 20, w & 0xFFFFF) == (a, b), \
                f"table {t}: blank interval of entry {key >> 5} element {key & 31}: {(w >> 20, w & 0xFFFFF)}, expected {(a, b)}"
        assert int(dut.share_o.value) == share, f"table {t}: share matrix {int(dut.share_o.value):016x}, expected {share:016x}"
        assert int(dut.share_count_o.value) == NUM_VS * (NUM_VS + 1) // 2
    dut._log.info("codes %s; clocks: check max %d, load max %d", dict(sorted(codes.items())),
                  max(clocks["check"]), max(clocks["load"]))
    # the generator reaches every code the scheduler reports (8 DELAY is the firmware's)
    if TABLES >= 200:
        missing = {int(c) for c in P.CfgError if int(c) not in (8,)} - set(codes) - {0}
        assert not missing, f"codes never produced: {sorted(missing)}"


@cocotb.test()
async def abort_stops_at_once(dut):
    await start(dut)
    rng = random.Random(5)
    regs = random_table(rng, 300, num_vs=NUM_VS)
    table, delays = table_words(regs)
    dut.table_i.value = table
    dut.delays_i.value = delays
    dut.burst_half_period_i.value = 300
    for op, after in (("check", 37), ("load", 500), ("load", 1)):
        getattr(dut, op + "_i").value = 1
        await RisingEdge(dut.clk_i)
        getattr(dut, op + "_i").value = 0
        await ClockCycles(dut.clk_i, after)
        dut.abort_i.value = 1
        await RisingEdge(dut.clk_i)
        dut.abort_i.value = 0
        for _ in range(3):
            await RisingEdge(dut.clk_i)
            assert not int(dut.busy_o.value) and not int(dut.done_o.value), f"{op} aborted after {after}"
    # and the next check runs normally
    await run_op(dut, "check")
    assert (int(dut.err_o.value), int(dut.err_vs_o.value)) == decoded(regs)[0]
