#!/usr/bin/env python3
"""Derive the VexRiscv with a larger instruction cache from the pinned, pre-generated core.

The input is the pinned package's standard configuration, VexRiscv.v (RV32IM, 5 stages, 4 KiB
caches, no readable user counters). VexRiscv_Full.v (the same pipeline plus every machine
CSR, rdcycle / rdinstret) was the input until issue #8: its CSR plugin limited the board top
to 55.8 MHz (docs/synthesis.md), and both patch the same way (--src).

Why (issue #5, firmware/README.md "Soft-core CPU"): the per-pulse geometry fix executes
~15 KB of straight-line code; the pinned 4 KiB direct-mapped instruction cache refetches
most of it on every fix (37 % of the cycles were line refills). The pinned
pythondata-cpu-vexriscv (SpinalHDL output, no sbt / Maven here to regenerate it with
--iCacheSize) has no variant with a larger cache, so this script rewrites the few places of
its generated ``InstructionCache`` module where the cache geometry appears:

* the data RAM ``banks_0 [0:1023]`` (32-bit words) and the tag RAM ``ways_0_tags [0:127]``;
* the line index ``[11 : 5]`` and word index ``[11 : 2]`` slices of the fetch and refill
  addresses, and the widths of the wires that carry them;
* the flush counter (one bit more than the line index: it walks every line after reset /
  FENCE.I, its top bit says "done").

The tag keeps its 20 bits ``[31 : 12]``: with a larger cache the lowest tag bits are index
bits too, equal for every address of a line, so storing and comparing them is redundant but
correct (and the tag RAM is one DP16KD either way). Direct mapped, 32-byte lines, nothing else
changes (the core's pipeline, the bus, the data cache are untouched). Every substitution is
asserted to apply exactly as often as expected, so a different input file fails loudly.

The installed package is never edited; the output is a new file (default
build/gen/cpu/VexRiscv_icache16k.v, which rtl/sources.f lists; module name unchanged: VexRiscv).

    .venv/bin/python scripts/gen_vex_icache.py [--kib 16] [--src FILE] [--out FILE]
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LINE_BYTES = 32
ORIG_KIB = 4
SOURCE = "VexRiscv.v"  # in pythondata_cpu_vexriscv.data_location
DEFAULT_OUT = "build/gen/cpu/VexRiscv_icache16k.v"  # relative to the repository


class PatchError(RuntimeError):
    pass


def _sub(text: str, old: str, new: str, count: int, where: str = "InstructionCache") -> str:
    n = text.count(old)
    if n != count:
        raise PatchError(f"expected {count} occurrence(s) of {old!r} in {where}, found {n}: "
                         f"the pinned core is not the one this patch was written for")
    return text.replace(old, new)


def patch_dcache_data(module: str) -> str:
    """The DataCache module text with its four byte-lane RAMs merged into one 32-bit RAM.

    SpinalHDL writes the 4 KiB data RAM as four 1024 x 8 arrays (``ways_0_data_symbol0..3``),
    one per byte lane. Yosys cannot merge separate arrays, so on the ECP5 each took a DP16KD of
    its own, half used (1024 x 9). As one 1024 x 32 array with byte-lane writes it maps to two
    DP16KD (1024 x 18 with byte enables): same contents, same read and write timing."""
    d = "DataCache"
    m = module
    for i in range(4):
        m = _sub(m, f"  (* ram_style = \"block\" *) reg [7:0] ways_0_data_symbol{i} [0:1023];\n",
                 "  (* ram_style = \"block\" *) reg [31:0] ways_0_data [0:1023];\n" if i == 0 else "", 1, d)
    reads = "".join(f"      _zz_ways_0_datasymbol_read{sfx} <= ways_0_data_symbol{i}[dataReadCmd_payload];\n"
                    for i, sfx in enumerate(["", "_1", "_2", "_3"]))
    m = _sub(m, reads, "      {_zz_ways_0_datasymbol_read_3, _zz_ways_0_datasymbol_read_2, "
                       "_zz_ways_0_datasymbol_read_1, _zz_ways_0_datasymbol_read} <= "
                       "ways_0_data[dataReadCmd_payload];\n", 1, d)
    for i in range(4):
        hi, lo = 8 * i + 7, 8 * i
        m = _sub(m, f"ways_0_data_symbol{i}[dataWriteCmd_payload_address] <= "
                    f"dataWriteCmd_payload_data[{hi} : {lo}];",
                 f"ways_0_data[dataWriteCmd_payload_address][{hi} : {lo}] <= "
                 f"dataWriteCmd_payload_data[{hi} : {lo}];", 1, d)
    if "ways_0_data_symbol" in m:
        raise PatchError("DataCache still names a byte-lane RAM (ways_0_data_symbol) after the patch")
    return m


def patch_icache(module: str, kib: int) -> str:
    """The InstructionCache module text with a ``kib`` KiB direct-mapped cache."""
    size = kib * 1024
    if kib < ORIG_KIB or size & (size - 1):
        raise PatchError(f"--kib must be a power of two >= {ORIG_KIB}, got {kib}")
    top = size.bit_length() - 1          # address bits below the tag: 12 for 4 KiB, 14 for 16 KiB
    lines = size // LINE_BYTES
    words = size // 4
    lb = lines.bit_length() - 1          # line index bits (7 for 4 KiB)
    wb = words.bit_length() - 1          # word index bits (10 for 4 KiB)
    fc = lb + 1                          # flush counter bits
    m = module
    m = _sub(m, "reg [31:0] banks_0 [0:1023];", f"reg [31:0] banks_0 [0:{words - 1}];", 1)
    m = _sub(m, "reg [21:0] ways_0_tags [0:127];", f"reg [21:0] ways_0_tags [0:{lines - 1}];", 1)
    m = _sub(m, "reg        [7:0]    lineLoader_flushCounter;",
             f"reg        [{fc - 1}:0]    lineLoader_flushCounter;", 1)
    m = _sub(m, "wire       [6:0]    lineLoader_write_tag_0_payload_address;",
             f"wire       [{lb - 1}:0]    lineLoader_write_tag_0_payload_address;", 1)
    m = _sub(m, "wire       [9:0]    lineLoader_write_data_0_payload_address;",
             f"wire       [{wb - 1}:0]    lineLoader_write_data_0_payload_address;", 1)
    m = _sub(m, "wire       [9:0]    _zz_fetchStage_read_banksValue_0_dataMem;",
             f"wire       [{wb - 1}:0]    _zz_fetchStage_read_banksValue_0_dataMem;", 1)
    m = _sub(m, "wire       [6:0]    _zz_fetchStage_read_waysValues_0_tag_valid;",
             f"wire       [{lb - 1}:0]    _zz_fetchStage_read_waysValues_0_tag_valid;", 1)
    m = _sub(m, "lineLoader_flushCounter[7]", f"lineLoader_flushCounter[{fc - 1}]", 5)
    m = _sub(m, "lineLoader_flushCounter[6 : 0]", f"lineLoader_flushCounter[{fc - 2} : 0]", 1)
    m = _sub(m, "(lineLoader_flushCounter + 8'h01)", f"(lineLoader_flushCounter + {fc}'d1)", 1)
    m = _sub(m, "lineLoader_flushCounter <= 8'h0;", f"lineLoader_flushCounter <= {fc}'d0;", 1)
    m = _sub(m, "lineLoader_address[11 : 5]", f"lineLoader_address[{top - 1} : 5]", 2)
    m = _sub(m, "io_cpu_prefetch_pc[11 : 2]", f"io_cpu_prefetch_pc[{top - 1} : 2]", 1)
    m = _sub(m, "io_cpu_prefetch_pc[11 : 5]", f"io_cpu_prefetch_pc[{top - 1} : 5]", 1)
    # the tag stays [31 : 12] (see the module doc); check nothing else names the old geometry
    m = _sub(m, "[31 : 12]", "[31 : 12]", 2)
    left = re.findall(r"\[(?:11|6|9) : \d+\]|\[0:(?:1023|127)\]|8'h0", m)
    if left and kib != ORIG_KIB:
        raise PatchError(f"InstructionCache still names the 4 KiB geometry after the patch: {left}")
    return m


def _module_span(text: str, name: str, src: Path) -> tuple[int, int]:
    start = text.find(f"module {name} (")
    if start < 0 or text.count(f"module {name} (") != 1:
        raise PatchError(f"{src}: no single 'module {name} (' to patch")
    return start, text.index("endmodule", start) + len("endmodule")


def derive(src: Path, kib: int, merge_dcache: bool = True) -> str:
    text = src.read_text()
    if merge_dcache:
        ds, de = _module_span(text, "DataCache", src)
        text = text[:ds] + patch_dcache_data(text[ds:de]) + text[de:]
    start, end = _module_span(text, "InstructionCache", src)
    dnote = "; data cache RAM as one 32-bit array" if merge_dcache else ""
    head = (f"// Derived by scripts/gen_vex_icache.py from {src.name} of the pinned pythondata-cpu-vexriscv:\n"
            f"// instruction cache {kib} KiB direct mapped (original {ORIG_KIB} KiB), 32-byte lines{dnote};\n"
            f"// nothing else changed. Do not edit: regenerated by 'make regs'.\n")
    return head + text[:start] + patch_icache(text[start:end], kib) + text[end:]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--kib", type=int, default=16, help="instruction cache size in KiB (power of two >= 4)")
    ap.add_argument("--out", type=Path, default=ROOT / DEFAULT_OUT)
    ap.add_argument("--src", type=Path, default=None, help=f"input (default: the installed {SOURCE})")
    a = ap.parse_args()
    if a.src is None:
        import pythondata_cpu_vexriscv
        a.src = Path(pythondata_cpu_vexriscv.data_location) / SOURCE
    out = derive(a.src, a.kib)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = a.out.with_suffix(".tmp")
    tmp.write_text(out)
    tmp.replace(a.out)
    print(f"gen: {a.out} ({a.src.name}, {a.kib} KiB instruction cache)")


if __name__ == "__main__":
    main()
