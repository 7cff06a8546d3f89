#!/usr/bin/env python3
"""Simulation speed: sonar-seconds per wall-second for the golden model (fast firing alone,
with the acoustic model on three scenes, with geometry, through the simulated USB device and
the host driver) and, with --rtl, for the RTL whole-system scene test (Verilator).

Thin wrapper of ``multisonar experiment simspeed`` (host/multisonar/experiments/simspeed.py).
Cases run one after the other in this process; numbers depend on the machine and its load.

    .venv/bin/python scripts/bench_sim_speed.py [--seconds 1] [--rtl] [--plot out.png]
"""

from __future__ import annotations

import argparse

from multisonar.experiments.common import print_result
from multisonar.experiments import simspeed


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=1.0, help="sonar time per golden-model case")
    ap.add_argument("--rtl", action="store_true", help="also time the RTL system scene test (Verilator)")
    ap.add_argument("--plot", help="write a bar chart PNG")
    args = ap.parse_args(argv)
    res = simspeed.run(None, seconds=args.seconds, rtl=args.rtl)
    print_result(res, args.plot)


if __name__ == "__main__":
    main()
