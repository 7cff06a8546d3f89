"""``multisonar info | configure | stream | record | plot | serve``: the device subcommands.

Every command takes ``--url`` (default: ``$MULTISONAR_URL``, else the first board on libusb);
``sim://corridor`` runs the simulated device in-process, ``usbip://127.0.0.1:PORT`` talks to
``multisonar serve --port PORT``.
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import time
from pathlib import Path
from typing import Any, Callable

DEFAULT_SENSORS = "demo"


def add_url(p: argparse.ArgumentParser) -> None:
    from .urls import scheme_names

    p.add_argument("--url", default=os.environ.get("MULTISONAR_URL"),
                   help="device: usb:// (board, default), usbip://HOST:PORT, sim://SCENE (model), twin://SCENE "
                        "(the RTL twin); schemes: " + ", ".join(f"{k}://" for k in scheme_names())
                        + " (multisonar.urls) [$MULTISONAR_URL]")
    p.add_argument("--timeout", type=float, default=2.0, help="command timeout, s [%(default)s]")


def add_sensors(p: argparse.ArgumentParser, *, optional: bool = False) -> None:
    p.add_argument("--sensors", default=None if optional else DEFAULT_SENSORS,
                   help="virtual sensors: 'demo' (the demo's five), 'ring8' (eight over all 24 receivers, order 4) "
                        "or a YAML file with a list of VirtualSensor fields (name, tx, rx, order, t_v, ...)"
                        + ("" if optional else " [%(default)s]"))
    p.add_argument("--temperature", type=float, default=20.0, help="air temperature, degC [%(default)s]")


def device_errors(fn: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
    """Turn driver errors into one line on stderr and exit status 1."""

    @functools.wraps(fn)
    def run(args: argparse.Namespace) -> int:
        from .protocol import DeviceError, ProtocolError

        try:
            return fn(args)
        except BrokenPipeError:  # output piped into `head` and closed early
            return 0
        except (ConnectionError, TimeoutError, DeviceError, ProtocolError) as e:
            print(f"multisonar {args.command}: error: {e}", file=sys.stderr)
            return 1
        except KeyboardInterrupt:
            print(f"multisonar {args.command}: interrupted", file=sys.stderr)
            return 130

    return run


def load_sensors(spec: str) -> list[Any]:
    from .demo import SENSOR_SETS, demo_sensors
    from .schedule import VirtualSensor

    if spec in SENSOR_SETS:
        return demo_sensors(spec)
    import yaml

    path = Path(spec)
    doc = yaml.safe_load(path.read_text())
    items = doc.get("sensors") if isinstance(doc, dict) else doc
    if not isinstance(items, list) or not items:
        raise ValueError(f"{path}: expected a list of virtual sensors (or a mapping with 'sensors:')")
    out = []
    for i, d in enumerate(items):
        if not isinstance(d, dict):
            raise ValueError(f"{path}: sensor {i} is not a mapping")
        d = dict(d)
        if "source" in d:
            d["source"] = tuple(d["source"])
        try:
            out.append(VirtualSensor(**d))
        except TypeError as e:
            raise ValueError(f"{path}: sensor {i} ({d.get('name', '?')}): {e}") from None
    return out


def _open(args: argparse.Namespace):
    from .device import Device

    return Device.open(args.url, timeout_s=args.timeout)


@device_errors
def cmd_info(args: argparse.Namespace) -> int:
    with _open(args) as dev:
        i = dev.info()
        u = dev._dev
        print(f"device      {dev.url}: {getattr(u, 'manufacturer', '?')} / {getattr(u, 'product', '?')}, "
              f"serial {getattr(u, 'serial_number', '?')}, USB {u.idVendor:04x}:{u.idProduct:04x}")
        print(f"protocol    {i.protocol_version} (max payload {i.max_payload} bytes)")
        print(f"registers   map revision {i.regmap_revision}, gateware {i.gateware_version}, build 0x{i.build_id:08X}"
              + (" (simulated)" if i.simulated else ""))
        print(f"tick rate   {i.tick_hz} Hz")
        print(f"channels    {i.channels}, virtual sensors {i.max_vs}, max order {i.max_order}, "
              f"window slots per element {i.win_slots}")
        for k, v in dev.counters().items():
            if not k.startswith("host_"):
                print(f"  {k:<16} {v}")
    return 0


@device_errors
def cmd_configure(args: argparse.Namespace) -> int:
    sensors = load_sensors(args.sensors)
    with _open(args) as dev:
        sched = dev.configure(sensors, temperature_c=args.temperature)
        print(f"configured {len(sched.resolved)} virtual sensors on {dev.url}:")
        print(f"{'id':>2} {'name':<12} {'tx':<12} {'rx':<12} {'order':>5} {'D [us]':>7} {'max tof [ms]':>12}")
        for r in sched.resolved:
            print(f"{r.id:>2} {r.name:<12} {','.join(map(str, r.tx)):<12} {','.join(map(str, r.rx)):<12} "
                  f"{r.order:>5} {r.blank / 48:>7.0f} {r.max_tof / 48e3:>12.2f}")
        if args.start:
            dev.start()
            print("started")
    return 0


def _progress(n: int, wall: float, stats: dict[str, int] | None = None, total: str = "") -> None:
    extra = ""
    if stats:
        extra = f", lost {stats.get('lost', 0)}, bad crc {stats.get('bad_crc', 0)}"
    sys.stderr.write(f"\r  {n} frames{total} in {wall:5.1f} s ({n / max(wall, 1e-9):7.0f}/s){extra}   ")
    sys.stderr.flush()


def _prepare_stream(dev: Any, args: argparse.Namespace) -> None:
    if args.sensors is not None or not args.no_configure:
        dev.configure(load_sensors(args.sensors or DEFAULT_SENSORS), temperature_c=args.temperature)
    dev.start()


@device_errors
def cmd_stream(args: argparse.Namespace) -> int:
    from . import protocol as P

    with _open(args) as dev:
        _prepare_stream(dev, args)
        t0 = time.monotonic()
        n = 0
        last = 0.0
        out = sys.stdout
        if args.format == "csv":
            out.write("frame_seq,t0,vs,pulse_seq,rx,tof,flags\n")
        try:
            for f in dev.stream(duration_s=args.seconds, max_frames=args.frames):
                n += 1
                if args.format == "frames":
                    name = dev.sensor_names.get(f.vs, f"vs{f.vs}")
                    tofs = " ".join(f"{int(r['rx'])}:{int(r['tof'])}" for r in f.tof)
                    geo = ""
                    if len(f.geo):
                        g = f.geo[0]
                        geo = (f" {P.GEO_CLASSES[int(g['cls'])]} ({int(g['x_mm'])},{int(g['y_mm'])}) mm "
                               f"q{int(g['quality'])}")
                    out.write(f"#{f.seq} t0={f.t0} {name} seq={f.pulse_seq} {tofs}{geo}\n")
                elif args.format == "csv":
                    for r in f.tof:
                        out.write(f"{f.seq},{f.t0},{f.vs},{f.pulse_seq},{int(r['rx'])},{int(r['tof'])},{int(r['flags'])}\n")
                now = time.monotonic() - t0
                if now - last >= 0.5:
                    last = now
                    _progress(n, now, dev.stats.as_dict())
        finally:
            dev.stop()
            wall = time.monotonic() - t0
            _progress(n, wall, dev.stats.as_dict())
            sys.stderr.write("\n")
        c = dev.counters()
        print(f"{n} frames in {wall:.2f} s; device: sent {c['frames_sent']}, dropped {c['frames_dropped']}; "
              f"host: lost {c['host_lost']}, bad crc {c['host_bad_crc']}, queue dropped {c['host_queue_dropped']}",
              file=sys.stderr)
    return 0


@device_errors
def cmd_record(args: argparse.Namespace) -> int:
    if args.seconds is None and args.frames is None:
        args.seconds = 5.0
    with _open(args) as dev:
        _prepare_stream(dev, args)
        total = f"/{args.frames}" if args.frames else ""
        n = dev.record(args.out, duration_s=args.seconds, max_frames=args.frames,
                       progress=lambda k, w: _progress(k, w, dev.stats.as_dict(), total))
        sys.stderr.write("\n")
        dev.stop()
        c = dev.counters()
    size = Path(args.out).stat().st_size
    print(f"recorded {n} frames ({size} bytes) to {args.out}; lost {c['host_lost']}, device dropped "
          f"{c['frames_dropped']}")
    if args.mcap:  # the export of this recording: the channels of `multisonar export` and `live`
        from .export import ExportError, export_mcap

        try:
            stats = export_mcap(args.out, args.mcap, temperature_c=args.temperature, ros_distro=args.ros_distro)
        except ExportError as e:
            print(f"multisonar record: error: {e}", file=sys.stderr)
            return 1
        print(f"export: {args.mcap}: " + ", ".join(f"{k} {v}" for k, v in stats.items()))
    return 0


@device_errors
def cmd_plot(args: argparse.Namespace) -> int:
    import math

    import numpy as np

    from . import protocol as P
    from .constants import TICK_HZ, speed_of_sound
    from .device import read_recording

    rec = read_recording(args.path)
    if not rec.frames:
        raise ValueError(f"{args.path}: no frames")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ev = rec.events()
    geo = rec.geometry()
    names = {s["id"]: s["name"] for s in rec.meta.get("sensors", [])}
    c = speed_of_sound(20.0)
    t_first = int(ev["t0"].min()) if len(ev) else 0
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(13, 5.5))
    hit = (ev["flags"] & P.TOF_SAMPLE_MASK) == P.TOF_SAMPLE
    for vs in sorted(set(int(v) for v in ev["vs"])):
        m = hit & (ev["vs"] == vs)
        t = ((ev["t0"][m].astype(np.int64) - t_first) & 0xFFFFFFFF) / TICK_HZ
        a1.plot(t, ev["tof"][m] / TICK_HZ * c / 2, ".", ms=2, label=names.get(vs, f"vs{vs}"))
    a1.set_xlabel("device time [s]")
    a1.set_ylabel("range c*ToF/2 [m]")
    a1.set_title(f"first echoes in window ({len(ev)} ToF records, {len(rec.frames)} frames)")
    a1.legend(markerscale=4, fontsize=8)
    for k, name in enumerate(P.GEO_CLASSES):
        m = geo["cls"] == k
        if k == 0 or not m.any():
            continue
        a2.plot(geo["x_mm"][m] / 1000, geo["y_mm"][m] / 1000, "o" if name == "edge" else ".", ms=3, label=name)
    th = np.linspace(0, 2 * math.pi, 100)
    a2.plot(0.35 * np.cos(th), 0.35 * np.sin(th), "k-", lw=0.8)
    a2.set_aspect("equal")
    a2.set_xlabel("x [m] (robot frame)")
    a2.set_ylabel("y [m]")
    a2.set_title(f"geometry records ({len(geo)})")
    a2.legend(fontsize=8)
    fig.tight_layout()
    out = Path(args.out or Path(args.path).with_suffix(".png"))
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    print(f"wrote {out} ({len(rec.frames)} frames, {rec.corrupt} corrupt{', truncated' if rec.truncated else ''})")
    return 0


def serve_url(args: argparse.Namespace) -> str:
    """The model URL ``serve`` serves: --url as given, else one built from --scene / --twin and the
    simulated device's options."""
    from urllib.parse import quote, urlencode

    if args.url:
        return args.url
    scene = quote(args.scene, safe="")
    if args.twin:
        return f"twin://{scene}"
    q = {"source": args.source, "queue": args.queue} | ({"rate": args.rate} if args.rate is not None else {})
    return f"sim://{scene}?{urlencode(q)}"


@device_errors
def cmd_serve(args: argparse.Namespace) -> int:
    from .stopsignals import stop_on_signals
    from .urls import make_model
    from .usb.usbip_server import UsbipServer

    url = serve_url(args)
    model = make_model(url)  # any registered model scheme: sim://, twin://, a third party's
    try:
        try:
            srv = UsbipServer(model.function, args.host, args.port)
        except OSError as e:
            raise ConnectionError(f"cannot serve on {args.host}:{args.port}: {e.strerror or e}") from None
        # the handlers before the line that tells a supervisor we are up: a signal sent on that line stops cleanly
        with stop_on_signals(srv.request_stop):  # Ctrl-C, SIGTERM: the model closed below
            print(f"serving {url} at {srv.url}" + ("; use long timeouts" if model.min_timeout_s > 10 else "")
                  + "; Ctrl-C stops", flush=True)
            srv.serve_forever()
    finally:
        if model.close is not None:
            model.close()
    return 0


def register(sub: Any) -> None:
    """Add the device subcommands to the top-level parser's subparsers."""
    from .rosmsgs import DEFAULT_ROS_DISTRO, ROS_DISTROS

    p = sub.add_parser("info", help="device identity, versions, tick rate and counters")
    add_url(p)
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("configure", help="validate virtual sensors and load them into the device")
    add_url(p)
    add_sensors(p)
    p.add_argument("--start", action="store_true", help="start firing afterwards")
    p.set_defaults(func=cmd_configure)

    for name, helptext in (("stream", "stream time-of-flight frames"), ("record", "record frames to a file")):
        p = sub.add_parser(name, help=helptext)
        add_url(p)
        add_sensors(p, optional=True)
        p.add_argument("--no-configure", action="store_true", help="keep the device's current table")
        p.add_argument("--seconds", type=float, default=None if name == "record" else 5.0,
                       help="wall time to stream" + (" [5 unless --frames]" if name == "record" else " [%(default)s]"))
        p.add_argument("--frames", type=int, default=None, help="stop after this many frames")
        if name == "stream":
            p.add_argument("--format", choices=("summary", "frames", "csv"), default="frames",
                           help="stdout: one line per frame, CSV of ToF records, or only the summary [%(default)s]")
            p.set_defaults(func=cmd_stream)
        else:
            p.add_argument("--out", default="build/recording.msrec", help="recording file [%(default)s]")
            p.add_argument("--mcap", default=None, metavar="OUT.mcap",
                           help="also write the recording as a ROS 2 bag in MCAP (as 'multisonar export' does)")
            p.add_argument("--ros-distro", choices=tuple(ROS_DISTROS), default=DEFAULT_ROS_DISTRO,
                           help="with --mcap: the ROS 2 message layout [%(default)s]")
            p.set_defaults(func=cmd_record)

    p = sub.add_parser("plot", help="plot a recording (ranges over time, geometry fixes)")
    p.add_argument("path", help="recording file (multisonar record)")
    p.add_argument("--out", default=None, help="PNG [PATH with .png]")
    p.set_defaults(func=cmd_plot)

    p = sub.add_parser("serve", help="serve a simulated device over USB/IP (for --url usbip://...)")
    p.add_argument("--url", default=None,
                   help="the device model to serve, any model scheme: sim://SCENE?rate=R&source=S&queue=N&seed=S, "
                        "twin://SCENE, ... (default: built from the options below)")
    p.add_argument("--scene", default="corridor", help="scene name or YAML path [%(default)s]")
    p.add_argument("--host", default="127.0.0.1", help="bind address [%(default)s]")
    p.add_argument("--port", type=int, default=3240, help="TCP port [%(default)s]")
    p.add_argument("--rate", type=float, default=None,
                   help="sonar time per wall time (frames are dropped when not read); default: lock-step")
    p.add_argument("--source", choices=("model", "replay"), default="model", help="[%(default)s]")
    p.add_argument("--queue", type=int, default=256, help="device frame queue [%(default)s]")
    p.add_argument("--twin", action="store_true",
                   help="serve the full-system twin (the device's RTL in Verilator, make twin) instead of the model")
    p.set_defaults(func=cmd_serve)
