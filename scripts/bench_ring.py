#!/usr/bin/env python3
"""Full-ring refresh (issue #27): 8 virtual sensors over all 24 elements on a static room,
orders 1..MAX_ORDER, distance 1..5.7 m.

Thin wrapper of ``multisonar experiment ring`` (host/multisonar/experiments/ring.py): the
tick-exact scheduler model with the device's decision lead; complete sweeps of all 24
directions per second, per-direction and per-sensor rates, against the goal (>= 100 Hz at 2 m,
>= 60 Hz at 5.7 m) and Browne & Kleeman's 60 Hz at 5.7 m. Prints the markdown table.

    .venv/bin/python scripts/bench_ring.py [--plot out.png] [--json out.json] [--quick] [--rtl] [--workers N]
"""

from __future__ import annotations

import argparse
import json

from multisonar.experiments import ring
from multisonar.experiments.common import json_safe, print_result
from multisonar.experiments.executor import make_executor


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--plot", help="write the figure to this PNG")
    ap.add_argument("--json", help="write the machine-readable figures to this file")
    ap.add_argument("--quick", action="store_true", help="2 m and 5.7 m only, shorter runs")
    ap.add_argument("--temperature", type=float, default=20.0)
    ap.add_argument("--rtl", action="store_true", help="run the goal distances on the RTL scheduler too (Verilator)")
    ap.add_argument("--workers", type=int, default=1)
    args = ap.parse_args(argv)
    with make_executor(args.workers) as ex:
        res = ring.run(ex, quick=args.quick, temperature_c=args.temperature, rtl=args.rtl)
    print_result(res, args.plot)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(json_safe(res.json_data), fh, indent=1, allow_nan=False)
        print(f"figures written to {args.json}")


if __name__ == "__main__":
    main()
