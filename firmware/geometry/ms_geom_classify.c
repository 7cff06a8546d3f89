/*
 * ms_geom_classify.c - the fix (both fits + the edge / wall / uncertain decision of
 * geometry.classify, without its cylinder model), every number format: ms_fix tries the
 * format's fast path (msg_fix_fast) and falls back to the general path here; ms_classify is
 * ms_prepare + ms_fix.
 */
#include "ms_geom_internal.h"

/* ms_fix's general path (the step-by-step port): out of the per-pulse section */
static __attribute__((noinline)) int fix_general(const ms_array *a, const ms_len_t *path, int reason, ms_class *out)
{
    prob P;
    cand cp = {{0, 0}, 0, 0, 1, 0}, cw = {{0, 0}, 0, 0, 1, 0};
    int sp = MS_BADIN, sw = MS_BADIN, i, n = a->n;
    real sig = LEN_IN(a->sigma), x2[2], thr[2];
    if (reason == MS_OK && !(sig > 0 && ISFIN(sig))) reason = MS_BADIN;
    if (reason == MS_OK) reason = msg_setup(&P, a->rx, path, n, a->src, 3);
    out->reason = (uint8_t)reason;
    if (reason == MS_OK) {
        P.no_tol = P.no_gdop = 1;
        P.tol = P.max_gdop = 0;
        P.fov = a->opts.fov;
        msg_set_axis(&P, a->rx, a->opts.axis_mode, a->opts.axis);
        sp = msg_point_core(&P, &cp);
        sw = msg_wall_core(&P, &cw);
        for (i = 0; i < 2; i++) {
            real q = DIV(i == 0 ? cp.rms : cw.rms, sig);
            x2[i] = MUL(q, q) * n;
            if (!ISFIN(x2[i]) || x2[i] > BIGV) x2[i] = BIGV;
            out->chi2[i] = NUM_OUT(x2[i]);
            thr[i] = NUM_IN(a->thr[i]);
        }
        decide(out, sp, sw, x2[0], x2[1], thr[0], thr[1], K(9.21));
    }
    msg_finish_point(&P, a->src, sp, &cp, &out->point);
    msg_finish_wall(&P, a->src, sw, &cw, &out->wall);
    return out->kind;
}

int ms_fix(const ms_array *a, const ms_len_t *path, ms_class *out)
{
    int reason, kind = msg_fix_fast(a, path, out, &reason);
    return kind != MS_FIX_DECLINED ? kind : fix_general(a, path, reason, out);
}

int ms_classify(const ms_vec2 *rx, const ms_len_t *path, int n, ms_vec2 src, ms_len_t noise_sigma,
                const ms_class_opts *opts, ms_class *out)
{
    ms_array a;
    ms_opts o;
    ms_class_opts d;
    if (!opts) {
        ms_class_opts_default(&d);
        opts = &d;
    }
    ms_opts_default(&o);
    o.fov = opts->fov;
    o.axis_mode = opts->axis_mode;
    o.axis = opts->axis;
    ms_prepare(&a, rx, n, src, &o, opts, noise_sigma);
    return ms_fix(&a, path, out);
}
