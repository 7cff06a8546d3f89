"""The scheduler engine's data memory and I/O map (docs/sched_engine.md).

Data memory (32-bit words): the tracking state of (sensor s, receiver r) at
``TRK + 2 * (24 s + r)``: word A = tof[23:0] | seq[7:0] << 24, word B = v[23:0] (two's
complement) | flags << 24 (bit 24 tracked, 25 init, 26 vel, 31:28 miss count); the candidate's
predicted T_E of receiver r at ``CAND + r``; per element tx_until (``TU + e``) and
blank_until (``BU + e``), valid slots (``WV + e``), the head's close tick and slot | 0x100
(``HC + e``, ``HS + e``); the candidate's blank interval of element e at ``BA + e``, ``BB + e``;
per sensor s at ``SENS + 32 s``: due (S_DUE), quiet, pulse id (S_SEQ), flags (S_FLAGS:
tracking, in_init, epoch, any receiver tracked), open init windows (S_OPEN), tracking pulses
since the last init ping (S_TRK, saturating at 255), miss limit K (S_K), reinit_every M
(S_REINIT, 0 off), mode (S_MODE: 1 track), the other sensors sharing an element (S_SHARE,
one bit per sensor), the close tick of its last tracking pulse's windows (S_CLR, miss hold).
"""

from __future__ import annotations

from ..sched_ucode import Program

NUM_RX = 24
WSLOTS = 16
TRK = 0x100           # tracking state, 2 words per (sensor, receiver): 0x100..0x27F
TU = 0x340            # per element: tx_until (absolute tick)
BU = 0x358            # per element: blank_until (absolute tick)
BA = 0x370            # the candidate's blank interval [a, b) of element e (offsets from t0)
BB = 0x388
CAND = 0x3A0          # candidate T_E per receiver
WV = 0x3B8            # per element: valid reserved-window slots (bit mask)
HC = 0x3D0            # per element: the head's (earliest) close tick
HS = 0x3E8            # per element: the head's slot | 0x100 while there is a head
WH = 0x280            # per element: slots whose window saw an echo (bit mask)
WR = 0x298            # per element: slots whose first echo the miss gate rejected
ONEHOT = 0x2C0        # ONEHOT + k = 1 << k, k < 32 (a decoder on the bus; no shifter)
MAIN = 0x2E0          # the main loop's variables (M_* offsets)

# the slot unit's I/O registers (bus addresses above the data memory)
SU_TA, SU_TB, SU_TWA, SU_TWB, SU_GO = 0x400, 0x401, 0x402, 0x403, 0x404
SU_X, SU_FLAGS, SU_MINC, SU_VALID = 0x405, 0x406, 0x407, 0x408
SU_CONF, SU_EDGE, SU_HEAD, SU_SENSOR = 0, 1 << 10, 2 << 10, 3 << 10   # SU_GO modes
SU_LATENCY = WSLOTS + 5   # clocks from SU_GO to the results, all slots valid (a valid slot per
                          # clock, five stages)
# outputs of IEL: a window slot written (fields, then the address commits it; WIN keeps no
# start: the window is [t0 + we - len, t0 + we), len the sensor's window length, T_V + T_N or,
# for an init ping, R - D, from the hardware's table of the applied sensors), a trigger
# (tick, then the element commits it), a head set for the close detector (tick, then element |
# slot << 8 commits it; element | 1 << 16: the element has no head)
W_T0, W_WE, W_META, W_ADDR = 0x410, 0x412, 0x413, 0x414
TRIG_T, TRIG_EL, HD_T, HD_EL = 0x418, 0x419, 0x41C, 0x41D
EVT_LO, EVT_HI = 0x420, 0x421   # an event word: low half, then the high half commits it
# the divider: DIV_X = dividend (< 2^24), DIV_N = divisor (1..15) starts it; DIV_Q = floor(x / n)
# once DIV_STAT bit 7 (busy) falls, at most DIV_LATENCY clocks later (a restoring divider, one
# quotient bit per clock)
DIV_X, DIV_N, DIV_Q, DIV_STAT = 0x428, 0x429, 0x42A, 0x42B
DIV_LATENCY = 26
# the main loop's hardware (sched_program.system): the tick counter; the work queue's head
# (Q_STAT bit 0: a word {Q_T, Q_E edges, Q_C closes} is visible, a write of Q_POP drops it);
# the WIN read port (write the slot address to WIN_RA, its fields from two clocks later)
TICK, Q_STAT, Q_T, Q_E, Q_C, Q_POP = 0x430, 0x431, 0x432, 0x433, 0x434, 0x435
WIN_RA, WIN_T0, WIN_WE, WIN_META = 0x438, 0x439, 0x43A, 0x43B
# the logical tick a dispatch starts (LAG_CUR) and the one whose work is done (T_DONE): the
# hardware's lateness check (P / 2) and lag measure; a stop request (STOP_REQ bit 0, with the
# tick STOP_AT): the program finishes every logical tick before it, then writes HALT
LAG_CUR, T_DONE, STOP_REQ, STOP_AT, HALT = 0x43C, 0x43D, 0x43E, 0x43F, 0x440
# the blank offsets of (sensor s, element e): a at BLK + 64 s + e, b at BLK + 64 s + 32 + e
# (ms_sched_uc keeps them in WIN's spare rows; the program reads them while the slot unit is idle)
BLK = 0x800
# the configuration load's own tables, written through ms_sched_uc's load port only (never on the
# program's bus): the window length of sensor s's windows at LD_WLEN + 2 s + init (init: R - D;
# tracking: T_V + T_N), its triggers' burst cycles at LD_BURST + s, its tx elements at LD_TXM + s
# (pulse_tx_o), and the enabled sensors' rx elements at LD_RXANY (the work queue takes their edges)
LD_WLEN, LD_BURST, LD_TXM, LD_RXANY = 0x480, 0x490, 0x498, 0x4A0

# per-sensor words at SENS + 32 s
SENS = 0x000
S_DUE, S_QUIET, S_SEQ, S_FLAGS, S_OPEN, S_TRK, S_K, S_MODE = 0, 1, 3, 4, 5, 6, 18, 23
S_REINIT, S_SHARE = 22, 24
S_CLR = 26            # the close tick of the sensor's last tracking pulse's windows (miss hold)
# the table's words the main loop reads (the firmware's load writes them): next evaluation (as a t0),
# element masks (tx, rx, with a blank interval), order, T_V, T_N, blanking D, max ToF R, T_E
# limits, v_max, R - D, start phase, receivers
S_NXT, S_TX, S_RX, S_BLK, S_ORDER, S_TV, S_TN, S_D, S_RMAX = 2, 7, 8, 9, 10, 11, 12, 13, 14
S_LO, S_HI, S_VMAX, S_QOFF, S_PHASE, S_NRX = 15, 16, 19, 20, 21, 25
F_TRACKING, F_IN_INIT, F_EPOCH, F_ANY_TRK = 1, 2, 4, 8    # S_FLAGS bits
NUM_VS = 8
UCODE_WORDS = 1088    # ms_sched_uc's ROM depth: 1,024 words in two DP16KD (UCODE_BRAM), 64 in logic
UCODE_BRAM = 1024
# main-loop variables at MAIN + M_*: the start tick, decision lead P, L = edge latency, the
# miss gate, the next logical tick, the current one, its edges and closes left, td and armed,
# the sensor of the SCHED phase, saved kernel results; sensor masks: the table's sensors
# (M_ACT, the load's), those to re-evaluate now (M_WAKE), those EDF holds (M_HOLD), those the
# SCHED phase has still to visit (M_SREM)
M_START, M_P, M_L, M_GATE, M_ENG, M_CUR, M_EDGES, M_CLOSES = range(8)
M_TD, M_ARMED, M_S, M_RX, M_SLOT, M_RES, M_QUIET, M_INIT = range(8, 16)
M_WIN, M_NWIN, M_TV, M_TN, M_PERIOD, M_T0, M_FLAGS = range(16, 23)
M_ACT, M_WAKE, M_HOLD, M_SREM = range(23, 27)
M_MHOLD, M_WEND = 27, 28   # RX_FILTER.miss_hold (0 / 1); the candidate's te_max + T_N
MISS_MAX = 15

# register conventions of the kernels
R_MASK24, R_SIGN24 = 28, 29   # constants 0xFFFFFF and 0x800000 (loaded by prologue())
R_STRIDE = 31                 # constant: the sensor words' stride (SENS + R_STRIDE * s)
SENS_STRIDE = 32


def pack_rx(tracked: bool, tof: int, seq: int, v: int, miss: int = 0, init: bool = False,
            vel: bool = False) -> tuple[int, int]:
    """The two data-memory words of a receiver's tracking state (words A and B above)."""
    flags = int(tracked) | int(init) << 1 | int(vel) << 2 | (miss & 0xF) << 4
    return (tof & 0xFF_FFFF) | (seq & 0xFF) << 24, (v & 0xFF_FFFF) | flags << 24


def prologue(p: Program) -> Program:
    """Constants every kernel relies on."""
    return p.li(R_MASK24, 0xFF_FFFF).li(R_SIGN24, 0x80_0000).li(R_STRIDE, SENS_STRIDE)
