"""USB device core: host clock error tolerance and simulation speed (wire-level cocotb test).

    .venv/bin/python scripts/bench_usb_clock.py [--errors -3,-2,-1,-0.5,-0.25,0,0.25,0.5,1,2,3] [--skew 0..3] [--plot out.png]

Errors are in percent of the 12 Mbit/s host bit rate (USB 2.0 full speed allows +-0.25 %).
For each one: bus reset, Linux-like enumeration with descriptor checks, bulk OUT (toggles,
repeated packet) and bulk IN (NAK, lost ACK + retry, short packet, zero-length packet).
Prints a markdown table: pass/fail, packets, max device response delay, simulated time, wall time
and simulated device clocks per second.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "rtl"))
os.environ["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--errors", default="-3,-2,-1,-0.5,-0.25,0,0.25,0.5,1,2,3",
                    help="host clock errors in percent, comma separated")
    ap.add_argument("--skew", type=int, default=0, choices=range(4),
                    help="host D- later than D+ by this many host clocks (quarter bits)")
    ap.add_argument("--plot", help="write a PNG (pass/fail and speed per error)")
    args = ap.parse_args()
    from cocotb_run import run_cocotb
    from test_usb_device import TB, USB_RTL

    errors = [float(e) for e in args.errors.split(",")]
    out = ROOT / "build" / "bench" / "usb_clock.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    # same sources as tests/rtl/test_usb_device.py, so the Verilator build is shared; the
    # simulator's log goes to stderr so stdout carries only the table
    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    try:
        run_cocotb("usb_device_tb", "tb_usb_bench", sources=USB_RTL + TB,
                   extra_env={"USB_BENCH_ERRORS": ",".join(str(e / 100) for e in errors),
                              "USB_BENCH_OUT": str(out), "USB_BENCH_SKEW": str(args.skew)})
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)
    rows = json.loads(out.read_text())
    print(f"D- skew: {args.skew} host clock(s)\n")
    print("| host clock error | result | packets | max response delay (bits) | sim time (us) | wall (s) | device clocks/s |")
    print("|---:|---|---:|---:|---:|---:|---:|")
    for r in rows:
        res = "pass" if r["ok"] else f"FAIL: {r['msg']}"
        print(f"| {100 * r['error']:+.2f} % | {res} | {r['packets']} | {r['max_delay_bits']:.2f} | "
              f"{r['sim_us']:.0f} | {r['wall_s']:.2f} | {r['dev_clocks_per_s'] / 1e3:.0f} k |")
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6, 3.2))
        x = [100 * r["error"] for r in rows]
        ax.bar(x, [r["dev_clocks_per_s"] / 1e3 for r in rows], width=0.2,
               color=["tab:green" if r["ok"] else "tab:red" for r in rows])
        ax.set_xlabel("host clock error (%)  [green: pass, red: fail]")
        ax.set_ylabel("simulated device clocks/s (k)")
        fig.tight_layout()
        fig.savefig(args.plot, dpi=120)


if __name__ == "__main__":
    main()
