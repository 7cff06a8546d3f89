"""`multisonar demo --backend golden` (the golden model alone) end to end on a short span: files
written, fixes close to the scene's truth. The twin backend (`make demo`) is tests/test_twin.py."""

from __future__ import annotations

import csv

import numpy as np

from multisonar.cli import main as cli_main


def test_demo_maps_the_corridor(tmp_path, capsys):
    assert cli_main(["demo", "--backend", "golden", "--scene", "corridor", "--seconds", "0.6", "--out", str(tmp_path)]) == 0
    for name in ("map.png", "summary.md", "fixes.csv", "events.npz"):
        assert (tmp_path / name).stat().st_size > 0, name
    rows = list(csv.DictReader(open(tmp_path / "fixes.csv")))
    walls = np.array([float(r["error_m"]) for r in rows if r["kind"] == "wall"])
    assert len(walls) >= 20, "the side sensors should map the corridor walls"
    assert np.median(walls) < 0.005, f"median wall-fix error {np.median(walls):.4f} m"
    ev = np.load(tmp_path / "events.npz")
    assert ev["tof"].size > 100 and set(np.unique(ev["sensor"])) == {0, 1, 2, 3, 4}
    assert "samples/s per receiver" in capsys.readouterr().out


def test_demo_rejects_unknown_scene(tmp_path, capsys):
    assert cli_main(["demo", "--backend", "golden", "--scene", "no_such_scene", "--out", str(tmp_path)]) == 1
    assert "no_such_scene" in capsys.readouterr().err
