"""Kernels of a decision: SCHED (may the sensor decide), CAND (predictions), ORDER (effective
order and period), CONF (the conflict scan), ISSUE (the sensor's state, the pulse record) and
IEL (windows, reservations, triggers, heads)."""

from __future__ import annotations

from ..sched_ucode import Program
from .layout import (BA, BB, BU, CAND, DIV_N, DIV_Q, DIV_STAT, DIV_X, EVT_HI, EVT_LO, F_ANY_TRK,
                     F_EPOCH, F_IN_INIT, F_TRACKING, HC, HD_EL, HD_T, HS, R_MASK24, R_SIGN24, SENS,
                     SU_FLAGS, SU_GO, SU_MINC, SU_TA, SU_TB, SU_TWA, SU_TWB, SU_VALID, SU_X, S_DUE,
                     S_FLAGS, S_OPEN, S_QUIET, S_REINIT, S_SEQ, S_SHARE, S_TRK, TRIG_EL, TRIG_T, TU,
                     WH, WR, WV, W_ADDR, W_META, W_T0, W_WE)


def cand_kernel(p: Program) -> Program:
    """CAND for a tracking sensor: for every receiver of the mask in r1 (ascending), if its
    tracking state (base address in r2) is tracked, the prediction for pulse seq r3 (8 bits),
    ``tof + gap * v`` with gap = (r3 - seq) mod 256, clamped to [r4, r5] (the sensor's
    te_limits), stored at CAND + r; r6 / r7 the least / greatest prediction (0x7FFFFFFF / 0
    when none), r8 the receivers that got one (one-hot bits), r9 how many, r21 the OR of every
    receiver's flags byte (bits 7:4: a miss count is pending, the miss hold). Model:
    FastFiringModel._predict and the te_min / te_max of _try_issue."""
    p.li(6, 0x7FFF_FFFF).li(7, 0).li(8, 0).li(9, 0).li(21, 0)
    p.tst(1).b("eq", "cand_done")
    p.label("cand_loop")
    p.lsb(10, 1).addi(11, 1, -1)
    p.add(12, 10, 10).andn(13, 1, 11)      # 2 r, the receiver's one-hot bit
    p.add(12, 12, 2).and_(1, 1, 11)        # its state's address, the mask without it
    p.ld(14, 12, 0).ld(15, 12, 1)          # words A and B
    p.rotb(16, 15, 3).and_(19, 14, R_MASK24)   # flags byte; tof
    p.or_(21, 21, 16)
    p.andi(16, 16, 1)
    p.b("eq", "cand_next")                 # not tracked: no window
    p.rotb(17, 14, 3).and_(18, 15, R_MASK24)   # seq byte; v (24 bits)
    p.andi(17, 17, 0xFF).xor(18, 18, R_SIGN24)
    p.sub(17, 3, 17).sub(18, 18, R_SIGN24)     # gap; v sign-extended
    p.andi(17, 17, 0xFF)
    p.mul(20, 17, 18)
    p.add(20, 20, 19)                      # prediction
    p.clamp(20, 4, 5).st(20, 10, CAND)                  # clamped to [lo, hi]
    p.cmp(20, 6).b("ge", "cand_min").mov(6, 20)           # te_min, te_max
    p.label("cand_min").cmp(20, 7).b("le", "cand_max").mov(7, 20)
    p.label("cand_max")
    p.or_(8, 8, 13).addi(9, 9, 1)
    p.label("cand_next").tst(1).b("ne", "cand_loop")
    p.label("cand_done")
    return p


def conf_kernel(p: Program) -> Program:
    """CONF: the conflict scan of a candidate pulse at t0 = r1 over the elements of mask r2
    (tx elements r3, elements with a window r4, with a blank interval r9): for a tx element its
    trigger t0 + a against tx_until, for a window element the window start t0 + wa against
    blank_until, then the slot unit over the element's reserved windows. The window of
    receiver e is [te - T_V, te + T_N) with te = CAND + e and T_V / T_N in r5 / r6. Result:
    r7 = 1 when the pulse conflicts, r8 the latest retry t0 (model FastFiringModel._conflict,
    None when r7 = 0)."""
    p.li(7, 0).li(8, 0)                        # r8: the retry relative to t0, while r7 = 1
    p.tst(2).b("eq", "conf_done")
    p.label("conf_loop")
    p.lsb(10, 2).addi(11, 2, -1)
    p.andn(12, 2, 11).and_(2, 2, 11)           # element's one-hot bit; the mask without it
    p.ld(13, 10, BA).ld(14, 10, BB)            # blank interval [a, b)
    p.ld(15, 10, CAND).ld(16, 10, TU)
    p.add(13, 13, 1).add(14, 14, 1)            # t0 + a, t0 + b
    p.sub(17, 15, 5).add(18, 15, 6)            # window offsets te - T_V, te + T_N
    p.st(13, 0, SU_TA).st(14, 0, SU_TB)
    p.add(17, 17, 1).add(18, 18, 1)            # t0 + wa, t0 + wb
    p.st(17, 0, SU_TWA).st(18, 0, SU_TWB)
    p.ld(24, 10, WV).mov(21, 10)
    p.st(24, 0, SU_VALID).and_(20, 12, 9)      # SU_GO: the element; blank on?
    p.b("eq", "conf_noblk").ori(21, 21, 0x100)
    p.label("conf_noblk").and_(20, 12, 4)      # window on?
    p.b("eq", "conf_nowin").ori(21, 21, 0x200)
    p.label("conf_nowin").and_(19, 12, 3)      # tx element?
    p.st(21, 0, SU_GO)                         # the slot unit scans while the rules below run
    p.tst(19).b("eq", "conf_notx")
    p.sub(22, 16, 13).b("le", "conf_notx")     # tx_until - (t0 + a) > 0: retry
    p.call("conf_fold")
    p.label("conf_notx").tst(20).b("eq", "conf_wait")
    p.ld(16, 10, BU)
    p.sub(22, 16, 17).b("le", "conf_wait")     # blank_until - (t0 + wa) > 0: retry
    p.call("conf_fold")
    p.label("conf_wait").ld(23, 0, SU_FLAGS)
    p.andi(0, 23, 0x80).b("ne", "conf_wait")
    p.andi(0, 23, 1).b("eq", "conf_full")
    p.ld(22, 0, SU_X)
    p.call("conf_fold")
    p.label("conf_full").andi(0, 23, 2).b("eq", "conf_next")
    p.ld(22, 0, SU_MINC)
    p.sub(22, 22, 1)                           # the earliest close, relative to t0
    p.call("conf_fold")
    p.label("conf_next").tst(2).b("ne", "conf_loop")
    p.jmp("conf_done")
    # r8 = max(r8, r22) with r7 = 1 (a retry relative to t0)
    p.label("conf_fold").tst(7).b("eq", "conf_take")
    p.cmp(22, 8).b("le", "conf_keep")
    p.label("conf_take").mov(8, 22).li(7, 1)
    p.label("conf_keep").ret()
    p.label("conf_done").add(8, 8, 1)          # the retry as a t0
    return p


# ------------------------------------------------------------------ IEL: the issue's writes
def iel_kernel(p: Program) -> Program:
    """IEL, the writes of a pulse issued at t0 = r1 over the elements of mask r2 (tx r3, with a
    window r4, with a blank interval r9; T_V / T_N in r5 / r6, the window of element e being
    [te - T_V, te + T_N) with te = CAND + e; an init ping uses te = 0, T_V = -D, T_N = R):
    blank_until and (tx) tx_until = max(, t0 + b); a trigger at t0 + a per tx element; the
    window in the element's lowest free slot (WV), its fields from r1, the end offset and the
    meta word r24 (its echo flags WH / WR cleared); the head (HC / HS and the close detector)
    when the new window closes first.
    Close tick = t0 + we + r25 (r25 = L - 1). Model: the issue part of _try_issue."""
    p.li(26, 16).li(27, 256)
    p.tst(2).b("eq", "iel_done")
    p.label("iel_loop")
    p.lsb(10, 2).addi(11, 2, -1)
    p.andn(12, 2, 11).and_(2, 2, 11)
    p.ld(13, 10, BB).ld(16, 10, BU)
    p.and_(0, 12, 9)
    p.b("eq", "iel_notx")                    # no blank interval: no tx either
    p.add(14, 13, 1)                         # t0 + b
    p.sub(0, 14, 16).b("le", "iel_bu")       # later than blank_until?
    p.st(14, 10, BU)
    p.label("iel_bu").and_(0, 12, 3)
    p.b("eq", "iel_notx")
    p.ld(16, 10, TU).ld(13, 10, BA)
    p.add(15, 13, 1)                         # the trigger tick t0 + a
    p.sub(0, 14, 16).b("le", "iel_tu")       # later than tx_until?
    p.st(14, 10, TU)
    p.label("iel_tu").st(15, 0, TRIG_T).st(10, 0, TRIG_EL)
    p.label("iel_notx").and_(0, 12, 4)
    p.b("eq", "iel_next")
    p.ld(15, 10, CAND).ld(17, 10, WV)
    p.mul(7, 10, 26)                         # the element's first slot address, e * 16
    p.add(19, 15, 6)                         # we (WIN keeps no start: the sensor's length)
    p.xori(21, 17, -1)                       # free slots
    p.lsb(22, 21).addi(23, 21, -1)           # the lowest; its one-hot bit below
    p.andn(23, 21, 23).add(7, 7, 22)
    p.or_(17, 17, 23).add(30, 1, 19)
    p.st(17, 10, WV).st(1, 0, W_T0).st(19, 0, W_WE).st(24, 0, W_META)
    p.st(7, 0, W_ADDR).add(30, 30, 25)       # the window's close tick t0 + we - 1 + L
    p.ld(13, 10, WH).ld(16, 10, WR)    # the slot's echo flags start clear
    p.andn(13, 13, 23).andn(16, 16, 23)
    p.st(13, 10, WH).st(16, 10, WR)
    p.ld(16, 10, HS).ld(13, 10, HC)
    p.andi(0, 16, 0x100).b("eq", "iel_head")
    p.sub(0, 30, 13).b("ge", "iel_next")     # the head closes first: keep it
    p.label("iel_head").mul(8, 22, 27).st(30, 10, HC)
    p.ori(16, 22, 0x100).st(30, 0, HD_T)
    p.st(16, 10, HS).or_(8, 8, 10)
    p.st(8, 0, HD_EL)
    p.label("iel_next").tst(2).b("ne", "iel_loop")
    p.label("iel_done")
    return p


# ------------------------------------------------------------------ ISSUE: the sensor's state
def issue_kernel(p: Program) -> Program:
    """ISSUE, the sensor's side of a pulse issued at t0 = r1 by sensor r7 (words at r8): the
    pulse record (docs/fast_firing.md section 6; n_win r3, init ping r4 = 1), then pulse id + 1;
    an init ping flips the epoch, starts the init phase with r3 open windows, clears the
    tracking pulse count and the tracking states of the receivers in mask r6 (at r9 + 2 r);
    a tracking pulse counts (saturating at 255); due = t0 + period r2, quiet = t0 + r5 (max
    ToF - D). Model: the issue part of FastFiringModel._try_issue."""
    p.ld(10, 8, S_SEQ).ld(11, 8, S_FLAGS).li(17, 32)
    p.li(12, 2048).li(13, 8192)
    p.mul(14, 7, 17).mul(15, 4, 12)                     # sensor << 5; init_ping << 11
    p.mul(16, 10, 13).or_(14, 14, 3)                    # pulse id << 13; n_win
    p.or_(14, 14, 15).lui(18, 0x40000)                  # bit 62 of the word: bit 30 of the high half
    p.or_(14, 14, 16)
    p.or_(14, 14, 18)
    p.st(1, 0, EVT_LO).st(14, 0, EVT_HI)
    p.addi(10, 10, 1).li(19, 0xFFFF)
    p.add(12, 1, 2).add(13, 1, 5)                       # due, quiet
    p.and_(10, 10, 19)                                  # the pulse id wraps at 2^16
    p.st(10, 8, S_SEQ).st(12, 8, S_DUE).st(13, 8, S_QUIET)
    p.tst(4).b("eq", "issue_track")
    p.xori(11, 11, F_EPOCH)
    p.andi(11, 11, ~(F_TRACKING | F_ANY_TRK))
    p.ori(11, 11, F_IN_INIT)
    p.st(11, 8, S_FLAGS).st(3, 8, S_OPEN).st(0, 8, S_TRK)
    p.tst(6).b("eq", "issue_done")
    p.label("issue_rx").lsb(10, 6).addi(11, 6, -1)
    p.add(12, 10, 10)
    p.add(12, 12, 9).and_(6, 6, 11)                     # the state's address; the mask without r
    p.st(0, 12, 0).st(0, 12, 1).b("ne", "issue_rx")     # (flags of the mask's and)
    p.jmp("issue_done")
    p.label("issue_track").ld(10, 8, S_TRK)
    p.cmpi(10, 255).b("eq", "issue_done")
    p.addi(10, 10, 1)
    p.st(10, 8, S_TRK)
    p.label("issue_done")
    return p


# ------------------------------------------------------------------ SCHED: may the sensor decide?
SCHED_NOT_YET, SCHED_QUIET, SCHED_HOLD, SCHED_GO = 0, 1, 2, 3


def sched_kernel(p: Program) -> Program:
    """SCHED, whether sensor r7 (words at r8) decides at tick r1 for t0 = r1 + P (P in r2):
    r10 = SCHED_NOT_YET (in its init phase, or not due by t0), SCHED_QUIET (an init ping
    before its quiet tick: r11 = the quiet tick, the retry t0), SCHED_HOLD (a sensor sharing an
    element is eligible with an earlier (due, id)) or SCHED_GO (on to the candidate; r12 = 1
    for an init ping). A tracking sensor with M = reinit_every tracking pulses since its init
    ping stops tracking first (r13 = 1: the caller cancels its windows). Model: the part of
    FastFiringModel._try_issue before the candidate, with _eligible."""
    p.li(10, SCHED_NOT_YET).li(13, 0).li(12, 0)
    p.add(14, 1, 2).ld(11, 8, S_FLAGS).ld(20, 8, S_DUE)   # t0 = now + P
    p.andi(0, 11, F_IN_INIT).b("ne", "sched_done")
    p.sub(0, 14, 20).b("lt", "sched_done")                # not due by t0
    p.andi(0, 11, F_TRACKING).b("eq", "sched_init")
    p.ld(15, 8, S_REINIT).ld(16, 8, S_TRK)
    p.tst(15).b("eq", "sched_edf")                        # reinit_every off
    p.sub(0, 16, 15).b("lt", "sched_edf")
    p.andi(11, 11, ~F_TRACKING).li(13, 1)                 # forced re-initialisation
    p.st(11, 8, S_FLAGS)
    p.label("sched_init").ld(15, 8, S_QUIET).li(12, 1)
    p.sub(0, 14, 15).b("ge", "sched_edf")
    p.li(10, SCHED_QUIET).mov(11, 15).jmp("sched_done")
    p.label("sched_edf").ld(16, 8, S_SHARE).li(17, 32)
    p.label("sched_o").tst(16).b("eq", "sched_go")
    p.lsb(18, 16).addi(19, 16, -1)
    p.mul(21, 18, 17).and_(16, 16, 19)                    # o's words; the mask without o
    p.ld(22, 21, SENS + S_FLAGS).ld(23, 21, SENS + S_DUE).ld(24, 21, SENS + S_QUIET)
    p.andi(0, 22, F_IN_INIT).b("ne", "sched_o")           # o waits for its init result
    p.sub(0, 14, 23).b("lt", "sched_o")                   # o not due by t0
    p.andi(0, 22, F_TRACKING).b("ne", "sched_elig")
    p.sub(0, 14, 24).b("lt", "sched_o")                   # o's init ping still quiet
    p.label("sched_elig").sub(0, 23, 20).b("lt", "sched_hold")   # o due earlier
    p.b("ne", "sched_o")
    p.sub(0, 18, 7).b("ge", "sched_o")                    # the same due: the lower id first
    p.label("sched_hold").li(10, SCHED_HOLD).jmp("sched_done")
    p.label("sched_go").li(10, SCHED_GO)
    p.label("sched_done")
    return p


# ------------------------------------------------------------------ ORDER: the effective order
def order_kernel(p: Program) -> Program:
    """ORDER, the largest n <= order r1 whose interlacing is feasible for predictions te_min r2
    .. te_max r3 (T_V r4, T_N r5, blanking D r6): T_s = floor((te_min - T_V - D) / n) > 0 and
    (n + 1) T_s >= te_max + T_N, tried from n = order down (the divider gives each T_s). Result:
    r7 = n (0: none), r8 = the period (T_s, or te_max + T_N for n = 0). Model:
    schedule.effective_order and pulse_period."""
    p.sub(9, 2, 4).add(10, 3, 5)                   # te_min - T_V; te_max + T_N
    p.mov(7, 1).mov(8, 10)                         # n = order
    p.sub(9, 9, 6).b("le", "order_none")           # x = te_min - T_V - D <= 0: no T_s > 0
    p.st(9, 0, DIV_X)
    p.label("order_try").tst(7).b("eq", "order_none")
    p.st(7, 0, DIV_N)
    p.label("order_wait").ld(11, 0, DIV_STAT)
    p.andi(0, 11, 0x80).b("ne", "order_wait")          # the divider is busy
    p.ld(12, 0, DIV_Q).mov(13, 7).li(14, 0)
    p.label("order_mul").add(14, 14, 12).addi(13, 13, -1)   # (n + 1) T_s by n + 1 additions
    p.b("ge", "order_mul")
    p.tst(12).b("eq", "order_next")                # T_s = 0: infeasible
    p.sub(0, 14, 10).b("lt", "order_next")
    p.mov(8, 12).jmp("order_done")
    p.label("order_next").addi(7, 7, -1).jmp("order_try")
    p.label("order_none").li(7, 0).mov(8, 10)
    p.label("order_done")
    return p
