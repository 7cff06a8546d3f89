"""The foundation: layout data, generated parameters and register map agree everywhere."""

from __future__ import annotations

import math
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import multisonar
from multisonar import TICK_HZ, LayoutError, load_layout, speed_of_sound
from multisonar.cli import main as cli_main
from multisonar.tools.gen_layout import generate

ROOT = Path(__file__).resolve().parents[1]
GEN = ROOT / "build" / "gen"


def test_default_layout_is_the_design_ring():
    lay = load_layout()
    assert lay.n == 24
    r = np.linalg.norm(lay.positions, axis=1)
    np.testing.assert_allclose(r, 0.35, atol=1e-9)
    np.testing.assert_allclose(np.degrees(lay.axes), np.arange(24) * 15.0, atol=1e-9)
    # axes point radially outward
    np.testing.assert_allclose(np.arctan2(lay.positions[:, 1], lay.positions[:, 0]) % (2 * np.pi), lay.axes, atol=1e-9)
    np.testing.assert_allclose(lay.spacing(), 2 * 0.35 * math.sin(math.radians(7.5)), atol=1e-9)
    assert abs(lay.spacing()[0] - 0.0914) < 1e-3  # the paper's 91 mm
    assert lay.neighbours(0) == [23, 1]


@pytest.mark.parametrize("mutation, message", [
    (lambda d: d.update(colour="red"), "unknown key"),
    (lambda d: d["elements"][3].update(id=7), "ids must be 0..N-1"),
    (lambda d: d["elements"][3].pop("y"), "exactly the keys"),
    (lambda d: d["elements"][4].update(x=d["elements"][3]["x"], y=d["elements"][3]["y"]), "closer than 1 mm"),
    (lambda d: d.update(units={"length": "mm", "angle": "deg"}), "units must be"),
    (lambda d: d["transducer"].update(gain=3), "unknown transducer key"),
])
def test_layout_errors_name_the_problem(tmp_path, mutation, message):
    import yaml

    doc = yaml.safe_load((ROOT / "sim/layouts/ring24.yaml").read_text())
    mutation(doc)
    p = tmp_path / "bad.yaml"
    p.write_text(yaml.safe_dump(doc))
    with pytest.raises(LayoutError, match=message):
        load_layout(p)


def test_unknown_layout_lists_known_ones():
    with pytest.raises(LayoutError, match=r"known layouts: \['ring24'"):
        load_layout("ring99")


def test_speed_of_sound():
    assert speed_of_sound(0.0) == pytest.approx(331.3)
    assert speed_of_sound(20.0) == pytest.approx(343.2, abs=0.05)
    with pytest.raises(ValueError, match="not a physical"):
        speed_of_sound(-300.0)


def test_generated_parameters_come_from_the_layout(tmp_path):
    lay = load_layout()
    files = generate(lay, tmp_path)
    sv = (tmp_path / "rtl/ms_layout_pkg.sv").read_text()
    assert f"NUM_CH = {lay.n};" in sv and f"TICK_HZ = {TICK_HZ};" in sv
    hdr = (tmp_path / "firmware/ms_layout.h").read_text()
    xs = [int(v) for v in re.search(r"ms_elem_x_um\[MS_NUM_CH\] = \{([^}]*)\}", hdr).group(1).split(",")]
    np.testing.assert_allclose(np.array(xs) * 1e-6, lay.positions[:, 0], atol=1e-6)
    # the build tree holds the same text (make regs generated it from the same file)
    for f in files:
        built = GEN / f.relative_to(tmp_path)
        assert built.read_text() == f.read_text(), f"{built} is stale: run 'make regs'"


def test_register_map_constants_agree_with_python():
    from multisonar.generated import sonar_regs as R

    assert R.REGISTERS["TICK_HZ"].reset == TICK_HZ
    assert R.REGISTERS["CAPS"].fields["NUM_CH"].get(R.REGISTERS["CAPS"].reset) == load_layout().n
    assert R.REGISTERS["VS_TX_MASK"].fields["MASK"].width == load_layout().n
    assert R.REGISTERS["VS_MODE"].addr(3) == R.VS_MODE_ADDR + 3 * R.REGISTERS["VS_MODE"].strides[0]
    with pytest.raises(IndexError):
        R.REGISTERS["VS_MODE"].addr(8)
    hdr = (GEN / "firmware/sonar_regs.h").read_text()
    assert re.search(r"SONAR_REGS__TICK_HZ__HZ_reset\s+0x2dc6c00", hdr)


@pytest.mark.skipif(shutil.which("riscv64-unknown-elf-gcc") is None, reason="RISC-V gcc not installed (make setup installs it)")
def test_generated_c_headers_compile_for_the_soft_core(tmp_path):
    src = tmp_path / "probe.c"
    src.write_text('#include "sonar_regs.h"\n#include "ms_layout.h"\n'
                   "int probe(void) { return MS_NUM_CH + ms_elem_x_um[0] / 1000 + (int)sizeof(sonar_regs_t); }\n")
    r = subprocess.run(["riscv64-unknown-elf-gcc", "-march=rv32im", "-mabi=ilp32", "--specs=picolibc.specs", "-Wall", "-Werror", "-Wno-unused-variable",
                        "-I", str(GEN / "firmware"), "-c", str(src), "-o", str(tmp_path / "probe.o")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_cli_version_and_placeholders(capsys):
    assert cli_main(["version"]) == 0
    out = capsys.readouterr().out
    assert f"multisonar {multisonar.__version__}" in out and str(TICK_HZ) in out
    assert cli_main(["experiment"]) == 2  # no name: lists the experiments
    assert "fig3" in capsys.readouterr().err
    assert cli_main(["stream"]) == 1  # no board on this machine: a clear error, not a hang
    assert "no Multisonar board" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        cli_main(["--help"])
    assert e.value.code == 0
    assert cli_main(["layout", "--layout", "ring99"]) == 1
    assert "known layouts" in capsys.readouterr().err


def test_cli_entry_point_installed():
    exe = Path(__import__("sys").executable).parent / "multisonar"
    r = subprocess.run([str(exe), "version"], capture_output=True, text=True)
    assert r.returncode == 0 and "tick rate 48000000 Hz" in r.stdout


def test_scheduler_fields_match_the_register_map():
    """Every CSR field the golden scheduler fills exists in the RDL with the same width."""
    from multisonar.regmap import check_field_widths, schedule_writes
    from multisonar.schedule import Schedule, VirtualSensor

    check_field_widths()
    sched = Schedule(load_layout(), [VirtualSensor("front", tx=[23, 0, 1], rx=[23, 0, 1], order=2),
                                     VirtualSensor("left", tx=[6], rx=[5, 6, 7])])
    writes = dict(schedule_writes(sched))
    from multisonar.generated import sonar_regs as R

    mode = R.REGISTERS["VS_MODE"]
    assert mode.fields["ORDER"].get(writes[mode.addr(0)]) == 2
    assert mode.fields["MODE"].get(writes[mode.addr(7)]) == 0  # unused table entries are off
    tx = R.REGISTERS["VS_TX_MASK"]
    assert writes[tx.addr(0)] == (1 << 23) | 1 | 2
