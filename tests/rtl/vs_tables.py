"""Random virtual-sensor tables for the check of the table (the firmware's sched_table.c,
tests/test_fw_sched_table.py): valid entries, some switched off, and single fields pushed to each
refusal of multisonar.simdevice.decode_vs_table. No cocotb: the host tests import it too."""

from __future__ import annotations

import random

from multisonar.constants import DEVICE_DECISION_LEAD
from multisonar.generated import sonar_regs as R
from multisonar.simdevice import RegisterFile

NUM_CH = 24
MASK24 = (1 << 24) - 1


def random_table(rng: random.Random, half: int, p_off: float = 0.2, num_vs: int = 8) -> RegisterFile:
    """Valid entries (each off with p_off); in half of the tables one entry gets one or two
    fields pushed to refusals."""
    regs = RegisterFile()
    refused = rng.randrange(num_vs) if rng.random() < 0.5 else -1
    dmem = R.MEMORIES["DELAY"]

    def put(name: str, fields: dict, vs: int) -> None:
        reg = R.REGISTERS[name]
        v = 0
        for f, x in fields.items():
            v = reg.fields[f].put(v, x)
        regs.set_hw(name, v, vs)

    for vs in range(8):
        if vs >= num_vs or rng.random() < p_off:
            put("VS_MODE", {"MODE": 0, "ORDER": rng.randrange(16), "MISS_LIMIT": rng.randrange(16)}, vs)
            continue
        n_tx = rng.choice([1, 1, 2, 3, 4, 24])
        start = rng.randrange(NUM_CH)
        tx = sum(1 << ((start + i) % NUM_CH) for i in range(n_tx))
        rx = rng.randrange(1, 1 << NUM_CH)
        nb = rng.randrange(4)
        burst = rng.randrange(1, 20)
        delays = [rng.choice([0, rng.randrange(64), rng.randrange(1 << 16)]) for _ in range(32)]
        dmax = max(delays[e] for e in range(NUM_CH) if tx >> e & 1)
        t_dead = burst * 2 * half + rng.randrange(3000)
        t_xt = rng.randrange(1, 6000)
        if max(t_dead, t_xt) + dmax <= DEVICE_DECISION_LEAD:
            t_dead = DEVICE_DECISION_LEAD + 1 - dmax + rng.randrange(2000)
        t_v = rng.randrange(1, 20000)
        t_n = max(rng.randrange(1, 20000), DEVICE_DECISION_LEAD + 1 - t_v)
        blank = max(t_dead, t_xt) + dmax
        max_tof = min(MASK24, blank + t_v + t_n + rng.randrange(1 << 20))
        fields = {
            "mode": rng.choice([1, 1, 2]), "order": rng.randrange(9), "k": rng.randrange(1, 16),
            "reinit": rng.randrange(256), "tx": tx, "rx": rx, "nb": nb, "burst": burst,
            "t_dead": t_dead, "t_xt": t_xt, "t_v": t_v, "t_n": t_n, "max_tof": max_tof,
            "vmax": rng.randrange(1 << 16), "phase": rng.randrange(1 << 24),
        }
        for _ in range(rng.choice([1, 1, 2]) if vs == refused else 0):  # push fields to refusals
            f = rng.choice(["mode", "tx0", "txgap", "rx", "order", "k", "burst", "t_v", "t_n", "t_xt",
                            "dead_short", "max_tof", "lead", "win_short"])
            if f == "mode":
                fields["mode"] = 3
            elif f == "tx0":
                fields["tx"] = 0
            elif f == "txgap":
                fields["tx"] = (1 << start) | (1 << ((start + rng.randrange(2, 12)) % NUM_CH))
            elif f == "rx":
                fields["rx"] = 0
            elif f == "order":
                fields["order"] = rng.randrange(9, 16)
            elif f == "k":
                fields["k"] = 0
            elif f == "burst":
                fields["burst"] = 0
            elif f in ("t_v", "t_n", "t_xt"):
                fields[f] = 0
            elif f == "dead_short":
                fields["t_dead"] = rng.randrange(max(1, burst * 2 * half))
            elif f == "max_tof":
                fields["max_tof"] = rng.randrange(max(1, blank + t_v + t_n))
            elif f == "lead":
                fields["t_dead"], fields["t_xt"] = burst * 2 * half, 1
                for e in range(32):
                    delays[e] = rng.randrange(64)
            else:
                fields["t_v"], fields["t_n"] = rng.randrange(1, 2048), rng.randrange(1, 2048)
        put("VS_TX_MASK", {"MASK": fields["tx"]}, vs)
        put("VS_RX_MASK", {"MASK": fields["rx"]}, vs)
        put("VS_MODE", {"MODE": fields["mode"], "ORDER": fields["order"], "MISS_LIMIT": fields["k"],
                        "REINIT_EVERY": fields["reinit"]}, vs)
        put("VS_WINDOW", {"T_V": fields["t_v"], "T_N": fields["t_n"]}, vs)
        put("VS_T_DEAD", {"TICKS": fields["t_dead"] & ((1 << 19) - 1)}, vs)
        put("VS_MAX_TOF", {"TICKS": fields["max_tof"]}, vs)
        put("VS_XTALK", {"T_XTALK": fields["t_xt"] & ((1 << 19) - 1), "NB": fields["nb"]}, vs)
        put("VS_TRACK", {"VMAX": fields["vmax"], "BURST_CYCLES": fields["burst"]}, vs)
        put("VS_PHASE", {"TICKS": fields["phase"]}, vs)
        for e in range(32):
            regs.values[dmem.address + (vs * 32 + e) * dmem.stride] = delays[e]
    regs.set_hw("BURST", R.REGISTERS["BURST"].fields["HALF_PERIOD"].put(R.REGISTERS["BURST"].reset, half))
    return regs
