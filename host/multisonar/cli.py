"""The ``multisonar`` command line."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from . import __version__
from .constants import TICK_HZ, speed_of_sound
from .layout import DEFAULT_LAYOUT, LayoutError, load_layout


def _cmd_version(args: argparse.Namespace) -> int:
    regmap = "not generated (run 'make regs')"
    try:
        from .generated import sonar_regs as R

        reg = R.REGISTERS["VERSION"]
        regmap = f"{reg.fields['REGMAP'].get(reg.reset)} (gateware {reg.fields['MAJOR'].get(reg.reset)}.{reg.fields['MINOR'].get(reg.reset)})"
    except ImportError:
        pass
    print(f"multisonar {__version__}")
    print(f"register map revision {regmap}")
    print(f"tick rate {TICK_HZ} Hz")
    return 0


def _cmd_layout(args: argparse.Namespace) -> int:
    import math

    lay = load_layout(args.layout)
    c = speed_of_sound(args.temperature)
    print(f"layout {lay.name} ({lay.source}): {lay.n} elements, speed of sound {c:.2f} m/s at {args.temperature} degC")
    print(f"{'id':>3} {'x [m]':>9} {'y [m]':>9} {'axis [deg]':>10} {'to next [mm]':>12}")
    for i, ((x, y), a, s) in enumerate(zip(lay.positions, lay.axes, lay.spacing())):
        print(f"{i:>3} {x:>9.4f} {y:>9.4f} {math.degrees(a):>10.1f} {s * 1e3:>12.1f}")
    return 0


def _cmd_regs(args: argparse.Namespace) -> int:
    try:
        from .generated import sonar_regs as R
    except ImportError:
        print("multisonar: the register map is not generated; run 'make regs'", file=sys.stderr)
        return 2
    print(f"{'address':>8}  {'register':<14} {'array':<8} fields")
    for reg in R.REGISTERS.values():
        arr = "x".join(map(str, reg.dims)) if reg.dims else ""
        fields = ", ".join(f"{f.name.lower()}[{f.lsb + f.width - 1}:{f.lsb}]" for f in reg.fields.values())
        print(f"  0x{reg.address:04X}  {reg.name:<14} {arr:<8} {fields}")
    for mem in R.MEMORIES.values():
        print(f"  0x{mem.address:04X}  {mem.name:<14} {mem.entries}x{mem.width}b (memory)")
    return 0


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="multisonar", description="Multisonar: 24-element ultrasonic ring — tools, golden model and host driver.")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser("version", help="package, register-map and tick-rate versions")
    p.set_defaults(func=_cmd_version)

    p = sub.add_parser("layout", help="print the sensor layout")
    p.add_argument("--layout", default=DEFAULT_LAYOUT, help="layout name or YAML path [%(default)s]")
    p.add_argument("--temperature", type=float, default=20.0, help="air temperature, degC [%(default)s]")
    p.set_defaults(func=_cmd_layout)

    p = sub.add_parser("regs", help="print the register map")
    p.set_defaults(func=_cmd_regs)

    p = sub.add_parser("demo", help="run the main simulation on the default scene")
    p.add_argument("--out", default="build/demo", help="output folder [%(default)s]")
    p.add_argument("--scene", default="corridor", help="scene name or YAML path [%(default)s]")
    p.add_argument("--seconds", type=float, default=None,
                   help="sonar time to simulate (default: twin 2 s or the scene's if shorter; golden: the scene's)")
    p.add_argument("--backend", choices=("twin", "golden"), default="twin",
                   help="twin: the RTL full-system twin over USB/IP (Verilator); golden: the golden model alone "
                        "[%(default)s]")
    p.add_argument("--fst", default=None, metavar="PATH",
                   help="twin: write an FST waveform of the whole device (tracing build, several times slower)")
    p.add_argument("--inproc", action="store_true",
                   help="twin: reach the device through the in-process pyusb backend instead of USB/IP")
    p.add_argument("--no-compare", action="store_true", help="twin: do not run the golden model alongside")
    p.add_argument("--sensors", choices=("demo", "ring8"), default="demo",
                   help="demo: five sensors (a phased front sensor, four side sensors); ring8: the maximum load, "
                        "eight sensors over all 24 receivers at order 4 [%(default)s]")
    p.set_defaults(func=_cmd_demo)

    from .device_cli import register as _register_device_commands

    # info / configure / stream / record / plot / serve: the host driver (issue #6)
    _register_device_commands(sub)

    from .experiments import EXPERIMENTS

    p = sub.add_parser("experiment", help="the paper's experiments and the speed/accuracy report (golden model)",
                       description="Run one experiment; writes NAME.md, NAME.csv and NAME.png (fig3, ring, safety: also NAME.json) "
                       "into --out. "
                       + "; ".join(f"{k}: {d}" for k, (_, d) in EXPERIMENTS.items()))
    p.add_argument("name", nargs="?", choices=list(EXPERIMENTS), metavar="NAME", help=" | ".join(EXPERIMENTS))
    p.add_argument("--out", default=None, help="output folder [build/experiments/NAME]")
    p.add_argument("--quick", action="store_true", help="a short version (seconds; what the tests run)")
    p.add_argument("--workers", type=int, default=None, help="local worker processes [number of cores]")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run the sweep on a Dask distributed cluster, e.g. tcp://10.0.0.5:8786 (needs 'distributed')")
    p.add_argument("--rtl", action="store_true",
                   help="fig3: add the RTL scheduler column; ring: run the goal distances on the RTL scheduler too; "
                        "simspeed: time the full-system twin and the RTL system test (Verilator)")
    p.add_argument("--twin", action="store_true",
                   help="fig3: add a column measured on the full-system twin (the whole device in Verilator)")
    p.add_argument("--backend", choices=("model", "twin"), default="model",
                   help="fig9, fig10, person: 'twin' also runs the cases on the full-system twin (the whole "
                        "device in Verilator) and puts its results next to the golden model's [%(default)s]")
    p.add_argument("--trials", type=int, default=None, metavar="N", help="safety: crossings to run [1000; --quick 12]")
    p.add_argument("--seed", type=int, default=None, metavar="S", help="safety: first seed (trials S..S+N-1) [0]")
    p.set_defaults(func=_cmd_experiment)

    from .rosmsgs import DEFAULT_ROS_DISTRO, ROS_DISTROS

    p = sub.add_parser("export", help="export a recording (.msrec) for robotics tools (ROS 2 MCAP)")
    p.add_argument("recording", metavar="REC", help="recording written by 'multisonar record'")
    p.add_argument("--mcap", required=True, metavar="OUT.mcap", help="ROS 2 bag in MCAP format to write")
    p.add_argument("--frame-id", default="base_link", help="robot frame of the messages [%(default)s]")
    p.add_argument("--temperature", type=float, default=20.0, help="air temperature for ToF -> range, degC [%(default)s]")
    p.add_argument("--ros-distro", choices=tuple(ROS_DISTROS), default=DEFAULT_ROS_DISTRO,
                   help="ROS 2 distribution whose message layout to write (Range has 'variance' from iron on) "
                        "[%(default)s]")
    p.set_defaults(func=_cmd_export)

    p = sub.add_parser("live", help="Foxglove WebSocket server of live ROS 2 messages (docs/live.md)")
    from .live import add_arguments as _add_live_arguments

    _add_live_arguments(p)
    p.set_defaults(func=_cmd_live)
    return ap


def _cmd_live(args: argparse.Namespace) -> int:
    from .live import cmd_live

    return cmd_live(args)


def _cmd_experiment(args: argparse.Namespace) -> int:
    import os

    from .experiments import TWIN_BACKEND_EXPERIMENTS, ExecutorError, ExperimentError, run_experiment

    if args.name is None:
        from .experiments import EXPERIMENTS

        print("multisonar experiment: name an experiment:\n" + "\n".join(f"  {k:<9} {d}" for k, (_, d) in EXPERIMENTS.items()),
              file=sys.stderr)
        return 2
    opts = {"rtl": True} if args.rtl else {}
    if args.rtl and args.name not in ("fig3", "simspeed", "ring"):
        raise ValueError("--rtl applies to fig3, ring and simspeed only (the others run on the golden model for now)")
    if args.twin:
        if args.name != "fig3":
            raise ValueError("--twin applies to fig3 only (simspeed --rtl times the twin; make demo runs it)")
        opts["twin"] = True
    if args.backend != "model":
        if args.name not in TWIN_BACKEND_EXPERIMENTS:
            raise ValueError(f"--backend {args.backend} applies to {', '.join(TWIN_BACKEND_EXPERIMENTS)} only")
        opts["backend"] = args.backend
    for key in ("trials", "seed"):
        if getattr(args, key) is not None:
            if args.name != "safety":
                raise ValueError(f"--{key} applies to safety only")
            opts[key] = getattr(args, key)
    workers = args.workers if args.workers is not None else (os.cpu_count() or 1)
    mode = f"Dask scheduler {args.scheduler}" if args.scheduler else f"{workers} local worker(s)"
    backend = "golden model and full-system twin" if args.backend == "twin" else "golden model"
    print(f"experiment {args.name}{' (quick)' if args.quick else ''}: {backend}, {mode}", file=sys.stderr)
    try:
        res, files = run_experiment(args.name, args.out, quick=args.quick, workers=workers, scheduler=args.scheduler,
                                    **opts)
    except (ExecutorError, ExperimentError) as e:
        print(f"multisonar experiment: error: {e}", file=sys.stderr)
        return 1
    print(res.markdown)
    print(f"experiment {args.name}: {res.summary['wall_s']:.1f} s wall; wrote " + ", ".join(str(f) for f in files))
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    from .export import ExportError, export_mcap

    try:
        stats = export_mcap(args.recording, args.mcap, frame_id=args.frame_id, temperature_c=args.temperature,
                            ros_distro=args.ros_distro)
    except ExportError as e:
        print(f"multisonar export: error: {e}", file=sys.stderr)
        return 1
    print(f"export: {args.mcap}: " + ", ".join(f"{k} {v}" for k, v in stats.items()))
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from .demo import run_demo

    from .twin import TwinError

    try:
        return run_demo(args.scene, args.out, seconds=args.seconds, backend=args.backend, fst=args.fst,
                        usbip=not args.inproc, compare=not args.no_compare, sensors=args.sensors)
    except TwinError as e:
        print(f"multisonar demo: error: {e}", file=sys.stderr)
        return 1


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (LayoutError, ValueError, FileNotFoundError) as e:
        print(f"multisonar {args.command}: error: {e}", file=sys.stderr)
        return 1
    except BrokenPipeError:  # output piped into `head` and closed early
        return 0


if __name__ == "__main__":
    sys.exit(main())
