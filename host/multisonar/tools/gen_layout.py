"""Generate the layout-dependent parameters for RTL, SystemRDL and firmware from the layout file.

    python -m multisonar.tools.gen_layout --layout ring24 --out build/gen

writes ``rtl/ms_layout_pkg.sv`` (channel count for every RTL parameter default),
``rdl/ms_layout.rdlh`` (the same for the register map) and ``firmware/ms_layout.h``
(element positions and axes for the geometry code). Nobody types these numbers by hand.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ..constants import TICK_HZ
from ..layout import Layout, load_layout


def _banner(layout: Layout, comment: str) -> str:
    return f"{comment} Generated from {layout.source.name if layout.source else layout.name} by multisonar.tools.gen_layout. Do not edit.\n"


def sv_package(layout: Layout) -> str:
    return (_banner(layout, "//")
            + "package ms_layout_pkg;\n"
            + f"  localparam int NUM_CH = {layout.n};\n"
            + f"  localparam int TICK_HZ = {TICK_HZ};\n"
            + "endpackage\n")


def rdl_header(layout: Layout) -> str:
    return (_banner(layout, "//")
            + f"`define MS_NUM_CH {layout.n}\n"
            + f"`define MS_TICK_HZ {TICK_HZ}\n")


def c_header(layout: Layout) -> str:
    xs = ", ".join(f"{round(x * 1e6)}" for x in layout.positions[:, 0])
    ys = ", ".join(f"{round(y * 1e6)}" for y in layout.positions[:, 1])
    ax = ", ".join(f"{a:.9f}" for a in layout.axes)
    return (_banner(layout, "//")
            + "#ifndef MS_LAYOUT_H\n#define MS_LAYOUT_H\n\n#include <stdint.h>\n\n"
            + f"#define MS_NUM_CH {layout.n}\n#define MS_TICK_HZ {TICK_HZ}u\n"
            + f"#define MS_RING_DOWN_TICKS {round(layout.transducer.ring_down_s * TICK_HZ)}u\n"
            + f"#define MS_BEAM_HALF_ANGLE_RAD {layout.transducer.beam_half_angle:.9f}\n\n"
            + "/* Element positions in the robot frame, micrometres; axes in radians CCW from x. */\n"
            + f"static const int32_t ms_elem_x_um[MS_NUM_CH] = {{{xs}}};\n"
            + f"static const int32_t ms_elem_y_um[MS_NUM_CH] = {{{ys}}};\n"
            + f"static const float ms_elem_axis_rad[MS_NUM_CH] = {{{ax}}};\n\n#endif\n")


def generate(layout: Layout, out: Path) -> list[Path]:
    files = {out / "rtl" / "ms_layout_pkg.sv": sv_package(layout),
             out / "rdl" / "ms_layout.rdlh": rdl_header(layout),
             out / "firmware" / "ms_layout.h": c_header(layout)}
    for path, text in files.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.exists() or path.read_text() != text:  # keep mtimes stable for make
            path.write_text(text)
    return list(files)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", default="ring24", help="layout name or YAML path")
    ap.add_argument("--out", type=Path, required=True, help="output folder (e.g. build/gen)")
    args = ap.parse_args(argv)
    for p in generate(load_layout(args.layout), args.out):
        print(p)


if __name__ == "__main__":
    main()
