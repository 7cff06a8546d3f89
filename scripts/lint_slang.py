#!/usr/bin/env python3
"""Strict IEEE 1800 front end over our RTL: slang (pyslang), as `make lint` runs it.

Verilator accepts some things the standard does not (a signal used above its declaration,
for one); slang does not, and neither do the strict front ends our users feed the RTL to.
This elaborates the whole design (rtl/sources.f, then the ULX3S board files with Yosys'
ECP5 cell library for the vendor primitives) and fails on:
  - any error, in any file (third-party CPUs and generated code included: they must parse);
  - any warning in our own RTL (rtl/); warnings in generated or third-party files are
    counted and listed by kind but are not ours to change.

Warning kinds waived in our RTL are listed, each with its reason, in a waiver file
(rtl/lint/slang_waivers.txt, passed with --waivers).

Usage: lint_slang.py [--top TOP] [--waivers FILE] [-v LIBFILE] FILE...   (compile order)
"""
from __future__ import annotations

import argparse
import os
import re
import sys
from collections import Counter

import pyslang

DIAG_RE = re.compile(r"^(?P<file>[^:\s]+):(?P<line>\d+):(?P<col>\d+): (?P<sev>error|warning): (?P<msg>.*)$")


def read_waivers(path: str | None) -> list[str]:
    """slang options of a waiver file: one per line, '#' starts a comment."""
    if not path:
        return []
    opts = [ln.split("#", 1)[0].strip() for ln in open(path, encoding="utf-8")]
    bad = [o for o in opts if o and not o.startswith("-Wno-")]
    if bad:
        raise SystemExit(f"lint_slang: {path}: only -Wno-<kind> lines are allowed, not {bad}")
    return [o for o in opts if o]


def run(files: list[str], libs: list[str], top: str | None,
        waivers: list[str]) -> tuple[str, int]:
    """Elaborate with slang's own driver (the `slang` command line); returns its report and
    the error count."""
    driver = pyslang.driver.Driver()
    driver.addStandardArgs()
    args = ["slang", "--timescale", "1ns/1ps", "--error-limit=0"]
    if top:
        args += ["--top", top]
    args += waivers
    for lib in libs:
        args += ["-v", lib]
    args += files
    if not driver.parseCommandLine(" ".join(args), pyslang.driver.CommandLineOptions()):
        raise SystemExit("lint_slang: slang refused its command line")
    if not driver.processOptions() or not driver.parseAllSources():
        raise SystemExit("lint_slang: slang could not read the sources")
    comp = driver.createCompilation()
    engine = driver.diagEngine  # carries the -W options
    engine.clearClients()
    client = pyslang.TextDiagnosticClient()
    engine.addClient(client)
    for d in comp.getAllDiagnostics():
        engine.issue(d)
    return client.getString(), engine.numErrors


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--top", help="top module (default: every uninstantiated module)")
    ap.add_argument("-v", dest="libs", action="append", default=[],
                    help="library file: its modules are used only where instantiated")
    ap.add_argument("--waivers", help="file of -Wno-<kind> options, one per line, with reasons")
    ap.add_argument("files", nargs="+")
    a = ap.parse_args()
    report, n_err = run(a.files, a.libs, a.top, read_waivers(a.waivers))
    ours, foreign = [], Counter()
    lines = report.splitlines()
    for i, line in enumerate(lines):
        m = DIAG_RE.match(line)
        if not m:
            continue
        path = os.path.relpath(m["file"])
        if m["sev"] == "error" or path.startswith("rtl" + os.sep):
            ours.append("\n".join(lines[i:i + 3]))
        else:
            kind = re.search(r"\[(-W[^\]]+)\]", m["msg"])
            foreign[(os.path.basename(path), kind[1] if kind else m["msg"])] += 1
    if foreign:
        kinds = ", ".join(f"{name} {kind} x{n}" for (name, kind), n in sorted(foreign.items()))
        print(f"lint_slang: {sum(foreign.values())} warnings in generated or third-party files "
              f"ignored ({kinds})")
    if ours or n_err:
        print("\n".join(ours), file=sys.stderr)
        print(f"lint_slang: {n_err} errors, {len(ours)} findings in our RTL or errors anywhere",
              file=sys.stderr)
        return 1
    print(f"lint_slang: clean ({len(a.files)} files, slang {pyslang.__version__})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
