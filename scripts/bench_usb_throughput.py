#!/usr/bin/env python3
"""Throughput and latency of the host driver against the simulated device (issue #6).

For each transport (in-process pyusb backend, USB/IP over 127.0.0.1) and frame source
(``replay``: frames of a model run replayed, i.e. transport-limited; ``model``: the golden
model in lock-step, i.e. model-limited) it streams for ``--seconds`` and reports frames/s,
wire bytes/s and ToF records/s decoded into numpy, plus the ECHO command round trip.

"Echo-to-host latency (sim time)": for every first echo in a window, the device time from the
echo's arrival (t0 + ToF) to the moment its frame is closed and queued for the bulk IN
endpoint (the frame timestamp): the frame packer waits for the pulse's last window, so this
is the latency a board adds before USB. Full-speed USB itself carries at most 19 x 64 bytes
per 1 ms frame (1.216 MB/s) on bulk; the table shows how far the host side is from that.

    .venv/bin/python scripts/bench_usb_throughput.py [--seconds 3] [--plot build/bench/usb.png]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "host"))

from multisonar import protocol as P  # noqa: E402
from multisonar.constants import TICK_HZ  # noqa: E402
from multisonar.demo import DEMO_SENSORS  # noqa: E402
from multisonar.device import Device  # noqa: E402
from multisonar.schedule import VirtualSensor  # noqa: E402
from multisonar.simdevice import SimDevice  # noqa: E402
from multisonar.usb.usbip_server import UsbipServer  # noqa: E402

FS_BULK_MAX = 19 * 64 * 1000  # bytes/s, full-speed bulk ceiling


def run_case(transport: str, source: str, seconds: float) -> dict:
    sim = SimDevice("corridor", source=source)
    srv = None
    if transport == "usbip":
        srv = UsbipServer(sim).start()
        dev = Device.open(srv.url)
    else:
        dev = Device.attach(sim)
    try:
        dev.configure([VirtualSensor(n, tx=t, rx=r, order=1) for n, t, r in DEMO_SENSORS])
        rtt = [dev.echo(b"x" * 16) for _ in range(200)]
        dev.start()
        # warm-up (replay buffer, first pulses)
        for _ in dev.stream(max_frames=20):
            pass
        frames: list[P.Frame] = []
        t0 = time.perf_counter()
        for f in dev.stream(duration_s=seconds):
            frames.append(f)
        wall = time.perf_counter() - t0
        dev.stop()
        c = dev.counters()
    finally:
        dev.close()
        if srv is not None:
            srv.close()
    ev = P.frames_to_events(frames)  # the numpy table a user gets
    wire = sum(len(f.payload) + P.HEADER_SIZE + P.CRC_SIZE for f in frames)
    first = (ev["flags"] & P.TOF_FIRST_ECHO) != 0
    lat = ((ev["timestamp"][first].astype(np.int64) - ev["t0"][first].astype(np.int64)) & 0xFFFFFFFF) \
        - ev["tof"][first].astype(np.int64)
    ts = np.array([f.timestamp for f in frames], dtype=np.int64)
    sonar_s = float(np.sum(np.diff(ts) & 0xFFFFFFFF)) / TICK_HZ  # frames close in time order; unwrap
    return {
        "transport": transport, "source": source, "frames": len(frames), "wall": wall,
        "fps": len(frames) / wall, "Bps": wire / wall, "recs": len(ev) / wall,
        "rtt_us": statistics.median(rtt) * 1e6, "rtt99_us": float(np.percentile(rtt, 99)) * 1e6,
        "lat_ms": float(np.median(lat)) / TICK_HZ * 1e3 if len(lat) else float("nan"),
        "lat99_ms": float(np.percentile(lat, 99)) / TICK_HZ * 1e3 if len(lat) else float("nan"),
        "rt": sonar_s / wall, "lost": c["host_lost"], "bad": c["host_bad_crc"],
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=3.0, help="streaming time per case [%(default)s]")
    ap.add_argument("--transports", default="inproc,usbip")
    ap.add_argument("--sources", default="replay,model")
    ap.add_argument("--plot", default=None, help="write a PNG bar chart here")
    a = ap.parse_args(argv)
    rows = []
    for source in a.sources.split(","):
        for transport in a.transports.split(","):
            print(f"  {transport} / {source} ...", file=sys.stderr, flush=True)
            rows.append(run_case(transport, source, a.seconds))
    print("| transport | source | frames/s | wire kB/s | % of FS bulk | ToF records/s | x real time | "
          "ECHO RTT median / p99 [us] | echo-to-host latency median / p99 [ms sim] | lost | bad CRC |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['transport']} | {r['source']} | {r['fps']:.0f} | {r['Bps'] / 1e3:.1f} | "
              f"{100 * r['Bps'] / FS_BULK_MAX:.0f} | {r['recs']:.0f} | {r['rt']:.2f} | "
              f"{r['rtt_us']:.0f} / {r['rtt99_us']:.0f} | {r['lat_ms']:.2f} / {r['lat99_ms']:.2f} | "
              f"{r['lost']} | {r['bad']} |")
    print(f"\nFull-speed bulk ceiling {FS_BULK_MAX / 1e3:.0f} kB/s; {a.seconds} s per case; frames of the demo's "
          "five virtual sensors on scene 'corridor'.")
    if a.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(1, 2, figsize=(11, 4))
        labels = [f"{r['transport']}\n{r['source']}" for r in rows]
        ax[0].bar(labels, [r["fps"] for r in rows])
        ax[0].set_ylabel("frames/s")
        ax[0].set_yscale("log")
        ax[1].bar(labels, [r["Bps"] / 1e3 for r in rows])
        ax[1].axhline(FS_BULK_MAX / 1e3, color="r", ls="--", label="full-speed bulk ceiling")
        ax[1].set_ylabel("wire kB/s")
        ax[1].set_yscale("log")
        ax[1].legend()
        fig.suptitle("simulated Multisonar -> numpy")
        fig.tight_layout()
        Path(a.plot).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(a.plot, dpi=110)
        print(f"wrote {a.plot}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
