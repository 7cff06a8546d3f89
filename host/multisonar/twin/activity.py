"""Where the twin's clocks go: the activity profile of the verilated device (issue #30).

The harness (sim/twin/ms_twin.cpp, ``twin_profile``) classifies every clock by what can change
in it besides the counters that advance with time (the tick, the phaser's phase, the CPU's
cycle timer):

* ``engine``: the scheduler's microcode engine is outside its idle poll loop (it dispatches an
  edge, a close or a decision);
* ``tx_run``: a transmit burst runs on some element (its drive toggles every half period);
* ``rx_settle``: a receive conditioner has not settled on its input (an echo edge passes the
  synchroniser and the glitch filter);
* ``usb``: a USB packet is in flight on the transaction-level port;
* ``cpu``: the CPU is not stalled in the firmware's idle wait (a read of the SoC's WAIT
  register, which returns when an event word or a command comes or WAKE_AT is reached).

A clock in none of them is *calm*: the device would leave it exactly as it found it, but for
those counters. Skipping calm clocks (with the counters advanced as the RTL would) is the
exact idle-clock skip issue #30 names; its gain on a workload is at most ``1 / any``, with
``any`` the fraction of clocks in which some unit works. The firmware's profile (clocks per
function, by the CPU's last-stage PC) comes with it.
"""

from __future__ import annotations

import functools
import shutil
import subprocess
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

#: the harness's counters, in its order (enum Act in ms_twin.cpp). ``sim_*``: the clocks the twin
#: simulated (did not skip) by who works in them: only the CPU, only the sonar side (engine,
#: bursts, receivers, USB), both, or neither (calm, but not skipped: the skip's margins)
COUNTERS = ("clocks", "engine", "tx_run", "rx_settle", "usb", "cpu", "sonar", "any",
            "sim_cpu_only", "sim_sonar_only", "sim_both", "sim_calm")
CLASSES = COUNTERS[1:8]
SIMULATED = COUNTERS[8:]


@functools.lru_cache(maxsize=1)
def poll_labels() -> tuple[int, int, int]:
    """ROM addresses of the engine's idle poll loop: its start (the microcode's ``poll``), the
    stop path after it (``poll_stop``) and ``poll_time``, where the exact skip starts and ends
    (TwinSim.set_skip). Assembled once per process."""
    from ..tools.sched_program.mainloop import POLL, main_program
    from ..tools.sched_program.system import UCODE_WORDS

    labels = main_program().assemble(depth=UCODE_WORDS).labels
    return int(labels[POLL]), int(labels["poll_stop"]), int(labels["poll_time"])


def poll_range() -> tuple[int, int]:
    """ROM addresses [lo, hi) of the engine's idle poll loop (``poll`` up to ``poll_stop``)."""
    lo, hi, _ = poll_labels()
    return lo, hi


@dataclass
class Symbol:
    name: str
    start: int  #: byte address
    size: int  #: bytes


def firmware_symbols(elf: Path) -> list[Symbol]:
    """Function symbols (text) of a firmware ELF, by address (riscv64-unknown-elf-nm)."""
    nm = shutil.which("riscv64-unknown-elf-nm")
    if nm is None:
        raise FileNotFoundError("riscv64-unknown-elf-nm not found (make setup installs gcc-riscv64-unknown-elf)")
    out = subprocess.run([nm, "-S", "--defined-only", str(elf)], capture_output=True, text=True, check=True).stdout
    syms = []
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[2] in ("T", "t"):
            syms.append(Symbol(parts[3], int(parts[0], 16), int(parts[1], 16)))
    return sorted(syms, key=lambda s: s.start)


@dataclass
class Activity:
    """Clock counts of one profiled stretch of the twin (see the module's doc)."""

    counts: dict[str, int]
    functions: dict[str, int] = field(default_factory=dict)  #: firmware clocks per function

    @property
    def clocks(self) -> int:
        return self.counts["clocks"]

    def fraction(self, name: str) -> float:
        return self.counts[name] / self.clocks if self.clocks else 0.0

    def bound(self, busy: str = "any") -> float:
        """The most an exact skip could speed this workload up if only the clocks of class
        ``busy`` had to be simulated: 1 / their fraction."""
        f = self.fraction(busy)
        return 1.0 / f if f > 0 else float("inf")

    @property
    def simulated(self) -> int:
        """Clocks the twin simulated (the rest it skipped)."""
        return sum(self.counts[k] for k in SIMULATED)

    @property
    def skip_bound(self) -> float:
        """The most an exact skip of the calm clocks could speed this workload up."""
        return self.bound("any")

    def as_dict(self, top: int = 12) -> dict[str, Any]:
        fw = sorted(self.functions.items(), key=lambda kv: -kv[1])
        total = sum(self.functions.values()) or 1
        return {"clocks": self.clocks,
                "fractions": {k: round(self.fraction(k), 4) for k in CLASSES},
                "simulated": {k: round(self.counts[k] / max(self.simulated, 1), 4) for k in SIMULATED},
                "skip_speedup_bound": round(self.skip_bound, 3),
                "sonar_only_skip_speedup_bound": round(self.bound("sonar"), 3),
                "firmware_functions": [{"function": k, "clocks": v, "fraction": round(v / total, 4)}
                                       for k, v in fw[:top]]}


def by_function(symbols: list[Symbol], pc_clocks: list[int]) -> dict[str, int]:
    """Clocks per firmware function from clocks per word ("?" for words outside every symbol)."""
    out: dict[str, int] = {}
    k = 0
    for w, n in enumerate(pc_clocks):
        if not n:
            continue
        a = 4 * w
        while k + 1 < len(symbols) and symbols[k + 1].start <= a:
            k += 1
        s = symbols[k] if symbols and symbols[k].start <= a < symbols[k].start + max(symbols[k].size, 4) else None
        name = s.name if s else "?"
        out[name] = out.get(name, 0) + int(n)
    return out

