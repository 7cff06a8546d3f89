#!/usr/bin/env python3
"""The speed/accuracy trade as one report: firing order, window width, receivers per virtual
sensor, geometry arithmetic -> sample rate, fix rate, latency, miss rate, range and angle
error (table + Pareto plot).

Thin wrapper of ``multisonar experiment tradeoff`` (host/multisonar/experiments/tradeoff.py,
where the scenario and the definitions are stated). The sweep runs on local processes
(--workers) or a Dask cluster (--scheduler tcp://HOST:PORT).

    .venv/bin/python scripts/bench_tradeoff.py [--quick] [--seconds 2] [--workers N] [--scheduler ADDR] [--plot out.png]
"""

from __future__ import annotations

import argparse
import os

from multisonar.experiments.common import print_result
from multisonar.experiments import tradeoff
from multisonar.experiments.executor import make_executor


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="a few configurations, 0.4 s each")
    ap.add_argument("--seconds", type=float, default=None, help="sonar time per configuration [2, quick 0.4]")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--scheduler", default=None, help="Dask scheduler address")
    ap.add_argument("--plot", help="write the Pareto plot to this PNG")
    args = ap.parse_args(argv)
    with make_executor(args.workers, args.scheduler) as ex:
        res = tradeoff.run(ex, quick=args.quick, seconds=args.seconds)
    print_result(res, args.plot)


if __name__ == "__main__":
    main()
