#!/usr/bin/env python3
"""Paper Fig. 9: wall-orientation error against the true wall orientation, 45 .. 135 deg,
2 and 3 receivers, with and without re-aiming.

Thin wrapper of ``multisonar experiment fig9`` (host/multisonar/experiments/fig9.py, where
the set-up is stated). Prints the markdown tables.

    .venv/bin/python scripts/bench_fig9_wall_angle.py [--cases 2000] [--step 5] [--plot out.png] [--workers N]
"""

from __future__ import annotations

import argparse

from multisonar.experiments.common import print_result
from multisonar.experiments import fig9
from multisonar.experiments.executor import make_executor


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", type=int, default=2000, help="noisy trials per orientation")
    ap.add_argument("--step", type=float, default=5.0, help="orientation step, deg")
    ap.add_argument("--distance", type=float, default=1.0, help="wall distance from the transmitter, m")
    ap.add_argument("--sigma-us", type=float, default=1.0)
    ap.add_argument("--seed", type=int, default=9)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--plot", help="write a PNG (mean +- std and max abs error vs orientation)")
    args = ap.parse_args(argv)
    with make_executor(args.workers) as ex:
        res = fig9.run(ex, cases=args.cases, step_deg=args.step, distance_m=args.distance, sigma_us=args.sigma_us,
                       seed=args.seed)
    print_result(res, args.plot)


if __name__ == "__main__":
    main()
