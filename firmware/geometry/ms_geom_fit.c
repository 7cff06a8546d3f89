/*
 * ms_geom_fit.c - the two-parameter fit of the general path, every number format: the point
 * and wall models with their Jacobians, damped Gauss-Newton (geometry._gauss_newton) and the
 * choice between the two polished candidates of a receiver pair (geometry._select). The step
 * itself is the format's (msg_ls_step).
 */
#include "ms_geom_internal.h"

/* residuals f and Jacobian J at p: the point model (path = |p| + |p - c_i|) or the wall's
 * (mirror image p: path = |p - c_i|); returns |p| > 0 */
static int model_eval(int kind, const prob *P, const real p[2], real *f, real (*J)[2])
{
    int i;
    real x = p[0], y = p[1], r0 = msg_hyp(x, y), u0x = 0, u0y = 0;
    if (kind == MODEL_POINT && r0 > 0) {
        u0x = DIV(x, r0);
        u0y = DIV(y, r0);
    }
    for (i = 0; i < P->n; i++) {
        real dx = x - P->c[i].x, dy = y - P->c[i].y, r1 = msg_hyp(dx, dy), ux = 0, uy = 0;
        if (r1 > 0) {
            ux = DIV(dx, r1);
            uy = DIV(dy, r1);
        }
        if (kind == MODEL_POINT) {
            f[i] = r0 + r1 - P->r[i];
            J[i][0] = u0x + ux;
            J[i][1] = u0y + uy;
        } else {
            f[i] = r1 - P->r[i];
            J[i][0] = ux;
            J[i][1] = uy;
        }
    }
    return r0 > 0;
}

typedef struct {
    real p[2];
    real f[MS_MAX_RX];
    real J[MS_MAX_RX][2];
    real cost;
    int ok;
} gstate;

void msg_gauss_newton(int kind, const prob *P, const real p0[2], int iters, cand *out)
{
    gstate cur, trial;
    int it, h, n = P->n;
    real step[2], gd;
    int gd_inf;
    cur.p[0] = p0[0];
    cur.p[1] = p0[1];
    cur.ok = model_eval(kind, P, cur.p, cur.f, cur.J);
    cur.cost = msg_cost(cur.f, n);
    for (it = 0; it < iters; it++) {
        real po0 = cur.p[0], po1 = cur.p[1], c_old = cur.cost, t0, t1, moved;
        int done = 0;
        msg_ls_step(cur.J, cur.f, n, step, &gd, &gd_inf);
        t0 = step[0];
        t1 = step[1];
        for (h = 0; h < 5; h++) {
            trial.p[0] = cur.p[0] + t0;
            trial.p[1] = cur.p[1] + t1;
            trial.ok = model_eval(kind, P, trial.p, trial.f, trial.J);
            trial.cost = msg_cost(trial.f, n);
            if (ACCEPT(trial.cost, cur.cost) && trial.ok && ISFIN(trial.p[0]) && ISFIN(trial.p[1])) {
                cur = trial;
                done = 1;
                break;
            }
            t0 = HALF(t0);
            t1 = HALF(t1);
        }
        moved = msg_hyp(cur.p[0] - po0, cur.p[1] - po1);
        if (!done || SETTLED(moved, c_old, cur.cost, P->scale)) break;
    }
    msg_ls_step(cur.J, cur.f, n, step, &gd, &gd_inf);
    out->p[0] = cur.p[0];
    out->p[1] = cur.p[1];
    out->ok = cur.ok;
    out->rms = msg_rms(cur.cost, n);
    out->gd = gd;
    out->gd_inf = gd_inf;
}

/* misfit at a point without iterating (for candidates that are not physical anyway) */
void msg_no_fit(int kind, const prob *P, const real p0[2], cand *out)
{
    gstate s;
    s.p[0] = p0[0];
    s.p[1] = p0[1];
    model_eval(kind, P, s.p, s.f, s.J);
    out->p[0] = p0[0];
    out->p[1] = p0[1];
    out->ok = 0;
    out->rms = msg_rms(msg_cost(s.f, P->n), P->n);
    out->gd = 0;
    out->gd_inf = 1;
}

/* candidate selection shared by point and wall (geometry._select): physical -> misfit <= tol
 * -> axis within fov -> gdop <= max_gdop; returns the reason (pre when that is not MS_OK) */
int msg_select(const prob *P, const cand *k, int pre, int *idx_out)
{
    int acc[2], nacc, best, idx, reason = MS_OK, i;
    for (i = 0; i < 2; i++) acc[i] = k[i].ok && (P->no_tol || k[i].rms <= P->tol);
    nacc = acc[0] + acc[1];
    if (k[0].ok && k[1].ok) best = k[1].rms < k[0].rms ? 1 : 0;
    else best = (!k[0].ok && k[1].ok) ? 1 : 0;
    idx = best;
    if (!k[0].ok && !k[1].ok) reason = MS_UNPHYS;
    else if (nacc == 0) reason = P->n == 2 ? MS_NOINT : MS_INCONS;
    else if (nacc == 1) idx = acc[0] ? 0 : 1;
    else {
        real dist = msg_hyp(k[0].p[0] - k[1].p[0], k[0].p[1] - k[1].p[1]);
        real lim = PAIR_SAME(P->scale, k);
        if (dist > lim) {
            int inside[2];
            for (i = 0; i < 2; i++)
                inside[i] = P->has_axis && ANG_LE(msg_ang_absdiff(ATAN2(k[i].p[1], k[i].p[0]), P->axis), P->fov);
            if (inside[0] + inside[1] == 1) idx = inside[0] ? 0 : 1;
            else reason = MS_AMBIG;
        }
    }
    if (reason == MS_OK && !P->no_gdop && (k[idx].gd_inf || !(k[idx].gd <= P->max_gdop))) reason = MS_ILLCOND;
    if (pre != MS_OK) reason = pre;
    *idx_out = idx;
    return reason;
}
