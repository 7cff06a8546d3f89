#!/usr/bin/env python3
"""Paper Fig. 3: per-sensor sample rate of fast firing vs distance, order 1..4.

Runs the tick-exact scheduler model (multisonar.fastfiring) on a static reflector at each
distance and measures the pulse rate of the tracking phase (one sample per receiver per
pulse), next to the analytic formula T_s = (T_E - T_dead - T_V)/n (Eq. (2) generalised) and
the interlace limit 1/(T_dead + T_V + T_N). Prints a markdown table.

    .venv/bin/python scripts/bench_fig3_sample_rate.py [--plot out.png] [--temperature 20]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from multisonar.constants import TICK_HZ, speed_of_sound
from multisonar.fastfiring import FastFiringModel, SyntheticEchoSource
from multisonar.layout import load_layout
from multisonar.schedule import (Schedule, VirtualSensor, analytic_period_s, interlace_limit_s, min_tof_for_order)

DISTANCES = [0.5, 0.6, 0.7, 0.8, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.3]
ORDERS = [1, 2, 3, 4]


def measure(layout, d: float, order: int, temperature_c: float) -> tuple[float, int]:
    """Measured sample rate (Hz) of the tracking phase and the effective order used."""
    sensor = VirtualSensor("s", tx=[0], rx=[0], order=order, max_range_m=4.5)  # 4.3 m echo inside the open window
    src = SyntheticEchoSource(d, temperature_c=temperature_c)
    model = FastFiringModel(Schedule(layout, [sensor], temperature_c=temperature_c), src)
    res = model.run(int(0.04 * TICK_HZ))  # init ping (<= 27 ms) + first tracking pulses
    res2 = model.run(int(0.10 * TICK_HZ))
    track = [p for p in res.pulses + res2.pulses if not p.init]
    if len(track) < 3 or any(p.init for p in res2.pulses):
        return float("nan"), -1
    t0 = np.array([p.t0 for p in track[1:]])
    return TICK_HZ / float(np.mean(np.diff(t0))), track[-1].order


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--plot", help="write the figure to this PNG")
    ap.add_argument("--temperature", type=float, default=20.0)
    args = ap.parse_args()
    layout = load_layout()
    c = speed_of_sound(args.temperature)
    t_dead = layout.transducer.ring_down_s
    tv = tn = 0.5e-3
    limit = 1.0 / interlace_limit_s(t_dead_s=t_dead, t_v_s=tv, t_n_s=tn)
    t_start = time.perf_counter()
    rows = []
    for d in DISTANCES:
        row = {"d": d, "te": 2 * d / c}
        for n in ORDERS:
            meas, n_eff = measure(layout, d, n, args.temperature)
            ana = 1.0 / analytic_period_s(d, n, t_dead_s=t_dead, t_v_s=tv, t_n_s=tn, c=c)
            row[n] = (meas, ana, n_eff)
        rows.append(row)
    wall = time.perf_counter() - t_start

    print(f"Sample rate per virtual sensor (Hz), static reflector, T_dead = {t_dead * 1e3:.2f} ms, "
          f"T_V = T_N = 0.5 ms, {args.temperature:g} degC (c = {c:.1f} m/s).")
    print("measured = tick model (mean pulse period of the tracking phase); analytic = 1/T_s, "
          "T_s = (T_E - T_dead - T_V)/n at the highest feasible n <= order (T_E + T_N if none); "
          "[n] = order actually used.\n")
    head = "| d (m) | T_E (ms) | " + " | ".join(f"order {n}: measured [n] / analytic" for n in ORDERS) + " | interlace limit |"
    print(head)
    print("|" + "---|" * (3 + len(ORDERS)))
    for r in rows:
        cells = []
        for n in ORDERS:
            meas, ana, n_eff = r[n]
            cells.append(f"{meas:7.1f} [{n_eff}] / {ana:7.1f}")
        print(f"| {r['d']:.2f} | {r['te'] * 1e3:6.2f} | " + " | ".join(cells) + f" | {limit:.0f} |")
    blank = int(round(t_dead * TICK_HZ))
    tvt = int(round(tv * TICK_HZ))
    print("\nMinimum distance for fast firing of order n (T_E >= (n+1)(T_dead+T_V) + n*T_N, Eq. (1) generalised):")
    for n in ORDERS:
        te = min_tof_for_order(n, tvt, tvt, blank) / TICK_HZ
        print(f"- order {n}: T_E >= {te * 1e3:.2f} ms, d >= {c * te / 2:.3f} m")
    print(f"\n(paper: fast firing applies beyond ~70 cm, i.e. T_E > 2 T_dead + 2 T_V + T_N = 4.5 ms -> "
          f"{c * 4.5e-3 / 2:.3f} m; below that the model falls back to order 0 = windowed, not interlaced)")
    print(f"\nmodel wall time: {wall:.2f} s for {len(DISTANCES) * len(ORDERS)} runs")

    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        dd = np.linspace(0.5, 4.3, 200)
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for n in ORDERS:
            ax.plot(dd, [1 / analytic_period_s(x, n, t_dead_s=t_dead, t_v_s=tv, t_n_s=tn, c=c) for x in dd],
                    label=f"order {n} (analytic)")
            ax.plot([r["d"] for r in rows], [r[n][0] for r in rows], "o", ms=4, color=ax.lines[-1].get_color())
        ax.axhline(limit, ls="--", color="k", lw=0.8, label="interlace limit")
        ax.axhline(100, ls=":", color="grey", lw=0.8, label="100 Hz (10 ms control)")
        ax.set_xlabel("distance d (m)")
        ax.set_ylabel("samples per second per sensor")
        ax.set_title("Fast firing: sample rate vs distance (dots: tick model)")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
        fig.tight_layout()
        fig.savefig(args.plot, dpi=120)
        print(f"plot written to {args.plot}")


if __name__ == "__main__":
    main()
