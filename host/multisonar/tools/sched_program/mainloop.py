"""The scheduler's main loop in microcode: the kernels of ``decision`` and ``events`` in the
order the golden model runs them, one logical tick at a time (docs/sched_engine.md).

- INIT (start tick S from M_START): per sensor due = next evaluation = S + phase, quiet = S,
  pulse id, open windows and tracking count 0, flags only F_ACT; per element blank_until =
  tx_until = S, no windows, no head; the next logical tick is S.
- IDLE: td = the next time-driven decision tick, eng + the least offset over the sensors that
  are active, not in their init phase and woken or not held (0 when woken or when their next
  evaluation's t0 is <= eng + P); then poll: the work queue's head is taken when nothing is
  armed or its tick is <= td; otherwise td is dispatched alone once the tick counter is three
  past it (every edge or close of a tick <= td is then in the queue: a word is visible two
  clocks after its tick).
- DISPATCH of logical tick cur: edges (receivers ascending; EDGE, the window's fields through
  the WIN read port, HIT, the slot's echo flags, the sensor woken by a first echo of its
  current epoch), closes (receivers ascending; a valid head closing now: CLOSE, its slot freed,
  the sensor woken, a safety cancel wakes every sensor and runs SAFE; then HEAD), then SCHED
  for sensors 0..7: a sensor decides when it is active, not in its init phase and woken, or
  not held and due (cur + P >= its next evaluation); only the woken ones are visited when
  none can be due (IDLE's td is after eng and cur is before it). Not due: next evaluation =
  due; quiet: = the quiet tick; held (EDF): hold; otherwise CAND + ORDER (tracking) or the
  init ping's windows, CONF (a conflict: next evaluation = the retry), ISSUE + IEL (next
  evaluation = the new due, every other sensor woken). A forced re-initialisation runs SAFE
  first.

Kernels that are subroutines (SAFE) end in ``ret``; the engine has one link register, so no
subroutine calls another and CONF (which calls its own fold) stays inline. The program's
variables live in data memory (MAIN + M_*), so each kernel gets its inputs afresh.
"""

from __future__ import annotations

from ..sched_ucode import Program, UcodeError
from .decision import (SCHED_HOLD, SCHED_NOT_YET, SCHED_QUIET, cand_kernel, conf_kernel, iel_kernel,
                       issue_kernel, order_kernel, sched_kernel)
from .events import close_kernel, edge_kernel, head_kernel, hit_kernel, safe_kernel
from .layout import (BA, BB, BLK, BU, CAND, F_ANY_TRK, F_EPOCH, F_IN_INIT, HALT, HC, HS, LAG_CUR,
                     MAIN, M_ACT, M_ARMED, M_CLOSES, M_CUR, M_EDGES, M_ENG, M_FLAGS, M_GATE, M_HOLD,
                     M_INIT, M_L, M_MHOLD, M_NWIN, M_P, M_PERIOD, M_QUIET, M_RES, M_RX, M_S, M_SLOT, M_SREM,
                     M_START, M_T0, M_TD, M_TN, M_TV, M_WAKE, M_WEND, M_WIN, NUM_RX, NUM_VS, ONEHOT, Q_C,
                     Q_E, Q_POP, Q_STAT, Q_T, SENS, STOP_AT, STOP_REQ, S_BLK, S_CLR, S_D, S_DUE, S_FLAGS,
                     S_HI, S_LO, S_NRX, S_NXT, S_OPEN, S_ORDER, S_PHASE, S_QOFF, S_QUIET, S_RMAX,
                     S_RX, S_SEQ, S_TN, S_TRK, S_TV, S_TX, S_VMAX, SU_TA, TICK, TRK, TU, T_DONE,
                     WH, WIN_META, WIN_RA, WIN_T0, WIN_WE, WR, WSLOTS, WV, R_STRIDE, prologue)

POLL = "poll"   # the idle poll loop's label (the harness skips whole turns of it)


def _get(p: Program, rd: int, var: int) -> Program:
    return p.ld(rd, 0, MAIN + var)


def _put(p: Program, rs: int, var: int) -> Program:
    return p.st(rs, 0, MAIN + var)


def _sensor_words(p: Program, rd: int, rs: int) -> Program:
    """rd = the words of sensor rs (SENS + SENS_STRIDE s)."""
    return p.mul(rd, rs, R_STRIDE).addi(rd, rd, SENS) if SENS else p.mul(rd, rs, R_STRIDE)


def _current_sensor(p: Program) -> Program:
    """r7 = the SCHED phase's sensor, r8 = its words."""
    return _sensor_words(_get(p, 7, M_S), 8, 7)


def _tracking_base(p: Program, rd: int, rs: int, rx: int | None = None, tmp: int = 17) -> Program:
    """rd = TRK + 48 s (+ 2 rx): sensor rs's tracking states (receiver rx's)."""
    p.li(tmp, 2 * NUM_RX).mul(rd, rs, tmp)
    if rx is not None:
        p.add(rd, rd, rx).add(rd, rd, rx)
    return p.addi(rd, rd, TRK)


def _pop_lowest(p: Program, idx: int, mask: int, tmp: int = 11) -> Program:
    """idx = the index of mask's lowest set bit, which is cleared (mask != 0)."""
    return p.lsb(idx, mask).addi(tmp, mask, -1).and_(mask, mask, tmp)


def _next_of(p: Program, var: int, idx: int, mask: int, done: str, idx_var: int) -> Program:
    """The lowest set bit of mask variable ``var``: its index into ``idx`` and variable
    ``idx_var``, and the variable without it; to ``done`` when none is left. (The index is
    stored first: the store of the mask then does not follow the instruction that makes it.)"""
    _get(p, mask, var)
    p.tst(mask).b("eq", done)
    _pop_lowest(p, idx, mask)
    _put(p, idx, idx_var)
    return _put(p, mask, var)


def _win_read(p: Program, el: int, slot: int, tmp: int = 11) -> Program:
    """Address slot ``slot`` of element ``el`` on the WIN read port (its fields two clocks
    later)."""
    return p.li(tmp, WSLOTS).mul(tmp, el, tmp).add(tmp, tmp, slot).st(tmp, 0, WIN_RA)


def _meta_fields(p: Program, meta: int, seq: int, sensor: int, bits: int) -> Program:
    """Split a window's meta word (seq byte 0, init bit 8, epoch bit 9, sensor byte 2): seq,
    sensor, and ``bits`` = bit 0 init, bit 1 epoch."""
    p.andi(seq, meta, 0xFF).rotb(sensor, meta, 2).rotb(bits, meta, 1)
    return p.andi(sensor, sensor, 0xFF).andi(bits, bits, 3)


def _wake(p: Program, sensor: int) -> Program:
    """Sensor register ``sensor`` re-evaluates in this tick's SCHED phase. Uses r17, r18."""
    p.ld(17, sensor, ONEHOT)
    _get(p, 18, M_WAKE)
    p.or_(18, 18, 17)
    return _put(p, 18, M_WAKE)


def _wake_others_sub(p: Program) -> Program:
    """The subroutine ``wake_others``: every sensor of the table but r7 (the SCHED phase's)
    re-evaluates, those above r7 in this SCHED phase: they join the sensors it has still to
    visit (a phase that started with the woken sensors only visits them all, as one that
    started with every sensor does). Uses r17, r18."""
    p.label("wake_others")
    p.ld(17, 7, ONEHOT)
    p.add(17, 17, 17)
    p.sub(17, 0, 17)                                    # the sensors above r7
    _get(p, 18, M_ACT)
    p.and_(17, 17, 18)
    _get(p, 18, M_SREM)
    p.or_(18, 18, 17)
    _put(p, 18, M_SREM)
    p.ld(17, 7, ONEHOT)
    _get(p, 18, M_ACT)
    p.andn(18, 18, 17)
    _get(p, 17, M_WAKE)
    p.or_(18, 18, 17)
    _put(p, 18, M_WAKE)
    return p.ret()


# ------------------------------------------------------------------ INIT and IDLE
def _init(p: Program) -> None:
    _get(p, 1, M_START).li(7, NUM_VS - 1)
    p.label("init_s")
    _sensor_words(p, 8, 7)
    p.ld(10, 8, S_PHASE)
    p.add(10, 10, 1)
    p.st(10, 8, S_DUE).st(10, 8, S_NXT).st(1, 8, S_QUIET).st(0, 8, S_FLAGS)
    p.st(0, 8, S_SEQ).st(0, 8, S_OPEN).st(0, 8, S_TRK)
    p.addi(7, 7, -1).b("ge", "init_s")
    p.li(6, NUM_RX - 1)
    p.label("init_e").st(1, 6, BU).st(1, 6, TU).st(0, 6, WV).st(0, 6, HS).st(0, 6, WH)
    p.st(0, 6, WR).addi(6, 6, -1).b("ge", "init_e")
    _put(p, 1, M_ENG)
    _put(p, 0, M_WAKE)
    _put(p, 0, M_HOLD)


def _idle(p: Program) -> None:
    p.label("idle")
    _get(p, 1, M_ENG)
    _get(p, 2, M_P)
    _get(p, 9, M_ACT)
    _get(p, 15, M_WAKE)
    _get(p, 16, M_HOLD)
    p.add(3, 1, 2).li(4, 0x7FFF_FFFF)                  # eng + P; the least offset (none)
    p.and_(15, 15, 9).andn(16, 9, 16)                  # woken; not held
    p.or_(9, 15, 16)                                    # the sensors td depends on
    p.label("td_s").tst(9).b("eq", "td_done")
    _pop_lowest(p, 7, 9)
    _sensor_words(p, 8, 7)
    p.ld(11, 8, S_FLAGS).ld(12, 8, S_NXT).ld(13, 7, ONEHOT)
    p.andi(0, 11, F_IN_INIT).b("ne", "td_s")
    p.and_(0, 15, 13).b("ne", "td_now")
    p.sub(13, 12, 3).b("le", "td_now")                  # its t0 is due by eng + P
    p.cmp(13, 4).b("ge", "td_s")
    p.mov(4, 13).jmp("td_s")
    p.label("td_now").li(4, 0)
    p.label("td_done").add(5, 1, 4).li(6, 0x7FFF_FFFF)
    p.xor(6, 6, 4)                                      # armed: r6 != 0
    _put(p, 5, M_TD)
    _put(p, 6, M_ARMED)
    # the poll loop: the tick first, then the queue (a word of a tick <= td is visible by then);
    # while a stop is requested only ticks before STOP_AT, then HALT once they are all done
    p.label(POLL).ld(10, 0, TICK).ld(11, 0, Q_STAT).ld(19, 0, STOP_REQ)
    p.andi(0, 11, 1).b("eq", "poll_time")
    p.ld(12, 0, Q_T)
    p.tst(19).b("eq", "poll_word")
    p.ld(20, 0, STOP_AT)
    p.sub(0, 12, 20).b("ge", "poll_time")               # stopping: not before STOP_AT
    p.label("poll_word").tst(6).b("eq", "poll_take")    # nothing armed: take it
    p.sub(0, 12, 5).b("le", "poll_take")                # its tick comes no later than td
    p.label("poll_time").tst(19).b("ne", "poll_stop")
    p.label("poll_td").tst(6).b("eq", POLL)
    p.sub(13, 10, 5)
    p.cmpi(13, 3).b("lt", POLL)
    p.mov(1, 5).li(13, 0).li(14, 0).jmp("dispatch")     # td alone
    p.label("poll_stop").ld(20, 0, STOP_AT)
    p.tst(6).b("eq", "poll_end")
    p.sub(0, 5, 20).b("lt", "poll_td")                  # td before STOP_AT: still to do
    p.label("poll_end").sub(13, 10, 20)
    p.cmpi(13, 3).b("lt", POLL)                         # words before STOP_AT may still come
    p.andi(0, 11, 1).b("eq", "halt")
    p.sub(0, 12, 20).b("lt", POLL)
    p.label("halt").st(0, 0, HALT)
    p.label("halt_spin").jmp("halt_spin")
    p.label("poll_take").ld(13, 0, Q_E).ld(14, 0, Q_C)
    p.st(0, 0, Q_POP).mov(1, 12)
    p.label("dispatch")
    p.st(1, 0, LAG_CUR)
    _put(p, 1, M_CUR)
    _put(p, 13, M_EDGES)
    _put(p, 14, M_CLOSES)


# ------------------------------------------------------------------ DISPATCH: edges, closes
def _edges(p: Program) -> None:
    p.label("edge_next")
    _next_of(p, M_EDGES, 6, 13, "close_next", M_RX)
    _get(p, 1, M_CUR)
    _get(p, 2, M_L)
    p.sub(1, 1, 2)                                      # the edge's timestamp n = cur - L
    edge_kernel(p)                                      # r10: its window's slot, or -1
    p.tst(10).b("lt", "edge_next")                      # outside every window: dropped
    _put(p, 10, M_SLOT)
    _win_read(p, 6, 10)
    p.ld(15, 10, ONEHOT).ld(12, 6, WH)
    p.ld(2, 0, WIN_T0).ld(16, 0, WIN_META)
    _meta_fields(p, 16, 3, 7, 18)
    p.andi(4, 18, 1)                                    # HIT's flags: bit 0 init ping
    _sensor_words(p, 8, 7)
    p.and_(0, 12, 15).b("eq", "edge_first")
    p.ori(4, 4, 4)                                      # bit 2: an echo came before
    p.label("edge_first").ld(19, 8, S_FLAGS)
    p.andi(18, 18, 2)
    p.add(18, 18, 18).andi(19, 19, F_EPOCH)             # the window's epoch at F_EPOCH
    p.xor(0, 18, 19).b("ne", "edge_old")
    p.ori(4, 4, 2)                                      # bit 1: the sensor's current epoch
    p.label("edge_old")
    _put(p, 4, M_FLAGS)
    _tracking_base(p, 5, 7, 6)
    p.ld(9, 8, S_VMAX).ld(10, 8, S_LO).ld(11, 8, S_HI)
    _get(p, 8, M_GATE)
    hit_kernel(p)                                       # r12 = 1: the gate rejected it
    _get(p, 4, M_FLAGS)
    p.andi(0, 4, 4).b("ne", "edge_next")                # a later echo: nothing more
    _get(p, 10, M_SLOT)
    _get(p, 6, M_RX)
    p.ld(15, 10, ONEHOT).ld(16, 6, WH).ld(17, 6, WR)
    p.or_(16, 16, 15)
    p.st(16, 6, WH)
    p.tst(12).b("eq", "edge_kept")
    p.or_(17, 17, 15)
    p.st(17, 6, WR)
    p.label("edge_kept").andi(0, 4, 2).b("eq", "edge_next")   # an earlier epoch's window
    _wake(p, 7)
    p.andi(0, 4, 1).b("eq", "edge_next")
    _sensor_words(p, 8, 7)
    p.ld(11, 8, S_FLAGS)
    p.ori(11, 11, F_ANY_TRK)                            # an init ping's echo: a track exists
    p.st(11, 8, S_FLAGS).jmp("edge_next")


def _closes(p: Program) -> None:
    p.label("close_next")
    _next_of(p, M_CLOSES, 6, 14, "sp_phase", M_RX)
    _get(p, 1, M_CUR)
    p.ld(12, 6, HS).ld(13, 6, HC)
    p.andi(0, 12, 0x100).b("eq", "close_head")          # no head
    p.sub(0, 13, 1).b("ne", "close_head")               # the head does not close now
    p.andi(10, 12, 0xFF)
    p.ld(15, 10, ONEHOT).ld(16, 6, WV)
    p.and_(0, 16, 15).b("eq", "close_head")             # cancelled (SAFE): no result
    _win_read(p, 6, 10)
    p.ld(17, 6, WH).ld(18, 6, WR)
    p.ld(2, 0, WIN_T0).ld(3, 0, WIN_WE).ld(19, 0, WIN_META)
    _get(p, 21, M_L)
    p.add(20, 2, 3).addi(21, 21, -1)
    p.add(20, 20, 21)
    p.sub(0, 20, 1).b("ne", "close_head")               # a cancelled head's slot, reused since
    p.andn(16, 16, 15)
    p.st(16, 6, WV)                                     # the slot is free
    _meta_fields(p, 19, 4, 7, 20)
    # CLOSE's flags: bit 0 init ping, 1 the window's epoch (as in the meta bits), 2 an echo,
    # 3 the echo was rejected
    p.andi(5, 20, 3)
    p.and_(0, 17, 15).b("eq", "close_nowh")
    p.ori(5, 5, 4)
    p.label("close_nowh").and_(0, 18, 15).b("eq", "close_nowr")
    p.ori(5, 5, 8)
    p.label("close_nowr")
    _sensor_words(p, 8, 7)
    _tracking_base(p, 9, 7, 6)
    close_kernel(p)                                     # r10 = 1: the safety rule cancels
    _wake(p, 7)
    p.tst(10).b("eq", "close_head")
    _get(p, 11, M_ACT)
    _put(p, 11, M_WAKE)                                 # every sensor re-evaluates
    _get(p, 1, M_CUR)
    p.call("safe_sub")
    p.label("close_head")
    _get(p, 1, M_CUR)
    _get(p, 6, M_RX)
    head_kernel(p)
    p.jmp("close_next")


# ------------------------------------------------------------------ SCHED
def _sched(p: Program) -> None:
    # The sensors to visit: every one of the table, or only the woken ones where no other can be
    # due: IDLE found none due by eng (td > eng, so every sensor td depends on has its next
    # evaluation after td + P) and this tick comes before td. (Only SCHED changes a next
    # evaluation, a hold or the init flag; a close that ends an init ping wakes its sensor.)
    p.label("sp_phase")
    _get(p, 9, M_ACT)
    _get(p, 15, M_WAKE)
    _get(p, 6, M_ARMED)
    _get(p, 5, M_TD)
    _get(p, 1, M_ENG)
    _get(p, 2, M_CUR)
    p.and_(15, 15, 9)
    p.tst(6).b("eq", "sp_few")                          # none armed: none due
    p.cb("le", 5, 1, "sp_all")                          # td <= eng: one may be due now
    p.cb("ge", 2, 5, "sp_all")                          # this tick is td or later
    p.label("sp_few").mov(9, 15)
    p.label("sp_all")
    _put(p, 9, M_SREM)
    p.label("sp_s")
    _next_of(p, M_SREM, 7, 9, "sp_end", M_S)
    _sensor_words(p, 8, 7)
    p.ld(11, 8, S_FLAGS).ld(12, 8, S_NXT).ld(13, 7, ONEHOT)
    _get(p, 15, M_WAKE)
    _get(p, 16, M_HOLD)
    _get(p, 1, M_CUR)
    _get(p, 2, M_P)
    p.andi(0, 11, F_IN_INIT).b("ne", "sp_s")
    p.and_(0, 15, 13).b("ne", "sp_eval")
    p.and_(0, 16, 13).b("ne", "sp_s")
    p.add(14, 1, 2)
    p.sub(0, 14, 12).b("lt", "sp_s")                   # before its next evaluation
    p.label("sp_eval").andn(15, 15, 13).andn(16, 16, 13)
    _put(p, 15, M_WAKE)
    _put(p, 16, M_HOLD)
    sched_kernel(p)
    _put(p, 10, M_RES)
    _put(p, 11, M_QUIET)
    _put(p, 12, M_INIT)
    p.tst(13).b("eq", "sp_res")
    p.call("safe_sub")                                  # reinit_every: cancel, then an init ping
    p.label("sp_res")
    _current_sensor(p)
    _get(p, 10, M_RES)
    p.cmpi(10, SCHED_NOT_YET).b("ne", "sp_quiet")
    p.ld(13, 8, S_DUE)
    p.st(13, 8, S_NXT).jmp("sp_s")
    p.label("sp_quiet").cmpi(10, SCHED_QUIET).b("ne", "sp_hold")
    _get(p, 13, M_QUIET)
    p.st(13, 8, S_NXT).jmp("sp_s")
    p.label("sp_hold").cmpi(10, SCHED_HOLD).b("ne", "sp_go")
    p.ld(13, 7, ONEHOT)
    _get(p, 16, M_HOLD)
    p.or_(16, 16, 13)
    _put(p, 16, M_HOLD)
    p.jmp("sp_s")
    p.label("sp_go")
    _decision(p)
    p.jmp("sp_s")
    p.label("sp_end")
    _get(p, 1, M_CUR)
    p.st(1, 0, T_DONE)
    p.addi(1, 1, 1)
    _put(p, 1, M_ENG)
    p.jmp("idle")


def _decision(p: Program) -> None:
    """Sensor r7 (words r8) decides for t0 = cur + P: its windows and period, CONF, then ISSUE
    and IEL or the deferral."""
    _get(p, 1, M_CUR)
    _get(p, 2, M_P)
    p.add(1, 1, 2)
    _put(p, 1, M_T0)
    _get(p, 12, M_INIT)
    p.tst(12).b("eq", "dec_track")
    # an init ping: a window on every receiver, [D, R) (te = 0, T_V = -D, T_N = R), period R
    p.ld(13, 8, S_RX).ld(14, 8, S_D).ld(15, 8, S_RMAX).ld(16, 8, S_NRX)
    _put(p, 13, M_WIN)
    p.sub(14, 0, 14)
    _put(p, 14, M_TV)
    _put(p, 15, M_TN)
    _put(p, 15, M_PERIOD)
    _put(p, 16, M_NWIN)
    p.label("dec_zero").tst(13).b("eq", "dec_blank")
    _pop_lowest(p, 17, 13, 18)
    p.st(0, 17, CAND).jmp("dec_zero")
    # a tracking pulse: predictions, effective order and period
    p.label("dec_track").ld(1, 8, S_RX).ld(3, 8, S_SEQ).ld(4, 8, S_LO).ld(5, 8, S_HI)
    _tracking_base(p, 2, 7)
    cand_kernel(p)                                      # r6 / r7 te_min / max, r8 mask, r9 count
    _put(p, 8, M_WIN)
    _put(p, 9, M_NWIN)
    p.mov(2, 6).mov(3, 7)
    _current_sensor(p)
    p.ld(1, 8, S_ORDER).ld(4, 8, S_TV).ld(5, 8, S_TN).ld(6, 8, S_D)
    _put(p, 4, M_TV)
    _put(p, 5, M_TN)
    # the miss hold (docs/fast_firing.md section 4.4): with a miss pending on a receiver the
    # sensor decides only once its last tracking pulse's windows have closed (S_CLR), then at
    # order 0
    _get(p, 22, M_MHOLD)
    p.andi(21, 21, 0xF0)                                # cand's OR of the flags: the miss counts
    p.tst(22).b("eq", "dec_order")                      # RX_FILTER.miss_hold off
    p.tst(21).b("eq", "dec_order")                      # no miss pending
    _get(p, 23, M_CUR)
    p.ld(24, 8, S_CLR)
    p.sub(0, 23, 24).b("ge", "dec_order0")              # the windows in flight have closed
    _get(p, 25, M_P)
    p.add(24, 24, 25)                                   # due = the close tick + P (a t0)
    p.st(24, 8, S_DUE).st(24, 8, S_NXT)
    p.call("wake_others")                               # the sensors its earlier due held
    p.jmp("sp_s")
    p.label("dec_order0").li(1, 0)
    p.label("dec_order")
    order_kernel(p)                                     # r8 = the period, r10 = te_max + T_N
    _put(p, 8, M_PERIOD)
    _put(p, 10, M_WEND)
    # the sensor's blank offsets into BA / BB
    p.label("dec_blank")
    _current_sensor(p)
    p.ld(9, 8, S_BLK).li(17, 64)
    p.mul(18, 7, 17)
    p.label("dec_blk").tst(9).b("eq", "dec_conf")
    _pop_lowest(p, 10, 9)
    p.add(19, 18, 10)
    p.ld(20, 19, BLK).ld(21, 19, BLK + 32)
    p.st(20, 10, BA).st(21, 10, BB).jmp("dec_blk")
    p.label("dec_conf")
    _operands(p)
    conf_kernel(p)                                      # r7 = 1: conflict, r8 the retry t0
    p.tst(7).b("eq", "dec_issue")
    p.mov(13, 8)
    _current_sensor(p)
    p.st(13, 8, S_NXT).jmp("sp_s")
    p.label("dec_issue")
    _current_sensor(p)
    _get(p, 1, M_T0)
    _get(p, 2, M_PERIOD)
    _get(p, 3, M_NWIN)
    _get(p, 4, M_INIT)
    p.ld(5, 8, S_QOFF).ld(6, 8, S_RX)
    _tracking_base(p, 9, 7)
    issue_kernel(p)
    _current_sensor(p)
    p.ld(13, 8, S_DUE)
    p.st(13, 8, S_NXT)                                  # next evaluation at the new due
    _get(p, 12, M_INIT)
    p.tst(12).b("ne", "dec_clr")                        # an init ping: no S_CLR
    _get(p, 13, M_WEND)
    _get(p, 14, M_T0)
    _get(p, 15, M_L)
    p.add(13, 13, 14).addi(15, 15, -1)
    p.add(13, 13, 15)
    p.st(13, 8, S_CLR)                                  # t0 + te_max + T_N - 1 + L
    p.label("dec_clr")
    p.call("wake_others")
    # the windows' meta word: the pulse's seq (before ISSUE's + 1), init, the new epoch, sensor
    p.ld(13, 8, S_SEQ).ld(14, 8, S_FLAGS)
    _get(p, 4, M_INIT)
    p.addi(13, 13, -1).li(17, 128)
    p.andi(13, 13, 0xFF).andi(14, 14, F_EPOCH)
    p.mul(14, 14, 17).rotb(15, 4, 3)                    # epoch << 9; init << 8
    p.rotb(16, 7, 2).or_(24, 13, 14)                    # sensor << 16
    p.or_(15, 15, 16)
    p.or_(24, 24, 15)
    _operands(p)
    _get(p, 25, M_L)
    p.addi(25, 25, -1)
    iel_kernel(p)


def _operands(p: Program) -> Program:
    """CONF's and IEL's shared inputs: r1 t0, r2 every element touched, r3 tx, r4 windows, r9
    blank intervals, r5 / r6 T_V / T_N (sensor words at r8)."""
    _get(p, 1, M_T0)
    _get(p, 4, M_WIN)
    _get(p, 5, M_TV)
    _get(p, 6, M_TN)
    p.ld(3, 8, S_TX).ld(9, 8, S_BLK)
    return p.or_(2, 9, 4)


def main_program() -> Program:
    """The whole program: INIT, then IDLE / DISPATCH / SCHED forever; SAFE as a subroutine."""
    p = prologue(Program("sched_main"))
    _init(p)
    _idle(p)
    _edges(p)
    _closes(p)
    _sched(p)
    p.label("safe_sub")
    safe_kernel(p)
    p.ret()
    _wake_others_sub(p)
    for insn in p.items:                 # the bus decodes I/O writes from r0-based stores only
        if not isinstance(insn, str) and insn.op == "st" and insn.ra and insn.imm >= SU_TA:
            raise UcodeError(f"{insn.where}: I/O store through r{insn.ra}")
    return p
