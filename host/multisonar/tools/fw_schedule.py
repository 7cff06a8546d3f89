"""Compiled-in schedule of the sonar firmware (firmware/app/sonar).

Only the soft-core reaches the sonar core's register bus in ``ms_system``, so the firmware
carries its virtual-sensor table in its image: this tool turns a validated
:class:`~multisonar.schedule.Schedule` into a C header with

* the register writes of :func:`multisonar.regmap.schedule_writes` (sonar-block byte
  offsets, values), written at boot; START checks, loads and starts them;
* per sensor what the firmware needs for geometry and re-aiming: table index, transmit and
  receive elements, phasing delays, base masks, the virtual source in micrometres for every
  rotation of the group around the ring (re-aiming shifts a group by whole elements, so no
  trigonometry runs on the soft-core), the path offset added to ``c * tof`` (phased groups:
  the shortest element-to-source distance, as ``multisonar.simdevice``), the group axis as a
  binary angle (2^32 per turn) and its maximum range in ticks;
* the temperature (0.01 degC) for the speed of sound.

    python -m multisonar.tools.fw_schedule --header build/fw/sonar_app_cfg.h [--config scene]

One module owns the configurations, so the firmware image and the testbench that checks it
(tests/rtl/tb_system_scene.py imports :func:`schedule_for`) cannot drift apart.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..layout import Layout, load_layout
from ..regmap import schedule_writes
from ..schedule import MAX_ORDER, NUM_VS, Schedule, VirtualSensor

#: air temperature of the compiled-in configurations, degC (APP_TEMPERATURE_CC)
TEMPERATURE_C = 20.0


def scene_sensors() -> list[VirtualSensor]:
    """The whole-system test's table: a sensor looking along +x (element 0, receivers 23, 0, 1:
    a wall ahead) and one looking along -x (element 12, receivers 11..13: a point reflector ~28
    deg off its axis, which makes the firmware re-aim it by one element)."""
    return [
        VirtualSensor("front", tx=[0], rx=[23, 0, 1], order=1, max_range_m=2.5),
        VirtualSensor("back", tx=[12], rx=[11, 12, 13], order=1, max_range_m=2.5, phase=0.5e-3),
    ]


def demo_sensors() -> list[VirtualSensor]:
    """`make demo`'s table (multisonar.demo.DEMO_SENSORS): compiled into the twin's image so
    that the firmware knows the phased front group's virtual source (a group loaded over USB
    that matches a compiled-in one, rotations included, gets its geometry)."""
    from ..demo import demo_sensors as sensors

    return sensors()


CONFIGS: dict[str, Callable[[], list[VirtualSensor]]] = {"scene": scene_sensors, "demo": demo_sensors}


def rotate_sensor(s: VirtualSensor, k: int, n: int) -> VirtualSensor:
    """The same virtual sensor with its groups moved k elements round an n-element ring (and
    its virtual source rotated by k * 2 pi / n): what the firmware's re-aim does."""
    a = 2.0 * math.pi * k / n
    x, y = s.source
    src = (x * math.cos(a) - y * math.sin(a), x * math.sin(a) + y * math.cos(a))
    return replace(s, tx=[(int(e) + k) % n for e in s.tx], rx=[(int(e) + k) % n for e in s.rx], source=src)


def schedule_for(config: str = "scene", layout: Layout | None = None, rotations: dict[int, int] | None = None,
                 temperature_c: float = TEMPERATURE_C) -> Schedule:
    """The configuration's schedule; ``rotations`` {table index: element shift} gives the table
    after the firmware's re-aims."""
    if config not in CONFIGS:
        raise ValueError(f"unknown firmware schedule config {config!r}; known: {sorted(CONFIGS)}")
    layout = layout or load_layout()
    sensors = CONFIGS[config]()
    rot = rotations or {}
    sensors = [rotate_sensor(s, rot.get(i, 0), layout.n) for i, s in enumerate(sensors)]
    return Schedule(layout, sensors, temperature_c=temperature_c)


def power_up_writes(config: str = "scene", layout: Layout | None = None) -> list[tuple[int, int]]:
    """The register writes the firmware built with ``config`` makes at power-up (its compiled-in
    table, ``app_writes``): what START runs unless WRITE_REGS replaced it."""
    return schedule_writes(schedule_for(config, layout))


def _check_rotation_symmetric(layout: Layout) -> None:
    n = layout.n
    a = 2.0 * math.pi / n
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    if not np.allclose(layout.positions @ rot.T, np.roll(layout.positions, -1, axis=0), atol=1e-6):
        raise ValueError(f"layout {layout.name!r} is not a uniform ring: re-aiming by element shifts "
                         "needs positions that rotate into each other")


def _um(v: float) -> int:
    return int(round(v * 1e6))


def _bang(rad: float) -> int:
    """Binary angle, 2^32 per turn, as uint32."""
    return int(round(rad / (2.0 * math.pi) * 2**32)) & 0xFFFFFFFF


def header(config: str = "scene", temperature_c: float = TEMPERATURE_C) -> str:
    layout = load_layout()
    _check_rotation_symmetric(layout)
    sched = schedule_for(config, layout, temperature_c=temperature_c)
    res = sched.validate()
    writes = schedule_writes(sched)
    n = layout.n
    pos = layout.positions
    L = [f"// Generated by multisonar.tools.fw_schedule (config {config!r}). Do not edit.",
         "#ifndef SONAR_APP_CFG_H", "#define SONAR_APP_CFG_H", "", "#include <stdint.h>", "",
         f"#define APP_CFG_NAME \"{config}\"",
         f"#define APP_TEMPERATURE_CC {int(round(temperature_c * 100))}",
         f"#define APP_NUM_SENSORS {len(res)}",
         f"#define APP_NUM_WRITES {len(writes)}",
         f"#define APP_RING_N {n}",
         "#define APP_MAX_GROUP 8",
         f"#define APP_MAX_ORDER {MAX_ORDER}  /* the scheduler's highest fast-firing order (CAPS) */",
         f"#define APP_NUM_VS {NUM_VS}", "",
         "/* schedule_writes(): sonar-block byte offset, value; START checks, loads and starts them */",
         "static const uint32_t app_writes[APP_NUM_WRITES][2] = {"]
    L += [f"    {{0x{a:03X}u, 0x{v:08X}u}}," for a, v in writes]
    L += ["};", "", "/* element outward axes, binary angle (2^32 per turn) */",
          "static const uint32_t app_elem_axis[APP_RING_N] = {" +
          ", ".join(f"0x{_bang(math.atan2(p[1], p[0])):08X}u" for p in pos) + "};", "",
          "typedef struct {",
          "    uint8_t vs, n_tx, n_rx, pad;",
          "    uint8_t tx[APP_MAX_GROUP];      /* elements, ring order */",
          "    uint8_t rx[APP_MAX_GROUP];      /* elements, ascending */",
          "    uint16_t delay[APP_MAX_GROUP];  /* phasing delay of tx[i], ticks */",
          "    uint32_t max_tof;               /* ticks: longest window close after t0 */",
          "    int32_t path_offset_um;         /* added to c * tof (phased groups: nearest element - source) */",
          "    int32_t src_um[APP_RING_N][2];  /* virtual source after a shift of k elements */",
          "} app_sensor_t;", "",
          "static const app_sensor_t app_sensors[APP_NUM_SENSORS] = {"]
    for r in res:
        if len(r.tx) > 8 or len(r.rx) > 8:
            raise ValueError(f"sensor {r.name!r}: groups of at most 8 elements in the firmware table")
        src0 = np.array(r.source if len(r.tx) > 1 else pos[int(r.tx[0])], float)
        off = float(np.min(np.linalg.norm(pos[r.tx] - src0, axis=1))) if len(r.tx) > 1 else 0.0
        srcs = []
        for k in range(n):
            a = 2.0 * math.pi * k / n
            srcs.append((src0[0] * math.cos(a) - src0[1] * math.sin(a), src0[0] * math.sin(a) + src0[1] * math.cos(a)))
        L += [f"    {{ /* {r.name} */ {r.id}, {len(r.tx)}, {len(r.rx)}, 0,",
              "      {" + ", ".join(str(int(e)) for e in r.tx) + "},",
              "      {" + ", ".join(str(int(e)) for e in r.rx) + "},",
              "      {" + ", ".join(str(int(d)) for d in r.delays) + "},",
              f"      {r.max_tof}u, {_um(off)},",
              "      {" + ", ".join(f"{{{_um(x)}, {_um(y)}}}" for x, y in srcs) + "} },"]
    L += ["};", "", "#endif", ""]
    return "\n".join(L)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--header", type=Path, required=True, help="C header to write")
    ap.add_argument("--config", default="scene", choices=sorted(CONFIGS))
    ap.add_argument("--temperature", type=float, default=TEMPERATURE_C, help="air temperature, degC")
    a = ap.parse_args(argv)
    a.header.parent.mkdir(parents=True, exist_ok=True)
    a.header.write_text(header(a.config, a.temperature))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
