"""The twin's activity profile helpers (multisonar.twin.activity) on made-up symbol tables: the
clocks-per-function fold, the bound. The profile itself runs in
tests/test_twin.py::test_twin_matches_golden_model against the harness's own record."""

from __future__ import annotations

import math

from multisonar.twin.activity import COUNTERS, Activity, Symbol, by_function, poll_range


def test_by_function_folds_words_and_names_the_gaps():
    syms = [Symbol("a", 0, 8), Symbol("b", 8, 4), Symbol("c", 16, 4)]
    clocks = [1, 2, 3, 4, 5, 0]  # word 3 (byte 12) lies in no symbol; word 5 never ran
    assert by_function(syms, clocks) == {"a": 3, "b": 3, "?": 4, "c": 5}


def test_activity_fractions_and_bound():
    counts = dict.fromkeys(COUNTERS, 0) | {"clocks": 1000, "engine": 100, "cpu": 150, "sonar": 200, "any": 250}
    a = Activity(counts, {"main": 600, "poll_events": 400})
    assert a.fraction("any") == 0.25 and a.skip_bound == 4.0
    d = a.as_dict()
    assert d["skip_speedup_bound"] == 4.0 and d["sonar_only_skip_speedup_bound"] == 5.0
    assert d["firmware_functions"][0] == {"function": "main", "clocks": 600, "fraction": 0.6}
    assert math.isinf(Activity(dict.fromkeys(COUNTERS, 0) | {"clocks": 10}).skip_bound)


def test_poll_range_is_the_engines_poll_loop():
    lo, hi = poll_range()
    assert 0 < lo < hi and hi - lo < 32  # a short loop near the program's start (IDLE follows INIT)
