"""The sonar core's event-FIFO word (docs/fast_firing.md section 6): one source for its layout.

The golden model packs and unpacks words with these tables (:mod:`multisonar.fastfiring`), the
scheduler's program writes them (:mod:`multisonar.tools.sched_program`), and the make gen step
turns them into the firmware's reader, ``build/gen/firmware/ms_event_word.h``
(:mod:`multisonar.tools.gen_contracts`), and the FIFO's overflow bit, ``ms_protocol_pkg``.
Fields are (lsb, width) of the 64-bit word.
"""

from __future__ import annotations

from .schedule import ELEM_W, SEQ_W, TOF_W, VS_ID_W

#: a ToF event: the first echo of a window (in_window, first_echo; gated: the gated miss rule
#: rejected it) or an empty window's close (window_empty)
EVENT_FIELDS: dict[str, tuple[int, int]] = {
    "tof": (0, TOF_W), "rx": (24, ELEM_W), "seq": (29, SEQ_W), "sensor": (37, VS_ID_W),
    "in_window": (40, 1), "first_echo": (41, 1), "window_empty": (42, 1), "init_ping": (43, 1),
    "gated": (45, 1),
}
#: pulse record: bit 62 set (EVT_HI shows bits 62:32); sensor and init_ping where a ToF event has them
PULSE_ID_W = 16
PULSE_FIELDS: dict[str, tuple[int, int]] = {
    "t0": (0, 32), "n_win": (32, 5), "sensor": (37, VS_ID_W), "init_ping": (43, 1),
    "pulse_id": (45, PULSE_ID_W),
}
PULSE_RECORD_BIT = 1 << 62
#: cancel record: bits 62 and 61 set, the logical tick and the sensor
CANCEL_RECORD_BIT = 1 << 61
CANCEL_FIELDS: dict[str, tuple[int, int]] = {"tick": (0, 32), "sensor": (37, VS_ID_W)}
#: set in the next word the FIFO stores after it had to drop words (ms_event_fifo OVF_BIT): every
#: kind of word keeps this bit free
EVENT_OVERFLOW_BIT = 1 << 44

__all__ = ["CANCEL_FIELDS", "CANCEL_RECORD_BIT", "EVENT_FIELDS", "EVENT_OVERFLOW_BIT", "PULSE_FIELDS",
           "PULSE_ID_W", "PULSE_RECORD_BIT"]
