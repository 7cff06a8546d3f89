#!/usr/bin/env python3
"""Paper Fig. 3: per-sensor sample rate of fast firing vs distance, order 1..4.

Thin wrapper of ``multisonar experiment fig3`` (host/multisonar/experiments/fig3.py): the
tick-exact scheduler model on a static reflector at each distance, next to the analytic
T_s = (T_E - T_dead - T_V)/n and the interlace limit. Prints the markdown table.

    .venv/bin/python scripts/bench_fig3_sample_rate.py [--plot out.png] [--temperature 20] [--rtl] [--workers N]
"""

from __future__ import annotations

import argparse

from multisonar.experiments.common import print_result
from multisonar.experiments import fig3
from multisonar.experiments.executor import make_executor


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--plot", help="write the figure to this PNG")
    ap.add_argument("--temperature", type=float, default=20.0)
    ap.add_argument("--rtl", action="store_true", help="add the RTL scheduler column (Verilator)")
    ap.add_argument("--workers", type=int, default=1)
    args = ap.parse_args(argv)
    with make_executor(args.workers) as ex:
        res = fig3.run(ex, temperature_c=args.temperature, rtl=args.rtl)
    print_result(res, args.plot)


if __name__ == "__main__":
    main()
