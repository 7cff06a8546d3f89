/*
 * ms_geom_point.c - the point (edge) solver of the general path, every number format:
 * geometry.solve_point. A point reflector at x satisfies R_i*rho - c_i.x = (R_i^2 - |c_i|^2)/2
 * (source at the origin, rho = |x|): the best-conditioned receiver pair gives a line cut by the
 * cone rho^2 = x^2 + y^2, both candidates are polished (ms_geom_fit.c) and one is chosen.
 * Public: ms_solve_point, ms_point_prepared (which asks the format's fast path first).
 */
#include "ms_geom_internal.h"

static void cross3(const real *a, const real *b, real *o)
{
    o[0] = MUL(a[1], b[2]) - MUL(a[2], b[1]);
    o[1] = MUL(a[2], b[0]) - MUL(a[0], b[2]);
    o[2] = MUL(a[0], b[1]) - MUL(a[1], b[0]);
}
static real dot3(const real *a, const real *b) { return MUL(a[0], b[0]) + MUL(a[1], b[1]) + MUL(a[2], b[2]); }
static real lor(const real *a, const real *b) { return MUL(a[0], b[0]) + MUL(a[1], b[1]) - MUL(a[2], b[2]); }

/* Two candidate points from two ellipses sharing the focus at the origin; returns 1 when the
 * pair is degenerate */
static int point_pair(v2 c1, v2 c2, real R1, real R2, real cand[2][2], int ok[2])
{
    real n1 = msg_hyp(c1.x, c1.y), n2 = msg_hyp(c2.x, c2.y);
    real r1[3], r2[3], n[3], nh[3], w[3], z0[3], a1, a2, nn, scale, nns, A, B, Cq, disc, sq, q, t1, t2;
    real z1r, z2r;
    int deg, okq, okA, i, far1, far2;
    r1[0] = -c1.x; r1[1] = -c1.y; r1[2] = R1;
    r2[0] = -c2.x; r2[1] = -c2.y; r2[2] = R2;
    a1 = HALF(MUL(R1 - n1, R1 + n1));
    a2 = HALF(MUL(R2 - n2, R2 + n2));
    cross3(r1, r2, n);
    nn = SQRT(dot3(n, n));
    scale = SQRT(MUL(dot3(r1, r1), dot3(r2, r2)));
    deg = nn <= MUL(K(1e-12), scale);
    nns = deg ? K(1.0) : nn;
    for (i = 0; i < 3; i++) {
        nh[i] = DIV(n[i], nns);
        w[i] = MUL(a1, r2[i]) - MUL(a2, r1[i]);
    }
    cross3(w, nh, z0);
    for (i = 0; i < 3; i++) z0[i] = DIV(z0[i], nns);
    A = lor(nh, nh);
    B = lor(z0, nh);
    Cq = lor(z0, z0);
    disc = MUL(B, B) - MUL(A, Cq);
    if (disc < 0) disc = 0;
    sq = SQRT(disc);
    q = -(B + (B >= 0 ? sq : -sq));
    okq = q != 0;
    okA = ABS(A) > K(1e-15);
    /* roots the format cannot hold are no candidates (FAR_ROOT: Q beyond 1000 m; float none) */
    far1 = okA && FAR_ROOT(q, A);
    far2 = okq && FAR_ROOT(Cq, q);
    t1 = okA && !far1 ? DIV(q, A) : 0;
    t2 = okq && !far2 ? DIV(Cq, q) : 0;
    cand[0][0] = z0[0] + MUL(t1, nh[0]);
    cand[0][1] = z0[1] + MUL(t1, nh[1]);
    z1r = z0[2] + MUL(t1, nh[2]);
    cand[1][0] = z0[0] + MUL(t2, nh[0]);
    cand[1][1] = z0[1] + MUL(t2, nh[1]);
    z2r = z0[2] + MUL(t2, nh[2]);
    ok[0] = z1r > 0 && (okA || !okq) && !deg;
    ok[1] = z2r > 0 && !deg;
    if (far1) ok[0] = 0;
    if (far2) ok[1] = 0;
    return deg;
}

/* the best-conditioned receiver pair for the point model */
static void pick_pair_point(const prob *P, int *pi, int *pj)
{
    real rows[MS_MAX_RX][3], mu[3] = {0, 0, 0}, best = -1, d2, nr, cr[3];
    int k, i = 0, j = 0, n = P->n, t;
    for (k = 0; k < n; k++) {
        rows[k][0] = -P->c[k].x;
        rows[k][1] = -P->c[k].y;
        rows[k][2] = P->r[k];
        nr = SQRT(dot3(rows[k], rows[k]));
        for (t = 0; t < 3; t++) {
            rows[k][t] = DIV(rows[k][t], nr);
            mu[t] += rows[k][t];
        }
    }
    for (t = 0; t < 3; t++) mu[t] /= n;
    for (k = 0; k < n; k++) {
        real d[3];
        for (t = 0; t < 3; t++) d[t] = rows[k][t] - mu[t];
        d2 = dot3(d, d);
        if (d2 > best) { best = d2; i = k; }
    }
    best = -1;
    for (k = 0; k < n; k++) {
        cross3(rows[i], rows[k], cr);
        d2 = dot3(cr, cr);
        if (d2 > best) { best = d2; j = k; }
    }
    *pi = i;
    *pj = j;
}

int msg_point_core(const prob *P, cand *best)
{
    int pre = msg_short_check(P), i = 0, j = 1, deg, ok0[2], k, idx, reason;
    real c0[2][2];
    cand kk[2];
    if (P->n > 2) pick_pair_point(P, &i, &j);
    deg = point_pair(P->c[i], P->c[j], P->r[i], P->r[j], c0, ok0);
    for (k = 0; k < 2; k++) {
        if (ok0[k]) {
            msg_gauss_newton(MODEL_POINT, P, c0[k], P->n == 2 ? 6 : 12, &kk[k]);
            kk[k].ok = kk[k].ok && msg_hyp(kk[k].p[0], kk[k].p[1]) > 0;
        } else {
            msg_no_fit(MODEL_POINT, P, c0[k], &kk[k]);
        }
    }
    if (pre == MS_OK && deg) pre = MS_DEGEN;
    reason = msg_select(P, kk, pre, &idx);
    *best = kk[idx];
    return reason;
}

void msg_finish_point(const prob *P, ms_vec2 src, int reason, const cand *c, ms_point_fit *out)
{
    real x = c->p[0], y = c->p[1];
    if (reason == MS_OK && !(ISFIN(x) && ISFIN(y) && ISFIN(c->rms))) reason = MS_NOCONV;
    out->reason = (uint8_t)reason;
    out->valid = reason == MS_OK;
    if (!out->valid) {
        out->x = out->y = out->range = out->residual = 0;
        out->bearing = 0;
        out->gdop = 0;
        return;
    }
    (void)P;
    out->x = LEN_OUT(x + LEN_IN(src.x));
    out->y = LEN_OUT(y + LEN_IN(src.y));
    out->range = LEN_OUT(msg_hyp(x, y));
    out->bearing = ATAN2(y, x);
    out->residual = LEN_OUT(c->rms);
    out->gdop = c->gd_inf ? NUM_OUT(BIGV) : NUM_OUT(c->gd);
}

int ms_point_prepared(const ms_array *a, const ms_len_t *path, ms_point_fit *out)
{
    prob P;
    cand c = {{0, 0}, 0, 0, 1, 0};
    int reason;
    if (msg_fast_point(a, path, out)) return out->valid;
    reason = msg_prepared_setup(a, path, 2, &P);
    if (reason == MS_OK) reason = msg_point_core(&P, &c);
    msg_finish_point(&P, a->src, reason, &c, out);
    return out->valid;
}

int ms_solve_point(const ms_vec2 *rx, const ms_len_t *path, int n, ms_vec2 src, const ms_opts *opts,
                   ms_point_fit *out)
{
    ms_array a;
    ms_prepare(&a, rx, n, src, opts, NULL, 1);
    return ms_point_prepared(&a, path, out);
}
