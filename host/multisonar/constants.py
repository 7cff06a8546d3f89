"""Physical and system constants shared by the golden model, host driver and tools.

The clock rate is also written into the register map (rtl/sonar_regs.rdl, TICK_HZ) so the
device reports it; tests check that both agree.
"""

from __future__ import annotations

import math

#: System clock of the FPGA (USB full speed needs 48 MHz). Time of flight and delays are
#: counted in ticks of this clock.
TICK_HZ: int = 48_000_000
TICK_S: float = 1.0 / TICK_HZ

#: Decision lead P of the RTL scheduler (ms_sonar_core LEAD, docs/fast_firing.md section 3.1): a
#: pulse is decided P ticks before its t0. 32768 ticks (683 us) leave the scheduler's microcode
#: program its worst lag, a same-tick burst of eight sensors, within P / 2
#: (scripts/bench_sched_mainloop.py). The device refuses a table whose blanking D is not longer
#: than P (cfg_error LEAD: 117 mm of range) or whose window T_V + T_N is not longer than P / 2
#: (WINDOW_SHORT: 341 us, +-29 mm around the prediction).
DEVICE_DECISION_LEAD: int = 32768

#: Default air temperature for the speed of sound.
DEFAULT_TEMPERATURE_C: float = 20.0


def speed_of_sound(temperature_c: float = DEFAULT_TEMPERATURE_C) -> float:
    """Speed of sound in dry air, m/s: c = 331.3 * sqrt(1 + T/273.15)."""
    if not math.isfinite(temperature_c) or temperature_c <= -273.15:
        raise ValueError(f"temperature {temperature_c!r} degC is not a physical air temperature")
    return 331.3 * math.sqrt(1.0 + temperature_c / 273.15)


def seconds_to_ticks(t_s: float) -> int:
    """Nearest clock tick for a time in seconds (the RTL quantises to one clock)."""
    return int(round(t_s * TICK_HZ))


def ticks_to_seconds(ticks: int | float) -> float:
    return float(ticks) * TICK_S
