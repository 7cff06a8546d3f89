/*
 * ms_geom_internal.h - what the geometry library's C files share; callers include ms_geom.h.
 *
 * The general path (setup, fit, point, wall, classify, cylinder) is one source for every
 * number format: `real` is double, float or Q32.32 int64 and every product / quotient / root
 * goes through MUL / DIV / SQRT (ms_geom_f_arith.h, ms_geom_q_arith.h). What else differs per
 * format is a function of the "format interface" below, implemented once per format
 * (ms_geom_f_math.c, ms_geom_q_math.c), and the fast path (ms_geom_q_fast.c; the float formats
 * have none: ms_geom_f_fast.c). The build compiles the common files plus one format's.
 */
#ifndef MS_GEOM_INTERNAL_H
#define MS_GEOM_INTERNAL_H

#include "ms_geom.h"

#include <stddef.h>

/* The per-pulse code (ms_fix and the Q fast path it runs) goes into one section of its own, so
 * it lies contiguous in the image (~11 KB) and does not evict itself from a direct-mapped
 * instruction cache (VexRiscv_Full with the 16 KiB cache of scripts/gen_vex_icache.py:
 * firmware/README.md). Only the placement changes, not the code. */
#if defined(__riscv) && defined(__GNUC__)
#define MS_HOT __attribute__((section(".text.ms_hot")))
#else
#define MS_HOT
#endif

/* cylinder: 'same solution' widening of the reduced-precision formats (CYL_SAME; a tuning knob) */
#ifndef CYL_SAME_K
#define CYL_SAME_K 1e-6
#endif

/* The number format's layer (real, ang, MUL, DIV, ...): the one place the general path's source
 * depends on MS_GEOM_ARITH (it is compiled for every format). */
#if MS_GEOM_ARITH == MS_ARITH_Q
#include "ms_geom_q_arith.h"
#else
#include "ms_geom_f_arith.h"
#endif

#define ABS(a) ((a) < 0 ? -(a) : (a))

/* ======================================================================================
 * the problem of one solve (source shifted to the origin) and a fitted candidate
 * ====================================================================================== */
typedef struct {
    real x, y;
} v2;

typedef struct {
    int n;
    v2 c[MS_MAX_RX]; /* receivers relative to the source */
    real r[MS_MAX_RX];
    real scale; /* max R */
    int has_axis;
    ang axis, fov;
    real tol, max_gdop;
    int no_tol, no_gdop;
} prob;

typedef struct {
    real p[2];
    real rms, gd;
    int gd_inf, ok;
} cand;

enum { MODEL_POINT = 0, MODEL_WALL = 1 };

/* ======================================================================================
 * format interface: one implementation per number format (ms_geom_f_math.c, ms_geom_q_math.c).
 * Lengths in `real` are metres (Q: Q32.32 metres), angles `ang` (Q: binary angle, 2^32 per turn).
 * ====================================================================================== */
real msg_hyp(real x, real y);          /* |(x, y)| */
real msg_hyp3(real x, real y, real z); /* |(x, y, z)| */
real msg_cost(const real *f, int n);   /* a fit's cost from its n residuals (float: sum f^2; Q: |f|) */
real msg_rms(real cost, int n);        /* RMS residual from msg_cost */
ang msg_ang_absdiff(ang a, ang b);     /* |a - b| wrapped to half a turn */
/* Gauss-Newton step minimising |J d + f| over n rows (column-scaled normal equations) and
 * gdop = sqrt(trace((J^T J)^-1)); *gd_inf when J^T J is singular (step and gd then 0) */
void msg_ls_step(real (*J)[2], const real *f, int n, real step[2], real *gd, int *gd_inf);
/* msg_ls_step's first half, the same in every format (each format solves it its own way): the
 * column norms s0, s1 of J (1 for a zero column), then with the columns scaled by them
 * [a b; b d] = J^T J and (g0, g1) = -J^T f. Inline: one call site per format. */
static inline void msg_ls_normal(real (*J)[2], const real *f, int n, real *s0_out, real *s1_out,
                                 real *a_out, real *b_out, real *d_out, real *g0_out, real *g1_out)
{
    real s0 = 0, s1 = 0, a = 0, b = 0, d = 0, g0 = 0, g1 = 0, j0, j1;
    int i;
    for (i = 0; i < n; i++) {
        s0 += MUL(J[i][0], J[i][0]);
        s1 += MUL(J[i][1], J[i][1]);
    }
    s0 = SQRT(s0);
    s1 = SQRT(s1);
    if (!(s0 > 0)) s0 = K(1.0);
    if (!(s1 > 0)) s1 = K(1.0);
    for (i = 0; i < n; i++) {
        j0 = DIV(J[i][0], s0);
        j1 = DIV(J[i][1], s1);
        a += MUL(j0, j0);
        b += MUL(j0, j1);
        d += MUL(j1, j1);
        g0 -= MUL(j0, f[i]);
        g1 -= MUL(j1, f[i]);
    }
    *s0_out = s0, *s1_out = s1, *a_out = a, *b_out = b, *d_out = d, *g0_out = g0, *g1_out = g1;
}
/* cylinder: cos and sin of th (radians) */
void msg_cossin(real th, real *c, real *s);
/* cylinder: 1 when the bearing th (radians) lies more than fov + 90 deg off the axis */
int msg_off_axis(real th, ang axis, ang fov);

/* ======================================================================================
 * general path (step by step the algorithm of host/multisonar/geometry.py)
 * ====================================================================================== */
/* ms_geom_setup.c: fill P from the inputs (without options); MS_OK or MS_BADIN */
int msg_setup(prob *P, const ms_vec2 *rx, const ms_len_t *path, int n, ms_vec2 src, int min_n);
void msg_set_axis(prob *P, const ms_vec2 *rx, int mode, ms_ang_t axis);
void msg_apply_opts(prob *P, const ms_vec2 *rx, const ms_opts *o);
/* the general path's problem for a prepared array (its options applied) */
int msg_prepared_setup(const ms_array *a, const ms_len_t *path, int min_n, prob *P);
int msg_short_check(const prob *P); /* MS_SHORT when a path is not longer than its baseline |c_i| */

/* ms_geom_fit.c: two-parameter damped Gauss-Newton from p0 and the candidate choice */
void msg_gauss_newton(int kind, const prob *P, const real p0[2], int iters, cand *out);
void msg_no_fit(int kind, const prob *P, const real p0[2], cand *out);
int msg_select(const prob *P, const cand *k, int pre, int *idx_out);

/* ms_geom_point.c, ms_geom_wall.c: the reason; *best gets the chosen candidate */
int msg_point_core(const prob *P, cand *best);
int msg_wall_core(const prob *P, cand *best);
void msg_finish_point(const prob *P, ms_vec2 src, int reason, const cand *c, ms_point_fit *out);
void msg_finish_wall(const prob *P, ms_vec2 src, int reason, const cand *c, ms_wall_fit *out);

/* ======================================================================================
 * fast path of the format (ms_geom_q_fast.c; float: ms_geom_f_fast.c, where every call
 * declines)
 * ====================================================================================== */
/* ms_prepare's last step, from what it stored in a: set a->fast and the fast path's fields;
 * returns a->fast */
int msg_fast_prepare(ms_array *a);
/* a prepared point / wall fit by the fast path: 1 when it answered (out filled), 0 -> general */
int msg_fast_point(const ms_array *a, const ms_len_t *path, ms_point_fit *out);
int msg_fast_wall(const ms_array *a, const ms_len_t *path, ms_wall_fit *out);
/* ms_fix's fast path alone: the kind, or MS_FIX_DECLINED (out's fields then unspecified and
 * *reason_out the input check's MS_OK / MS_BADIN for the general path) */
int msg_fix_fast(const ms_array *a, const ms_len_t *path, ms_class *out, int *reason_out);

/* the start of every fix: out's kind, flags and chi-squares cleared, the thresholds set; returns
 * MS_BADIN (bad array, N < 3, no path, sigma <= 0) or MS_OK. Always inlined: the fast fix's
 * code is then that of the same lines written out in it. */
static inline __attribute__((always_inline)) int fix_begin(const ms_array *a, const ms_len_t *path, ms_class *out)
{
    int i;
    out->kind = MS_KIND_UNCERTAIN;
    out->accepted = 0;
    for (i = 0; i < 3; i++) {
        out->chi2[i] = 0;
        out->thr[i] = a->thr[i];
    }
    /* sigma > 0 <=> LEN_IN(sigma) > 0; LEN_IN (a 64-bit division in Q) only on the general path */
    return (a->bad || a->n < 3 || !path || a->sigma <= 0) ? MS_BADIN : MS_OK;
}

/* the edge / wall / uncertain rule of geometry.classify on two chi-squares (any one scale for
 * x2p, x2w, tp, tw, gap_lim); inlined into both fixes, the general (ms_geom_classify.c) and the
 * fast one (ms_geom_q_fast.c) */
MS_HOT static inline void decide(ms_class *out, int sp, int sw, real x2p, real x2w, real tp, real tw,
                                 real gap_lim)
{
    int e = (sp == MS_OK || sp == MS_AMBIG) && x2p <= tp;
    int w = (sw == MS_OK || sw == MS_AMBIG) && x2w <= tw;
    out->accepted = (uint8_t)(e | (w << 1));
    if (e && !w) out->kind = MS_KIND_EDGE;
    else if (w && !e) out->kind = MS_KIND_WALL;
    else if (e && w) {
        real gap = x2p - x2w;
        if (gap < -gap_lim) out->kind = MS_KIND_EDGE;
        else if (gap > gap_lim) out->kind = MS_KIND_WALL;
    }
}

#endif
