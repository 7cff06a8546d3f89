"""Encode a validated :class:`~multisonar.schedule.Schedule` as register writes.

The field layout comes only from the generated register map
(``multisonar.generated.sonar_regs``, from ``rtl/regs/sonar_regs.rdl``); this module only
says which scheduler quantity lives in which register field. The host driver, the cocotb
testbenches and the firmware tests all configure the sonar core through it.
"""

from __future__ import annotations

from .schedule import REGISTER_FIELDS, Schedule

#: scheduler field (Schedule.to_registers()) -> (register, field) of the VS table
SENSOR_FIELDS: dict[str, tuple[str, str]] = {
    "tx_mask": ("VS_TX_MASK", "MASK"),
    "rx_mask": ("VS_RX_MASK", "MASK"),
    "mode": ("VS_MODE", "MODE"),
    "order": ("VS_MODE", "ORDER"),
    "miss_limit": ("VS_MODE", "MISS_LIMIT"),
    "reinit_every": ("VS_MODE", "REINIT_EVERY"),
    "t_v": ("VS_WINDOW", "T_V"),
    "t_n": ("VS_WINDOW", "T_N"),
    "t_dead": ("VS_T_DEAD", "TICKS"),
    "max_tof": ("VS_MAX_TOF", "TICKS"),
    "t_xtalk": ("VS_XTALK", "T_XTALK"),
    "xtalk_nb": ("VS_XTALK", "NB"),
    "vmax": ("VS_TRACK", "VMAX"),
    "burst_cycles": ("VS_TRACK", "BURST_CYCLES"),
    "phase": ("VS_PHASE", "TICKS"),
}
#: scheduler fields that are not registers: the table index itself, and D, which the firmware
#: derives when it loads the table.
NOT_REGISTERS = {"id", "blank"}


def _regs():
    from .generated import sonar_regs

    return sonar_regs


def check_field_widths() -> None:
    """Raise if the scheduler's field widths and the register map disagree."""
    R = _regs()
    missing = set(REGISTER_FIELDS) - set(SENSOR_FIELDS) - NOT_REGISTERS
    if missing:
        raise RuntimeError(f"scheduler fields with no register: {sorted(missing)}")
    for name, (reg, field) in SENSOR_FIELDS.items():
        width = R.REGISTERS[reg].fields[field].width
        if width != REGISTER_FIELDS[name][0]:
            raise RuntimeError(f"{name}: scheduler uses {REGISTER_FIELDS[name][0]} bits, {reg}.{field} has {width}")


def schedule_writes(schedule: Schedule) -> list[tuple[int, int]]:
    """(address, value) bus writes that load ``schedule`` into the VS table and delay memory.

    Sensors not in the schedule are written with mode 0 (off). The firmware checks and loads
    them at START (load_writes: what it writes to the scheduler).
    """
    R = _regs()
    regs = schedule.to_registers()
    n_vs = R.REGISTERS["VS_MODE"].dims[0]
    values: dict[tuple[str, int], int] = {}
    for vs in range(n_vs):
        for reg, _ in SENSOR_FIELDS.values():
            values[(reg, vs)] = R.REGISTERS[reg].reset
        values[("VS_MODE", vs)] = R.REGISTERS["VS_MODE"].fields["MODE"].put(values[("VS_MODE", vs)], 0)
    for f in regs["sensors"]:
        for name, (reg, field) in SENSOR_FIELDS.items():
            values[(reg, f["id"])] = R.REGISTERS[reg].fields[field].put(values[(reg, f["id"])], f[name])
    writes = [(R.REGISTERS[reg].addr(vs), v) for (reg, vs), v in values.items()]
    mem = R.MEMORIES["DELAY"]
    for entry, ticks in sorted(regs["delay_mem"].items()):
        writes.append((mem.address + entry * mem.stride, ticks))
    return writes


def load_writes(schedule: Schedule, *, glitch_min: int, miss_gate: int, lead: int,
                miss_hold: bool = True) -> list[tuple[int, int]]:
    """(address, value) bus writes of the scheduler's load image for ``schedule`` through
    LOAD_ADDR / LOAD_DATA, as the firmware's START writes them (firmware/app/sonar/sched_table.c;
    the scheduler stopped), before CTRL.enable | CTRL.start. ``glitch_min``, ``miss_gate`` and
    ``miss_hold`` are RX_FILTER's fields, ``lead`` the scheduler's decision lead."""
    from .tools.sched_program.system import load_image, load_sequence

    R = _regs()
    image = load_image(schedule.validate(), lead=lead, glitch_min=glitch_min, miss_gate=miss_gate,
                       miss_hold=miss_hold)
    at_addr, at_data = R.REGISTERS["LOAD_ADDR"].addr(), R.REGISTERS["LOAD_DATA"].addr()
    return [x for a, w in load_sequence(image) for x in ((at_addr, a), (at_data, w))]
