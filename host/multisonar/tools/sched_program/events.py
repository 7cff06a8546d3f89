"""Kernels of the events of a tick: EDGE (the window an edge falls in), HIT (its echo), CLOSE
(a window's result), HEAD (the next window to close) and SAFE (a sensor's windows cancelled)."""

from __future__ import annotations

from ...event_word import CANCEL_FIELDS, CANCEL_RECORD_BIT, EVENT_FIELDS, PULSE_FIELDS, PULSE_RECORD_BIT
from ..sched_ucode import Program
from .layout import (EVT_HI, EVT_LO, F_ANY_TRK, F_EPOCH, F_IN_INIT, F_TRACKING, HC, HD_EL, HD_T, HS,
                     NUM_RX, R_MASK24, R_SIGN24, R_STRIDE, SENS_STRIDE, SU_EDGE, SU_FLAGS, SU_GO, SU_HEAD, SU_MINC,
                     SU_SENSOR, SU_TA, SU_VALID, SU_X, S_DUE, S_FLAGS, S_K, S_MODE, S_OPEN, WV)


# The kernels pack event words without a shifter (multiplies, byte rotations, immediates), so they
# are written for this layout of multisonar.event_word; a change of it must fail here, not on the wire.
_PACKED_FOR = {"event": {"tof": (0, 24), "rx": (24, 5), "seq": (29, 8), "sensor": (37, 3), "in_window": (40, 1),
                         "first_echo": (41, 1), "window_empty": (42, 1), "init_ping": (43, 1), "gated": (45, 1)},
               "pulse": {"t0": (0, 32), "n_win": (32, 5), "sensor": (37, 3), "init_ping": (43, 1),
                         "pulse_id": (45, 16)},
               "cancel": {"tick": (0, 32), "sensor": (37, 3)}, "bits": (62, 61)}
if (_PACKED_FOR != {"event": EVENT_FIELDS, "pulse": PULSE_FIELDS, "cancel": CANCEL_FIELDS,
                    "bits": (PULSE_RECORD_BIT.bit_length() - 1, CANCEL_RECORD_BIT.bit_length() - 1)}):
    raise ImportError("multisonar.event_word changed: the scheduler program's event packing "
                      "(sched_program/events.py, decision.py) must be rewritten for it")


def _hi_bits(*names: str) -> int:
    """The event word's one-bit fields ``names`` as bits of its high half (bits 63:32)."""
    return sum(1 << (EVENT_FIELDS[n][0] - 32) for n in names)


KIND_FIRST_ECHO = _hi_bits("in_window", "first_echo")   # 0x300
KIND_GATED = KIND_FIRST_ECHO | _hi_bits("gated")         # 0x2300: a first echo the gate rejected
KIND_EMPTY = _hi_bits("window_empty")                    # 0x400


def _tof_event(p: Program, tof: int, seq: int, rx: int, sensor: int, flags: int, kind: int | tuple[int],
               tmp: tuple[int, int, int, int, int]) -> Program:
    """Write a ToF event word (docs/fast_firing.md section 6): tof (register, 24 bits), rx, the
    pulse seq's low byte, the sensor, the init_ping bit from bit 0 of register ``flags`` and
    ``kind``, the in_window / first_echo / window_empty / gated bits as bits of the high half
    (0x300: a first echo, 0x400: an empty window, 0x2300: a first echo the gate rejected);
    ``kind`` is that constant or ``(register,)`` holding it. Packed without a shifter: seq << 29
    is seq << 5 rotated right a byte (its bits 2:0 land in the low half, 7:3 in the high one).
    Uses the five ``tmp`` registers; ``tof`` and the inputs stay."""
    a, b, c, d, e = tmp
    p.andi(b, seq, 0xFF)
    p.mul(b, b, R_STRIDE).rotb(c, rx, 1)                # seq << 5 (R_STRIDE = 32); rx << 24
    p.rotb(b, b, 1).mul(d, sensor, R_STRIDE)            # seq << 29; sensor << 5 (bit 37)
    p.li(e, -0x2000_0000)
    p.and_(a, b, e).andi(b, b, 0x1F)                    # seq bits of the low half; of the high half
    p.or_(c, c, a).or_(b, b, d)
    p.or_(c, c, tof).andi(d, flags, 1)                  # low half; init_ping
    p.li(a, 2048)
    p.mul(d, d, a)                                      # init_ping << 11 (bit 43)
    if isinstance(kind, tuple):
        p.or_(b, b, kind[0])
    else:
        p.ori(b, b, kind)
    p.or_(b, b, d)
    return p.st(c, 0, EVT_LO).st(b, 0, EVT_HI)


assert SENS_STRIDE == 32, "R_STRIDE doubles as the constant 32 (<< 5) in the kernels below"


# ------------------------------------------------------------------ HIT: an echo in a window
def hit_kernel(p: Program) -> Program:
    """HIT, an edge at tick r1 in a window (t0 r2, pulse seq r3 (8 bits), flags r4: bit 0 init
    ping, bit 1 of the sensor's current epoch, bit 2 the window saw an echo before) of receiver
    r6 of sensor r7, tracking state at r5 (words A, B); gate r8 (0 off), v_max r9, T_E limits
    r10 / r11. The first echo writes its event word (docs/fast_firing.md section 6) and, for a
    window of the current epoch, updates the tracking state (an init ping's first echo starts
    the track; a tracking window's first echo is a sample if the pulse gap is 1..127, with
    velocity when the gap is 1 after a tracking sample (once measured and with the gate on: v plus
    half the residual from the prediction, rounded down); after a gap a track with velocity
    keeps it, its gate and its miss count) unless the gated miss rule rejects it: |tof - prediction| >
    G with a measured velocity, > v_max * gap (unsigned 8-bit gap) for the sample that would
    measure it (not after the init ping's sample); r8 is free after the test
    (r12 = 1: then the window counts as a miss and the event word has its gated bit). The word
    is written last, when the gate has decided. A later echo does nothing. Model:
    FastFiringModel._rise and _sample (max_echoes_per_window = 1)."""
    p.li(12, 0).andi(0, 4, 4).b("ne", "hit_done")        # not the first echo: no event
    p.sub(14, 1, 2)
    p.and_(14, 14, R_MASK24)                             # tof
    p.li(13, KIND_FIRST_ECHO)                            # the event's kind: in_window, first_echo
    p.andi(0, 4, 2).b("eq", "hit_event")                 # an earlier epoch's window: no sample
    p.ld(23, 5, 0).ld(24, 5, 1)
    p.andi(0, 4, 1).b("ne", "hit_init")
    p.rotb(25, 24, 3).rotb(26, 23, 3)                    # flags byte; seq byte of the state
    p.andi(0, 25, 1).b("eq", "hit_event")                # not tracked: no sample, no gate
    p.andi(26, 26, 0xFF).and_(18, 24, R_MASK24)
    p.sub(27, 3, 26).xor(18, 18, R_SIGN24)
    p.andi(27, 27, 0xFF).sub(18, 18, R_SIGN24)           # gap (8 bits); v
    p.and_(20, 23, R_MASK24)                             # the state's tof
    p.tst(8).b("eq", "hit_sample")                       # gate off
    p.andi(0, 25, 4).b("ne", "hit_pred")                 # velocity measured: the gate G
    p.andi(0, 25, 2).b("ne", "hit_sample")               # after the init ping's sample: no bound
    p.mul(8, 27, 9)                                      # no velocity yet: v_max per pulse of the gap
    p.label("hit_pred").xori(21, 27, 0x80).sub(17, 0, 8)   # -bound
    p.li(16, 128)                                        # 2^7, for the update below
    p.addi(21, 21, -128)                                 # the gap, signed
    p.mul(22, 21, 18)
    p.add(22, 22, 20)                                    # prediction, then its clamp
    p.clamp(22, 10, 11)
    p.sub(15, 14, 22)                                    # the residual r (kept for the update)
    p.cb("gt", 15, 8, "hit_rej")
    p.cb("ge", 15, 17, "hit_sample")                     # -bound <= r <= bound: a sample
    p.label("hit_rej").li(12, 1).li(13, KIND_GATED).jmp("hit_event")   # gated; a miss at close
    p.label("hit_sample").tst(27).b("eq", "hit_event")   # gap 0: no sample
    p.andi(0, 27, 0x80).b("ne", "hit_event")             # gap 128..255 (negative): no sample
    p.li(26, 0).li(21, 1)                                # v, flags: tracked
    p.cmpi(27, 1).b("eq", "hit_next")
    p.andi(0, 25, 4).b("eq", "hit_write")                # a gap, velocity not measured: v = 0
    p.mov(26, 18).andi(21, 25, 0xFF)                     # a gap: v, vel and miss count kept
    p.jmp("hit_write")
    p.label("hit_next").andi(0, 25, 2).b("ne", "hit_write")   # after the init ping's sample: no v
    p.andi(0, 25, 4).b("eq", "hit_raw")                  # the sample that measures v
    p.tst(8).b("eq", "hit_raw")                          # gate off: v from the last two samples
    # a gated sample with a measured velocity: v + h, h = r >> 1 for the residual r (|r| <= G, so
    # r * 2^7 fits 32 bits): bits 23:0 of r * 2^7 rotated a byte, then sign-extended from 24 bits
    p.mul(17, 15, 16)
    p.rotb(17, 17, 1)
    p.add(26, 18, 17)
    p.and_(26, 26, R_MASK24)
    p.xor(26, 26, R_SIGN24)
    p.sub(26, 26, R_SIGN24).jmp("hit_vclamp")
    p.label("hit_raw").sub(26, 14, 20)                   # v = tof - last tof
    p.label("hit_vclamp").sub(22, 0, 9)                  # within +-v_max
    p.clamp(26, 22, 9)
    p.li(21, 5)                                          # tracked, vel
    p.label("hit_write").andi(16, 3, 0xFF).and_(26, 26, R_MASK24)
    p.rotb(16, 16, 1).rotb(21, 21, 1)
    p.or_(23, 14, 16).or_(24, 26, 21)
    p.st(23, 5, 0).st(24, 5, 1).jmp("hit_event")
    p.label("hit_init").andi(16, 3, 0xFF).li(21, 3)      # an init ping's echo: tracked, init
    p.rotb(16, 16, 1).rotb(21, 21, 1)
    p.or_(23, 14, 16)
    p.st(23, 5, 0).st(21, 5, 1)
    p.label("hit_event")
    _tof_event(p, 14, 3, 6, 7, 4, (13,), (15, 16, 18, 19, 20))
    p.label("hit_done")
    return p


# ------------------------------------------------------------------ CLOSE: a window's result
def close_kernel(p: Program) -> Program:
    """CLOSE of the head window of receiver r6 at tick r1: window t0 r2, end offset r3, pulse
    seq r4 (8 bits), flags r5 (bit 0 init ping, bit 1 the window's epoch, bit 2 saw an echo,
    bit 3 that echo was rejected by the gate), sensor r7 (its words at r8 = SENS + 32 s),
    tracking state at r9. An empty window writes its event word; an empty or rejected tracking
    window of the current epoch counts a miss, and K misses while tracking end the tracking
    (due = min(due, now); r10 = 1: the caller cancels the sensor's windows); the last open
    window of an init ping ends the init phase (tracking if the mode is track and a receiver
    got an echo). Model: FastFiringModel._on_close."""
    p.li(10, 0).ld(11, 8, S_FLAGS).andi(0, 5, 4)
    p.b("ne", "close_hit")                              # an echo came: no event
    p.and_(18, 3, R_MASK24)                             # tof = end - t0
    _tof_event(p, 18, 4, 6, 7, 5, KIND_EMPTY, (12, 13, 14, 15, 16))   # window_empty
    p.jmp("close_miss")
    p.label("close_hit").andi(0, 5, 8).b("eq", "close_init")   # a sample: no miss
    p.label("close_miss").andi(0, 5, 1).b("ne", "close_init")  # init pings count no misses
    p.andi(12, 11, F_EPOCH).andi(13, 5, 2)
    p.add(13, 13, 13)                                   # the window's epoch at F_EPOCH
    p.cb("ne", 12, 13, "close_done")                    # an earlier epoch's window
    p.ld(12, 9, 1).ld(14, 8, S_K)
    p.rotb(13, 12, 3)
    p.andi(15, 13, 0xF0)                                # miss count << 4 (flags byte)
    p.cmpi(15, 0xF0).b("eq", "close_sat")               # saturated at 15
    p.addi(15, 15, 0x10).li(16, 0x1000_0000)
    p.add(12, 12, 16)                                   # miss + 1 in word B (bits 31:28)
    p.st(12, 9, 1)
    p.label("close_sat").mul(14, 14, R_STRIDE).add(16, 15, 15)   # K << 5; miss << 5
    p.andi(0, 11, F_TRACKING).b("eq", "close_done")     # not tracking: no safety
    p.sub(0, 16, 14).b("lt", "close_done")              # fewer than K misses
    p.andi(11, 11, ~F_TRACKING).li(10, 1)      # safety: re-initialise now
    p.ld(12, 8, S_DUE).st(11, 8, S_FLAGS)
    p.sub(0, 1, 12).b("ge", "close_done")
    p.st(1, 8, S_DUE).jmp("close_done")                 # due = min(due, now)
    p.label("close_init").andi(0, 5, 1).b("eq", "close_done")
    p.andi(12, 11, F_EPOCH).andi(13, 5, 2)
    p.add(13, 13, 13)
    p.cb("ne", 12, 13, "close_done")                    # an earlier epoch's init ping
    p.ld(12, 8, S_OPEN)
    p.addi(12, 12, -1)
    p.st(12, 8, S_OPEN).b("ne", "close_done")           # windows of the init ping still open
    p.ld(13, 8, S_MODE).andi(11, 11, ~(F_IN_INIT | F_TRACKING))
    p.andi(14, 11, F_ANY_TRK)
    p.b("eq", "close_flags")
    p.cmpi(13, 1).b("ne", "close_flags")
    p.ori(11, 11, F_TRACKING)                           # track mode and an echo: tracking
    p.label("close_flags").st(11, 8, S_FLAGS)
    p.label("close_done")
    return p


# ------------------------------------------------------------------ the slot unit's other scans
def _su_scan(p: Program, tag: str, el: int, ta: int, mode: int) -> Program:
    """Start the slot unit on element register ``el`` (its valid slots from WV) with TA from
    register ``ta`` in ``mode``, and wait for it; r23 = SU_FLAGS. Uses r20, r21."""
    p.ld(20, el, WV).ori(21, el, mode)
    p.st(20, 0, SU_VALID).st(ta, 0, SU_TA).st(21, 0, SU_GO)
    p.label(f"{tag}_wait").ld(23, 0, SU_FLAGS)
    p.andi(0, 23, 0x80).b("ne", f"{tag}_wait")
    return p


def edge_kernel(p: Program) -> Program:
    """EDGE, the window of receiver r6 holding the edge timestamp r1: r10 = its slot, or -1
    outside every window (the edge is gated). Model: the window search of FastFiringModel._rise."""
    _su_scan(p, "edge", 6, 1, SU_EDGE)
    p.li(10, -1).andi(0, 23, 1)
    p.b("eq", "edge_done")
    p.ld(10, 0, SU_X)
    p.label("edge_done")
    return p


def _head_rescan(p: Program, tag: str) -> Program:
    """Element r6's head after its windows changed: the slot closing first after tick r1, into
    HC / HS and to the close detector, or no head. Uses r20-r23, r25, r26."""
    _su_scan(p, tag, 6, 1, SU_HEAD)
    p.andi(0, 23, 1).b("eq", f"{tag}_none")
    p.ld(25, 0, SU_X).ld(26, 0, SU_MINC).li(21, 256)
    p.ori(20, 25, 0x100).mul(21, 25, 21)
    p.st(26, 6, HC).st(20, 6, HS).or_(21, 21, 6)
    p.st(26, 0, HD_T).st(21, 0, HD_EL).jmp(f"{tag}_done")
    p.label(f"{tag}_none").lui(21, 0x10).st(0, 6, HS)       # 1 << 16: no head
    p.or_(21, 21, 6)
    p.st(21, 0, HD_EL)
    p.label(f"{tag}_done")
    return p


def head_kernel(p: Program) -> Program:
    """HEAD, element r6's next window to close (after its head closed at tick r1, its slot
    cleared from WV): the earliest close of its remaining windows, or none. Model: the
    element's windows after FastFiringModel._on_close removes one."""
    return _head_rescan(p, "head")


def safe_kernel(p: Program) -> Program:
    """SAFE, the cancel of sensor r7 at tick r1: the cancel record (docs/fast_firing.md section
    6), then on every element the sensor's windows leave WV. Heads stay as they are (as in
    the golden model): a cancelled head still reaches its close tick, where the caller finds its
    slot no longer valid, writes nothing for it and runs HEAD. Model: FastFiringModel._cancel."""
    p.li(17, 32).lui(18, 0x60000)                           # bits 62, 61: bits 30, 29 of the high half
    p.mul(19, 7, 17)
    p.or_(19, 19, 18)                                       # sensor << 5 (bit 37)
    p.st(1, 0, EVT_LO).st(19, 0, EVT_HI)
    p.li(6, NUM_RX - 1)
    p.label("safe_el")
    _su_scan(p, "safe_scan", 6, 7, SU_SENSOR)
    p.ld(22, 0, SU_X).ld(24, 6, WV)
    p.andn(24, 24, 22)
    p.st(24, 6, WV).addi(6, 6, -1).b("ge", "safe_el")
    return p
