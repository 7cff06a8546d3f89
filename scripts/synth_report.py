"""Synthesis report: resource use, Fmax per clock and the critical path of a `make synth` run.

    .venv/bin/python scripts/synth_report.py make --target ecp5 --device LFE5U-45F-CABGA381 \
        --stat build/synth/ecp5/stat.json --pnr build/synth/ecp5/report.json \
        --require-mhz 48 --out build/synth/ecp5/report.txt
    .venv/bin/python scripts/synth_report.py compare build/synth/ecp5/report.txt synth/ecp5_25k_report.txt \
        --min-mhz 62.4 --max-lut-growth 0.10

    .venv/bin/python scripts/synth_report.py blocks build/synth/blocks/ms_sched_uc.json ...
    .venv/bin/python scripts/synth_report.py late build/synth/ecp5/pnr.json --mhz 62.4
    .venv/bin/python scripts/synth_report.py area build/synth/blocks/ms_sched_uc.net.json

`make` writes the report (yosys `stat -json` cell counts + nextpnr `--report` JSON) and exits
non-zero when a clock misses --require-mhz. `compare` checks a fresh report against the
committed one (synth/ecp5_25k_report.txt): it fails when Fmax is below --min-mhz or LUT use grew
by more than --max-lut-growth, and always prints the differences. `blocks` prints a markdown
table of the yosys cells of blocks synthesised alone (`make synth-blocks`): where the area is.
`late` reads a nextpnr report written with --detailed-timing-report (`make synth
SYNTH_DETAIL=1`) and lists the register inputs whose routed arrival time misses a clock of
--mhz, grouped by block and by register: where the long paths of the whole design are (nextpnr
itself prints only the single worst path per clock).
`area` reads a mapped ECP5 netlist (Yosys `write_json` after synth_ecp5, e.g. `make
synth-blocks` writes build/synth/blocks/BLOCK.net.json) and charges every LUT4 (1) and CCU2C (2)
to the registers and RAM ports its output reaches through other logic, split evenly among them:
which register's input logic costs the area.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

# nextpnr BEL types per family (the product is ECP5): what counts as LUTs, flip-flops, block RAM and DSP
FAMILY_BELS: dict[str, dict[str, str]] = {
    "ecp5": {"luts": "TRELLIS_COMB", "ffs": "TRELLIS_FF", "bram": "DP16KD", "dsp": "MULT18X18D",
             "io": "TRELLIS_IO", "lutram": "TRELLIS_RAMW"},
}
# yosys cell types worth listing (technology-mapped netlist before placement)
YOSYS_CELLS = ("LUT4", "CCU2C", "PFUMX", "L6MUX21", "TRELLIS_FF", "TRELLIS_DPR16X4", "DP16KD", "MULT18X18D",
               "SB_LUT4", "SB_CARRY", "SB_DFF", "SB_DFFE", "SB_DFFR", "SB_DFFSR", "SB_DFFER", "SB_DFFESR",
               "SB_DFFSS", "SB_DFFESS", "SB_DFFS", "SB_DFFES", "SB_RAM40_4K", "SB_MAC16", "SB_PLL40_CORE",
               "SB_PLL40_PAD", "EHXPLLL")


class SynthReportError(RuntimeError):
    """A report input is missing or malformed, or a check failed."""


@dataclass
class Summary:
    """The numbers a report file carries (parsed back by `compare`)."""

    values: dict[str, str]

    def number(self, key: str) -> float:
        if key not in self.values:
            raise SynthReportError(f"report has no '{key}' line; regenerate it with `make synth`")
        return float(self.values[key].split()[0])


def _load_json(path: Path, what: str) -> dict:
    if not path.is_file():
        raise SynthReportError(f"{what} {path} does not exist: did the synthesis step before it fail?")
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise SynthReportError(f"{what} {path} is not valid JSON ({e})") from e


def yosys_cells(stat: dict) -> dict[str, int]:
    """Cell counts of the top module from `stat -json` (the design is flat after synth_*)."""
    design = stat.get("design") or {}
    cells = design.get("num_cells_by_type")
    if cells is None:  # older layout: per module
        mods = stat.get("modules") or {}
        cells = {}
        for mod in mods.values():
            for k, v in (mod.get("num_cells_by_type") or {}).items():
                cells[k] = cells.get(k, 0) + int(v)
    return {k: int(v) for k, v in cells.items()}


def critical_path_lines(pnr: dict, limit: int = 12) -> list[str]:
    """The longest path of each clock, as 'delay  cell.port' lines from nextpnr's report."""
    out: list[str] = []
    for cp in pnr.get("critical_paths", []):
        segs = cp.get("path", [])
        if not segs:
            continue
        total = sum(float(s.get("delay", 0.0)) for s in segs)
        logic = sum(1 for s in segs if s.get("type") == "logic")
        route = sum(float(s.get("delay", 0.0)) for s in segs if s.get("type") == "routing")
        start, end = segs[0].get("from", {}), segs[-1].get("to", {})
        out.append(f"critical_path: {cp.get('from', '?')} -> {cp.get('to', '?')}: {total:.2f} ns, "
                   f"{logic} logic levels, {route:.2f} ns routing")
        out.append(f"  from {start.get('cell', '?')}.{start.get('port', '?')}")
        cells: list[str] = []
        for s in segs:
            c = s.get("to", {}).get("cell")
            if c and s.get("type") == "logic" and c not in cells:
                cells.append(c)
        shown = cells if len(cells) <= limit else cells[: limit // 2] + ["..."] + cells[-limit // 2:]
        for c in shown:
            out.append(f"  via  {c}")
        out.append(f"  to   {end.get('cell', '?')}.{end.get('port', '?')}")
    return out


def make_report(args: argparse.Namespace) -> int:
    stat = _load_json(Path(args.stat), "yosys statistics")
    pnr = _load_json(Path(args.pnr), "nextpnr report")
    bels = FAMILY_BELS[args.target]
    util = pnr.get("utilization", {})
    lines = [
        f"# Multisonar synthesis report (make synth TARGET={args.target}); regenerate with make synth",
        f"target: {args.target}",
        f"device: {args.device}",
    ]
    for extra in args.note or []:
        lines.append(f"# {extra}")
    for key in ("luts", "ffs", "bram", "dsp", "io", "lutram"):
        bel = bels.get(key)
        if bel and bel in util:
            u = util[bel]
            pct = 100.0 * u["used"] / u["available"] if u["available"] else 0.0
            lines.append(f"{key}: {u['used']} / {u['available']} {bel} ({pct:.1f} %)")
    cells = yosys_cells(stat)
    lines.append("yosys_cells: " + ", ".join(f"{k} {cells[k]}" for k in YOSYS_CELLS if k in cells))
    fmax = pnr.get("fmax", {})
    if not fmax:
        raise SynthReportError(f"{args.pnr} has no 'fmax' entry: nextpnr found no clock (is the clock constrained?)")
    failed = []
    worst = None
    for clk, f in sorted(fmax.items()):
        achieved = float(f["achieved"])
        margin = achieved / args.require_mhz
        lines.append(f"fmax_mhz[{clk}]: {achieved:.2f} (required {args.require_mhz:.2f} MHz, margin {margin:.2f}x, "
                     f"nextpnr constraint {float(f.get('constraint', 0)):.2f})")
        worst = achieved if worst is None else min(worst, achieved)
        if achieved < args.require_mhz:
            failed.append(f"{clk}: {achieved:.2f} MHz < {args.require_mhz:.2f} MHz")
    lines.append(f"fmax_mhz: {worst:.2f}")
    lines += critical_path_lines(pnr)
    text = "\n".join(lines) + "\n"
    Path(args.out).write_text(text)
    print(text, end="")
    if failed:
        print(f"synth: TIMING NOT MET ({'; '.join(failed)}); report {args.out}", file=sys.stderr)
        return 1
    print(f"synth: timing met; report {args.out}")
    return 0


def parse_report(path: Path) -> Summary:
    if not path.is_file():
        raise SynthReportError(f"report {path} does not exist")
    values: dict[str, str] = {}
    for line in path.read_text().splitlines():
        if not line or line.startswith(("#", " ")) or ":" not in line:
            continue
        key, _, value = line.partition(":")
        values.setdefault(key.strip(), value.strip())
    return Summary(values)


def seed_fmax(path: Path) -> dict[int, float | None]:
    """Per placer seed, the Fmax a report's header line lists (`seed N (best of seed 1: X MHz,
    seed 2: failed, ...)`, written by `best`); None for a seed that did not route. A report of a
    single seed lists none: {}."""
    import re

    out: dict[int, float | None] = {}
    for line in path.read_text().splitlines():
        if line.startswith("#") and "best of" in line:
            for seed, what in re.findall(r"seed (\d+): ([^,)]+)", line.split("best of", 1)[1]):
                m = re.match(r"([0-9.]+) MHz", what.strip())
                out[int(seed)] = float(m.group(1)) if m else None
    return out


def compare(new_path: Path, ref_path: Path, min_mhz: float, max_lut_growth: float,
            min_worst_mhz: float | None = None) -> list[str]:
    """Differences between two reports; returns the list of failures (empty = pass). Fmax is the
    best seed's; with ``min_worst_mhz`` every seed the report lists must also have routed at
    that Fmax or more (the timing margin at every placement, not at the luckiest one)."""
    new, ref = parse_report(new_path), parse_report(ref_path)
    print(f"{'key':<16} {'committed':>12} {'this build':>12}  change")
    for key in ("luts", "ffs", "bram", "dsp", "lutram", "fmax_mhz"):
        if key in new.values or key in ref.values:
            a = ref.number(key) if key in ref.values else float("nan")
            b = new.number(key) if key in new.values else float("nan")
            rel = f"{100.0 * (b - a) / a:+.1f} %" if a else ""
            print(f"{key:<16} {a:>12.2f} {b:>12.2f}  {rel}")
    failures = []
    if new.values.get("device") != ref.values.get("device"):
        failures.append(f"device changed: {ref.values.get('device')} -> {new.values.get('device')} "
                        f"(update {ref_path} with the new report if intended)")
    fmax = new.number("fmax_mhz")
    if fmax < min_mhz:
        failures.append(f"Fmax {fmax:.2f} MHz is below {min_mhz:.2f} MHz ({min_mhz / 48.0:.2f}x the 48 MHz clock)")
    if min_worst_mhz is not None:
        seeds = seed_fmax(new_path)
        if seeds:
            got = sorted(v for v in seeds.values() if v is not None)
            print(f"seeds: {', '.join(f'{k}: ' + ('failed' if v is None else f'{v:.2f}') for k, v in sorted(seeds.items()))}"
                  f" MHz; worst {got[0] if got else float('nan'):.2f}, median "
                  f"{(got[(len(got) - 1) // 2] + got[len(got) // 2]) / 2 if got else float('nan'):.2f}")
        for seed, v in sorted(seeds.items()):
            if v is None or v < min_worst_mhz:
                failures.append(f"seed {seed}: {'did not route' if v is None else f'{v:.2f} MHz'}, every seed must reach "
                                f"{min_worst_mhz:.2f} MHz ({min_worst_mhz / 48.0:.2f}x the 48 MHz clock)")
    luts_new, luts_ref = new.number("luts"), ref.number("luts")
    if luts_new > luts_ref * (1.0 + max_lut_growth):
        failures.append(f"LUT use grew {100.0 * (luts_new / luts_ref - 1):.1f} % ({luts_ref:.0f} -> {luts_new:.0f}), "
                        f"more than {100 * max_lut_growth:.0f} %: check the change, then commit the new report "
                        f"({new_path} -> {ref_path})")
    return failures


BLOCK_COLUMNS = ("LUT4", "CCU2C", "PFUMX", "L6MUX21", "TRELLIS_FF", "TRELLIS_DPR16X4", "DP16KD", "MULT18X18D")


def blocks_table(paths: list[Path]) -> list[str]:
    """Markdown table, one row per block (file name = block), of its technology-mapped cells;
    with the out-of-context place and route of a block beside it (BLOCK.pnr.json, `make
    synth-blocks SYNTH_BLOCKS_PNR=1`) also its TRELLIS_COMB count and routed Fmax."""
    pnrs = [p.with_name(p.stem + ".pnr.json") for p in paths]
    routed = any(p.exists() for p in pnrs)
    extra = ("TRELLIS_COMB", "Fmax MHz") if routed else ()
    cols = BLOCK_COLUMNS + extra
    lines = ["| block | " + " | ".join(cols) + " |", "|---|" + "---:|" * len(cols)]
    for path, pnr_path in zip(paths, pnrs):
        cells = yosys_cells(_load_json(path, "yosys stat"))
        row = [str(cells.get(c, 0)) for c in BLOCK_COLUMNS]
        if routed:
            if pnr_path.exists():
                pnr = _load_json(pnr_path, "nextpnr report")
                comb = pnr.get("utilization", {}).get("TRELLIS_COMB", {}).get("used", "?")
                fmax = [float(f["achieved"]) for f in pnr.get("fmax", {}).values()]
                row += [str(comb), f"{min(fmax):.2f}" if fmax else "-"]
            else:
                row += ["-", "-"]
        lines.append(f"| {path.stem} | " + " | ".join(row) + " |")
    return lines


# register / RAM inputs that end a timing path (TRELLIS_FF data, enable and set/reset; LUT-RAM
# write ports; block RAM and multiplier inputs)
_ENDPOINT_PORTS = {"TRELLIS_FF": ("DI", "M", "CE", "LSR")}


def _register_stem(cell: str) -> str:
    """The RTL register a packed cell belongs to: 'a.b.x_q_TRELLIS_FF_Q_12' -> 'a.b.x_q'."""
    for cut in ("_TRELLIS_FF", "$DPRAM", "_DPR16X4"):
        if cut in cell:
            cell = cell[:cell.index(cut)]
    return cell


def late_endpoints(pnr: dict, mhz: float, setup_ns: float = 0.4) -> tuple[int, dict[tuple[str, str], float]]:
    """(endpoints seen, {(cell, port): worst arrival ns}) of the endpoints whose arrival
    (clock-to-out plus logic plus routing, from nextpnr's detailed net timings) exceeds the
    period at `mhz` minus `setup_ns`."""
    nets = pnr.get("detailed_net_timings")
    if nets is None:
        raise SynthReportError("no detailed_net_timings in the nextpnr report: run nextpnr with "
                               "--detailed-timing-report (make synth SYNTH_DETAIL=1)")
    limit = 1000.0 / mhz - setup_ns
    arrival: dict[tuple[str, str], float] = {}
    for net in nets:
        for ep in net.get("endpoints", []):
            cell, port = ep["cell"], ep["port"]
            is_ff = "TRELLIS_FF" in cell and port in _ENDPOINT_PORTS["TRELLIS_FF"]
            if not (is_ff or "DPRAM" in cell or "DP16KD" in cell or "MULT18" in cell):
                continue
            delay = ep["delay"]
            worst = max(delay) if isinstance(delay, list) else float(delay)
            arrival[(cell, port)] = max(arrival.get((cell, port), 0.0), worst)
    return len(arrival), {k: v for k, v in arrival.items() if v > limit}


def late_sources(pnr: dict, mhz: float) -> dict[str, int]:
    """Where the late paths start: each late endpoint is traced back through the latest
    arriving input of every cell on its way (from the detailed net timings) until a register
    output or a cell whose inputs the report does not list; returns {that cell: late endpoints}.
    A high-fanout enable shows as one cell with many endpoints behind it."""
    _, late = late_endpoints(pnr, mhz)
    arrival_in: dict[str, dict[str, float]] = {}
    driver: dict[tuple[str, str], tuple[str, str]] = {}
    for net in pnr["detailed_net_timings"]:
        for ep in net.get("endpoints", []):
            delay = ep["delay"]
            worst = max(delay) if isinstance(delay, list) else float(delay)
            ports = arrival_in.setdefault(ep["cell"], {})
            ports[ep["port"]] = max(ports.get(ep["port"], 0.0), worst)
            driver[(ep["cell"], ep["port"])] = (net["driver"], net["port"])
    starts: dict[str, int] = {}
    for cell, port in late:
        for _ in range(200):  # a path is far shorter; the bound only guards against loops
            src = driver.get((cell, port))
            if src is None:
                break
            cell, out_port = src
            inputs = arrival_in.get(cell)
            if out_port == "Q" or not inputs or "TRELLIS_FF" in cell:
                break
            port = max(inputs, key=inputs.__getitem__)
        starts[cell] = starts.get(cell, 0) + 1
    return starts


def late_tables(pnr: dict, mhz: float, depth: int = 4, rows: int = 40) -> list[str]:
    """Markdown: late endpoints per block (hierarchy cut at `depth`), then per register."""
    seen, late = late_endpoints(pnr, mhz)
    lines = [f"{len(late)} of {seen} register / RAM inputs arrive later than {1000.0 / mhz - 0.4:.2f} ns "
             f"(a {mhz:g} MHz clock less 0.4 ns setup)", "", "| block | late inputs | worst ns |", "|---|---:|---:|"]
    blocks: dict[str, list[float]] = {}
    regs: dict[tuple[str, str], list[float]] = {}
    for (cell, port), ns in late.items():
        stem = _register_stem(cell)
        blocks.setdefault(".".join(stem.split(".")[:depth]), []).append(ns)
        regs.setdefault((stem, port), []).append(ns)
    for name, v in sorted(blocks.items(), key=lambda kv: -len(kv[1])):
        lines.append(f"| {name} | {len(v)} | {max(v):.2f} |")
    lines += ["", "| register | pin | late bits | worst ns |", "|---|---|---:|---:|"]
    for (name, port), v in sorted(regs.items(), key=lambda kv: -max(kv[1]))[:rows]:
        lines.append(f"| {name} | {port} | {len(v)} | {max(v):.2f} |")
    return lines


_COMB_COST = {"LUT4": 1.0, "CCU2C": 2.0, "PFUMX": 0.0, "L6MUX21": 0.0}  # TRELLIS_COMB per cell


def area_by_register(netlist: dict, module: str | None = None) -> tuple[float, dict[str, float], dict[str, int]]:
    """(total LUT4 + 2 CCU2C, cost per sink, flip-flops) of a mapped ECP5 netlist. A sink is a
    flip-flop, `NET@CELL` (its output net, bit index dropped, and its cell, whose name carries
    the hierarchy), or a RAM / DSP input, `TYPE:PORT@CELL`; logic that reaches no sink (a top
    port) is charged to `<none>`. `by_register` sums the figures per register."""
    mods = netlist.get("modules", {})
    if module is None:
        tops = [m for m, v in mods.items() if str(v.get("attributes", {}).get("top", "0")).strip("0") != ""]
        if len(tops) != 1:
            raise SynthReportError(f"netlist has {len(tops)} top modules; name one of {sorted(mods)[:8]}")
        module = tops[0]
    if module not in mods:
        raise SynthReportError(f"module {module!r} is not in the netlist")
    mod = mods[module]
    net_name: dict[int, str] = {}
    for name, v in mod.get("netnames", {}).items():
        base = name if name.startswith("$") else name.split("[")[0]
        for b in v["bits"]:
            if isinstance(b, int) and (b not in net_name or (net_name[b].startswith("$") and not base.startswith("$"))):
                net_name[b] = base
    cells = mod.get("cells", {})
    readers: dict[int, list[tuple[str, str]]] = {}
    for cname, c in cells.items():
        dirs = c.get("port_directions", {})
        for port, bits in c.get("connections", {}).items():
            if dirs.get(port) != "output":
                for b in bits:
                    if isinstance(b, int):
                        readers.setdefault(b, []).append((cname, port))
    memo: dict[str, frozenset[str]] = {}

    def sinks(cname: str) -> frozenset[str]:  # iterative post-order walk over combinational cells
        stack = [(cname, False)]
        while stack:
            n, readers_done = stack.pop()
            c = cells[n]
            outs = [b for port, bits in c["connections"].items()
                    if c.get("port_directions", {}).get(port) == "output" for b in bits if isinstance(b, int)]
            if not readers_done:
                if n in memo:
                    continue
                memo[n] = frozenset()  # placeholder: cuts combinational loops
                stack.append((n, True))
                stack.extend((r, False) for b in outs for r, _ in readers.get(b, [])
                             if cells[r]["type"] in _COMB_COST and r not in memo)
                continue
            out: set[str] = set()
            for b in outs:
                for r, rp in readers.get(b, []):
                    rc = cells[r]
                    if rc["type"] in _COMB_COST:
                        out |= memo[r]
                    elif rc["type"] == "TRELLIS_FF":
                        out.add(f"{net_name.get(rc['connections']['Q'][0], r)}@{r}")
                    else:
                        out.add(f"{rc['type']}:{rp[:2]}@{r}")
            memo[n] = frozenset(out)
        return memo[cname]

    total, cost = 0.0, {}
    for cname, c in cells.items():
        w = _COMB_COST.get(c["type"], 0.0)
        if not w:
            continue
        total += w
        s = sinks(cname) or frozenset({"<none>"})
        for x in s:
            cost[x] = cost.get(x, 0.0) + w / len(s)
    ffs: dict[str, int] = {}
    for cname, c in cells.items():
        if c["type"] == "TRELLIS_FF":
            ffs[f"{net_name.get(c['connections']['Q'][0], '?')}@{cname}"] = 1
    return total, cost, ffs


def by_register(fig: dict[str, float]) -> dict[str, float]:
    """area_by_register's per-sink figures summed per register / RAM port (`NAME@CELL` -> `NAME`)."""
    out: dict[str, float] = {}
    for name, v in fig.items():
        reg = name.split("@")[0]
        out[reg] = out.get(reg, 0) + v
    return out


def area_by_instance(cost: dict[str, float], ffs: dict[str, int],
                     depth: int) -> list[tuple[str, tuple[float, int]]]:
    """area_by_register's figures summed per instance path: the first `depth` dot-separated parts
    of each sink's cell name, the costliest first. A name with fewer parts than `depth` + 1 is
    its own path's top level (`(top)`)."""
    def path(name: str) -> str:
        parts = name.split("@")[-1].lstrip("\\").split(".")
        return ".".join(parts[:min(depth, len(parts) - 1)]) or "(top)"
    out: dict[str, list] = {}
    for name, v in cost.items():
        out.setdefault(path(name), [0.0, 0])[0] += v
    for name, n in ffs.items():
        out.setdefault(path(name), [0.0, 0])[1] += n
    return sorted(((k, (v[0], v[1])) for k, v in out.items()), key=lambda kv: -kv[1][0])


def seed_run(d: Path) -> tuple[int, dict | None, float | None]:
    """One seed's place-and-route run directory: nextpnr's exit status (`rc`; 124 = stopped by
    the timeout, 1 when missing), its report (`pnr.json`) when it finished, and its Fmax (the
    slowest clock; None without a report or a clock)."""
    rc_file, pnr_file = d / "rc", d / "pnr.json"
    rc = int(rc_file.read_text().strip() or "1") if rc_file.exists() else 1
    if rc != 0 or not pnr_file.exists():
        return rc, None, None
    pnr = _load_json(pnr_file, "nextpnr report")
    clocks = [float(f["achieved"]) for f in pnr.get("fmax", {}).values()]
    return rc, pnr, min(clocks) if clocks else None


def best_seed(runs: list[tuple[int, Path]]) -> tuple[int, list[str], list[str]]:
    """The seed whose place and route reached the highest Fmax (its slowest clock).

    runs: (seed, directory) with the directory holding `rc` (nextpnr's exit status; 124 =
    stopped by the timeout), `pnr.json` and `nextpnr.log`. Returns the chosen seed, one
    summary line per seed, and the problems of the seeds that failed. Raises when none
    finished."""
    results: dict[int, float] = {}
    lines: list[str] = []
    problems: list[str] = []
    for seed, d in runs:
        rc, pnr, fmax = seed_run(d)
        if rc == 124:
            problems.append(f"seed {seed}: nextpnr did not finish in time (routing not converging?), "
                            f"see {d / 'nextpnr.log'}")
            lines.append(f"seed {seed}: timeout")
            continue
        if pnr is None:
            problems.append(f"seed {seed}: nextpnr failed (exit {rc}), see {d / 'nextpnr.log'}")
            lines.append(f"seed {seed}: failed")
            continue
        if fmax is None:
            problems.append(f"seed {seed}: {d / 'pnr.json'} has no 'fmax' entry")
            lines.append(f"seed {seed}: no clock")
            continue
        results[seed] = fmax
        lines.append(f"seed {seed}: {fmax:.2f} MHz")
    if not results:
        raise SynthReportError("no seed was placed and routed:\n  " + "\n  ".join(problems))
    # highest Fmax; among equal ones the seed listed first
    order = [seed for seed, _ in runs]
    chosen = max(results, key=lambda k: (results[k], -order.index(k)))
    return chosen, lines, problems


def block_trellis_comb(stat: dict) -> int:
    """TRELLIS_COMB of a block synthesised alone, from its yosys cells: one per LUT4, two per
    CCU2C, four per TRELLIS_DPR16X4 (nextpnr's packing; carry feed-in cells not counted)."""
    cells = yosys_cells(stat)
    return cells.get("LUT4", 0) + 2 * cells.get("CCU2C", 0) + 4 * cells.get("TRELLIS_DPR16X4", 0)


def sweep_report(runs: list[tuple[int, Path]], device: str, num_vs: int, wslots: int,
                 sched_stat: dict | None, require_mhz: float = 48.0,
                 goals: dict[str, float] | None = None) -> dict:
    """The placer-seed sweep of one netlist as a dict (written as JSON): the device, the
    scheduler's size, TRELLIS_COMB and DP16KD use (nextpnr's utilisation, the same for every
    seed of one netlist), the scheduler alone, and per seed whether it routed and its Fmax
    (slowest clock); then worst / median over the seeds and the goals met (issue #27)."""
    goals = goals or {"max_comb_pct": 80.0, "max_dp16kd": 56, "min_worst_mhz": 52.8, "min_median_mhz": 60.0,
                      "max_sched_comb": 3500, "max_sched_dp16kd": 6}
    seeds: list[dict] = []
    util: dict = {}
    for seed, d in runs:
        rc, pnr, fmax = seed_run(d)
        if pnr is not None:
            util = util or pnr.get("utilization", {})
        seeds.append({"seed": seed, "routed": fmax is not None,
                      "fmax_mhz": None if fmax is None else round(fmax, 2), "timeout": rc == 124})
    if not util:
        raise SynthReportError("no seed was placed and routed: " + ", ".join(str(d) for _, d in runs))
    comb, bram = util.get("TRELLIS_COMB", {}), util.get("DP16KD", {})
    routed = sorted(x["fmax_mhz"] for x in seeds if x["routed"])
    worst = routed[0] if len(routed) == len(seeds) else None  # an unrouted seed has no Fmax
    median = (routed[len(routed) // 2] + routed[(len(routed) - 1) // 2]) / 2 if routed else None
    comb_pct = 100.0 * comb.get("used", 0) / comb["available"] if comb.get("available") else None
    sched_comb = None if sched_stat is None else block_trellis_comb(sched_stat)
    sched_bram = None if sched_stat is None else yosys_cells(sched_stat).get("DP16KD", 0)
    met = {
        "trellis_comb": comb_pct is not None and comb_pct <= goals["max_comb_pct"],
        "dp16kd": bram.get("used", 10**9) <= goals["max_dp16kd"],
        "every_seed_meets_clock": worst is not None and worst >= require_mhz,
        "worst_seed": worst is not None and worst >= goals["min_worst_mhz"],
        "median": median is not None and median >= goals["min_median_mhz"],
        "scheduler_trellis_comb": sched_comb is not None and sched_comb <= goals["max_sched_comb"],
        "scheduler_dp16kd": sched_bram is not None and sched_bram <= goals["max_sched_dp16kd"],
    }
    return {
        "device": device, "num_vs": num_vs, "wslots": wslots, "require_mhz": require_mhz,
        "trellis_comb": {"used": comb.get("used"), "avail": comb.get("available"),
                         "pct": None if comb_pct is None else round(comb_pct, 1)},
        "dp16kd": {"used": bram.get("used"), "avail": bram.get("available")},
        "scheduler_trellis_comb": sched_comb, "scheduler_dp16kd": sched_bram,
        "seeds": seeds,
        "worst_mhz": worst, "median_mhz": None if median is None else round(median, 2),
        "goals": goals, "goals_met": met, "all_goals_met": all(met.values()),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    mk = sub.add_parser("make", help="write the report from yosys and nextpnr outputs")
    mk.add_argument("--target", choices=sorted(FAMILY_BELS), required=True)
    mk.add_argument("--device", required=True)
    mk.add_argument("--stat", required=True, help="yosys `stat -json` output")
    mk.add_argument("--pnr", required=True, help="nextpnr --report JSON")
    mk.add_argument("--require-mhz", type=float, default=48.0)
    mk.add_argument("--note", action="append", help="a comment line for the report header")
    mk.add_argument("--out", required=True)
    cp = sub.add_parser("compare", help="check a new report against the committed one")
    cp.add_argument("new", type=Path)
    cp.add_argument("ref", type=Path)
    cp.add_argument("--min-mhz", type=float, default=62.4, help="the best seed's Fmax at least")
    cp.add_argument("--min-worst-mhz", type=float, default=None, help="every listed seed's Fmax at least")
    cp.add_argument("--max-lut-growth", type=float, default=0.10)
    bp = sub.add_parser("blocks", help="table of the yosys cells of blocks synthesised alone")
    bp.add_argument("stats", type=Path, nargs="+", help="yosys `stat -json` outputs, named BLOCK.json")
    lp = sub.add_parser("late", help="register inputs that miss a clock, from a detailed nextpnr report")
    lp.add_argument("pnr", type=Path, help="nextpnr --report JSON written with --detailed-timing-report")
    lp.add_argument("--mhz", type=float, default=62.4, help="clock to check against (default: the 1.3x goal)")
    lp.add_argument("--depth", type=int, default=4, help="hierarchy levels that name a block")
    lp.add_argument("--rows", type=int, default=40, help="registers listed, latest first")
    lp.add_argument("--sources", action="store_true",
                    help="also list where the late paths start (cells with the most late endpoints behind them)")
    bs = sub.add_parser("best", help="pick the seed with the highest Fmax among parallel place-and-route runs")
    bs.add_argument("dir", type=Path, help="synthesis directory holding seed-N/ run directories")
    bs.add_argument("seeds", type=int, nargs="+")
    bs.add_argument("--files", nargs="+", default=["pnr.json", "nextpnr.log"],
                    help="files copied from the chosen run into DIR")
    sw = sub.add_parser("sweep", help="JSON report of a placer-seed sweep (make synth-sweep)")
    sw.add_argument("dir", type=Path, help="synthesis directory holding seed-N/ run directories")
    sw.add_argument("seeds", type=int, nargs="+")
    sw.add_argument("--device", required=True)
    sw.add_argument("--num-vs", type=int, required=True)
    sw.add_argument("--wslots", type=int, required=True)
    sw.add_argument("--sched-stat", type=Path, help="yosys `stat -json` of the scheduler (ms_sched_uc) synthesised alone")
    sw.add_argument("--require-mhz", type=float, default=48.0)
    sw.add_argument("--out", type=Path, required=True)
    ar = sub.add_parser("area", help="logic area charged to the registers it feeds, from a mapped ECP5 netlist")
    ar.add_argument("netlist", type=Path, help="Yosys write_json output after synth_ecp5")
    ar.add_argument("--module", help="module to read (default: the netlist's top)")
    ar.add_argument("--rows", type=int, default=40, help="registers listed, costliest first")
    ar.add_argument("--depth", type=int, default=0,
                    help="sum per instance path of this many levels instead (1: the top's instances)")
    args = ap.parse_args()
    try:
        if args.cmd == "make":
            return make_report(args)
        if args.cmd == "blocks":
            print("\n".join(blocks_table(args.stats)))
            return 0
        if args.cmd == "best":
            chosen, lines, problems = best_seed([(sd, args.dir / f"seed-{sd}") for sd in args.seeds])
            for prob in problems:
                print(f"synth: warning: {prob}", file=sys.stderr)
            for name in args.files:
                shutil.copyfile(args.dir / f"seed-{chosen}" / name, args.dir / name)
            summary = f"{chosen} (best of {', '.join(lines)})" if len(lines) > 1 else str(chosen)
            (args.dir / "seed.txt").write_text(summary + "\n")
            print(f"synth: seed {summary}")
            return 0
        if args.cmd == "sweep":
            sched = _load_json(args.sched_stat, "scheduler statistics") if args.sched_stat else None
            rep = sweep_report([(sd, args.dir / f"seed-{sd}") for sd in args.seeds], args.device, args.num_vs,
                               args.wslots, sched, args.require_mhz)
            args.out.write_text(json.dumps(rep, indent=1) + "\n")
            print("| seed | routed | Fmax (MHz) |\n|---:|---|---:|")
            for x in rep["seeds"]:
                print(f"| {x['seed']} | {'yes' if x['routed'] else 'no'} | {x['fmax_mhz'] or '-'} |")
            print(f"\n{rep['device']}: TRELLIS_COMB {rep['trellis_comb']['used']} / {rep['trellis_comb']['avail']} "
                  f"({rep['trellis_comb']['pct']} %), DP16KD {rep['dp16kd']['used']} / {rep['dp16kd']['avail']}, "
                  f"scheduler alone {rep['scheduler_trellis_comb']} TRELLIS_COMB; worst {rep['worst_mhz']} MHz, "
                  f"median {rep['median_mhz']} MHz; goals met: "
                  + ", ".join(f"{k} {'yes' if v else 'NO'}" for k, v in rep["goals_met"].items()))
            print(f"synth-sweep: wrote {args.out}")
            return 0
        if args.cmd == "area":
            total, cost, ffs = area_by_register(_load_json(args.netlist, "netlist"), args.module)
            print(f"{total:.0f} TRELLIS_COMB of logic (LUT4 + 2 CCU2C) in {args.netlist}\n")
            if args.depth:
                print(f"| instance path (depth {args.depth}) | TRELLIS_COMB | flip-flops |\n|---|---:|---:|")
                for name, (v, n) in area_by_instance(cost, ffs, args.depth)[:args.rows]:
                    print(f"| {name} | {v:.0f} | {n} |")
                return 0
            print("| register / RAM port fed | TRELLIS_COMB | its flip-flops |\n|---|---:|---:|")
            reg_cost, reg_ffs = by_register(cost), by_register(ffs)
            for name, v in sorted(reg_cost.items(), key=lambda kv: -kv[1])[:args.rows]:
                print(f"| {name} | {v:.0f} | {reg_ffs.get(name, 0):.0f} |")
            return 0
        if args.cmd == "late":
            pnr = _load_json(args.pnr, "nextpnr report")
            print("\n".join(late_tables(pnr, args.mhz, args.depth, args.rows)))
            if args.sources:
                print("\n| late paths start at (register, or the first cell the report names) | late inputs |\n|---|---:|")
                for cell, n in sorted(late_sources(pnr, args.mhz).items(), key=lambda kv: -kv[1])[:args.rows]:
                    print(f"| {cell} | {n} |")
            return 0
        failures = compare(args.new, args.ref, args.min_mhz, args.max_lut_growth, args.min_worst_mhz)
    except SynthReportError as e:
        print(f"synth_report: {e}", file=sys.stderr)
        return 2
    for f in failures:
        print(f"FAIL: {f}", file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
