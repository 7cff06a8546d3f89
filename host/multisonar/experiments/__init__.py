"""The paper's experiments and the speed/accuracy report (issue #7): ``multisonar experiment NAME``.

=========  ==============================================================================
fig3       sample rate vs distance, orders 1..4, golden model next to the interlace limit
           (``--rtl``: RTL scheduler column, Verilator)
fig9       wall-angle error vs orientation, 2 and 3 receivers, with and without re-aiming
fig10      map building while localising on known walls (corridor scene)
person     person crossing: occluder detection latency, track, velocity, predicted path
tradeoff   firing order, window, receivers, arithmetic -> rate, latency, miss rate, errors
simspeed   sonar-seconds per wall-second: golden model cases (``--rtl``: the RTL system test)
ring       full-ring refresh: 8 sensors over all 24 directions, static room, orders 1..MAX_ORDER
           (``--rtl``: the goal distances on the RTL scheduler, Verilator)
safety     occluder safety: randomised person crossings (``--trials N --seed S``), detection
           within N+K+1 pulses, tracking samples against the gate-only default, false fixes
=========  ==============================================================================

Each writes ``NAME.md`` (tables), ``NAME.csv`` (one row per measured point) and ``NAME.png``
(``fig3``, ``ring``, ``safety``, ``simspeed`` and the twin backend's runs also ``NAME.json``, machine-readable
figures) into the output folder (default ``build/experiments/NAME``). Sweeps run on a ``concurrent.futures``
executor (:mod:`.executor`): local processes, or a Dask cluster. The backend is the golden model; ``fig3 --twin``,
``--backend twin`` (fig9, fig10, person: :mod:`.twin_backend`) and ``--rtl`` (fig3, ring, simspeed) add the
device's RTL next to it.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .common import ExperimentError, ExperimentResult, write_outputs
from .executor import ExecutorError, make_executor

__all__ = ["EXPERIMENTS", "TWIN_BACKEND_EXPERIMENTS", "ExperimentError", "ExperimentResult", "ExecutorError", "run_experiment", "write_outputs"]


def _runner(module: str) -> Callable[..., ExperimentResult]:
    def run(executor: Any, **kw: Any) -> ExperimentResult:
        import importlib

        return importlib.import_module(f"{__name__}.{module}").run(executor, **kw)

    return run


#: name -> (runner, one-line description)
EXPERIMENTS: dict[str, tuple[Callable[..., ExperimentResult], str]] = {
    "fig3": (_runner("fig3"), "sample rate vs distance, orders 1..4 (paper Fig. 3)"),
    "fig9": (_runner("fig9"), "wall-angle error vs orientation, 2/3 receivers, re-aiming (Fig. 9)"),
    "fig10": (_runner("fig10"), "map building while localising on known walls (Fig. 10)"),
    "person": (_runner("person"), "person crossing: detection latency, track, velocity"),
    "tradeoff": (_runner("tradeoff"), "speed/accuracy trade: order, window, receivers, arithmetic"),
    "simspeed": (_runner("simspeed"), "simulation speed: sonar-seconds per wall-second per fidelity"),
    "ring": (_runner("ring"), "full-ring refresh: 8 sensors, all 24 directions, 2 m and 5.7 m (issue #27)"),
    "safety": (_runner("safety"), "occluder safety: randomised person crossings, false fixes (issue #28)"),
}


#: experiments that take ``backend="twin"`` (``--backend twin``): the twin's results next to the model's
TWIN_BACKEND_EXPERIMENTS = ("fig9", "fig10", "person")


def run_experiment(name: str, out: str | Path | None = None, *, quick: bool = False, workers: int | None = None,
                   scheduler: str | None = None, progress: bool = True, **options: Any) -> tuple[ExperimentResult, list[Path]]:
    """Run one experiment and write its files; returns the result and the files written."""
    if name not in EXPERIMENTS:
        raise ValueError(f"unknown experiment {name!r}; available: {', '.join(EXPERIMENTS)}")
    out_dir = Path(out) if out is not None else Path("build/experiments") / name
    t0 = time.time()
    with make_executor(workers, scheduler) as ex:
        res = EXPERIMENTS[name][0](ex, quick=quick, progress=progress, **options)
    res.summary.setdefault("wall_s", time.time() - t0)
    return res, write_outputs(res, out_dir)
