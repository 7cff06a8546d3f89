"""Gated miss rule of the golden model (docs/fast_firing.md section 4.4; RTL: ms_scheduler,
RX_FILTER.miss_gate) and the simulated device honouring the register. The RTL equality is
checked by tests/rtl/tb_ms_scheduler.py (miss_gate_*) and tb_ms_sonar_core.py."""

from __future__ import annotations

import struct

from multisonar import protocol as P
from multisonar.constants import speed_of_sound
from multisonar.fastfiring import DEFAULT_MISS_GATE, FastFiringModel, SyntheticEchoSource, _RxState, _Window
from multisonar.generated import sonar_regs as R
from multisonar.layout import load_layout
from multisonar.regmap import schedule_writes
from multisonar.schedule import Schedule, VirtualSensor
from multisonar.simdevice import SimDevice

MS = 48_000
LAYOUT = load_layout()


def _step_run(gate, jump_ticks=5000, **kw):
    """A static reflector (order 2, K = 2) whose ToF jumps by jump_ticks at 60 ms (inside the
    window, like an alias echo of another pulse)."""
    r0 = 1.2
    r1 = r0 + jump_ticks / 48e6 * speed_of_sound(20.0) / 2
    sched = Schedule(LAYOUT, [VirtualSensor("s", tx=[10], rx=[9, 10, 11], order=2, miss_limit=2, **kw)])
    args = {} if gate == "default" else {"miss_gate": gate}
    m = FastFiringModel(sched, SyntheticEchoSource(r0, step_ranges_m=r1, step_tick=60 * MS), **args)
    return m, m.run(120 * MS)


def test_alias_jump_outside_the_gate_counts_as_a_miss_and_reinitialises():
    m, res = _step_run("default")
    assert m.miss_gate == DEFAULT_MISS_GATE
    inits = [p for p in res.pulses if p.init]
    assert len(inits) == 2 and res.cancelled, "K = 2 gated windows must re-initialise the sensor"
    # the jumped echoes are still reported as in-window first echoes (no window_empty word)
    after = [e for e in res.events if not e.init_ping and e.tick > 60 * MS and e.tick < inits[1].t0]
    assert after and all(e.in_window and e.first_echo and not e.window_empty for e in after)


def test_gate_off_or_wider_than_the_jump_keeps_tracking():
    for gate in (0, None, 6000):
        _, res = _step_run(gate)
        assert sum(p.init for p in res.pulses) == 1, gate


def test_gate_needs_a_measured_velocity():
    """Right after the init ping (v not measured yet) a jump far outside the gate is a sample."""
    sched = Schedule(LAYOUT, [VirtualSensor("s", tx=[10], rx=[10], order=1, miss_limit=1)])
    m = FastFiringModel(sched, SyntheticEchoSource(1.5, velocity_mps=2.0))  # ~10 000 ticks per pulse
    res = m.run(300 * MS)
    assert sum(p.init for p in res.pulses) == 1
    st = m.sensors[0].rx[10]
    assert st.vel and st.v != 0


def test_the_sample_that_would_measure_velocity_is_gated_at_vmax_per_pulse():
    """No velocity yet, not right after the init ping: an echo further than v_max per pulse of the
    gap from the last sample is gated (it would set a clamped, wrong velocity and drag the track
    off: the twin's demo lost a side wall that way to one early spurious echo); within v_max it is
    the sample that measures v. Right after the init ping's sample there is no bound (its period
    differs). The rule follows the gate: off with it."""
    sched = Schedule(LAYOUT, [VirtualSensor("s", tx=[10], rx=[9, 10, 11], order=2, vmax=2000)])

    def hit(tof, *, seq, init=False, gate=DEFAULT_MISS_GATE):
        m = FastFiringModel(sched, SyntheticEchoSource({}), miss_gate=gate)
        s = m.sensors[0]
        st = _RxState(tracked=True, tof=200_000, seq=10, v=0, miss=0, init=init, vel=False)
        s.rx[10] = st
        w = _Window(0, 1 << 30, 0, 0, seq, 10, 0, False, s.epoch)
        m.windows[10].append(w)
        m._rise(10, tof)
        return w.rejected, st, m.events[-1]

    rejected, st, ev = hit(200_000 - 2001, seq=11)          # 2001 ticks in one pulse: > v_max
    assert rejected and ev.gated and (st.seq, st.vel) == (10, False)
    rejected, st, ev = hit(200_000 - 2000, seq=11)          # at v_max: the sample, v measured
    assert not rejected and not ev.gated and (st.seq, st.v, st.vel) == (11, -2000, True)
    assert not hit(200_000 + 5000, seq=13)[0]               # gap 3: bound 6000
    assert hit(200_000 + 6001, seq=13)[0]
    assert not hit(200_000 - 30_000, seq=11, init=True)[0]  # after the init ping's sample: no bound
    assert not hit(200_000 - 30_000, seq=11, gate=0)[0]     # gate off


def test_sample_after_a_skipped_pulse_keeps_velocity_gate_and_miss_count():
    """An echo that passes the gate after a missed window (pulse gap > 1) moves the track but
    keeps its velocity, its gate and its miss count; only a gated sample of the next pulse
    resets the count. So an alias that passes once between misses does not restart the K
    misses, and the sample after it is still gated (before, v was zeroed and the gate was off
    until two samples in a row: an alias passing once could take the track over)."""
    m = FastFiringModel(Schedule(LAYOUT, [VirtualSensor("s", tx=[10], rx=[9, 10, 11], order=2)]),
                        SyntheticEchoSource({}))
    s = m.sensors[0]
    st = _RxState(tracked=True, tof=200_000, seq=10, v=40, miss=2, vel=True)
    s.rx[10] = st

    def window(seq):
        return _Window(0, 1 << 30, 0, 0, seq, 10, 0, False, s.epoch)
    m._sample(s, st, window(12), 200_070)                  # gap 2, within the gate
    assert (st.tof, st.seq, st.v, st.miss, st.vel) == (200_070, 12, 40, 2, True)
    assert m._predict(s, st, 13) == 200_110                # the kept velocity predicts
    m._sample(s, st, window(13), 200_115)                  # the next pulse: a sample with v,
    assert (st.tof, st.seq, st.v, st.miss, st.vel) == (200_115, 13, 42, 0, True)   # v + (5 >> 1)
    fresh = _RxState(tracked=True, tof=200_000, seq=10, v=0, miss=1, vel=False)
    s.rx[10] = fresh
    m._sample(s, fresh, window(12), 200_500)               # no velocity yet: as before, v = 0
    assert (fresh.seq, fresh.v, fresh.miss, fresh.vel) == (12, 0, 0, False)


def test_simdevice_takes_the_gate_from_rx_filter_at_start():
    f = R.REGISTERS["RX_FILTER"].fields
    for gate in (None, 0, 1234):
        sim = SimDevice("corridor")
        writes = schedule_writes(Schedule(LAYOUT, [VirtualSensor("front", tx=[0], rx=[23, 0, 1])]))
        if gate is not None:
            rx = f["GLITCH_MIN"].put(f["MISS_GATE"].put(0, gate), 24)
            writes = writes + [(R.RX_FILTER_ADDR, rx)]
        pkt = P.decode_packet(sim.handle_command(P.encode_command(P.Opcode.WRITE_REGS, P.write_regs_payload(writes))))
        assert pkt.status == P.Status.OK
        r = P.decode_packet(sim.handle_command(P.encode_command(P.Opcode.READ_REGS, P.read_regs_payload([R.RX_FILTER_ADDR]))))
        assert f["MISS_GATE"].get(struct.unpack("<I", r.payload)[0]) == (DEFAULT_MISS_GATE if gate is None else gate)
        assert P.decode_packet(sim.handle_command(P.encode_command(P.Opcode.START))).status == P.Status.OK
        want = DEFAULT_MISS_GATE if gate is None else (gate or None)
        assert sim.model.miss_gate == want, (gate, sim.model.miss_gate)
        sim.handle_command(P.encode_command(P.Opcode.STOP))
        sim.close()
