#!/usr/bin/env python3
"""Where the full-system twin's time goes (issue #30): the profile behind its speed figures.

Two profiles of the demo's workload (corridor, the demo's five sensors, frames streamed to the
in-process driver):

1. Activity (always; multisonar.twin.activity): per clock, which units can change state beyond
   the counters that advance with time: the scheduler engine outside its poll loop, a transmit
   burst, a receive conditioner settling, a USB packet, the CPU awake (not stalled in its idle
   wait). A clock in none of them is calm; skipping calm clocks exactly (issue #30's first lever,
   which the twin does: scripts/bench_twin_skip.py) gains at most 1 / (fraction of clocks with
   activity). With the firmware's clocks per function.
2. Cost per clock by RTL block (--callgrind; needs valgrind): the twin built with line tables
   (make twin-prof) runs the workload under callgrind; the instructions of the generated C++
   are summed per RTL instance (the names Verilator gives the variables of each line), per
   clock. Deterministic: the same build gives the same counts on any machine and load, so it
   can judge changes a few per cent apart, which wall time cannot here.

    python scripts/bench_twin_profile.py [--seconds 0.2] [--callgrind] [--json F] [--plot F]
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "host"))

from multisonar.experiments.simspeed import profile_demo  # noqa: E402
from multisonar.twin.activity import CLASSES, SIMULATED  # noqa: E402

#: RTL blocks by the instance path of a generated line (first match wins)
BLOCKS = (
    (r"^u_soc\.g_vex\.u_cpu", "CPU (VexRiscv)"),
    (r"^u_sonar\.u_tx|^u_tx\b", "sonar: transmit phaser (24 channels)"),
    (r"^u_sonar\.g_rx|^g_rx", "sonar: receive conditioners (24)"),
    (r"^u_sonar\.u_csr|^u_csr", "sonar: registers (ms_csr + PeakRDL regblock)"),
    (r"^u_sonar\.u_sched|^u_sched|^u_eng|^u_slot|^u_closes", "sonar: scheduler (engine + units)"),
    (r"^u_sonar", "sonar: other (FIFO, glue)"),
    (r"^u_usb|^u_ep|^u_xact|^u_tx_tl|^u_pkt_rx|^u_desc", "USB device"),
    (r"^u_link|^u_cmd|^u_rep|^u_frm|^u_pack", "host link"),
    (r"^u_regs|bridge|^u_soc|^u_rst", "SoC: bus, registers, resets"),
)


def _block(path: str, source: str) -> str:
    for pat, name in BLOCKS:
        if re.search(pat, path):
            return name
    if "VexRiscv" in source or path.startswith(("IBus", "DBus")):
        return "CPU (VexRiscv)"
    if "ms_twin.cpp" in source:
        return "harness (ms_twin.cpp)"
    if "verilated" in source:
        return "Verilator runtime"
    if "_ms_soc_" in source:
        return "SoC: bus, registers, resets"
    if "_ms_system_usb_" in source:
        return "USB device"
    if "_ms_system_" in source:  # temporaries and control flow of the sonar core and the link
        return "sonar core + host link: lines naming no instance"
    if "___024root" in source or source.endswith("Vms_twin_top.cpp"):
        return "Verilator scheduling (eval, triggers)"
    return "other generated code"


def aggregate(ann: str, gen_dir: str) -> Counter[str]:
    """Instructions by RTL block from callgrind_annotate's per-line output: the lines of the
    generated C++ (in gen_dir), the harness and the Verilator runtime."""
    cost: Counter[str] = Counter()
    source = ""
    for line in ann.splitlines():
        if "annotated source:" in line:
            source = line.split("annotated source:")[1].strip()
            continue
        m = re.match(r"^\s*([\d,]+)\s+\(\s*[\d.]+%\)\s+(.*)$", line)
        if not m or not source or not (gen_dir in source or "ms_twin.cpp" in source or "verilated" in source):
            continue
        code = m.group(2)
        # calls (inclusive counts), and the summary lines (file:function, totals) that follow a section
        if "=>" in code or code.startswith(("/", ".", "???")) or code in ("events annotated", "PROGRAM TOTALS"):
            continue
        path = ""
        for ident in re.findall(r"[A-Za-z_]\w*__DOT__\w*", code):
            ident = re.sub(r"^.*?__PVT__|^__Vdly__|^__Vcellinp__", "", ident)
            ident = re.sub(r"__BRA__\d+__KET__", "", ident)
            parts = [p for p in ident.split("__DOT__")[:-1] if p.startswith(("u_", "g_", "IBus", "DBus"))]
            while parts[:1] in (["u_dev"], ["u_sys"]):  # (the whole design is inlined into the top)
                parts = parts[1:]
            if parts:
                path = ".".join(parts[:3])
                break
        if not path:
            m2 = re.search(r"__PVT__(u_[a-z]+)", code)
            path = m2.group(1) if m2 else ""
        cost[_block(path, source)] += int(m.group(1).replace(",", ""))
    return cost


def callgrind_blocks(seconds: float) -> dict:
    """Instructions per clock by RTL block, from callgrind on the line-table build."""
    for tool in ("valgrind", "callgrind_annotate"):
        if shutil.which(tool) is None:
            raise SystemExit(f"--callgrind needs {tool} (Debian: apt-get install valgrind)")
    subprocess.run(["make", "-s", "--no-print-directory", "-C", str(ROOT), "twin-prof"], check=True)
    lib = ROOT / "build/twin/prof/libmstwin.so"
    with tempfile.TemporaryDirectory() as tmp:
        out, side = Path(tmp) / "cg.out", Path(tmp) / "run.json"
        child = ("import json, sys; sys.path.insert(0, %r); "
                 "from multisonar.experiments.simspeed import profile_demo; "
                 "r = profile_demo(%r, library=%r, activity=False, warmup_s=0.0, skip=False); "
                 "json.dump({'clocks': r['clocks_from_reset']}, open(%r, 'w'))") % (
                     str(ROOT / "host"), seconds, str(lib), str(side))
        subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", sys.executable, "-c", child],
                       check=True, capture_output=True)
        clocks = json.loads(side.read_text())["clocks"]
        gen = sorted(str(p) for p in lib.parent.glob("*.cpp"))
        ann = subprocess.run(["callgrind_annotate", str(out), *gen], check=True, capture_output=True,
                             text=True).stdout
        total = subprocess.run(["callgrind_annotate", "--inclusive=yes", str(out)], check=True,
                               capture_output=True, text=True).stdout
    step = next((int(m.group(1).replace(",", "")) for m in
                 (re.match(r"\s*([\d,]+)\s.*Twin::step\(\) \[", line) for line in total.splitlines()) if m), 0)
    cost = aggregate(ann, "twin/prof/")  # the debug info names the sources relative to the repository
    annotated = sum(cost.values())
    return {"clocks": clocks, "instructions_per_clock": round(step / clocks, 1) if clocks else None,
            "annotated_per_clock": round(annotated / clocks, 1) if clocks else None,
            "blocks": [{"block": k, "per_clock": round(v / clocks, 1), "fraction": round(v / annotated, 4)}
                       for k, v in cost.most_common()]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=0.2, help="sonar time of the activity profile (default 0.2)")
    ap.add_argument("--warmup", type=float, default=0.05,
                    help="sonar time streamed from START before the activity profile starts (default 0.05)")
    ap.add_argument("--callgrind", action="store_true", help="also the cost per clock by RTL block (valgrind)")
    ap.add_argument("--callgrind-seconds", type=float, default=0.02,
                    help="sonar time streamed under callgrind after boot and START (default 0.02: ~3 min)")
    ap.add_argument("--json", type=Path, help="write the figures as JSON")
    ap.add_argument("--plot", type=Path, help="write a bar chart (PNG)")
    args = ap.parse_args()

    r = profile_demo(args.seconds, warmup_s=args.warmup)
    act = r["activity"]
    d = act.as_dict()
    print(f"# Activity of the twin: {r['scene']}, the demo's five sensors, {r['sonar_s']:.3f} sonar-s after "
          f"{args.warmup:g} s from START "
          f"({act.clocks:,} clocks; {r['sonar_s'] / r['wall_s']:.4f} sonar-s per wall-s with the profile on)\n")
    print("| class | clocks | fraction |\n|---|---:|---:|")
    for k in CLASSES:
        print(f"| {k} | {act.counts[k]:,} | {act.fraction(k):.1%} |")
    print(f"\nExact skip of the calm clocks: at most {act.skip_bound:.2f}x on this workload "
          f"({d['sonar_only_skip_speedup_bound']:.2f}x if the CPU's busy clocks were calm too).\n")
    print(f"The clocks the twin simulated ({act.simulated:,}, {act.simulated / act.clocks:.1%}; the rest it skipped), "
          "by who works in them:\n")
    print("| simulated | clocks | of the simulated |\n|---|---:|---:|")
    for k in SIMULATED:
        print(f"| {k[4:]} | {act.counts[k]:,} | {d['simulated'][k]:.1%} |")
    # the clock gates (docs/twin.md): clocks in which each unit's clock was held, of those simulated
    units = {"cpu": ("CPU (VexRiscv)", 1), "sonar": ("sonar core", 1), "rx": ("receive conditioners", 1),
             "tx": ("transmit elements (24 clocks)", 24), "usb": ("USB device", 1)}
    sim_clocks = max(r["simulated"], 1)
    gates = {k: {"held": r["clocks_held"][k], "of_simulated": round(r["clocks_held"][k] / (n * sim_clocks), 4)}
             for k, (_, n) in units.items()}
    print(f"\nClock gates: the simulated clocks in which a unit's clock was held ({r['simulated']:,} simulated)\n")
    print("| unit | clocks held | of the simulated |\n|---|---:|---:|")
    for k, (name, _) in units.items():
        print(f"| {name} | {gates[k]['held']:,} | {gates[k]['of_simulated']:.1%} |")
    print()
    print("| firmware function | clocks | of the CPU's |\n|---|---:|---:|")
    for f in d["firmware_functions"]:
        print(f"| {f['function']} | {f['clocks']:,} | {f['fraction']:.1%} |")
    out = {"scene": r["scene"], "warmup_s": args.warmup, "sonar_s": r["sonar_s"], "wall_s": round(r["wall_s"], 2),
           "sonar_s_per_wall_s_profiled": round(r["sonar_s"] / r["wall_s"], 5), "activity": d,
           "simulated_clocks": r["simulated"], "clock_gates": gates}
    if args.callgrind:
        cg = callgrind_blocks(args.callgrind_seconds)
        out["cost"] = cg
        print(f"\n# Cost per clock by RTL block (callgrind, {cg['clocks']:,} clocks from reset, boot included: "
              f"{cg['instructions_per_clock']:,} instructions per clock in Twin::step)\n")
        print("| block | instructions per clock | share |\n|---|---:|---:|")
        for b in cg["blocks"]:
            print(f"| {b['block']} | {b['per_clock']:,.0f} | {b['fraction']:.1%} |")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(out, indent=1))
        print(f"\nwrote {args.json}")
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        n = 2 if args.callgrind else 1
        fig, axes = plt.subplots(1, n, figsize=(6 * n, 4), squeeze=False)
        ks = list(CLASSES)
        axes[0][0].barh(ks[::-1], [act.fraction(k) for k in ks][::-1])
        axes[0][0].set_xlabel("fraction of clocks")
        axes[0][0].set_title(f"activity (skip bound {act.skip_bound:.2f}x)")
        if args.callgrind:
            bl = out["cost"]["blocks"]
            axes[0][1].barh([b["block"] for b in bl][::-1], [b["per_clock"] for b in bl][::-1])
            axes[0][1].set_xlabel("instructions per clock")
            axes[0][1].set_title("cost by RTL block")
        fig.tight_layout()
        args.plot.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(args.plot, dpi=110)
        print(f"wrote {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
