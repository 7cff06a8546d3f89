"""The scheduler's microcode kernels (multisonar.tools.sched_program) run on the engine's model
(sched_ucode.Machine) against the golden model: the same predictions, folds and window sets
for random tracking states, the extremes of the 24-bit fields included."""

import random

import pytest

from multisonar.fastfiring import FastFiringModel, SyntheticEchoSource, _RxState
from multisonar.layout import load_layout
from multisonar.schedule import Schedule, VirtualSensor
from multisonar.tools.sched_program import CAND, NUM_RX, TRK, cand_clocks, cand_kernel, pack_rx, prologue
from multisonar.tools.sched_ucode import Machine, Program

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
    p.label("start")
    cand_kernel(p)
    p.label("halt").jmp("halt")
    img = p.assemble()
    m = Machine(img.words, mem=mem)
    m.run(100_000, stop={img.labels["halt"]})
    return s, m, img


@pytest.mark.parametrize("seed", range(40))
def test_cand_kernel_predicts_as_the_model(seed):
    rng = random.Random(seed)
    rx = sorted(rng.sample(range(NUM_RX), rng.randrange(1, NUM_RX + 1)))
    sensors = [VirtualSensor("a", tx=[rx[0]], rx=rx, order=3), VirtualSensor("b", tx=[5], rx=[5, 6])]
    model = FastFiringModel(Schedule(LAYOUT, sensors), SyntheticEchoSource({}))
    sensor = rng.randrange(2)
    k = rng.randrange(1 << 16)
    s, m, _ = run_cand(model, sensor, k, rng)
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
