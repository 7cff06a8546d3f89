"""Paper Fig. 3: per-sensor sample rate of fast firing against distance, orders 1..MAX_ORDER.

The tick-exact scheduler model (:mod:`multisonar.fastfiring`) runs one collocated
sender/receiver on a static reflector at each distance; the measured rate is the mean pulse
rate of the tracking phase (one sample per receiver per pulse). Next to it: the analytic
formula T_s = (T_E - T_dead - T_V)/n (Eq. (2) generalised, at the highest feasible n <= order)
and the interlace limit 1/(T_dead + T_V + T_N). With ``rtl=True`` a few (distance, order)
cases also run on the RTL scheduler (ms_sched_uc in Verilator through cocotb, the machinery of
scripts/bench_rtl_sample_rate.py) and fill the RTL column. With ``twin=True`` the same cases run
on the full-system twin (multisonar.twin: the whole device in Verilator, configured and streamed
through the driver; the rate from the pulses the device fired) and fill the twin column.
"""

from __future__ import annotations

import sys
from concurrent.futures import Executor
from pathlib import Path
from typing import Any

import numpy as np

from ..constants import TICK_HZ, speed_of_sound
from ..schedule import MAX_ORDER
from .common import ExperimentError, ExperimentResult, md_table, run_scheduler_bench
from .executor import run_sweep

DISTANCES = [0.5, 0.6, 0.7, 0.8, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.3]
DISTANCES_QUICK = [0.6, 1.0, 2.0, 3.0, 4.0]
ORDERS = list(range(1, MAX_ORDER + 1))
# the RTL sample: four fixed cases, and the two highest orders at 4 m when the build has more than 4
RTL_CASES = [(2.0, 1), (2.0, 3), (4.0, 1), (4.0, 4)] + [(4.0, n) for n in (MAX_ORDER - 1, MAX_ORDER) if n > 4]
GOAL_4M_HZ = 250.0  # per-sensor rate at 4 m at the highest order (issue #27)
T_V_S = T_N_S = 0.5e-3


def measure_rate(distance_m: float, order: int, temperature_c: float = 20.0) -> dict[str, Any]:
    """One (distance, order) point on the golden model: measured tracking-phase pulse rate (Hz)
    and the effective order the scheduler used (-1 if it never settled into tracking)."""
    from ..fastfiring import FastFiringModel, SyntheticEchoSource
    from ..layout import load_layout
    from ..schedule import Schedule, VirtualSensor

    layout = load_layout()
    sensor = VirtualSensor("s", tx=[0], rx=[0], order=order, max_range_m=4.5, t_v=T_V_S, t_n=T_N_S)
    model = FastFiringModel(Schedule(layout, [sensor], temperature_c=temperature_c),
                            SyntheticEchoSource(distance_m, temperature_c=temperature_c))
    res = model.run(int(0.04 * TICK_HZ))  # init ping (<= 27 ms) + first tracking pulses
    res2 = model.run(int(0.10 * TICK_HZ))
    track = [p for p in res.pulses + res2.pulses if not p.init]
    if len(track) < 3 or any(p.init for p in res2.pulses):
        return {"measured_hz": float("nan"), "order_used": -1}
    t0 = np.array([p.t0 for p in track[1:]])
    return {"measured_hz": TICK_HZ / float(np.mean(np.diff(t0))), "order_used": int(track[-1].order)}


def twin_rate(distance_m: float, order: int, temperature_c: float = 20.0, seconds: float = 0.14) -> dict[str, Any]:
    """One (distance, order) point on the full-system twin: the sensor of :func:`measure_rate`
    configured over the driver, streamed for ``seconds`` of device time; the tracking-phase rate
    from the ticks the device fired (after the first 40 ms, as the golden model's)."""
    from ..fastfiring import SyntheticEchoSource
    from ..schedule import VirtualSensor
    from ..twin import open_twin

    sensor = VirtualSensor("s", tx=[0], rx=[0], order=order, max_range_m=4.5, t_v=T_V_S, t_n=T_N_S)
    src = SyntheticEchoSource(distance_m, temperature_c=temperature_c)
    with open_twin("empty", usbip=False, echo_source=src) as tw:
        tw.device.configure([sensor], temperature_c=temperature_c)
        tw.start()
        inits = []
        end = tw.sim.tick + int(seconds * TICK_HZ)
        for f in tw.device.stream(idle_timeout_s=300):
            if not f.is_geometry:
                inits.append((f.t0, bool(f.flags & 1)))
            if tw.sim.tick >= end:
                break
        s0 = tw.sim.first_schedule_start
        t0s = np.array([t0 for t0, _, _, _ in tw.sim.fires], dtype=np.int64)
    late = t0s[t0s >= s0 + int(0.04 * TICK_HZ)]
    init_late = any(init for t0, init in inits if t0 >= s0 + int(0.04 * TICK_HZ))
    if len(late) < 3 or init_late:
        return {"twin_hz": float("nan"), "pulses": int(len(t0s))}
    return {"twin_hz": TICK_HZ / float(np.mean(np.diff(late))), "pulses": int(len(t0s))}


def run(executor: Executor, *, quick: bool = False, rtl: bool = False, twin: bool = False,
        temperature_c: float = 20.0, progress: bool = True) -> ExperimentResult:
    from ..layout import load_layout
    from ..schedule import analytic_period_s, interlace_limit_s, min_tof_for_order

    layout = load_layout()
    c = speed_of_sound(temperature_c)
    t_dead = layout.transducer.ring_down_s
    limit = 1.0 / interlace_limit_s(t_dead_s=t_dead, t_v_s=T_V_S, t_n_s=T_N_S)
    dists = DISTANCES_QUICK if quick else DISTANCES
    tasks = [{"distance_m": d, "order": n, "temperature_c": temperature_c} for d in dists for n in ORDERS]
    meas = run_sweep(executor, measure_rate, tasks, label="fig3", progress=progress)
    rows = []
    for task, m in zip(tasks, meas):
        d, n = task["distance_m"], task["order"]
        ana = 1.0 / analytic_period_s(d, n, t_dead_s=t_dead, t_v_s=T_V_S, t_n_s=T_N_S, c=c)
        rows.append({"distance_m": d, "t_e_ms": 2 * d / c * 1e3, "order": n, "order_used": m["order_used"],
                     "measured_hz": m["measured_hz"], "analytic_hz": ana,
                     "rel_diff": m["measured_hz"] / ana - 1.0, "interlace_limit_hz": limit, "rtl_hz": float("nan"),
                     "twin_hz": float("nan")})
    rtl_note = "RTL column: not run (add --rtl; needs Verilator)."
    if rtl:
        rtl_rows = rtl_rates(RTL_CASES[:2] if quick else RTL_CASES)
        for rr in rtl_rows:
            for r in rows:
                if abs(r["distance_m"] - rr["distance_m"]) < 1e-9 and r["order"] == rr["order"]:
                    r["rtl_hz"] = rr["rtl_hz"]
            if not any(abs(r["distance_m"] - rr["distance_m"]) < 1e-9 and r["order"] == rr["order"] for r in rows):
                rows.append({"distance_m": rr["distance_m"], "t_e_ms": 2 * rr["distance_m"] / c * 1e3,
                             "order": rr["order"], "order_used": _max_order(rr["order_used"]), "measured_hz": rr["model_hz"],
                             "analytic_hz": float("nan"), "rel_diff": float("nan"), "interlace_limit_hz": limit,
                             "rtl_hz": rr["rtl_hz"], "twin_hz": float("nan")})
        rtl_note = ("RTL column: ms_sched_uc in Verilator (cocotb, tests/rtl/ms_scheduler_tb.sv) on the same "
                    "static reflector; pulse ticks compared with the golden model: "
                    + ", ".join(f"{r['distance_m']:g} m / order {r['order']}: {r['identical_pulses']}" for r in rtl_rows))

    twin_note = "Twin column: not run (add --twin; the whole device in Verilator, ~20 s per case)."
    if twin:
        cases = RTL_CASES[:2] if quick else RTL_CASES
        twin_rows = []
        for k, (d, n) in enumerate(cases):
            if progress:
                print(f"  fig3: twin case {k + 1}/{len(cases)}: {d:g} m, order {n}", file=sys.stderr)
            tr = twin_rate(d, n, temperature_c)
            twin_rows.append((d, n, tr))
            for r in rows:
                if abs(r["distance_m"] - d) < 1e-9 and r["order"] == n:
                    r["twin_hz"] = tr["twin_hz"]
        twin_note = ("Twin column: the full-system twin (RTL scheduler, firmware, USB, driver; rate from the pulses "
                     "the device fired after 40 ms): " + ", ".join(
                         f"{d:g} m / order {n}: {tr['twin_hz']:.2f} Hz" for d, n, tr in twin_rows))

    # wide table: one line per distance
    wide = []
    for d in dists:
        line: dict[str, Any] = {"d": d, "te": 2 * d / c * 1e3, "limit": limit}
        for r in rows:
            if r["distance_m"] == d:
                cell = f"{r['measured_hz']:.1f} [{r['order_used']}] / {r['analytic_hz']:.1f}"
                if np.isfinite(r["rtl_hz"]):
                    cell += f" / RTL {r['rtl_hz']:.1f}"
                if np.isfinite(r.get("twin_hz", float("nan"))):
                    cell += f" / twin {r['twin_hz']:.1f}"
                line[f"o{r['order']}"] = cell
        wide.append(line)
    cols = [("d", "d (m)"), ("te", "T_E (ms)")] + [(f"o{n}", f"order {n}: model [n] / analytic") for n in ORDERS] \
        + [("limit", "interlace limit (Hz)")]
    feas = []
    for n in ORDERS:
        blank = int(round(t_dead * TICK_HZ))
        tvt = int(round(T_V_S * TICK_HZ))
        te = min_tof_for_order(n, tvt, tvt, blank) / TICK_HZ
        feas.append(f"- order {n}: T_E >= {te * 1e3:.2f} ms, d >= {c * te / 2:.3f} m")
    ok = [r for r in rows if np.isfinite(r["rel_diff"])]
    max_dev = max(abs(r["rel_diff"]) for r in ok) if ok else float("nan")
    at4 = [r for r in rows if abs(r["distance_m"] - 4.0) < 1e-9 and r["order"] == MAX_ORDER]
    at4_hz = at4[0]["measured_hz"] if at4 else float("nan")
    at4_used = at4[0]["order_used"] if at4 else -1
    md = "\n".join([
        f"# Fig. 3: sample rate vs distance (fast firing, orders 1..{MAX_ORDER})", "",
        f"Golden model (tick-exact scheduler), one collocated sender/receiver (element 0) on a static reflector; "
        f"T_dead = {t_dead * 1e3:.2f} ms, T_V = T_N = {T_V_S * 1e3:.1f} ms, {temperature_c:g} degC (c = {c:.1f} m/s). "
        "Cells: measured rate [order used] / analytic rate 1/T_s, T_s = (T_E - T_dead - T_V)/n at the highest "
        "feasible n <= order (T_E + T_N if none); samples per second per receiver.", "",
        md_table(cols, wide, {"d": ".2f", "te": ".2f", "limit": ".0f"}), "",
        f"Largest |measured/analytic - 1|: {max_dev:.2%} (tick quantisation: the model's periods are whole ticks).",
        "", f"At 4 m: {at4_hz:.1f} Hz per sensor at order {MAX_ORDER} (order used {at4_used}); goal "
        f">= {GOAL_4M_HZ:.0f} Hz: {'met' if at4_hz >= GOAL_4M_HZ else 'NOT met'}.",
        "", "Minimum distance for fast firing of order n (T_E >= (n+1)(T_dead+T_V) + n*T_N, Eq. (1) generalised):",
        *feas, "", rtl_note, "", twin_note, ""])

    def plot(path: Path) -> None:
        import matplotlib.pyplot as plt

        from ..schedule import analytic_period_s as ap

        dd = np.linspace(min(dists), max(dists), 200)
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for n in ORDERS:
            ax.plot(dd, [1 / ap(x, n, t_dead_s=t_dead, t_v_s=T_V_S, t_n_s=T_N_S, c=c) for x in dd], label=f"order {n} (analytic)")
            col = ax.lines[-1].get_color()
            sel = [r for r in rows if r["order"] == n]
            ax.plot([r["distance_m"] for r in sel], [r["measured_hz"] for r in sel], "o", ms=4, color=col)
            rt = [r for r in sel if np.isfinite(r["rtl_hz"])]
            if rt:
                ax.plot([r["distance_m"] for r in rt], [r["rtl_hz"] for r in rt], "x", ms=9, mew=2, color=col)
            tw = [r for r in sel if np.isfinite(r.get("twin_hz", float("nan")))]
            if tw:
                ax.plot([r["distance_m"] for r in tw], [r["twin_hz"] for r in tw], "s", ms=10, mfc="none", color=col)
        ax.axhline(limit, ls="--", color="k", lw=0.8, label="interlace limit")
        ax.axhline(100, ls=":", color="grey", lw=0.8, label="100 Hz (10 ms control)")
        ax.set_xlabel("distance d (m)")
        ax.set_ylabel("samples per second per sensor")
        ax.set_title("Fast firing: sample rate vs distance (dots: golden model, x: RTL scheduler, squares: twin)")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        plt.close(fig)

    columns = ["distance_m", "t_e_ms", "order", "order_used", "measured_hz", "analytic_hz", "rel_diff",
               "interlace_limit_hz", "rtl_hz", "twin_hz"]
    summary = {"max_rel_diff": max_dev, "interlace_limit_hz": limit, "max_order": MAX_ORDER,
               "rate_4m_hz": at4_hz, "order_used_4m": at4_used,
               "goal_4m_hz": GOAL_4M_HZ, "goal_4m_met": bool(at4_hz >= GOAL_4M_HZ)}
    return ExperimentResult("fig3", "sample rate vs distance", columns, rows, md, plot, summary=summary,
                            json_data={"summary": summary, "rows": rows})


def _max_order(v: Any) -> int:
    """The bench reports the orders used as a list (one per tracking pulse) or a number."""
    return int(max(v)) if isinstance(v, (list, tuple)) and v else int(v) if not isinstance(v, (list, tuple)) else -1


def rtl_rates(cases: list[tuple[float, int]]) -> list[dict[str, Any]]:
    """Run the RTL scheduler rate bench (tests/rtl/tb_bench_rate.py)."""
    return run_scheduler_bench("tb_bench_rate", "fig3_rtl_rates.json", "RATE_OUT",
                               {"RATE_CASES": ",".join(f"{d:g}:{n}" for d, n in cases)})
