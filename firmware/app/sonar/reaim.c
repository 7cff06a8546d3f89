/* Re-aiming (paper section V.A: outside the high-confidence interval, responsibility moves to
 * the neighbouring elements), in bounded slices.
 *
 * An edge / wall fix whose bearing (wall: normal) is more than REAIM_DEG off the sensor's axis
 * requests a move of its tx and rx groups one element toward the reflector; LOST_PINGS init
 * pings in a row without a fix request one toward the side of its last fix. One move at a
 * time; a request while one is under way, or within REAIM_HOLDOFF of the last move taken, is
 * dropped (the next fix asks again). A move restarts the whole table: every sensor loses its
 * track and fires init pings, so the hold-off bounds what re-aiming costs the other sensors,
 * and the restart's init pings do not count as lost tracks (the counters restart with it).
 *
 *   MOVE     (not while a pulse id is within ID_WRAP_MARGIN of its 16-bit wrap) the moved
 *            groups placed, the sensor's VS entry and delay memory rewritten and the table
 *            checked (table_check): refused, the entry is put back and the running table
 *            never stops; accepted, CTRL.hold: the scheduler finishes every tick before it,
 *            drops all windows and stops;
 *   HOLD     once STATUS.running is low: the table loaded and started (table_load_start);
 *   WAIT     the main loop goes on. Every sensor restarts with an init ping of pulse id 0.
 *            Words leave the event FIFO in the order they were written, so the first such
 *            record (reaim_restart_seen) is the first word of the new table: every pulse still
 *            open is the old table's and goes out, cut; then the moved groups' geometry is
 *            prepared (ms_prepare, ~32 k cycles) and takes over. Here it delays no ToF frame:
 *            every pulse is out, and the new table's first event comes T_dead (1.5 ms by
 *            default) after its first trigger, which is after this record. No restart within
 *            APPLY_WAIT: taken over all the same (the record went in an overflow). */
#include "app.h"

#define REAIM_BANG ((int32_t)((uint32_t)REAIM_DEG * (4294967296.0 / 360.0)))

enum { RA_IDLE, RA_MOVE, RA_HOLD, RA_WAIT };
static struct {
    int state, si, dir, why;
    sensor_t nw;           /* the moved groups and their prepared array */
    uint32_t t_hold;
} ra;
/* the moved sensor's groups before its last move: jobs of its old pulses still queued at the
 * hand-over are solved on them (the next move is prepared only when the job queue is empty) */
static sensor_t prev;
static int prev_si = -1;
static uint32_t t_taken; /* when the last move was taken */
static int taken_any;

APP_HOT const sensor_t *placement_of(int si, int shift)
{
    if (sens[si].shift == shift)
        return &sens[si];
    if (prev_si == si && prev.shift == shift)
        return &prev;
    return 0;
}

static void request(int si, int dir, int why)
{
    if (ra.state != RA_IDLE || (taken_any && now32() - t_taken < REAIM_HOLDOFF))
        return;
    ra.state = RA_MOVE;
    ra.si = si;
    ra.dir = dir;
    ra.why = why;
}

/* what a pulse of sensor si found, once known (a fix or no fix) */
APP_HOT void sensor_outcome(int si, int init, int fixed)
{
    sensor_t *s = &sens[si];
    if (fixed)
        s->init_misses = 0;
    if (!running) /* STOP closes pulses: no re-aim restarts the sonar core */
        return;
    if (fixed) { /* outside the confidence interval round the axis: one element toward it */
        if (s->last_dev > REAIM_BANG || s->last_dev < -REAIM_BANG)
            request(si, s->last_dev > 0 ? 1 : -1, 1);
    } else if (init && ++s->init_misses >= LOST_PINGS) { /* track lost */
        s->init_misses = 0;
        if (s->last_side != 0)
            request(si, s->last_side, 2);
    }
}

static void write_group(const app_sensor_t *c, const sensor_t *s)
{
    VS_REG(c->vs, TX_MASK) = s->tx_mask;
    VS_REG(c->vs, RX_MASK) = s->rx_mask;
    for (int k = 0; k < c->n_tx; k++)
        table_write_delay(c->vs, s->tx[k], c->delay[k]);
}

static void report(uint32_t vs, uint32_t shift, uint32_t err)
{
    ms_report(0x30000000u | ((reaims & 0xFFu) << 20) | (vs << 16) | (shift << 8) | (err << 4)
              | (uint32_t)ra.why);
}

static int near_wrap(void)
{
    for (int i = 0; i < n_sens; i++)
        if (last_pulse_id[cfgs[i].vs] > 0xFFFFu - ID_WRAP_MARGIN)
            return 1;
    return 0;
}

static void put_back(uint32_t err)
{
    const app_sensor_t *c = &cfgs[ra.si];
    for (int k = 0; k < c->n_tx; k++)
        table_write_delay(c->vs, ra.nw.tx[k], 0u);
    write_group(c, &sens[ra.si]);
    report(c->vs, (uint32_t)sens[ra.si].shift, err);
    ra.state = RA_IDLE;
}

static void take_over(uint32_t now)
{
    sensor_t *s = &sens[ra.si];
    cut_open(-1, now); /* the old table's open pulses: the scheduler dropped their windows */
    ms_report(0x50000000u | (frame_seq & 0x0FFFFFFFu)); /* first frame of the new table */
    uint32_t t = now32();
    sensor_prepare(&ra.nw, &cfgs[ra.si], &ra.nw.arr);
    t = now32() - t;
    stat_max(MS_FW_STAT_CYCLES_REAIM_MAX, t);
    stat_max(MS_FW_STAT_CYCLES_SLICE_MAX, t);
    word_aside += t;
    ra.nw.last_side = s->last_side;
    ra.nw.last_dev = 0;
    for (int i = 0; i < n_sens; i++)
        sens[i].init_misses = 0;
    ra.nw.init_misses = 0;
    t_taken = now;
    taken_any = 1;
    prev = *s;
    prev_si = ra.si;
    *s = ra.nw;
    reaims++;
    MS_SOC(SCRATCH) = reaims;
    report(cfgs[ra.si].vs, (uint32_t)s->shift, 0u);
    ra.state = RA_IDLE;
}

APP_HOT int reaim_restart_seen(uint32_t id, uint32_t init, uint32_t now)
{
    if (ra.state != RA_WAIT || id != 0u || !init)
        return 0;
    take_over(now);
    return 1;
}

/* idle: the next slice of a move; every pass: whether the hold is over. Returns 1 when it
 * worked. */
APP_HOT int reaim_step(int idle)
{
    uint32_t t = now32();
    const app_sensor_t *c = &cfgs[ra.si];
    switch (ra.state) {
    case RA_MOVE: {
        if (!idle || near_wrap())
            return 0;
        prev_si = -1; /* runs with the job queue empty: no job of an older placement waits */
        sensor_place(&ra.nw, c, (sens[ra.si].shift + ra.dir + APP_RING_N) % APP_RING_N);
        for (int k = 0; k < c->n_tx; k++)
            table_write_delay(c->vs, sens[ra.si].tx[k], 0u);
        write_group(c, &ra.nw);
        uint32_t refused = table_check();
        if (refused) {
            put_back(refused & 0xFu);
            break;
        }
        MS_SONAR(CTRL) = SONAR_REGS__CTRL__ENABLE_bm | SONAR_REGS__CTRL__HOLD_bm;
        ra.t_hold = now32();
        ra.state = RA_HOLD;
        break;
    }
    case RA_HOLD:
        if (MS_SONAR(STATUS) & SONAR_REGS__STATUS__RUNNING_bm) {
            if (t - ra.t_hold <= APPLY_WAIT)
                return 0;
            MS_SONAR(CTRL) = 0u; /* the hold never ended: stop, and load all the same */
        }
        table_load_start();
        ra.t_hold = now32();
        ra.state = RA_WAIT;
        break;
    case RA_WAIT:
        if (t - ra.t_hold <= APPLY_WAIT)
            return 0;
        take_over(t);
        break;
    default:
        return 0;
    }
    stat_max(MS_FW_STAT_CYCLES_REAIM_MAX, now32() - t);
    return 1;
}

/* STOP or START: a move under way is dropped (the registers keep what was written last) */
void reaim_cancel(void) { ra.state = RA_IDLE; }

int reaim_idle(void) { return ra.state == RA_IDLE; }
