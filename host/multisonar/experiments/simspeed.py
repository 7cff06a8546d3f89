"""Simulation speed: sonar-seconds per wall-second, per simulation fidelity.

Golden-model rows (always): the fast-firing model alone on a synthetic echo source; with the
acoustic model on a static wall, on the person-crossing scene and on the corridor with the
demo's five sensors; the corridor with the per-pulse geometry as well (what ``make demo``
does); the simulated USB device driven through the host driver (``sim://corridor``,
lock-step: frames on the wire, decoded by the host). RTL rows (``rtl=True``, Verilator): the
full-system twin (bare device clock; corridor through the driver in-process and over USB/IP);
the whole-system scene test (ms_system = SoC running the sonar firmware + sonar core,
tests/rtl/tb_system_scene.py) at two sonar durations; the marginal rate (difference of sonar
time over difference of wall time) removes the fixed cost (simulator start, firmware boot,
checks). Timings run one after the other in this process (never in parallel, so they do not
compete for the cores); they depend on the machine and its load.
"""

from __future__ import annotations

import os
import sys
import time
from concurrent.futures import Executor
from pathlib import Path
from typing import Any

from ..constants import TICK_HZ
from .common import ExperimentError, ExperimentResult, batch_fixes, md_table, simulate_scene


def _row(name: str, fidelity: str, sonar_s: float, wall_s: float, pulses: int, events: int, note: str = "") -> dict[str, Any]:
    return {"case": name, "fidelity": fidelity, "sonar_s": sonar_s, "wall_s": wall_s,
            "speed": sonar_s / wall_s if wall_s > 0 else float("nan"), "pulses_per_wall_s": pulses / wall_s if wall_s else 0,
            "events": events, "note": note}


def golden_rows(seconds: float) -> list[dict[str, Any]]:
    from ..demo import DEMO_SENSORS
    from ..fastfiring import FastFiringModel, SyntheticEchoSource
    from ..layout import load_layout
    from ..scene import load_scene
    from ..schedule import Schedule, VirtualSensor

    rows = []
    lay = load_layout()
    t = time.perf_counter()
    m = FastFiringModel(Schedule(lay, [VirtualSensor("s", tx=[0], rx=[23, 0, 1], order=2)]),
                        SyntheticEchoSource(2.0, receivers=[23, 0, 1]))
    r = m.run(int(seconds * TICK_HZ))
    rows.append(_row("fast firing only (synthetic 2 m echo)", "golden: scheduler + gating", seconds,
                     time.perf_counter() - t, len(r.pulses), len(r.events), "1 sensor, 3 rx, order 2"))
    demo = [VirtualSensor(n, tx=tx, rx=rx, order=1) for n, tx, rx in DEMO_SENSORS]
    for label, scene, sensors, note in (
            ("wall_1m", "wall_1m", [VirtualSensor("front", tx=[0], rx=[23, 0, 1], order=1)], "1 sensor, 3 rx"),
            ("person_crossing", "person_crossing", [VirtualSensor("left", tx=[6], rx=[5, 6, 7], order=2)], "1 sensor, 3 rx"),
            ("corridor", "corridor", demo, "demo: 5 sensors")):
        sc = load_scene(scene)
        t = time.perf_counter()
        run = simulate_scene(sc, sensors, seconds, seed=1)
        rows.append(_row(label, "golden: acoustics + scheduler + gating", seconds, time.perf_counter() - t,
                         len(run.pulses), len(run.events), note))
    sc = load_scene("corridor")
    t = time.perf_counter()
    run = simulate_scene(sc, demo, seconds, seed=1)
    fixes = batch_fixes(sc.layout, run.resolved, run.echoes, sc.speed_of_sound)
    rows.append(_row("corridor + geometry", "golden: + per-pulse geometry (demo)", seconds, time.perf_counter() - t,
                     len(run.pulses), len(run.events), f"demo: 5 sensors, {len(fixes)} fixes"))
    rows.append(_device_row(seconds))
    return rows


def _device_row(seconds: float) -> dict[str, Any]:
    from ..demo import DEMO_SENSORS
    from ..device import Device
    from ..schedule import VirtualSensor

    t = time.perf_counter()
    t0s: list[int] = []
    n_ev = 0
    with Device.open("sim://corridor") as dev:
        dev.configure([VirtualSensor(n, tx=tx, rx=rx, order=1) for n, tx, rx in DEMO_SENSORS])
        dev.start()
        for f in dev.stream(duration_s=None, max_frames=10**9, idle_timeout_s=10.0):
            t0s.append(f.t0)
            n_ev += len(f.tof)
            if (t0s[-1] - t0s[0]) & 0xFFFFFFFF >= seconds * TICK_HZ:
                break
        dev.stop(drain_s=0.0)
    wall = time.perf_counter() - t
    sonar = ((t0s[-1] - t0s[0]) & 0xFFFFFFFF) / TICK_HZ if t0s else 0.0
    return _row("sim://corridor via the host driver", "golden: simulated USB device + host driver", sonar, wall,
                len(t0s), n_ev, "demo sensors, frames decoded by pyusb host code")


def rtl_rows(durations_ms: tuple[float, float] = (62.0, 124.0)) -> list[dict[str, Any]]:
    """Time the whole-system scene test (Verilator) at two sonar durations."""
    import shutil

    root = Path(__file__).resolve().parents[3]
    rtl_dir = root / "tests" / "rtl"
    os.environ["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"
    if shutil.which("verilator") is None or not (rtl_dir / "cocotb_run.py").exists():
        raise ExperimentError("RTL rows need Verilator and the repository's tests/rtl (make setup)")
    if str(rtl_dir) not in sys.path:
        sys.path.insert(0, str(rtl_dir))
    import subprocess

    from cocotb_run import run_cocotb  # type: ignore[import-not-found]

    hexfile = root / "build/fw/sonar_app.hex"
    subprocess.run(["make", "-s", str(hexfile.relative_to(root))], cwd=root, check=True)
    rows, walls = [], []
    # the first run may include the Verilator build: run the short case twice, time the last two
    for k, ms in enumerate((durations_ms[0], *durations_ms)):
        t = time.perf_counter()
        run_cocotb("system_scene_tb", "tb_system_scene", parameters={"INIT_FILE": f'"{hexfile}"'},
                   extra_sources=[rtl_dir / "system_scene_tb.sv"], icarus_ok=False, extra_env={"SCENE_MS": f"{ms:g}"})
        if k == 0:
            continue
        walls.append(time.perf_counter() - t)
        rows.append(_row(f"ms_system scene test, {ms:g} ms", "RTL: SoC + firmware + sonar core (Verilator + cocotb)",
                         ms / 1e3, walls[-1], 0, 0, "whole run incl. start-up and checks") | {"pulses_per_wall_s": float("nan")})
    d_sonar = (durations_ms[1] - durations_ms[0]) / 1e3
    d_wall = walls[1] - walls[0]
    rows.append(_row("ms_system marginal", "RTL: SoC + firmware + sonar core (Verilator + cocotb)", d_sonar, d_wall,
                     0, 0, "difference of the two runs (fixed costs removed)") | {"pulses_per_wall_s": float("nan")})
    return rows


def twin_rows(seconds: float = 0.1) -> list[dict[str, Any]]:
    """Time the full-system twin (multisonar.twin; built by `make twin` when needed): the bare
    verilated device with no echoes and no host, then the corridor with the demo's sensors
    streamed through the driver in-process and over USB/IP (what `make demo` runs)."""
    from ..twin import TwinError, TwinSim

    rows = []
    try:
        with TwinSim(None) as sim:
            sim.reset()
            sim.run(48_000)
            t = time.perf_counter()
            sim.run(int(seconds * TICK_HZ))
            wall = time.perf_counter() - t
        rows.append(_row("twin: bare device clock", "RTL: whole device, Verilator, no echoes, no host", seconds, wall,
                         0, 0, f"{seconds * TICK_HZ / wall / 1e6:.3f} M clocks/s (firmware idle)"))
        for usbip in (False, True):
            r = profile_demo(seconds, usbip=usbip, activity=False, warmup_s=0.0)
            how = "USB/IP on 127.0.0.1" if usbip else "in-process pyusb backend"
            rows.append(_row(f"twin: corridor, driver {how}", "RTL twin: acoustics + device RTL + USB + driver",
                             r["sonar_s"], r["wall_s"], r["frames"], 0,
                             f"5 demo sensors, frames to numpy (make demo); {r['skipped_share']:.0%} of the clocks "
                             "skipped exactly (calm)"))
    except TwinError as e:
        raise ExperimentError(f"twin rows: {e}") from None
    return rows


def profile_demo(seconds: float = 0.2, *, scene: str = "corridor", library: str | os.PathLike[str] | None = None,
                 activity: bool = True, warmup_s: float = 0.05, usbip: bool = False,
                 skip: bool = True) -> dict[str, Any]:
    """The demo's workload on the twin (the scene, the demo's five sensors, frames streamed to the
    driver, in-process or over USB/IP with ``usbip``): ``warmup_s`` of sonar time from START (the
    init pings, sensors locking on), then ``seconds`` with the activity profile on (``activity``;
    its bookkeeping costs ~15 % of a clock): the profile (or None), the clocks run and the wall
    time of the profiled part. ``skip``: the twin's exact skip of calm clocks (off: every clock
    simulated, as the cost-per-clock profile needs). twin_rows times the twin with it,
    bench_twin_profile.py profiles."""
    import time

    from ..demo import demo_sensors
    from ..scene import load_scene
    from ..twin import open_twin

    sc = load_scene(scene)
    with open_twin(sc, usbip=usbip, library=library, skip=skip) as tw:
        tw.device.configure(demo_sensors(), temperature_c=sc.temperature_c)
        tw.start()
        on = warmup_s <= 0  # no warm-up: profile and time from START
        if on and activity:
            tw.sim.start_profile()
        c0, t, frames, sk0 = tw.sim.cycles, time.perf_counter(), 0, tw.sim.skip_stats[1]
        held0 = tw.sim.clocks_held
        for _ in tw.device.stream(idle_timeout_s=300):
            if not on and tw.sim.cycles - c0 >= warmup_s * TICK_HZ:
                if activity:
                    tw.sim.start_profile()
                c0, t, frames, on, sk0 = tw.sim.cycles, time.perf_counter(), 0, True, tw.sim.skip_stats[1]
                held0 = tw.sim.clocks_held
            frames += on
            if on and tw.sim.cycles - c0 >= seconds * TICK_HZ:
                break
        wall = time.perf_counter() - t
        act = tw.sim.activity() if activity else None
        cycles, skipped = tw.sim.cycles, tw.sim.skip_stats[1] - sk0
        held = {k: v - held0[k] for k, v in tw.sim.clocks_held.items()}
    return {"scene": scene, "sensors": len(demo_sensors()), "sonar_s": (cycles - c0) / TICK_HZ, "wall_s": wall,
            "frames": frames, "activity": act, "clocks_from_reset": cycles,
            "skipped_share": skipped / max(cycles - c0, 1), "simulated": cycles - c0 - skipped,
            "clocks_held": held}


def twin_activity(seconds: float = 0.1) -> dict[str, Any]:
    """Where the twin's clocks go on the demo's workload (multisonar.twin.activity, issue #30): per
    clock, which units can change state beyond the counters that advance with time. A clock in
    none of them is calm; skipping calm clocks exactly gains at most 1 / (fraction with activity).
    The stretch varies: 0.05 s (--quick) after start-up is calmer than 1 s (docs/twin.md)."""
    from ..twin import TwinError

    try:
        r = profile_demo(seconds)
    except TwinError as e:
        raise ExperimentError(f"twin activity: {e}") from None
    return {"scene": r["scene"], "sensors": r["sensors"], "sonar_s": round(r["sonar_s"], 4)} | r["activity"].as_dict()


def run(executor: Executor | None = None, *, quick: bool = False, seconds: float | None = None, rtl: bool = False,
        progress: bool = True) -> ExperimentResult:
    secs = seconds or (0.1 if quick else 1.0)
    if progress:
        print(f"  simspeed: timing the golden model ({secs:g} s of sonar time per case, sequentially)", file=sys.stderr)
    rows = golden_rows(secs)
    note = "RTL rows: not run (--rtl; Verilator)."
    if rtl:
        if progress:
            print("  simspeed: timing the full-system twin (make twin on first use) and the cocotb scene test",
                  file=sys.stderr)
        rows += twin_rows(0.05 if quick else 0.1)
        if not quick:
            rows += rtl_rows()
        note = ("RTL rows: the full-system twin (multisonar.twin: Verilator, harness in C++, Python per pulse and "
                "per USB packet); the ms_system scene test (tests/rtl/tb_system_scene.py with SCENE_MS set, cocotb: "
                "wall time includes the checks; not with --quick).")
    activity: dict[str, Any] | None = None
    activity_md = "Twin activity (where its clocks go, the bound of an exact idle-clock skip): with --rtl."
    if rtl:
        activity = twin_activity(0.05 if quick else 0.2)
        f = activity["fractions"]
        activity_md = (f"Twin activity ({activity['scene']}, the demo's {activity['sensors']} sensors, "
                       f"{activity['sonar_s']:g} sonar-s after 0.05 s from START, multisonar.twin.activity): "
                       f"the scheduler engine works in {f['engine']:.1%} of the clocks, a transmit burst runs in {f['tx_run']:.1%}, a receive "
                       f"conditioner settles in {f['rx_settle']:.1%}, USB in {f['usb']:.1%}, the CPU is awake (not in "
                       f"its idle wait) in {f['cpu']:.1%}; some unit works in {f['any']:.1%}, so an exact skip of the "
                       f"calm clocks speeds the twin up {activity['skip_speedup_bound']:.3g}x at most on this "
                       f"workload ({activity['sonar_only_skip_speedup_bound']:.3g}x counting the sonar side alone); "
                       f"the twin skips them (docs/twin.md, scripts/bench_twin_skip.py). "
                       f"scripts/bench_twin_profile.py --callgrind adds the cost per clock by RTL block.")
    cols = [("case", "case"), ("fidelity", "fidelity"), ("sonar_s", "sonar time (s)"), ("wall_s", "wall time (s)"),
            ("speed", "sonar-s per wall-s"), ("pulses_per_wall_s", "pulses (frames) per wall-s"), ("note", "note")]
    md = "\n".join(["# Simulation speed: sonar-seconds per wall-second", "",
                    f"One process, cases run one after the other; python {sys.version.split()[0]}, "
                    f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the end.", "",
                    md_table(cols, rows, {"sonar_s": ".3f", "wall_s": ".2f", "speed": ".3g", "pulses_per_wall_s": ".0f"}),
                    "", note, "", activity_md, ""])

    def plot(path: Path) -> None:
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(9, 0.5 * len(rows) + 1.5))
        names = [r["case"] for r in rows][::-1]
        ax.barh(names, [r["speed"] for r in rows][::-1],
                color=["tab:orange" if r["fidelity"].startswith("RTL") else "tab:blue" for r in rows][::-1])
        ax.axvline(1.0, color="k", ls="--", lw=0.8, label="real time")
        ax.set_xscale("log")
        ax.set_xlabel("sonar-seconds per wall-second (log)")
        ax.set_title("simulation speed by fidelity (blue: golden model, orange: RTL)")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)

    columns = ["case", "fidelity", "sonar_s", "wall_s", "speed", "pulses_per_wall_s", "events", "note"]
    return ExperimentResult("simspeed", "simulation speed", columns, rows, md, plot,
                            summary={"rows": rows, "twin_activity": activity},
                            json_data={"rows": rows, "twin_activity": activity})
