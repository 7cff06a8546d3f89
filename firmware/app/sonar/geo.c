/* The geometry path (best effort, bounded): a closed pulse with >= 3 first echoes becomes a job
 * in this queue, run by the main loop when no event and no command waits; its record goes out
 * in a frame of its own (MS_FRAME_GEO, no ToF records). Queue full: the fix is skipped and counted.
 * A job runs ms_fix_fast only (the closed-form 3-receiver path, a few thousand cycles): what it
 * declines (the general path would take millions of cycles) is counted, never solved here. */
#include "app.h"

typedef struct {
    uint8_t vs, seq, flags;
    uint32_t firsts, t0;
    int shift;
    int32_t first_tof[APP_MAX_GROUP];
} geo_job_t;
static geo_job_t geo_q[GEO_JOBS];
static uint32_t geo_head, geo_tail;

/* mailbox 0x6 per geometry job: what happened (0 fix, 1 skipped: queue full, 2 declined: the
 * fast path does not solve it, 3 stale: the sensor was re-aimed since) << 24 | cycles */
APP_HOT static void geo_report(uint32_t what, uint32_t cycles)
{
    fw_stats[MS_FW_STAT_GEO_FIXES + what]++;
    stat_max(MS_FW_STAT_CYCLES_GEO_MAX, cycles);
    ms_report(0x60000000u | (what << 24) | (cycles > 0xFFFFFFu ? 0xFFFFFFu : cycles));
}

static int32_t div_round(int32_t v, int32_t d)
{
    return v >= 0 ? (v + d / 2) / d : -((-v + d / 2) / d);
}

static int32_t sat16(int32_t v, int32_t lo, int32_t hi) { return v < lo ? lo : v > hi ? hi : v; }

static uint32_t bang16(uint32_t a) { return ((a + 0x8000u) >> 16) & 0xFFFFu; }

APP_HOT void geo_enqueue(const group_t *g)
{
    const int si = vs_index[g->vs];
    const app_sensor_t *c = &cfgs[si];
    if (g->flags & MS_FRAME_LOST) /* no fix from incomplete data, and no verdict either */
        return;
    if (__builtin_popcount(g->firsts) < 3 || c->n_rx > APP_MAX_GROUP || c->n_tx > APP_MAX_GROUP) {
        sensor_outcome(si, g->flags & MS_FRAME_INIT_PING, 0); /* < 3 first echoes: no fix */
        return;
    }
    if (geo_tail - geo_head >= GEO_JOBS) {
        geo_report(1u, 0u);
        return;
    }
    geo_job_t *j = &geo_q[geo_tail % GEO_JOBS];
    j->vs = g->vs;
    j->seq = g->seq;
    j->flags = g->flags & MS_FRAME_INIT_PING;
    j->firsts = g->firsts;
    j->t0 = g->t0;
    j->shift = sens[si].shift;
    for (int k = 0; k < c->n_rx; k++)
        j->first_tof[k] = g->first_tof[k];
    geo_tail++;
}

/* the record of a fix (docs/protocol.md section 6, geometry record): class = kind + 1, a wall
 * its foot point / distance / normal, an edge its position / range / bearing; mm and 16-bit
 * binary angles rounded; quality = 255 * (1 - chi2 / threshold) of the chosen model */
APP_HOT static uint32_t geo_record(const ms_class *cl, int nf, uint32_t geo[4], uint32_t *bearing)
{
    uint32_t cls = (uint32_t)cl->kind + 1u, quality = 0;
    int32_t x = 0, y = 0, rng = 0, res = 0;
    uint32_t brg = 0, nrm = 0;
    int k = cls == 2u ? 1 : 0;
    if (cls == 1u || cls == 2u) { /* 255 * (1 - chi2 / threshold), Q16.16 in; 32-bit division */
        uint32_t thr = cl->thr[k] > 0 ? (uint32_t)cl->thr[k] : 0u;
        uint32_t chi = cl->chi2[k] < 0 ? 0u : (uint32_t)cl->chi2[k] < thr ? (uint32_t)cl->chi2[k] : thr;
        while (thr >= (1u << 23)) {
            thr >>= 1;
            chi >>= 1;
        }
        if (thr > 0)
            quality = 255u - (255u * chi + thr / 2u) / thr;
    }
    if (cls == 2u && cl->wall.valid) {
        x = cl->wall.foot_x; y = cl->wall.foot_y; rng = cl->wall.distance; res = cl->wall.residual;
        brg = nrm = (uint32_t)cl->wall.normal_angle;
    } else if (cl->point.valid) {
        x = cl->point.x; y = cl->point.y; rng = cl->point.range; res = cl->point.residual;
        brg = (uint32_t)cl->point.bearing;
    } else {
        cls = 4u;
        quality = 0;
    }
    geo[0] = ((uint32_t)sat16(div_round(x, 1000), -32768, 32767) & 0xFFFFu)
           | ((uint32_t)sat16(div_round(y, 1000), -32768, 32767) << 16);
    geo[1] = ((uint32_t)sat16(div_round(rng, 1000), 0, 65535)) | (bang16(brg) << 16);
    geo[2] = bang16(nrm) | (quality << 16) | (cls << 24);
    geo[3] = (uint32_t)nf | ((uint32_t)sat16(res, 0, 65535) << 16);
    *bearing = brg;
    return cls;
}

/* one geometry job: the fix (fast path only: bounded), its frame, the re-aiming input */
APP_HOT static void run_geo_job(const geo_job_t *j)
{
    uint32_t t = now32();
    const int si = vs_index[j->vs];
    if (si < 0)
        return;
    const app_sensor_t *c = &cfgs[si];
    const sensor_t *s = placement_of(si, j->shift);
    if (!s) { /* re-aimed twice since: its groups' array is gone */
        geo_report(3u, now32() - t);
        return;
    }
    int nf = __builtin_popcount(j->firsts);
    ms_class cl;
    if (nf != c->n_rx) { /* a subset of the receivers: only the general path solves it */
        geo_report(2u, now32() - t);
        return;
    }
    ms_len_t path[APP_MAX_GROUP];
    for (int k = 0; k < c->n_rx; k++)
        path[k] = (ms_len_t)(((uint64_t)(uint32_t)j->first_tof[k] * path_k + 0x80000000u) >> 32)
                + c->path_offset_um;
    if (ms_fix_fast(&s->arr, path, &cl) == MS_FIX_DECLINED) {
        geo_report(2u, now32() - t);
        return;
    }
    uint32_t geo[4], brg;
    uint32_t cls = geo_record(&cl, nf, geo, &brg);
    if (par_geometry)
        send_packet(MS_FRAME_GEO | j->flags, j->t0, j->vs, j->seq, 0u, 0, 0u, 1u, geo);
    int fixed = cls == 1u || cls == 2u;
    geo_report(0u, now32() - t);
    if (s != &sens[si]) /* a pulse of the groups before a move: no input for the next one */
        return;
    if (fixed) { /* re-aiming input: the fix's angle against the sensor's axis */
        sens[si].last_dev = (int32_t)(brg - s->axis);
        sens[si].last_side = sens[si].last_dev > 0 ? 1 : -1;
    }
    sensor_outcome(si, j->flags & MS_FRAME_INIT_PING, fixed);
}

APP_HOT int geo_step(void)
{
    if (geo_head == geo_tail)
        return 0;
    geo_job_t j = geo_q[geo_head % GEO_JOBS];
    geo_head++;
    run_geo_job(&j);
    return 1;
}

void geo_clear(void) { geo_head = geo_tail; }

int geo_pending(void) { return geo_head != geo_tail; }
