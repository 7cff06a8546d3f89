/* sched_table: the virtual-sensor table's check and the scheduler's load image (sched_table.h).
 *
 * The check follows multisonar.simdevice.decode_vs_table, refusal by refusal: first an enabled
 * entry with an over-wide DELAY word (the scheduler keeps 16 bits), then entry by entry its
 * mode, tx run, rx mask, order, miss limit, burst, window, maximum ToF and the decision lead.
 * The load writes what multisonar.tools.sched_program.system.load_image lists. Integer ticks
 * throughout; every difference is taken in int64_t, so no field value can wrap it.
 */
#include "sched_table.h"

#include "ms_protocol.h"
#include "ms_sched_layout.h"
#include "sonar_regs.h"

#define FIELD(word, reg, f) (((word) & SONAR_REGS__VS__##reg##__##f##_bm) >> SONAR_REGS__VS__##reg##__##f##_bp)
#define MASK24 0xFFFFFFu

enum { MODE_TRACK = 1, MODE_INIT_ONLY = 2, MAX_ORDER = 8, DELAY_BITS = 16 };

/* One table entry, decoded (the words of docs/protocol.md section 5). */
typedef struct {
    uint32_t mode, tx, rx, order, miss, reinit, t_v, t_n, t_dead, t_xt, nb, max_tof, vmax, burst,
        phase;
    uint32_t dmax;   /* the largest phasing delay of a tx element */
    uint32_t xt;     /* crosstalk neighbours: within nb of a tx element, not tx */
    uint32_t blank;  /* D = max(T_dead, T_xtalk) + dmax: the earliest window start */
} entry_t;

static uint32_t word(const ms_table_src_t *t, uint32_t vs, uint32_t reg)
{
    return t->vs[16u * vs + reg];
}

static uint32_t delay_of(const ms_table_src_t *t, uint32_t vs, uint32_t e)
{
    return t->delay[32u * vs + e] & ((1u << DELAY_BITS) - 1u);
}

static uint32_t ring_next(uint32_t e, int k)
{
    int j = ((int)e + k) % MS_TABLE_ELEMENTS;
    return (uint32_t)(j < 0 ? j + MS_TABLE_ELEMENTS : j);
}

/* 1 when the set bits of mask (non-empty) are one cyclic run of adjacent elements */
static int adjacent_run(uint32_t mask)
{
    uint32_t starts = 0;
    if (mask == MASK24)
        return 1;
    for (uint32_t e = 0; e < MS_TABLE_ELEMENTS; e++)
        if ((mask >> e & 1u) && !(mask >> ring_next(e, -1) & 1u))
            starts++;
    return starts == 1;
}

static uint32_t popcount24(uint32_t m)
{
    uint32_t n = 0;
    for (; m; m &= m - 1u)
        n++;
    return n;
}

static void decode(const ms_table_src_t *t, uint32_t vs, entry_t *s)
{
    uint32_t mode = word(t, vs, 2), win = word(t, vs, 3), xtalk = word(t, vs, 6),
             track = word(t, vs, 7);
    s->tx = word(t, vs, 0) & MASK24;
    s->rx = word(t, vs, 1) & MASK24;
    s->mode = FIELD(mode, MODE, MODE);
    s->order = FIELD(mode, MODE, ORDER);
    s->miss = FIELD(mode, MODE, MISS_LIMIT);
    s->reinit = FIELD(mode, MODE, REINIT_EVERY);
    s->t_v = FIELD(win, WINDOW, T_V);
    s->t_n = FIELD(win, WINDOW, T_N);
    s->t_dead = FIELD(word(t, vs, 4), T_DEAD, TICKS);
    s->max_tof = FIELD(word(t, vs, 5), MAX_TOF, TICKS);
    s->t_xt = FIELD(xtalk, XTALK, T_XTALK);
    s->nb = FIELD(xtalk, XTALK, NB);
    s->vmax = FIELD(track, TRACK, VMAX);
    s->burst = FIELD(track, TRACK, BURST_CYCLES);
    s->phase = FIELD(word(t, vs, 8), PHASE, TICKS);
    s->dmax = 0;
    s->xt = 0;
    for (uint32_t e = 0; e < MS_TABLE_ELEMENTS; e++) {
        if (!(s->tx >> e & 1u))
            continue;
        uint32_t d = delay_of(t, vs, e);
        if (d > s->dmax)
            s->dmax = d;
        for (uint32_t k = 1; k <= s->nb; k++)
            s->xt |= 1u << ring_next(e, (int)k) | 1u << ring_next(e, -(int)k);
    }
    s->xt &= ~s->tx;
    s->blank = (s->t_dead > s->t_xt ? s->t_dead : s->t_xt) + s->dmax;
}

static uint32_t check_entry(const ms_table_src_t *t, const entry_t *s)
{
    if (s->mode != MODE_TRACK && s->mode != MODE_INIT_ONLY)
        return MS_CFG_ERROR_BAD_MODE;
    if (s->tx == 0 || !adjacent_run(s->tx))
        return MS_CFG_ERROR_TX_MASK;
    if (s->rx == 0)
        return MS_CFG_ERROR_RX_MASK;
    if (s->order > MAX_ORDER)
        return MS_CFG_ERROR_ORDER;
    if (s->miss < 1)
        return MS_CFG_ERROR_MISS_LIMIT;
    if (s->burst < 1)
        return MS_CFG_ERROR_BURST;
    if (s->t_v < 1 || s->t_n < 1 || s->t_xt < 1
        || (uint64_t)s->t_dead < (uint64_t)s->burst * 2u * t->burst_half_period)
        return MS_CFG_ERROR_WINDOW;
    if ((int64_t)s->max_tof - s->t_n < (int64_t)s->blank + s->t_v)
        return MS_CFG_ERROR_MAX_TOF;
    if (s->blank <= t->lead)
        return MS_CFG_ERROR_LEAD;
    if (s->t_v + s->t_n <= t->lead / 2u)
        return MS_CFG_ERROR_WINDOW_SHORT;
    return MS_CFG_ERROR_OK;
}

uint32_t ms_table_check(const ms_table_src_t *t, uint32_t *entry)
{
    uint32_t any = 0;
    entry_t s;
    *entry = 0;
    for (uint32_t vs = 0; vs < MS_TABLE_ENTRIES; vs++) {
        uint32_t tx = word(t, vs, 0) & MASK24;
        if (FIELD(word(t, vs, 2), MODE, MODE) != 0 && (t->delay_over[vs] & tx)) {
            *entry = vs;
            return MS_CFG_ERROR_DELAY;
        }
    }
    for (uint32_t vs = 0; vs < MS_TABLE_ENTRIES; vs++) {
        decode(t, vs, &s);
        if (s.mode == 0)
            continue;
        any = 1;
        uint32_t code = check_entry(t, &s);
        if (code != MS_CFG_ERROR_OK) {
            *entry = vs;
            return code;
        }
    }
    return any ? MS_CFG_ERROR_OK : MS_CFG_ERROR_EMPTY_TABLE;
}

/* the blank interval [a, b) of element e (offsets from t0): a tx element's dead zone, a
   crosstalk neighbour's first to last neighbouring trigger + T_xtalk (schedule._xtalk) */
static void blank_interval(const ms_table_src_t *t, uint32_t vs, const entry_t *s, uint32_t e,
                           uint32_t *a, uint32_t *b)
{
    if (s->tx >> e & 1u) {
        *a = delay_of(t, vs, e);
        *b = *a + s->t_dead;
        return;
    }
    uint32_t lo = UINT32_MAX, hi = 0;
    for (uint32_t k = 1; k <= s->nb; k++) {
        uint32_t n[2] = {ring_next(e, (int)k), ring_next(e, -(int)k)};
        for (int i = 0; i < 2; i++) {
            if (!(s->tx >> n[i] & 1u))
                continue;
            uint32_t d = delay_of(t, vs, n[i]);
            lo = d < lo ? d : lo;
            hi = d > hi ? d : hi;
        }
    }
    *a = lo;
    *b = hi + s->t_xt;
}

uint32_t ms_table_load(const ms_table_src_t *t, ms_table_put_fn put, void *ctx)
{
    uint32_t act = 0, rx_any = 0, touch[MS_TABLE_ENTRIES];
    entry_t s;
    for (uint32_t vs = 0; vs < MS_TABLE_ENTRIES; vs++) {
        decode(t, vs, &s);
        touch[vs] = s.tx | s.xt | s.rx;
        if (s.mode != 0) {
            act |= 1u << vs;
            rx_any |= s.rx;
        }
    }
    for (uint32_t vs = 0; vs < MS_TABLE_ENTRIES; vs++) {
        if (!(act >> vs & 1u))
            continue;
        decode(t, vs, &s);
        uint32_t share = 0;
        for (uint32_t o = 0; o < MS_TABLE_ENTRIES; o++)
            if (o != vs && (act >> o & 1u) && (touch[o] & touch[vs]))
                share |= 1u << o;
        const uint32_t base = MS_SCHED_SENS + MS_SCHED_SENS_STRIDE * vs;
        const struct { uint32_t off, value; } w[] = {
            {MS_SCHED_S_TX, s.tx},
            {MS_SCHED_S_RX, s.rx},
            {MS_SCHED_S_BLK, s.tx | s.xt},
            {MS_SCHED_S_ORDER, s.order},
            {MS_SCHED_S_TV, s.t_v},
            {MS_SCHED_S_TN, s.t_n},
            {MS_SCHED_S_D, s.blank},
            {MS_SCHED_S_RMAX, s.max_tof},
            {MS_SCHED_S_LO, s.blank + s.t_v},
            {MS_SCHED_S_HI, s.max_tof - s.t_n},
            {MS_SCHED_S_VMAX, s.vmax},
            {MS_SCHED_S_QOFF, s.max_tof - s.blank},
            {MS_SCHED_S_PHASE, s.phase},
            {MS_SCHED_S_NRX, popcount24(s.rx)},
            {MS_SCHED_S_K, s.miss},
            {MS_SCHED_S_MODE, s.mode == MODE_TRACK ? 1u : 2u},
            {MS_SCHED_S_REINIT, s.reinit},
            {MS_SCHED_S_SHARE, share},
        };
        for (uint32_t i = 0; i < sizeof w / sizeof w[0]; i++)
            put(ctx, base + w[i].off, w[i].value);
        for (uint32_t e = 0; e < MS_TABLE_ELEMENTS; e++) {
            if (!((s.tx | s.xt) >> e & 1u))
                continue;
            uint32_t a, b;
            blank_interval(t, vs, &s, e, &a, &b);
            put(ctx, MS_SCHED_BLK + 64u * vs + e, a);
            put(ctx, MS_SCHED_BLK + 64u * vs + 32u + e, b);
        }
        /* the load port's own tables (window lengths: tracking, then an init ping's) */
        put(ctx, MS_SCHED_LD_WLEN + 2u * vs, s.t_v + s.t_n);
        put(ctx, MS_SCHED_LD_WLEN + 2u * vs + 1u, s.max_tof - s.blank);
        put(ctx, MS_SCHED_LD_BURST + vs, s.burst);
        put(ctx, MS_SCHED_LD_TXM + vs, s.tx);
    }
    put(ctx, MS_SCHED_LD_RXANY, rx_any);
    uint32_t latency = (t->glitch_min > 1u ? t->glitch_min : 1u) + 1u;
    put(ctx, MS_SCHED_MAIN + MS_SCHED_M_P, t->lead);
    put(ctx, MS_SCHED_MAIN + MS_SCHED_M_L, latency);
    put(ctx, MS_SCHED_MAIN + MS_SCHED_M_GATE, t->miss_gate);
    put(ctx, MS_SCHED_MAIN + MS_SCHED_M_MHOLD, t->miss_hold);
    put(ctx, MS_SCHED_MAIN + MS_SCHED_M_ACT, act);
    return act;
}
