/* Worst-case cycles of the per-pulse geometry on the soft-core over random inputs (issue #26).
 *
 * The real-time firmware (sonar_app.c) runs ms_fix_fast once per pulse and ms_prepare once per
 * virtual sensor; issue #26 wants the worst case of each over >= 1e5 random inputs, measured
 * on the SoC. bench_geom.c times 27 fixed cases; 64 KiB of RAM cannot hold 1e5, so here the
 * inputs are generated on the core (seeded xorshift64*, untimed integer math) and every call is
 * timed with the SoC cycle timer (counter overhead subtracted, as bench_geom.c). Kept on the
 * core: per outcome the count, min, max, sum and a histogram, the outcome per input class, the
 * max of the first fix after each ms_prepare (whose code evicts some of the fix's cache lines)
 * and of the others, the inputs of the worst call of each outcome (replayable: positions,
 * paths and the generator state) and every impossible answer (count + the first one). One
 * report through the mailbox at the end (scripts/bench_fw_random.py decodes it;
 * tests/rtl/test_ms_soc_random.py decode_report documents the words), plus a progress word
 * every BENCH_PROGRESS fixes.
 *
 * Virtual sensors (as sonar_app's sensor_setup): 3 adjacent receivers of the 24-element ring
 * (ms_layout.h, in a random order), the source at the middle element or at the ring centre
 * (demo's phased front group), ms_opts_default / ms_class_opts_default (auto axis, fov 60 deg),
 * sigma = 1 us of sound at 20 degC = 343 um. BENCH_SENSORS sensors, each prepared (timed) and
 * then used for BENCH_CALLS / BENCH_SENSORS fixes.
 * Inputs per fix (paths in um, what sonar_app hands over):
 *   point    45 %: a reflector 0.1..8 m from the middle element (3/4 in its front half plane,
 *            1/4 any direction: beside, behind, inside the ring), path = |p - s| + |p - rx_i|;
 *   wall     35 %: a foot point drawn the same way, path = |2 f - s - rx_i| (mirror image);
 *            both with noise per path, uniform +-A, A = 0 / 4 um / 343 um (1 sigma) / 3.4 mm;
 *   garbage  12 %: independent paths 0..33.5 m, too short (< 0.8 m), three equal, or a point /
 *            wall path triple with one path moved by up to 0.1 m (inconsistent);
 *   extreme   8 %: each path 0, +-1, INT32_MIN / MAX, the fast path's length limit 2^25 um
 *            and its neighbours, the baseline |rx_i - s| (+0..2), or random.
 * Every input is valid for ms_fix_fast (any int32 path; no UB). Checked per answer: the return
 * value is MS_FIX_DECLINED or a kind of edge / wall / uncertain equal to out->kind; reason OK;
 * accepted bits and the kind as decide() sets them; each fit's valid == (reason == OK), reason
 * in range; chi2 >= 0, cylinder chi2 0, thresholds the array's; a valid fit's range / distance
 * > 0, residual, gdop >= 0. ms_prepare must return 0 or 1.
 *
 * Build: mk/bench_random.mk (make build/fw/bench_fix_random[-CALLS-SENSORS-SEED[-cold]].hex).
 * -DBENCH_FIX_COLD: FENCE.I before every timed call (VexRiscv's instruction cache emptied: every
 * line of the call fetched from RAM, the cold worst case). Otherwise the cache holds whatever
 * the generator left, as in sonar_app, where other code runs between two fixes. */
#include <limits.h>
#include <stdint.h>

#include "ms_geom.h"
#include "ms_hw.h"
#include "ms_isqrt.h"
#include "ms_layout.h"

#ifndef BENCH_CALLS
#define BENCH_CALLS 100000
#endif
#ifndef BENCH_SENSORS
#define BENCH_SENSORS 1000
#endif
#ifndef BENCH_SEED
#define BENCH_SEED 1
#endif
#define BENCH_PROGRESS 10000 /* a progress word every that many fixes */

#if BENCH_SENSORS < 1 || BENCH_CALLS < BENCH_SENSORS
#error "need 1 <= BENCH_SENSORS <= BENCH_CALLS"
#endif

/* mailbox: progress words before the report, then the report (decode_report) */
#define RPT_PROGRESS 0xA0000000u /* | fixes done */
#define RPT_MAGIC 0x52460002u    /* "RF", report version 2 */
#define RPT_DONE 0x52464E44u
#define SIGMA_UM 343             /* sonar_app: (sound_um_s(2000) + 500000) / 1000000 */
/* histograms (cycles): NFINE bins of BIN, NCOARSE bins of COARSE * BIN, one overflow bin */
#define COARSE 8
#define FIX_BIN 64               /* ms_fix_fast: 0..16383 by 64, ..81919 by 512 (PicoRV32: ~24 k) */
#define FIX_NFINE 256
#define FIX_NCOARSE 128
#define PREP_BIN 256             /* ms_prepare: 0..65535 by 256, ..327679 by 2048 */
#define PREP_NFINE 256
#define PREP_NCOARSE 128
#define FIX_NBINS (FIX_NFINE + FIX_NCOARSE)
#define PREP_NBINS (PREP_NFINE + PREP_NCOARSE)
#define LEN_LIMIT (1 << 25)      /* fast path length limit (ms_geom_q_fast.c FQ_LIM >> FQ_SH), um */

enum { OUT_EDGE, OUT_WALL, OUT_UNCERTAIN, OUT_DECLINED, NOUT };
enum { CLS_POINT, CLS_WALL, CLS_GARBAGE, CLS_EXTREME, NCLS };
/* what an impossible answer violated (the first one is reported) */
enum { BAD_RETURN = 1, BAD_KIND, BAD_REASON, BAD_ACCEPTED, BAD_FIT_FLAGS, BAD_CHI2, BAD_FIT_VALUES,
       BAD_PREPARE };

typedef struct {
    ms_vec2 rx[3], src;
    ms_vec2 mid;      /* the middle element: reflectors are drawn round it */
    int32_t ax, ay;   /* its outward axis (not normalised: the element position) */
    uint32_t elems;   /* rx elements (8 bits each) | source at the centre << 24 */
} sensor_t;

/* one timed call's statistics */
typedef struct {
    uint32_t count, min, max;
    uint64_t sum;
} stat_t;

/* the inputs of one fix, enough to replay it (REC_WORDS in the report) */
typedef struct {
    uint32_t cycles;
    int32_t ret;
    uint32_t cls, call;
    uint64_t state;   /* the generator before this fix's inputs */
    sensor_t s;
    ms_len_t path[3];
} fix_rec_t;

static uint64_t rng_state;
static stat_t fix_stat[NOUT], prep_stat[2];
static uint32_t fix_hist[NOUT][FIX_NBINS + 1], prep_hist[2][PREP_NBINS + 1];
static uint32_t cls_out[NCLS][NOUT], cls_max[NCLS];
static uint32_t max_after_prepare, max_steady; /* the first fix of a sensor (after its ms_prepare) / the others */
static fix_rec_t worst[NOUT], first_bad;
static uint32_t worst_prep[4], n_bad, bad_what;
static sensor_t worst_prep_sensor;
static uint32_t t_over, n_words;

/* ---------------------------------------------------------------- untimed helpers */
static uint32_t rnd(void) /* xorshift64*, high word */
{
    rng_state ^= rng_state >> 12;
    rng_state ^= rng_state << 25;
    rng_state ^= rng_state >> 27;
    return (uint32_t)((rng_state * 0x2545F4914F6CDD1Dull) >> 32);
}

static uint32_t rnd_below(uint32_t n) { return (uint32_t)(((uint64_t)rnd() * n) >> 32); }

static int32_t rnd_span(int32_t a) { return (int32_t)rnd_below(2u * (uint32_t)a + 1u) - a; } /* -a..a */

/* |(dx, dy)| rounded to the micrometre */
static int32_t dist_um(int64_t dx, int64_t dy)
{
    uint64_t d2 = (uint64_t)(dx * dx + dy * dy);
    uint32_t r = (uint32_t)ms_isqrt64(d2);
    return (int32_t)(d2 - (uint64_t)r * r > r ? r + 1 : r);
}

static void random_sensor(sensor_t *s)
{
    static const uint8_t perm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    int m = (int)rnd_below(MS_NUM_CH), at_centre = (int)rnd_below(2), p = (int)rnd_below(6), i;
    s->elems = (uint32_t)at_centre << 24;
    for (i = 0; i < 3; i++) {
        int e = (m + MS_NUM_CH - 1 + perm[p][i]) % MS_NUM_CH;
        s->rx[i].x = ms_elem_x_um[e];
        s->rx[i].y = ms_elem_y_um[e];
        s->elems |= (uint32_t)e << (8 * i);
    }
    s->mid.x = s->ax = ms_elem_x_um[m];
    s->mid.y = s->ay = ms_elem_y_um[m];
    s->src.x = at_centre ? 0 : s->mid.x;
    s->src.y = at_centre ? 0 : s->mid.y;
}

/* an offset 0.1 m .. rmax from the middle element, rmax 0.5 / 2 / 8 m (near ranges are not
 * rare); 3/4 in the sensor's front half plane, 1/4 anywhere */
static void random_offset(const sensor_t *s, int32_t *dx, int32_t *dy)
{
    static const int32_t rmax_um[3] = {500000, 2000000, 8000000};
    int32_t rmax = rmax_um[rnd_below(3)];
    int front = rnd_below(4) != 0;
    for (;;) {
        int32_t x = rnd_span(rmax), y = rnd_span(rmax);
        int64_t d2 = (int64_t)x * x + (int64_t)y * y;
        if (d2 < 100000ll * 100000ll || d2 > (int64_t)rmax * rmax)
            continue;
        if (front && (int64_t)x * s->ax + (int64_t)y * s->ay <= 0)
            continue;
        *dx = x;
        *dy = y;
        return;
    }
}

static void point_paths(const sensor_t *s, ms_len_t path[3])
{
    int32_t dx, dy, i;
    random_offset(s, &dx, &dy);
    int64_t px = (int64_t)s->mid.x + dx, py = (int64_t)s->mid.y + dy;
    int32_t rho = dist_um(px - s->src.x, py - s->src.y);
    for (i = 0; i < 3; i++)
        path[i] = rho + dist_um(px - s->rx[i].x, py - s->rx[i].y);
}

static void wall_paths(const sensor_t *s, ms_len_t path[3])
{
    int32_t dx, dy, i;
    random_offset(s, &dx, &dy);
    /* mirror image of the source in the wall whose foot (from the source) is mid + d */
    int64_t mx = 2 * ((int64_t)s->mid.x + dx) - s->src.x, my = 2 * ((int64_t)s->mid.y + dy) - s->src.y;
    for (i = 0; i < 3; i++)
        path[i] = dist_um(mx - s->rx[i].x, my - s->rx[i].y);
}

static void add_noise(ms_len_t path[3])
{
    static const int32_t amp_um[4] = {0, 4, SIGMA_UM, 10 * SIGMA_UM};
    int32_t a = amp_um[rnd_below(4)], i;
    for (i = 0; i < 3; i++)
        path[i] += a ? rnd_span(a) : 0;
}

static uint32_t random_paths(const sensor_t *s, ms_len_t path[3])
{
    uint32_t u = rnd_below(100), i;
    if (u < 45) {
        point_paths(s, path);
        add_noise(path);
        return CLS_POINT;
    }
    if (u < 80) {
        wall_paths(s, path);
        add_noise(path);
        return CLS_WALL;
    }
    if (u < 92) {
        switch (rnd_below(4)) {
        case 0: /* independent, up to the fast path's length limit */
            for (i = 0; i < 3; i++)
                path[i] = (ms_len_t)rnd_below(LEN_LIMIT);
            break;
        case 1: /* shorter than (or about) the baseline */
            for (i = 0; i < 3; i++)
                path[i] = (ms_len_t)rnd_below(800000);
            break;
        case 2: /* three equal paths */
            path[0] = path[1] = path[2] = (ms_len_t)rnd_below(rnd_below(2) ? LEN_LIMIT : 2000000);
            break;
        default: /* a consistent triple with one path moved by up to 0.1 m */
            if (rnd_below(2))
                point_paths(s, path);
            else
                wall_paths(s, path);
            path[rnd_below(3)] += rnd_span(100000);
            break;
        }
        return CLS_GARBAGE;
    }
    for (i = 0; i < 3; i++) {
        static const int32_t fixed[9] = {0, 1, -1, INT32_MIN, INT32_MAX, LEN_LIMIT - 1, LEN_LIMIT,
                                         LEN_LIMIT + 1, 7 /* one tick of sound */};
        switch (rnd_below(3)) {
        case 0:
            path[i] = fixed[rnd_below(9)];
            break;
        case 1:
            path[i] = dist_um((int64_t)s->rx[i].x - s->src.x, (int64_t)s->rx[i].y - s->src.y) + (int32_t)rnd_below(3);
            break;
        default:
            path[i] = (ms_len_t)rnd_below(LEN_LIMIT);
            break;
        }
    }
    return CLS_EXTREME;
}

/* 0 or the BAD_* code of the first impossible thing in a fix's answer */
static uint32_t check_fix(const ms_array *arr, int ret, const ms_class *cl)
{
    const ms_point_fit *p = &cl->point;
    const ms_wall_fit *w = &cl->wall;
    if (ret == MS_FIX_DECLINED)
        return 0;
    if (ret != MS_KIND_EDGE && ret != MS_KIND_WALL && ret != MS_KIND_UNCERTAIN)
        return BAD_RETURN;
    if (cl->kind != ret)
        return BAD_KIND;
    if (cl->reason != MS_OK)
        return BAD_REASON;
    if (cl->accepted > 3 || (ret == MS_KIND_EDGE && !(cl->accepted & 1)) ||
        (ret == MS_KIND_WALL && !(cl->accepted & 2)) || (cl->accepted == 0 && ret != MS_KIND_UNCERTAIN) ||
        (cl->accepted == 1 && ret != MS_KIND_EDGE) || (cl->accepted == 2 && ret != MS_KIND_WALL))
        return BAD_ACCEPTED;
    if (p->valid > 1 || w->valid > 1 || p->reason >= MS_NREASONS || w->reason >= MS_NREASONS ||
        p->valid != (p->reason == MS_OK) || w->valid != (w->reason == MS_OK))
        return BAD_FIT_FLAGS;
    if (cl->chi2[0] < 0 || cl->chi2[1] < 0 || cl->chi2[2] != 0 || cl->thr[0] != arr->thr[0] ||
        cl->thr[1] != arr->thr[1] || cl->thr[2] != arr->thr[2])
        return BAD_CHI2;
    if ((p->valid && (p->range <= 0 || p->residual < 0 || p->gdop < 0)) ||
        (w->valid && (w->distance <= 0 || w->residual < 0 || w->gdop < 0)))
        return BAD_FIT_VALUES;
    return 0;
}

static void account(stat_t *st, uint32_t *hist, uint32_t bin, uint32_t nfine, uint32_t nbins, uint32_t cyc)
{
    uint32_t b = cyc / bin;
    if (b >= nfine)
        b = nfine + (cyc - nfine * bin) / (COARSE * bin);
    if (!st->count || cyc < st->min)
        st->min = cyc;
    if (cyc > st->max)
        st->max = cyc;
    st->count++;
    st->sum += cyc;
    hist[b < nbins ? b : nbins]++;
}

/* cycles from t0, the counter reads' own cost subtracted */
static uint32_t cycles_since(uint64_t t0, uint64_t t1)
{
    uint64_t d = t1 - t0;
    return d > t_over ? (uint32_t)(d - t_over) : 0u;
}

/* ---------------------------------------------------------------- report */
static void put(uint32_t w)
{
    ms_report(w);
    n_words++;
}

static void put_stat(const stat_t *st, const uint32_t *hist, uint32_t nbins)
{
    uint32_t i;
    put(st->count);
    put(st->min);
    put(st->max);
    put((uint32_t)st->sum);
    put((uint32_t)(st->sum >> 32));
    for (i = 0; i <= nbins; i++)
        put(hist[i]);
}

static void put_sensor(const sensor_t *s) /* 9 words */
{
    int i;
    put(s->elems);
    put((uint32_t)s->src.x);
    put((uint32_t)s->src.y);
    for (i = 0; i < 3; i++) {
        put((uint32_t)s->rx[i].x);
        put((uint32_t)s->rx[i].y);
    }
}

static void put_rec(const fix_rec_t *r) /* REC_WORDS = 18 */
{
    int i;
    put(r->cycles);
    put((uint32_t)r->ret);
    put(r->cls);
    put(r->call);
    put((uint32_t)r->state);
    put((uint32_t)(r->state >> 32));
    put_sensor(&r->s);
    for (i = 0; i < 3; i++)
        put((uint32_t)r->path[i]);
}

#define HDR_WORDS 21
#define REC_WORDS 18
#define STAT_WORDS(nb) (5 + (nb) + 1)
#define REPORT_WORDS (HDR_WORDS + NOUT * STAT_WORDS(FIX_NBINS) + NCLS * NOUT + NCLS + 2 + \
                      2 * STAT_WORDS(PREP_NBINS) + NOUT * REC_WORDS + 4 + 9 + REC_WORDS + 1)

int main(void)
{
    static ms_array arr;
    static sensor_t s;
    ms_opts opts;
    ms_class_opts copts;
    ms_class cl;
    ms_len_t path[3];
    uint64_t t0, t1;
    uint32_t call, sensor = 0, i, o;

    MS_SOC(WDT_TIMEOUT) = 0u; /* minutes of simulated time */
    ms_opts_default(&opts);
    ms_class_opts_default(&copts);
    rng_state = 0x9E3779B97F4A7C15ull ^ ((uint64_t)BENCH_SEED * 0xD1B54A32D192ED03ull);
    if (!rng_state)
        rng_state = 1;

    /* the cost of the counter reads themselves (deterministic: the smallest of a few) */
    t_over = UINT32_MAX;
    for (i = 0; i < 8; i++) {
        t0 = ms_cycles();
        t1 = ms_cycles();
        if (t1 - t0 < t_over)
            t_over = (uint32_t)(t1 - t0);
    }

    for (call = 0; call < BENCH_CALLS; call++) {
        fix_rec_t r;
        uint32_t bad, after_prepare = 0;
        int ret;
        if (call == 0 || (uint64_t)call * BENCH_SENSORS / BENCH_CALLS != sensor) { /* next sensor */
            sensor = (uint32_t)((uint64_t)call * BENCH_SENSORS / BENCH_CALLS);
            after_prepare = 1;
            random_sensor(&s);
#ifdef BENCH_FIX_COLD
            __asm__ volatile(".word 0x0000100f" ::: "memory"); /* fence.i */
#endif
            t0 = ms_cycles();
            ret = ms_prepare(&arr, s.rx, 3, s.src, &opts, &copts, SIGMA_UM);
            t1 = ms_cycles();
            r.cycles = cycles_since(t0, t1);
            o = ret == 1 ? 0u : 1u;
            account(&prep_stat[o], prep_hist[o], PREP_BIN, PREP_NFINE, PREP_NBINS, r.cycles);
            if (ret != 0 && ret != 1) {
                if (!n_bad++) {
                    bad_what = BAD_PREPARE;
                    first_bad.s = s;
                    first_bad.ret = ret;
                    first_bad.call = call;
                }
            }
            if (r.cycles >= worst_prep[0]) {
                worst_prep[0] = r.cycles;
                worst_prep[1] = (uint32_t)ret;
                worst_prep[2] = sensor;
                worst_prep[3] = call;
                worst_prep_sensor = s;
            }
        }
        r.state = rng_state;
        r.cls = random_paths(&s, path);
#ifdef BENCH_FIX_COLD
        __asm__ volatile(".word 0x0000100f" ::: "memory");
#endif
        t0 = ms_cycles();
        ret = ms_fix_fast(&arr, path, &cl);
        t1 = ms_cycles();
        r.cycles = cycles_since(t0, t1);

        o = ret == MS_FIX_DECLINED ? OUT_DECLINED : ret == MS_KIND_EDGE ? OUT_EDGE
          : ret == MS_KIND_WALL ? OUT_WALL : OUT_UNCERTAIN;
        bad = check_fix(&arr, ret, &cl);
        account(&fix_stat[o], fix_hist[o], FIX_BIN, FIX_NFINE, FIX_NBINS, r.cycles);
        cls_out[r.cls][o]++;
        if (r.cycles > cls_max[r.cls])
            cls_max[r.cls] = r.cycles;
        if (after_prepare && r.cycles > max_after_prepare)
            max_after_prepare = r.cycles;
        if (!after_prepare && r.cycles > max_steady)
            max_steady = r.cycles;
        if (bad || r.cycles >= worst[o].cycles) {
            r.ret = ret;
            r.call = call;
            r.s = s;
            for (i = 0; i < 3; i++)
                r.path[i] = path[i];
            if (r.cycles >= worst[o].cycles)
                worst[o] = r;
            if (bad && !n_bad++) {
                bad_what = bad;
                first_bad = r;
            }
        }
        if ((call + 1) % BENCH_PROGRESS == 0)
            ms_report(RPT_PROGRESS | (call + 1));
    }

    put(RPT_MAGIC);
    put(REPORT_WORDS);
    put((uint32_t)BENCH_SEED);
    put(BENCH_CALLS);
    put(BENCH_SENSORS);
    put(t_over);
#ifdef BENCH_FIX_COLD
    put(1u);
#else
    put(0u);
#endif
    put(COARSE);
    put(FIX_BIN);
    put(FIX_NFINE);
    put(FIX_NCOARSE);
    put(PREP_BIN);
    put(PREP_NFINE);
    put(PREP_NCOARSE);
    put(NOUT);
    put(NCLS);
    put(REC_WORDS);
    put(n_bad);
    put(bad_what);
    put(SIGMA_UM);
    put(LEN_LIMIT);
    for (o = 0; o < NOUT; o++)
        put_stat(&fix_stat[o], fix_hist[o], FIX_NBINS);
    for (i = 0; i < NCLS; i++)
        for (o = 0; o < NOUT; o++)
            put(cls_out[i][o]);
    for (i = 0; i < NCLS; i++)
        put(cls_max[i]);
    put(max_after_prepare);
    put(max_steady);
    for (o = 0; o < 2; o++)
        put_stat(&prep_stat[o], prep_hist[o], PREP_NBINS);
    for (o = 0; o < NOUT; o++)
        put_rec(&worst[o]);
    for (i = 0; i < 4; i++)
        put(worst_prep[i]);
    put_sensor(&worst_prep_sensor);
    put_rec(&first_bad);
    put(n_words + 1 == REPORT_WORDS ? RPT_DONE : 0xBADu); /* the decoder checks the length too */
    for (;;) {
    }
}
