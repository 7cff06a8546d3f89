"""The scheduler's whole microcode program on the engine's model (sched_program.mainloop with
the hardware of sched_program.system), against the golden model on the lag bench's loads:
whether every event word and trigger equals the model's, and how late the engine gets (the
largest tick counter - logical tick at the end of a logical tick's work) against the P / 2
budget, for each decision lead P; and the program's size.

    .venv/bin/python scripts/bench_sched_mainloop.py [--lead 32768 16384] [--only burst8]
        [--ms N] [--jobs 2] [--plot out.png]

Prints a markdown table; writes build/bench/sched_mainloop.json.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "host"))
OUT = ROOT / "build" / "bench" / "sched_mainloop.json"


def measure(name: str, lead: int, ms: int | None) -> dict:
    from multisonar.tools.sched_program.scenarios import SCENARIOS, run_scenario

    ms = ms or SCENARIOS[name].ms
    t = time.time()
    res, eng = run_scenario(name, lead, ms)
    wall = time.time() - t
    same = eng.words == res.words and eng.triggers == sorted((x.tick, x.element) for x in res.triggers)
    return {"scenario": name, "lead": lead, "budget": lead // 2, "sim_ms": ms, "lag_max": eng.lag_max,
            "within_budget": eng.lag_max < lead // 2 and not eng.late, "late": len(eng.late),
            "identical_to_model": same, "pulses": len(res.pulses), "words": len(res.words),
            "cancels": len(res.cancelled), "logical_ticks": eng.lag_ticks,
            "wall_s": round(wall, 2)}   # the golden model and the program


def main() -> int:
    from multisonar.tools.sched_program.mainloop import main_program
    from multisonar.tools.sched_program.scenarios import SCENARIOS

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lead", type=int, nargs="+", default=[32768], help="decision leads P (ticks)")
    ap.add_argument("--only", nargs="+", choices=sorted(SCENARIOS), help="these scenarios")
    ap.add_argument("--ms", type=int, help="simulated milliseconds (default: each scenario's own)")
    ap.add_argument("--jobs", type=int, default=2, help="processes")
    ap.add_argument("--plot", help="write a bar chart PNG")
    args = ap.parse_args()
    img = main_program().assemble(depth=4096)
    cases = [(n, p) for p in args.lead for n in (args.only or SCENARIOS)]
    with ProcessPoolExecutor(args.jobs) as ex:
        rows = list(ex.map(measure, *zip(*cases), [args.ms] * len(cases)))
    print(f"program: {len(img.words)} words ({img.nops_inserted} hazard NOPs)\n")
    print("| scenario | P | lag max (ticks) | P / 2 | within | program = model | pulses | words | cancels | ms |")
    print("|---|---:|---:|---:|---|---|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['scenario']} | {r['lead']} | {r['lag_max']} | {r['budget']} | {r['within_budget']} "
              f"| {r['identical_to_model']} | {r['pulses']} | {r['words']} | {r['cancels']} | {r['sim_ms']} |")
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps({"program_words": len(img.words), "hazard_nops": img.nops_inserted,
                               "rows": rows}, indent=1))
    print(f"\nwritten {OUT}")
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 3.5))
        ax.bar([f"{r['scenario']}\nP={r['lead']}" for r in rows], [r["lag_max"] for r in rows])
        for p in args.lead:
            ax.axhline(p // 2, ls="--", color="r")
        ax.set_ylabel("engine lag max (ticks)")
        fig.tight_layout()
        fig.savefig(args.plot, dpi=120)
    return 0 if all(r["identical_to_model"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
