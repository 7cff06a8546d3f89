"""The full-system twin (multisonar.twin, sim/twin/): the device's RTL in Verilator (VexRiscv +
sonar_app firmware, sonar core, host link, USB device core) with the acoustic model in the loop,
reached by the unchanged pyusb driver.

* scoreboard: with a noise-free scene, every pulse the RTL fires and every ToF record of every
  frame the driver receives equal the golden model's (FastFiringModel from the scheduler's start
  tick, decision lead 4096), and the firmware's geometry lies on the corridor's walls;
* `multisonar demo` on the twin over USB/IP: files, counters (nothing dropped or lost), wall fixes
  on the true walls;
* an FST waveform on request.

The twin is built by `make twin` on first use (~1 min of Verilator on 2 cores)."""

from __future__ import annotations

import csv
import math
from collections import defaultdict

import numpy as np
import pytest

from multisonar import protocol as P
from multisonar.cli import main as cli_main
from multisonar.constants import TICK_HZ
from multisonar.demo import demo_sensors
from multisonar.fastfiring import FastFiringModel, SceneEchoSource
from multisonar.scene import load_scene
from multisonar.twin import open_twin

LEAD = 4096  # ms_scheduler's decision lead (ticks)


class NoiseFree:
    """The scene's echoes without the random noise pulses: the model and the twin then draw the
    acoustic model's random numbers (fading, jitter) in the same order, pulse by pulse."""

    def __init__(self, inner: SceneEchoSource) -> None:
        self.inner = inner

    @property
    def t_offset(self) -> float:
        return self.inner.t_offset

    @t_offset.setter
    def t_offset(self, v: float) -> None:
        self.inner.t_offset = v

    def fire(self, t0, elements, delays):
        return self.inner.fire(t0, elements, delays)


def _source(scene) -> NoiseFree:
    return NoiseFree(SceneEchoSource(scene, rng=np.random.default_rng(11)))


def test_twin_matches_golden_model():
    scene = load_scene("corridor")
    src = _source(scene)
    with open_twin(scene, usbip=False, echo_source=src) as tw:
        dev = tw.device
        sched = dev.configure(demo_sensors(), temperature_c=scene.temperature_c)
        tw.start()
        frames = []
        end = tw.sim.tick + int(0.12 * TICK_HZ)
        for f in dev.stream(idle_timeout_s=120):
            frames.append(f)
            if tw.sim.tick >= end:
                break
        stop_tick = tw.sim.tick
        s0, s_last = tw.sim.first_schedule_start, tw.sim.schedule_start
        fires = list(tw.sim.fires)
        harness = tw.sim.counters()
        counters = dev.counters()
        offset = src.t_offset
    assert harness["echoes_late"] == 0 and harness["trig_orphans"] == 0 and harness["fires_incomplete"] == 0, harness
    assert counters["frames_dropped"] == 0 and counters["fifo_overflows"] == 0 and counters["host_lost"] == 0, counters
    assert counters["host_bad_crc"] == 0 and counters["watchdog"] == 0, counters
    # a re-aim by the firmware restarts the schedule with another table: compare the first table's span
    end = s_last if harness["schedule_starts"] > 1 else stop_tick
    assert end - s0 > 0.05 * TICK_HZ, f"the first table ran only {(end - s0) / TICK_HZ * 1e3:.1f} ms"

    # the golden model from the scheduler's start tick, same echoes (same scene time, same random draws)
    ref = SceneEchoSource(scene, rng=np.random.default_rng(11))
    ref.t_offset = offset
    model = FastFiringModel(sched, NoiseFree(ref), start_tick=s0, decision_lead=LEAD)
    res = model.run(end - s0)
    cut = end - 2 * LEAD  # the restart's validation and rebuild take well under LEAD clocks
    m_fires = [(p.t0, p.sensor) for p in res.pulses if p.t0 < cut]
    assert [(t0, vs) for t0, vs, _, _ in fires if t0 < cut] == m_fires, "pulse ticks / sensors differ from the model"
    resolved = sched.validate()
    for t0, vs, el, delays in (f for f in fires if f[0] < cut):  # each pulse's elements and phasing delays
        r = resolved[vs]
        want = sorted(zip(map(int, r.tx), map(int, r.delays)))
        assert sorted(zip(el.tolist(), delays.tolist())) == want, f"pulse at {t0}: elements/delays {el} {delays}"
    assert any(len(el) == 3 for _, _, el, _ in fires), "the phased 3-element front sensor never fired"
    closed = {(p.sensor, p.seq & 0xFF) for p in res.pulses
              if max((w[2] for w in p.windows), default=p.t0) < cut}
    frames = [f for f in frames if f.timestamp < cut and (f.vs, f.pulse_seq) in closed]

    groups: dict[tuple[int, int], list[tuple]] = defaultdict(list)
    for e in res.events:
        groups[(e.sensor, e.seq)].append((e.tof, e.rx, e.seq, e.sensor, int(e.in_window) | int(e.first_echo) << 1
                                          | int(e.window_empty) << 2 | int(e.init_ping) << 3))
    n_rec = n_wall = 0
    for f in frames:
        key = (f.vs, f.pulse_seq)
        got = [tuple(int(r[n]) for n in ("tof", "rx", "seq", "vs", "flags")) for r in f.tof]
        assert got == groups.get(key), f"pulse {key}: frame {got}, model {groups.get(key)}"
        n_rec += len(got)
        for g in f.geo:
            if P.GEO_CLASSES[int(g["cls"])] == "wall":  # the corridor walls at y = +-1.2 m, robot on y = 0
                t = (f.t0 - s0) / TICK_HZ + offset
                x, y, ph = scene.pose(t)
                assert abs(abs(float(y) + int(g["y_mm"]) * 1e-3 * math.cos(float(ph))) - 1.2) < 0.01, g
                n_wall += 1
    assert len(frames) >= 30 and n_rec >= 100 and n_wall >= 5, (len(frames), n_rec, n_wall)


def test_demo_on_the_twin_over_usbip(tmp_path, capsys):
    assert cli_main(["demo", "--seconds", "0.15", "--out", str(tmp_path)]) == 0
    for name in ("map.png", "summary.md", "fixes.csv", "events.npz", "frames.msrec"):
        assert (tmp_path / name).stat().st_size > 0, name
    out = capsys.readouterr().out
    assert "RTL twin" in out and "over USB/IP" in out
    summary = (tmp_path / "summary.md").read_text()
    assert "dropped 0, FIFO overflows 0" in summary and "lost 0, bad CRC 0" in summary, summary
    rows = list(csv.DictReader(open(tmp_path / "fixes.csv")))
    walls = np.array([float(r["error_m"]) for r in rows if r["kind"] == "wall"])
    assert len(walls) >= 10 and np.median(walls) < 0.005, walls
    ev = np.load(tmp_path / "events.npz")
    assert ev["tof"].size > 50 and set(np.unique(ev["sensor"])) == {0, 1, 2, 3, 4}
    # the recording reads back through the driver's reader
    from multisonar.device import read_recording

    rec = read_recording(tmp_path / "frames.msrec")
    assert len(rec.frames) >= 40 and len(rec.events()) == ev["tof"].size


def test_twin_writes_fst(tmp_path):
    from multisonar.twin import TwinError, TwinSim, library_path

    fst = tmp_path / "twin.fst"
    with TwinSim(None, fst=fst) as sim:  # builds build/twin/fst (make twin-fst) when needed
        sim.reset()
        sim.run(2000)
    data = fst.read_bytes()
    assert len(data) > 1000 and data[0] == 0  # FST block type 0: the header block
    with pytest.raises(TwinError, match="without FST"):
        TwinSim(None, fst=tmp_path / "never.fst", library=library_path(False))
