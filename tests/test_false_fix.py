"""False fixes under spurious pulses and crosstalk (issue #9; multisonar.safety.run_false_fix_trial).

A **fix** is what the firmware reports as one (firmware/app/sonar, a geometry frame): a pulse with first
in-window echoes on >= 3 receivers that the geometry classes edge (valid point fit) or wall
(valid wall fit). It is **false** when its point (edge position, wall foot), in the world with
the robot pose at the reflection instant, is more than FALSE_FIX_TOL_M (50 mm) from every true
reflector surface. The stated condition: the scene's default noise (crosstalk 0.1, jitter
1 us, fading 1.5 dB) with spurious pulses raised to 20 per channel and second, on the safety
trials' randomised wall + person-crossing scenes (seeds 0-11 here); stated bound (issue #28): at
most 0.1 % of the fixes and 0.1 false fixes per second of sonar time. First echoes the gated
miss rule rejects are flagged gated and are no geometry input (firmware and host). Measured
(scripts/bench_false_fix.py, seeds 0-19): 0 of 2087 fixes at crosstalk 0.1, 2 of 2131 (0.09 %,
0.06 /s; alias echoes that passed the gate) at crosstalk 1.0; seeds 0-11: 0 of 1193. Before
gated echoes were skipped: 7 of 1955 (0.36 %, 0.22 /s), all from alias echoes.
Counting the records the firmware classes "uncertain" as fixes too (no classification guard)
would give about 2.7 % off the truth: the test fails then. docs/experiments.md "Safety and false fixes (issue #9)"."""

from __future__ import annotations

import numpy as np

from multisonar.geometry import wall_path_lengths
from multisonar.layout import load_layout
from multisonar.safety import (FALSE_FIX_TOL_M, RX, TX, _fix_points, run_false_fix_trial,
                               summarise_false_fixes)

SPURIOUS_HZ = 20.0
MAX_FALSE_FIXES_PER_S = 0.1  # issue #28
MAX_FALSE_FIX_RATE = 0.001


def test_false_fixes_stay_below_the_stated_rate_at_20_spurious_pulses_per_second():
    s = summarise_false_fixes(run_false_fix_trial(seed, spurious_rate_hz=SPURIOUS_HZ) for seed in range(12))
    # the spurious pulses do reach the windows (else the bound below would say nothing; the gated
    # miss rule flags most of them, and the geometry skips those) ...
    assert s["false_samples"] + s["gated_false"] >= 0.005 * (s["samples"] + s["gated"]), s
    # ... the sensor still delivers fixes (no fixes = no false fixes, trivially) ...
    assert s["fixes_per_s"] >= 20, s
    # ... and the geometry turns (almost) none of them into a fix off every true surface
    assert s["false_fixes_per_s"] <= MAX_FALSE_FIXES_PER_S, s
    assert s["false_fix_rate"] <= MAX_FALSE_FIX_RATE, s


def test_the_false_fix_count_sees_fixes_off_the_truth():
    """With a zero tolerance every fix is off the truth: the counter is live."""
    r = run_false_fix_trial(0, tol_m=0.0)
    assert r.fixes > 20 and r.false_fixes == r.fixes
    assert run_false_fix_trial(0).max_fix_error_m < FALSE_FIX_TOL_M


def test_one_wrong_echo_leaves_no_fix():
    """The guard: a wall at 1.5 m seen by the three receivers is a wall fix at its foot; move one
    receiver's echo by 50 us (a spurious pulse in the window) and the record is no fix."""
    layout = load_layout()
    src = layout.positions[TX]
    C = layout.positions[list(RX)]
    paths = wall_path_lengths(1.5, np.pi / 2, C, src)[None, :].repeat(2, axis=0)
    paths[1, 0] += 343.0 * 50e-6
    pts, has, fix = _fix_points(list(RX), paths, src)
    assert fix[0] and abs(pts[0, 1] - (src[1] + 1.5)) < 1e-3
    assert has[1] and not fix[1]
