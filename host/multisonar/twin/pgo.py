"""The training run of the twin's profile-guided build (mk/twin.mk, ``make twin``).

``python -m multisonar.twin.pgo LIBRARY`` runs the instrumented harness (built with
``-fprofile-generate``, by g++ or clang: mk/twin.mk) on the demo's workload: boot, then 0.05 s
of the deterministic session of multisonar.twin.check.fixed_session (noisy corridor, the
compiled-in demo table, the exact skip on). At exit the library writes its profile, from which
the fast build is compiled (``-fprofile-use``; clang's raw profile is merged first): 1.3x the
clocks per second of a plain -O2 build (scripts/bench_twin_skip.py, docs/twin.md). The device's
run is the same every time; the profile's counts can differ a little between runs, where the
harness meets the echo thread's fences (a skip split at one)."""

from __future__ import annotations

import sys

from .check import booted_corridor, fixed_session


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        print("usage: python -m multisonar.twin.pgo LIBRARY", file=sys.stderr)
        return 2
    sim = booted_corridor(5, library=args[0])
    try:
        r = fixed_session(sim, 0.05, skip=True)
    finally:
        sim.close()
    print(f"twin pgo: trained on {r.tick} clocks, {len(r.fires)} pulses, {r.skip_stats[1]} clocks skipped")
    return 0


if __name__ == "__main__":
    sys.exit(main())
