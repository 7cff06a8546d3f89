"""The scheduler's microcode kernels (multisonar.tools.sched_program) run on the engine's model
(sched_ucode.Machine) against the golden model: the same predictions, folds and window sets
for random tracking states, the extremes of the 24-bit fields included."""

import random

import pytest

from multisonar.fastfiring import FastFiringModel, SyntheticEchoSource, _RxState, _Window
from multisonar.layout import load_layout
from multisonar.schedule import Schedule, VirtualSensor, effective_order, min_tof_for_order, pulse_period
from multisonar.tools.sched_program import (BA, BB, BU, CAND, R_MASK24, R_SIGN24, edge_kernel, head_kernel, safe_kernel, scan_clocks, F_ANY_TRK, F_EPOCH, F_IN_INIT,
                                            F_TRACKING, HC, HS, NUM_RX, S_DUE, S_FLAGS, S_K,
                                            S_MODE, S_OPEN, S_QUIET, S_REINIT, S_SEQ, S_SHARE,
                                            S_TRK, SCHED_GO, SCHED_HOLD, SCHED_NOT_YET,
                                            SCHED_QUIET, SENS, SENS_STRIDE, TRK, TU, WSLOTS, WV, cand_clocks,
                                            cand_kernel, close_clocks, close_kernel, conf_clocks,
                                            conf_kernel, EngineWithUnits, hit_clocks, hit_kernel,
                                            iel_clocks, iel_kernel, issue_kernel, order_clocks,
                                            order_kernel, pack_rx, prologue, run_kernel, sched_kernel, Slot,
                                            SlotUnit)
from multisonar.tools.sched_program.system import EchoPath, window_length
from multisonar.tools.sched_ucode import Program, UcodeError

LAYOUT = load_layout("ring24")


def pack_state(st: _RxState) -> tuple[int, int]:
    return pack_rx(st.tracked, st.tof, st.seq, st.v, st.miss, st.init, st.vel)


def random_state(rng: random.Random, seq: int, lo: int, hi: int) -> _RxState:
    kind = rng.random()
    if kind < 0.15:
        return _RxState()                                   # not tracked
    tof = rng.choice([lo, hi, rng.randrange(lo, hi + 1), rng.randrange(0, 1 << 24)])
    v = rng.choice([0, 1, -1, rng.randrange(-20000, 20001), 65535, -65535])
    gap = rng.choice([1, 2, 8, rng.randrange(1, 128), 255])
    return _RxState(tracked=True, tof=tof, seq=seq - gap, v=v, miss=rng.randrange(16),
                    init=rng.random() < 0.2, vel=rng.random() < 0.5)


def run_cand(model: FastFiringModel, sensor: int, k: int, rng: random.Random):
    s = model.sensors[sensor]
    lo, hi = s.cfg.te_limits()
    mem = {}
    base = TRK + 2 * NUM_RX * sensor
    mask = 0
    for r in map(int, s.cfg.rx):
        st = random_state(rng, k, lo, hi)
        s.rx[r] = st
        mem[base + 2 * r], mem[base + 2 * r + 1] = pack_state(st)
        mask |= 1 << r
    p = prologue(Program("cand")).li(1, mask).li(2, base).li(3, k & 0xFF).li(4, lo).li(5, hi)
    m, _ = run_kernel(p, cand_kernel, mem, max_cycles=100_000)
    return s, m


@pytest.mark.parametrize("seed", range(40))
def test_cand_kernel_predicts_as_the_model(seed):
    rng = random.Random(seed)
    rx = sorted(rng.sample(range(NUM_RX), rng.randrange(1, NUM_RX + 1)))
    sensors = [VirtualSensor("a", tx=[rx[0]], rx=rx, order=3), VirtualSensor("b", tx=[5], rx=[5, 6])]
    model = FastFiringModel(Schedule(LAYOUT, sensors), SyntheticEchoSource({}))
    sensor = rng.randrange(2)
    k = rng.randrange(1 << 16)
    s, m = run_cand(model, sensor, k, rng)
    te = {r: model._predict(s, st, k) for r, st in s.rx.items() if st.tracked}
    got = {r: m.mem[CAND + r] for r in range(NUM_RX) if m.regs[8] >> r & 1}
    assert got == te
    assert m.regs[9] == len(te)
    if te:
        assert (m.regs[6], m.regs[7]) == (min(te.values()), max(te.values()))
    else:
        assert (m.regs[6], m.regs[7]) == (0x7FFF_FFFF, 0)


def test_cand_kernel_clocks_per_receiver():
    """How long the engine takes per receiver (the hardware stream takes one clock): the
    figure bench_sched_engine.py reports; more receivers take proportionally longer."""
    c24, c12 = cand_clocks(24), cand_clocks(12)
    assert 10 * 24 < c24 < 100 * 24
    assert abs(c24 / 24 - c12 / 12) < 3


# ------------------------------------------------------------------ CONF with the slot unit
def random_conf_case(rng: random.Random):
    """A model whose elements hold random reserved windows, tx_until and blank_until around a
    candidate t0, and the candidate's blank intervals and windows."""
    model = FastFiringModel(Schedule(LAYOUT, [VirtualSensor("a", tx=[0], rx=[0])]), SyntheticEchoSource({}))
    wrap = rng.random() < 0.3
    t = (1 << 32) - rng.randrange(1, 1 << 21) if wrap else rng.randrange(1 << 22, 1 << 31)
    span = rng.choice([1 << 10, 1 << 16, 1 << 20])
    touched = rng.sample(range(NUM_RX), rng.randrange(1, NUM_RX + 1))
    tx = [e for e in touched if rng.random() < 0.25] or touched[:1]
    xt = [e for e in touched if e not in tx and rng.random() < 0.2]
    rxs = [e for e in touched if rng.random() < 0.7]
    blanks = [(e, rng.randrange(0, 1 << 16), 0) for e in tx + xt]
    blanks = [(e, a, a + rng.randrange(1, 1 << 19)) for e, a, _ in blanks]
    tv, tn = rng.randrange(1, 1 << 15), rng.randrange(1, 1 << 15)
    te = {e: rng.randrange(tv, 1 << 22) for e in rxs}
    wins = [(e, te[e] - tv, te[e] + tn) for e in sorted(rxs)]
    lo = {e: [t + a for x, a, _ in blanks if x == e] + ([t + te[e] - tv] if e in te else [])
          for e in range(NUM_RX)}
    hi = {e: [t + b for x, _, b in blanks if x == e] + ([t + te[e] + tn] if e in te else [])
          for e in range(NUM_RX)}
    for e in range(NUM_RX):
        # windows, tx_until and blank_until: random near t0, far before it, or exactly on the
        # candidate's edges (touching is no conflict)
        n = rng.choice([0, 0, 1, 3, rng.randrange(WSLOTS + 1), WSLOTS])
        model.windows[e] = []
        for _ in range(n):
            kind = rng.random()
            if kind < 0.15 and lo[e]:
                end = rng.choice(lo[e])
                start = end - rng.randrange(1, span)
            elif kind < 0.3 and hi[e]:
                start = rng.choice(hi[e])
                end = start + rng.randrange(1, span)
            else:
                start = t + rng.randrange(-4 * span, span)
                end = start + rng.randrange(1, span)
            model.windows[e].append(_Window(start, end, end - 1 + 3, 0, 0, e, start, False, 0))
        edge = rng.random() < 0.3 and lo[e]
        model.tx_until[e] = rng.choice(lo[e]) if edge else t + rng.randrange(-4 * span, span)
        edge = rng.random() < 0.3 and lo[e]
        model.blank_until[e] = rng.choice(lo[e]) + rng.choice([0, 1]) if edge else t + rng.randrange(-4 * span, span)
    return model, t, blanks, wins, len(tx), te, tv, tn, set(touched), set(tx), set(rxs)


@pytest.mark.parametrize("seed", range(100))
def test_conf_kernel_with_the_slot_unit_finds_the_models_retry(seed):
    rng = random.Random(seed)
    model, t, blanks, wins, n_tx, te, tv, tn, touched, tx, rxs = random_conf_case(rng)
    expect = model._conflict(t, blanks, wins, n_tx=n_tx)
    mem = {}
    for e in range(NUM_RX):
        mem[TU + e] = model.tx_until[e] & 0xFFFF_FFFF
        mem[BU + e] = model.blank_until[e] & 0xFFFF_FFFF
    for e, a, b in blanks:
        mem[BA + e], mem[BB + e] = a, b
    for e, v in te.items():
        mem[CAND + e] = v
    su = SlotUnit()
    for e, ws in enumerate(model.windows):   # the element's windows in random slots
        ks = rng.sample(range(WSLOTS), len(ws))
        for k, w in zip(ks, ws):
            su.slots[e * WSLOTS + k] = Slot(w.start & 0xFFFF_FFFF, w.end & 0xFFFF_FFFF, w.close & 0xFFFF_FFFF)
        mem[WV + e] = sum(1 << k for k in ks)
    mask = lambda es: sum(1 << e for e in es)  # noqa: E731
    p = prologue(Program("conf")).li(1, t).li(2, mask(touched)).li(3, mask(tx)).li(4, mask(rxs))
    p.li(5, tv).li(6, tn).li(9, mask(e for e, _, _ in blanks))
    m, _ = run_kernel(p, conf_kernel, mem, su, max_cycles=200_000)
    assert bool(m.regs[7]) == (expect is not None)
    if expect is not None:
        assert m.regs[8] == expect & 0xFFFF_FFFF


def test_conf_kernel_clocks_per_element():
    """The CONF figure of bench_sched_engine.py: proportional to the elements, longer with
    full slots (the slot unit's scan) than with none."""
    full24, full8, empty24 = conf_clocks(24, 3, 16), conf_clocks(8, 3, 16), conf_clocks(24, 3, 0)
    assert abs(full24 / 24 - full8 / 8) < 3 and empty24 < full24 < 200 * 24


# ------------------------------------------------------------------ IEL
def issue_case(seed: int):
    """A sensor about to issue at t0 = t (built without conflict), with old windows in random
    slots of its elements; returns the model after _try_issue, its state before, and the
    kernel's inputs."""
    rng = random.Random(seed)
    start = rng.randrange(NUM_RX)
    ntx = rng.randrange(1, 4)
    tx = [(start + i) % NUM_RX for i in range(ntx)]
    rx = sorted({(start + i) % NUM_RX for i in range(-rng.randrange(0, 5), ntx + rng.randrange(0, 5))})
    vs = VirtualSensor("s", tx=tx, rx=rx, order=rng.randrange(1, 5), xtalk_neighbours=rng.randrange(0, 3),
                       source=tuple(LAYOUT.positions[tx].mean(axis=0) * 0.5))
    model = FastFiringModel(Schedule(LAYOUT, [vs]), SyntheticEchoSource({}))
    s, c = model.sensors[0], model.sensors[0].cfg
    t = rng.randrange(1 << 24, 1 << 30)
    model.now, s.due, s.quiet = t, t, t
    s.seq = rng.choice([rng.randrange(1 << 16), 0xFFFF, (1 << 16) + rng.randrange(1 << 16)])
    init = rng.random() < 0.3
    lo, hi = c.te_limits()
    for r in map(int, c.rx):   # an init ping also finds the states of an earlier track
        s.rx[r] = random_state(rng, s.seq, lo, hi)
    if not init:
        s.tracking = True
        if not any(st.tracked for st in s.rx.values()):
            s.rx[int(c.rx[0])] = _RxState(tracked=True, tof=lo, seq=s.seq - 1)
    slots = {}
    touched = set(map(int, c.tx)) | set(map(int, c.xtalk_elements)) | set(map(int, c.rx))
    for e in range(NUM_RX):
        n = rng.randrange(0, WSLOTS - 1) if e in touched else 0
        pos = rng.sample(range(WSLOTS), n)
        ws = []
        for k in pos:   # old windows: over before any of the candidate's intervals begins
            end = t - rng.randrange(0, 1 << 16)
            w = _Window(end - rng.randrange(1, 1 << 16), end, end + rng.randrange(-2, 1 << 18), 0, 0, e, 0, False, 0)
            ws.append(w)
            slots[(e, k)] = w
        model.windows[e] = ws
        # a receiver's blank_until before t0 (else the pulse would wait), a blank-only element's
        # also later than the new blanking (kept)
        late = e not in set(map(int, c.rx)) and rng.random() < 0.4
        model.blank_until[e] = t + rng.randrange(1 << 21) if late else t - rng.randrange(0, 1 << 20)
        model.tx_until[e] = t - rng.randrange(0, 1 << 20)
    s.track_pulses = rng.choice([0, 5, 254, 255, 300])
    s.epoch = rng.randrange(2)
    te = ({} if init else {r: model._predict(s, st, s.seq) for r, st in s.rx.items() if st.tracked})
    before = {"bu": list(model.blank_until), "tu": list(model.tx_until),
              "sensor": sensor_words(s, c) | {S_SEQ: s.seq & 0xFFFF, S_TRK: min(s.track_pulses, 255)},
              "rx": {r: pack_state(st) for r, st in s.rx.items()}}
    model._try_issue(s)
    return model, t, c, init, te, slots, before


@pytest.mark.parametrize("seed", range(60))
def test_iel_kernel_writes_what_the_model_issues(seed):
    model, t, c, init, te, slots, before = issue_case(seed)
    assert len(model.pulses) == 1, "the case is built to issue without conflict"
    mem = {}
    for e in range(NUM_RX):
        mem[BU + e], mem[TU + e] = before["bu"][e], before["tu"][e]
        mem[WV + e] = sum(1 << k for (x, k) in slots if x == e)
        olds = [(w.close, k) for (x, k), w in slots.items() if x == e]
        if olds:
            close, k = min(olds)
            mem[HC + e], mem[HS + e] = close, k | 0x100
    for e, a, b in c.blank_intervals():
        mem[BA + e], mem[BB + e] = a, b
    for e, v in te.items():
        mem[CAND + e] = v
    wins = [int(e) for e in c.rx] if init else sorted(te)
    mask = lambda es: sum(1 << int(e) for e in es)  # noqa: E731
    blk = [e for e, _, _ in c.blank_intervals()]
    p = prologue(Program("iel")).li(1, t).li(2, mask(set(blk) | set(wins))).li(3, mask(c.tx))
    p.li(4, mask(wins)).li(9, mask(blk)).li(24, 0x5A).li(25, model.latency - 1)
    p.li(5, -c.blank if init else c.t_v).li(6, c.max_tof if init else c.t_n)
    m, _ = run_kernel(p, iel_kernel, mem, max_cycles=200_000)
    for e in range(NUM_RX):
        assert m.mem[BU + e] == model.blank_until[e] and m.mem[TU + e] == model.tx_until[e], f"element {e}"
        new = [w for w in model.windows[e] if w.t0 == t]
        got = [(a, f) for a, f in m.out.slots.items() if a // WSLOTS == e]
        assert len(got) == len(new) <= 1
        if new:
            addr, (t0, we, meta) = got[0]
            w = new[0]
            free = [k for k in range(WSLOTS) if (e, k) not in slots]
            assert addr % WSLOTS == free[0] and meta == 0x5A
            length = window_length(c, init)   # WIN keeps no start: the hardware's length table
            assert (t0 + we - length, t0 + we, t0 + we - 1 + model.latency) == (w.start, w.end, w.close)
            assert m.mem[WV + e] == mem[WV + e] | 1 << free[0]
        if model.windows[e]:
            closes = {(x, k): w.close for (x, k), w in slots.items() if x == e}
            if new:
                closes[(e, addr % WSLOTS)] = new[0].close
            k = m.mem[HS + e]
            assert k & 0x100 and m.mem[HC + e] == closes[(e, k & 0xFF)] == min(closes.values())
    assert sorted(m.out.triggers) == sorted((trg.tick, trg.element) for trg in model.triggers)


def test_iel_kernel_clocks_per_element():
    """The IEL figure of bench_sched_engine.py: the same clocks for every further element."""
    c8, c16, c24 = iel_clocks(8, 3), iel_clocks(16, 3), iel_clocks(24, 3)
    assert abs((c24 - c16) - (c16 - c8)) <= 8 and c24 < 200 * 24


# ------------------------------------------------------------------ HIT
@pytest.mark.parametrize("seed", range(150))
def test_hit_kernel_samples_gates_and_reports_as_the_model(seed):
    rng = random.Random(seed)
    vs = [VirtualSensor("a", tx=[3], rx=[2, 3, 4], order=2), VirtualSensor("b", tx=[9], rx=[8, 9, 10])]
    gate = rng.choice([None, 2400, rng.randrange(1, 5000)])
    model = FastFiringModel(Schedule(LAYOUT, vs), SyntheticEchoSource({}), miss_gate=gate)
    sensor = rng.randrange(2)
    s, c = model.sensors[sensor], model.sensors[sensor].cfg
    rx = int(rng.choice(list(c.rx)))
    lo, hi = c.te_limits()
    s.epoch = rng.randrange(2)
    k = rng.randrange(200, 1 << 16)           # the window's pulse
    st = random_state(rng, k, lo, hi)
    st.seq = k - rng.choice([1, 1, 2, 5, 127, 0, -1, -3]) if st.tracked else st.seq
    if st.tracked and rng.random() < 0.5:     # an echo near the prediction, to exercise the gate
        off = rng.randrange(-3000, 3001)
        if gate and rng.random() < 0.5:      # on the gate's edge: accepted at gate, refused beyond
            off = rng.choice([-1, 1]) * (gate + rng.choice([0, 1]))
        tof_guess = model._predict(s, st, k) + off
    else:
        tof_guess = rng.randrange(lo - 5000, hi + 5000)
    t0 = rng.randrange(1 << 20, 1 << 31)
    init = rng.random() < 0.25
    w = _Window(t0 + lo - 10_000, t0 + hi + 10_000, 0, sensor, k, rx, t0, init,
                s.epoch if rng.random() < 0.85 else 1 - s.epoch)
    w.n_edges = 1 if rng.random() < 0.1 else 0
    n = t0 + max(lo - 9_000, min(hi + 9_000, tof_guess))
    s.rx[rx] = st
    before = pack_state(st)
    model.windows[rx] = [w]
    model.now = n + model.latency
    model._rise(rx, n)
    base = TRK + 2 * (NUM_RX * sensor + rx)
    mem = {base: before[0], base + 1: before[1]}
    flags = int(init) | int(w.epoch == s.epoch) << 1 | int(w.n_edges > 1) << 2
    p = prologue(Program("hit")).li(1, n).li(2, t0).li(3, k & 0xFF).li(4, flags).li(5, base)
    p.li(6, rx).li(7, sensor).li(8, gate or 0).li(9, c.vmax).li(10, lo).li(11, hi)
    m, _ = run_kernel(p, hit_kernel, mem, max_cycles=10_000)
    assert m.out.events == model.words
    assert (m.mem[base], m.mem[base + 1]) == pack_state(s.rx[rx])
    assert m.regs[12] == int(w.rejected)


@pytest.mark.parametrize("gate", [500, 65535])
@pytest.mark.parametrize("v_kind", ["zero", "slow", "at_vmax", "at_minus_vmax"])
def test_hit_kernel_smooths_the_velocity_as_the_model(gate, v_kind):
    """A gated sample of the next pulse with a measured velocity: the track takes the echo's
    time of flight and the velocity half the residual from the prediction (rounded down, v
    within +-v_max); residuals of both signs, odd and even, up to the gate's edges."""
    vs = [VirtualSensor("a", tx=[3], rx=[2, 3, 4], order=2)]
    model = FastFiringModel(Schedule(LAYOUT, vs), SyntheticEchoSource({}), miss_gate=gate)
    s, c = model.sensors[0], model.sensors[0].cfg
    lo, hi = c.te_limits()
    v = {"zero": 0, "slow": -137, "at_vmax": c.vmax, "at_minus_vmax": -c.vmax}[v_kind]
    k, t0, rx = 5000, 1 << 24, 3
    for off in sorted({-gate, -gate + 1, -3, -1, 0, 1, 2, 3, min(1001, gate - 2), gate - 1, gate}):
        st = _RxState(tracked=True, tof=(lo + hi) // 2, seq=k - 1, v=v, miss=2, init=False, vel=True)
        s.rx[rx] = st
        before = pack_state(st)
        n = t0 + model._predict(s, st, k) + off
        w = _Window(t0 + lo - 10_000, t0 + hi + 10_000, 0, 0, k, rx, t0, False, s.epoch)
        model.windows[rx], model.words = [w], []
        model.now = n + model.latency
        model._rise(rx, n)
        assert not w.rejected and st.vel and st.miss == 0
        assert st.tof == (lo + hi) // 2 + v + off and st.v == max(-c.vmax, min(c.vmax, v + (off >> 1))), off
        base = TRK + 2 * rx
        p = prologue(Program("hit")).li(1, n).li(2, t0).li(3, k & 0xFF).li(4, 2).li(5, base)
        p.li(6, rx).li(7, 0).li(8, gate).li(9, c.vmax).li(10, lo).li(11, hi)
        m, _ = run_kernel(p, hit_kernel, {base: before[0], base + 1: before[1]}, max_cycles=10_000)
        assert m.out.events == model.words
        assert (m.mem[base], m.mem[base + 1]) == pack_state(st), off
        assert m.regs[12] == 0


def test_hit_kernel_clocks():
    """The HIT figure of bench_sched_engine.py: the gated sample path, a few dozen clocks."""
    assert 20 < hit_clocks() < 200


# ------------------------------------------------------------------ CLOSE
def sensor_words(s, c) -> dict[int, int]:
    """A sensor's words in the data memory (sched_program's per-sensor layout)."""
    flags = (int(s.tracking) * F_TRACKING | int(s.in_init) * F_IN_INIT | (s.epoch & 1) * F_EPOCH
             | int(any(st.tracked for st in s.rx.values())) * F_ANY_TRK)
    return {S_DUE: s.due & 0xFFFF_FFFF, S_FLAGS: flags, S_OPEN: s.init_open, S_K: c.miss_limit,
            S_MODE: 1 if c.mode.value == "track" else 2}


@pytest.mark.parametrize("seed", range(150))
def test_close_kernel_counts_misses_and_ends_init_as_the_model(seed):
    rng = random.Random(seed)
    vs = [VirtualSensor("a", tx=[3], rx=[2, 3, 4], order=2, miss_limit=rng.randrange(1, 6),
                        mode=rng.choice(["track", "track", "init"])),
          VirtualSensor("b", tx=[9], rx=[8, 9, 10])]
    model = FastFiringModel(Schedule(LAYOUT, vs), SyntheticEchoSource({}))
    sensor = rng.randrange(2)
    s, c = model.sensors[sensor], model.sensors[sensor].cfg
    lo, hi = c.te_limits()
    rx = int(rng.choice(list(c.rx)))
    now = rng.randrange(1 << 22, 1 << 31)
    model.now = now
    s.epoch = rng.randrange(2)
    s.tracking = rng.random() < 0.6
    s.in_init = not s.tracking and rng.random() < 0.8
    s.init_open = rng.randrange(1, 4) if s.in_init else 0
    s.due = now + rng.randrange(-50_000, 50_000)
    for r in map(int, c.rx):
        s.rx[r] = random_state(rng, 1000, lo, hi)
        s.rx[r].miss = rng.choice([0, 1, c.miss_limit - 1, 14, 15])
    init = rng.random() < 0.4
    t0 = now - rng.randrange(50_000, 200_000)
    we = rng.randrange(lo, hi)
    w = _Window(t0 + we - 48_000, t0 + we, now, sensor, rng.randrange(1 << 16), rx, t0, init,
                s.epoch if rng.random() < 0.8 else 1 - s.epoch)
    if init and w.epoch == s.epoch:   # a current init ping's window: the sensor is in its init phase
        s.tracking, s.in_init, s.init_open = False, True, rng.randrange(1, 4)
    w.n_edges = rng.choice([0, 0, 1, 2])
    w.rejected = w.n_edges > 0 and rng.random() < 0.4
    model.windows[rx] = [w]
    words = sensor_words(s, c)
    base_s = SENS + SENS_STRIDE * sensor
    trk = TRK + 2 * (NUM_RX * sensor + rx)
    mem = {base_s + k: v for k, v in words.items()}
    mem[trk], mem[trk + 1] = pack_state(s.rx[rx])
    flags = int(init) | (w.epoch & 1) << 1 | int(w.n_edges > 0) << 2 | int(w.rejected) << 3
    model._on_close(w)
    p = prologue(Program("close")).li(1, now).li(2, t0).li(3, we).li(4, w.seq & 0xFF).li(5, flags)
    p.li(6, rx).li(7, sensor).li(8, base_s).li(9, trk)
    m, _ = run_kernel(p, close_kernel, mem, max_cycles=10_000)
    cancelled = any(r.__class__.__name__ == "SensorCancel" for r in model.records)
    assert m.out.events == [wd for wd in model.words if not wd >> 61 & 1]   # the cancel record is SAFE's
    assert m.regs[10] == int(cancelled)
    assert (m.mem[trk], m.mem[trk + 1]) == pack_state(s.rx[rx])
    after = sensor_words(s, c)
    assert m.mem[base_s + S_DUE] == after[S_DUE] and m.mem[base_s + S_OPEN] == after[S_OPEN]
    assert m.mem[base_s + S_FLAGS] & (F_TRACKING | F_IN_INIT) == after[S_FLAGS] & (F_TRACKING | F_IN_INIT)


def test_close_kernel_clocks():
    """The CLOSE figure of bench_sched_engine.py (its longest path)."""
    assert 20 < close_clocks() < 200


# ------------------------------------------------------------------ ISSUE
@pytest.mark.parametrize("seed", range(60))
def test_issue_kernel_updates_the_sensor_as_the_model(seed):
    model, t, c, init, te, slots, before = issue_case(seed)
    s = model.sensors[0]
    pulse = model.pulses[-1]
    base_s, trk = SENS, TRK
    mem = {base_s + k: v for k, v in before["sensor"].items()}
    for r, (a, b) in before["rx"].items():
        mem[trk + 2 * r], mem[trk + 2 * r + 1] = a, b
    rxm = sum(1 << int(r) for r in c.rx)
    p = prologue(Program("issue")).li(1, t).li(2, pulse.period).li(3, len(pulse.windows))
    p.li(4, int(init)).li(5, c.max_tof - c.blank).li(6, rxm).li(7, 0).li(8, base_s).li(9, trk)
    m, _ = run_kernel(p, issue_kernel, mem, max_cycles=10_000)
    records = [w for w in model.words if w >> 62 & 1]
    assert m.out.events == records
    after = sensor_words(s, c) | {S_SEQ: s.seq & 0xFFFF, S_TRK: min(s.track_pulses, 255)}
    for k in (S_DUE, S_SEQ, S_OPEN, S_TRK):
        assert m.mem[base_s + k] == after[k], k
    assert m.mem[base_s + S_QUIET] == s.quiet & 0xFFFF_FFFF
    assert m.mem[base_s + S_FLAGS] == after[S_FLAGS]
    for r, st in s.rx.items():
        assert (m.mem.get(trk + 2 * r, 0), m.mem.get(trk + 2 * r + 1, 0)) == pack_state(st)


# ------------------------------------------------------------------ SCHED
class ProbeModel(FastFiringModel):
    """The model with the outcomes of _try_issue's first part made visible: a hold (the EDF
    rule's _hold_retry), reaching the candidate (_conflict, answered with a retry so nothing
    issues) and a cancel."""

    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        self.seen = []

    def _hold_retry(self, t):
        self.seen.append("hold")
        return None

    def _conflict(self, t, blanks, wins, n_tx=0):
        self.seen.append("go")
        return t + 1

    def _cancel(self, sensor):
        self.seen.append("cancel")


@pytest.mark.parametrize("seed", range(200))
def test_sched_kernel_decides_as_the_model(seed):
    rng = random.Random(seed)
    n = rng.randrange(2, 6)
    vs = []
    for i in range(n):   # sensors on random elements: some share, some do not
        e = rng.randrange(6 if rng.random() < 0.7 else NUM_RX)   # mostly a crowded sector
        vs.append(VirtualSensor(f"s{i}", tx=[e], rx=[e, (e + 1) % NUM_RX], order=2,
                                reinit_every=rng.choice([0, 0, 3, 8])))
    lead = rng.choice([0, 4096, 32768])
    model = ProbeModel(Schedule(LAYOUT, vs), SyntheticEchoSource({}), decision_lead=lead)
    now = rng.randrange(1 << 22, 1 << 31)
    model.now = now
    t = now + lead
    for s in model.sensors:
        s.tracking = rng.random() < 0.5
        s.in_init = not s.tracking and rng.random() < 0.3
        s.due = t + rng.choice([0, 1, -1, rng.randrange(-100_000, 100_000)])
        s.quiet = t + rng.choice([0, 1, -1, rng.randrange(-100_000, 100_000)])
        s.track_pulses = rng.choice([0, 2, 3, 8, 20])
        for r in map(int, s.cfg.rx):
            s.rx[r] = _RxState(tracked=s.tracking)
    if rng.random() < 0.3:   # equal dues (at t0 itself, or before): the lower id goes first
        due = t - rng.choice([0, 5])
        for s in model.sensors:
            s.due = due
    sid = rng.randrange(n)
    mem = {}
    for s in model.sensors:
        base = SENS + SENS_STRIDE * s.cfg.id
        mem.update({base + k: v for k, v in sensor_words(s, s.cfg).items()})
        mem[base + S_QUIET] = s.quiet & 0xFFFF_FFFF
        mem[base + S_TRK] = min(s.track_pulses, 255)
        mem[base + S_REINIT] = s.cfg.reinit_every
        mem[base + S_SHARE] = sum(1 << o for o in range(n) if o != s.cfg.id and model._shares[s.cfg.id][o])
    s = model.sensors[sid]
    heap_before = len(model._heap)
    model._try_issue(s)
    pushed = model._heap[heap_before:] if len(model._heap) > heap_before else []
    p = prologue(Program("sched")).li(1, now).li(2, lead).li(7, sid).li(8, SENS + SENS_STRIDE * sid)
    m, _ = run_kernel(p, sched_kernel, mem, max_cycles=10_000)
    outcome = m.regs[10]
    if "go" in model.seen:
        assert outcome == SCHED_GO and m.regs[12] == int(not s.tracking)
    elif "hold" in model.seen:
        assert outcome == SCHED_HOLD
    elif pushed:
        assert outcome == SCHED_QUIET and m.regs[11] == s.quiet & 0xFFFF_FFFF
    else:
        assert outcome == SCHED_NOT_YET
    assert m.regs[13] == int("cancel" in model.seen)
    assert bool(m.mem[SENS + SENS_STRIDE * sid + S_FLAGS] & F_TRACKING) == s.tracking


# ------------------------------------------------------------------ ORDER
@pytest.mark.parametrize("seed", range(300))
def test_order_kernel_finds_the_models_order_and_period(seed):
    rng = random.Random(seed)
    tv, tn, d = rng.randrange(1, 40_000), rng.randrange(1, 40_000), rng.randrange(1, 100_000)
    order = rng.randrange(0, 9)
    te_min = rng.randrange(1, 1 << 23)
    te_max = te_min + rng.choice([0, 1, rng.randrange(0, 1 << 20)])
    if rng.random() < 0.3:   # near an order's edge: T_E where order n just becomes feasible
        n = rng.randrange(1, 9)
        te_min = te_max = min_tof_for_order(n, tv, tn, d) + rng.choice([-1, 0, 1])
    want_n = effective_order(order, te_min, te_max, tv, tn, d)
    want_p = pulse_period(want_n, te_min, te_max, tv, tn, d)
    p = prologue(Program("order")).li(1, order).li(2, te_min).li(3, te_max).li(4, tv).li(5, tn)
    p.li(6, d)
    m, _ = run_kernel(p, order_kernel, {}, max_cycles=100_000)
    assert (m.regs[7], m.regs[8]) == (want_n, want_p)


def test_order_kernel_clocks():
    """The ORDER figures of bench_sched_engine.py: each further try costs the same."""
    c1, c2, c8 = order_clocks(1), order_clocks(2), order_clocks(8)
    assert c1 < c2 < c8 < 2000


def test_a_kernel_that_does_not_finish_is_reported():
    def spin(p):
        return p.label("spin").jmp("spin")
    with pytest.raises(UcodeError, match="spin did not finish in 50 clocks"):
        run_kernel(Program("t"), spin, max_cycles=50)


# ------------------------------------------------------------------ EDGE, HEAD, SAFE (slot unit scans)
def element_windows(rng: random.Random, model, e: int, t: int, sensors: int = 1):
    """Non-overlapping windows (as reservations keep them) on element e in random slots, with
    distinct seq numbers (the slot's index) and closes; into the model and a slot unit."""
    n = rng.randrange(0, WSLOTS + 1)
    ks = rng.sample(range(WSLOTS), n)
    start = t + rng.randrange(-200_000, 0)
    ws = {}
    for k in ks:
        start += rng.randrange(1, 5_000)
        end = start + rng.randrange(1, 20_000)
        ws[k] = _Window(start, end, end - 1 + model.latency, rng.randrange(sensors), k, e, start - 1000,
                        False, 0)
        start = end
    model.windows[e] = list(ws.values())
    return ws


def slot_state(ws_by_el: dict[int, dict[int, _Window]]):
    su, mem = SlotUnit(), {}
    for e, ws in ws_by_el.items():
        for k, w in ws.items():
            su.slots[e * WSLOTS + k] = Slot(w.start, w.end, w.close, w.sensor)
        mem[WV + e] = sum(1 << k for k in ws)
        if ws:
            k = min(ws, key=lambda k: ws[k].close)
            mem[HC + e], mem[HS + e] = ws[k].close, k | 0x100
    return su, mem


def one_element_case(seed: int):
    """A one-sensor model whose element 0 holds random windows (element_windows), and the
    same windows in a slot unit and the data memory."""
    rng = random.Random(seed)
    model = FastFiringModel(Schedule(LAYOUT, [VirtualSensor("a", tx=[0], rx=[0])]), SyntheticEchoSource({}))
    model.sensors[0].rx[0] = _RxState()
    t = rng.randrange(1 << 22, 1 << 31)
    ws = element_windows(rng, model, 0, t)
    su, mem = slot_state({0: ws})
    return rng, model, t, ws, su, mem


@pytest.mark.parametrize("seed", range(100))
def test_edge_kernel_finds_the_models_window(seed):
    rng, model, t, ws, su, mem = one_element_case(seed)
    if ws and rng.random() < 0.7:   # inside a window, on its first or last tick, or just after it
        w = rng.choice(list(ws.values()))
        n = rng.choice([w.start, w.end - 1, w.end, rng.randrange(w.start, w.end)])
    else:
        n = t + rng.randrange(-250_000, 50_000)
    model.now = n + model.latency
    model._rise(0, n)
    p = prologue(Program("edge")).li(1, n).li(6, 0)
    m, _ = run_kernel(p, edge_kernel, mem, su)
    found = [ev.seq for ev in model.events]          # the window's seq is its slot here
    assert m.regs[10] == (found[0] if found else 0xFFFF_FFFF)


@pytest.mark.parametrize("seed", range(60))
def test_head_kernel_finds_the_next_window_to_close(seed):
    rng, model, t, ws, su, mem = one_element_case(seed)
    if ws:   # the head closes: out of the model's windows and out of WV
        k = mem[HS] & 0xFF
        model._on_close(ws[k])
        mem[WV] &= ~(1 << k)
        now = ws[k].close
    else:
        now = t
    p = prologue(Program("head")).li(1, now).li(6, 0)
    m, _ = run_kernel(p, head_kernel, mem, su)
    rest = model.windows[0]
    if rest:
        first = min(rest, key=lambda w: w.close)
        assert m.mem[HS] == first.seq | 0x100 and m.mem[HC] == first.close
        assert m.out.heads == [(0, first.seq, first.close)]
    else:
        assert m.mem[HS] == 0 and m.out.heads == [(0, None, None)]


@pytest.mark.parametrize("seed", range(40))
def test_safe_kernel_cancels_the_sensors_windows_as_the_model(seed):
    """The cancel record and the windows left on every element as the model's _cancel."""
    rng = random.Random(seed)
    vs = [VirtualSensor(f"s{i}", tx=[i], rx=[i]) for i in range(3)]
    model = FastFiringModel(Schedule(LAYOUT, vs), SyntheticEchoSource({}))
    t = rng.randrange(1 << 22, 1 << 31)
    ws_by_el = {e: element_windows(rng, model, e, t, sensors=3) for e in range(NUM_RX)}
    su, mem = slot_state(ws_by_el)
    sensor = rng.randrange(3)
    model.now = t
    model._cancel(sensor)
    p = prologue(Program("safe")).li(1, t).li(7, sensor)
    heads = {e: mem.get(HS + e) for e in range(NUM_RX)}
    m, _ = run_kernel(p, safe_kernel, mem, su)
    assert m.out.events == model.words
    for e in range(NUM_RX):
        rest = {w.seq for w in model.windows[e]}
        assert m.mem[WV + e] == sum(1 << k for k in rest), f"element {e}"
        assert m.mem.get(HS + e) == heads[e] and not m.out.heads   # heads are left to close


def test_scan_kernel_clocks():
    """The EDGE / HEAD / SAFE figures of bench_sched_engine.py (each checks its own result)."""
    c = scan_clocks()
    assert 20 < c["edge"] < 100 and 20 < c["head"] < 100 and 24 * 20 < c["safe"] < 24 * 120


# ------------------------------------------------------------------ the receive path of a whole-program run
class RiseRecorder(FastFiringModel):
    """The model, recording every filtered rise (detection tick, receiver, run start)."""

    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        self.rise_log = []

    def _rise(self, rx, n):
        self.rise_log.append((self.now, rx, n))
        super()._rise(rx, n)


@pytest.mark.parametrize("scene,glitch", [("corridor", 2), ("person_crossing", 6)])
def test_echo_path_gives_the_models_rises(scene, glitch):
    """EchoPath fed with the model's pulses (fired at their decision ticks, in order) and the
    same noise gives the very rises the model processes: edges, noise, glitches and merged runs."""
    import numpy as np

    from multisonar.demo import demo_sensors
    from multisonar.fastfiring import SceneEchoSource
    from multisonar.scene import load_scene

    sc = load_scene(scene)
    sched = Schedule(sc.layout, demo_sensors("demo"), temperature_c=sc.temperature_c)
    lead, span = 4096, 9_600_000   # 0.2 s
    model = RiseRecorder(sched, SceneEchoSource(sc, rng=np.random.default_rng(3)), decision_lead=lead,
                         glitch_min=glitch)
    model.run(span)
    path = EchoPath(sc.layout.n, SceneEchoSource(sc, rng=np.random.default_rng(3)), glitch)
    path.noise(0, span)
    cfg = {c.id: c for c in model.cfg}
    fires = [(p.t0 - lead, p.t0, p.sensor) for p in model.pulses]
    got, fi = [], 0
    while True:
        nxt = [t for t in (path.next_tick(), fires[fi][0] if fi < len(fires) else None) if t is not None]
        if not nxt or min(nxt) >= span:
            break
        t = min(nxt)
        got += [(t, rx, n) for rx, n in path.rises(t)]
        while fi < len(fires) and fires[fi][0] == t:
            c = cfg[fires[fi][2]]
            path.fire(fires[fi][1], c.tx.copy(), c.delays.copy())
            fi += 1
    assert len(model.rise_log) > 50
    assert got == model.rise_log


@pytest.mark.parametrize("kernel", [cand_kernel, conf_kernel, iel_kernel, issue_kernel, sched_kernel,
                                    order_kernel, hit_kernel, close_kernel, edge_kernel, head_kernel,
                                    safe_kernel])
def test_kernels_keep_the_constant_registers(kernel):
    """No kernel writes the registers prologue() loads (a whole program runs them in turn)."""
    p = Program("k")
    kernel(p)
    written = {i.writes() for i in p.items if not isinstance(i, str)}
    assert not written & {R_MASK24, R_SIGN24}
