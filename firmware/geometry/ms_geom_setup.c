/*
 * ms_geom_setup.c - problem set-up of the general path and the per-sensor preparation
 * (ms_prepare), every number format: option defaults, the inputs shifted to the source, the
 * axis, the classification thresholds; the fast path's own preparation is the format's
 * (msg_fast_prepare: ms_geom_q_fast.c).
 */
#include "ms_geom_internal.h"

void ms_opts_default(ms_opts *o)
{
    o->tol = DEF_TOL;
    o->max_gdop = DEF_MAX_GDOP;
    o->fov = DEF_FOV;
    o->axis_mode = MS_AXIS_AUTO;
    o->no_tol = 0;
    o->no_gdop = 0;
    o->axis = 0;
}

void ms_class_opts_default(ms_class_opts *o)
{
    ms_opts d;
    ms_opts_default(&d);
    o->fov = d.fov;
    o->axis_mode = MS_AXIS_AUTO;
    o->axis = 0;
    o->z = DEF_Z;
}

/* returns MS_OK or MS_BADIN; fills P (without opts) */
int msg_setup(prob *P, const ms_vec2 *rx, const ms_len_t *path, int n, ms_vec2 src, int min_n)
{
    int i;
    real sx, sy;
    if (n < min_n || n > MS_MAX_RX || !rx || !path) return MS_BADIN;
    sx = LEN_IN(src.x);
    sy = LEN_IN(src.y);
    P->n = n;
    P->scale = 0;
    if (!ISFIN(sx) || !ISFIN(sy)) return MS_BADIN;
    for (i = 0; i < n; i++) {
        real cx = LEN_IN(rx[i].x), cy = LEN_IN(rx[i].y), r = LEN_IN(path[i]);
        if (!ISFIN(cx) || !ISFIN(cy) || !ISFIN(r) || !(r > 0)) return MS_BADIN;
        P->c[i].x = cx - sx;
        P->c[i].y = cy - sy;
        P->r[i] = r;
        if (r > P->scale) P->scale = r;
    }
    return MS_OK;
}

/* the axis: as set, or (MS_AXIS_AUTO) the mean outward direction of the receivers seen from
 * the robot origin when that mean is long enough (>= 0.3), else none */
void msg_set_axis(prob *P, const ms_vec2 *rx, int mode, ms_ang_t axis)
{
    int i, cnt = 0;
    real mx = 0, my = 0;
    P->has_axis = 0;
    P->axis = 0;
    if (mode == MS_AXIS_SET) {
        if (!ANG_ISFIN(axis)) return;
        P->has_axis = 1;
        P->axis = axis;
        return;
    }
    if (mode != MS_AXIS_AUTO) return;
    for (i = 0; i < P->n; i++) {
        real cx = LEN_IN(rx[i].x), cy = LEN_IN(rx[i].y), nr = msg_hyp(cx, cy);
        if (nr > K(1e-9)) {
            mx += DIV(cx, nr);
            my += DIV(cy, nr);
            cnt++;
        }
    }
    if (cnt == 0) cnt = 1;
    mx /= cnt;
    my /= cnt;
    if (msg_hyp(mx, my) >= K(0.3)) {
        P->has_axis = 1;
        P->axis = ATAN2(my, mx);
    }
}

void msg_apply_opts(prob *P, const ms_vec2 *rx, const ms_opts *o)
{
    ms_opts d;
    if (!o) {
        ms_opts_default(&d);
        o = &d;
    }
    P->tol = LEN_IN(o->tol);
    P->max_gdop = NUM_IN(o->max_gdop);
    P->no_tol = o->no_tol;
    P->no_gdop = o->no_gdop;
    P->fov = o->fov;
    msg_set_axis(P, rx, o->axis_mode, o->axis);
}

int msg_short_check(const prob *P)
{
    int i;
    for (i = 0; i < P->n; i++) {
        real cn = msg_hyp(P->c[i].x, P->c[i].y);
        if (P->r[i] <= MUL(cn, K(1.0 + 1e-15))) return MS_SHORT;
    }
    return MS_OK;
}

/* Wilson-Hilferty chi-square quantile for k degrees of freedom at normal quantile z */
static real chi2_quantile(real z, int k)
{
    real ks, h, t;
    if (k <= 0) return 0;
    ks = K(1.0) * k;
    h = DIV(K(2.0), 9 * ks);
    t = K(1.0) - h + MUL(z, SQRT(h));
    return MUL(MUL(MUL(t, t), t), ks);
}

int ms_prepare(ms_array *a, const ms_vec2 *rx, int n, ms_vec2 src, const ms_opts *opts,
               const ms_class_opts *copts, ms_len_t noise_sigma)
{
    ms_class_opts dc;
    real z;
    int i;
    if (!copts) {
        ms_class_opts_default(&dc);
        copts = &dc;
    }
    if (opts) a->opts = *opts;
    else ms_opts_default(&a->opts);
    a->n = n;
    a->src = src;
    a->sigma = noise_sigma;
    a->fast = 0;
    a->bad = n < 2 || n > MS_MAX_RX || !rx;
    for (i = 0; i < MS_MAX_RX; i++) {
        a->rx[i].x = (!a->bad && i < n) ? rx[i].x : 0;
        a->rx[i].y = (!a->bad && i < n) ? rx[i].y : 0;
    }
    z = NUM_IN(copts->z);
    a->thr[0] = a->thr[1] = NUM_OUT(chi2_quantile(z, n - 2));
    a->thr[2] = NUM_OUT(n == 3 ? K(1e-6) : chi2_quantile(z, n - 3));
    return msg_fast_prepare(a);
}

int msg_prepared_setup(const ms_array *a, const ms_len_t *path, int min_n, prob *P)
{
    int reason = a->bad ? MS_BADIN : msg_setup(P, a->rx, path, a->n, a->src, min_n);
    if (reason == MS_OK) msg_apply_opts(P, a->rx, &a->opts);
    return reason;
}
