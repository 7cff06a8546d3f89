/*
 * ms_geom_wall.c - the wall solver of the general path, every number format:
 * geometry.solve_wall. A wall is the mirror image m of the source with |m - c_i| = R_i: the
 * circle pair of the two receivers furthest apart gives two candidates (the half chord:
 * half_chord of the format's arith header), both are polished (ms_geom_fit.c) and one is
 * chosen; a physical wall has every receiver on the source's side. Public: ms_solve_wall,
 * ms_wall_prepared (which asks the format's fast path first).
 */
#include "ms_geom_internal.h"

/* Intersections of circles (c1, R1), (c2, R2); returns 1 when the centres coincide */
static int circle_pair(v2 c1, v2 c2, real R1, real R2, real cand[2][2])
{
    real ex = c2.x - c1.x, ey = c2.y - c1.y, D = msg_hyp(ex, ey), Ds, ehx, ehy, a, h, bx, by;
    int deg = D <= MUL(K(1e-12), K(1.0) + msg_hyp(c1.x, c1.y) + msg_hyp(c2.x, c2.y));
    Ds = deg ? K(1.0) : D;
    ehx = DIV(ex, Ds);
    ehy = DIV(ey, Ds);
    a = DIV(MUL(R1 - R2, R1 + R2), 2 * Ds) + HALF(Ds);
    h = half_chord(Ds, R1, R2);
    bx = c1.x + MUL(a, ehx);
    by = c1.y + MUL(a, ehy);
    cand[0][0] = bx - MUL(h, ehy);
    cand[0][1] = by + MUL(h, ehx);
    cand[1][0] = bx + MUL(h, ehy);
    cand[1][1] = by - MUL(h, ehx);
    return deg;
}

/* the receiver furthest from the centroid and the one furthest from it */
static void pick_pair_far(const prob *P, int *pi, int *pj)
{
    int k, i = 0, j = 0, n = P->n;
    real mx = 0, my = 0, best = -1, dx, dy, d2;
    for (k = 0; k < n; k++) {
        mx += P->c[k].x;
        my += P->c[k].y;
    }
    mx /= n;
    my /= n;
    for (k = 0; k < n; k++) {
        dx = P->c[k].x - mx;
        dy = P->c[k].y - my;
        d2 = MUL(dx, dx) + MUL(dy, dy);
        if (d2 > best) { best = d2; i = k; }
    }
    best = -1;
    for (k = 0; k < n; k++) {
        dx = P->c[k].x - P->c[i].x;
        dy = P->c[k].y - P->c[i].y;
        d2 = MUL(dx, dx) + MUL(dy, dy);
        if (d2 > best) { best = d2; j = k; }
    }
    *pi = i;
    *pj = j;
}

int msg_wall_core(const prob *P, cand *best)
{
    int pre = msg_short_check(P), i = 0, j = 1, deg, k, idx, reason, t;
    real c0[2][2];
    cand kk[2];
    if (P->n > 2) pick_pair_far(P, &i, &j);
    deg = circle_pair(P->c[i], P->c[j], P->r[i], P->r[j], c0);
    for (k = 0; k < 2; k++) {
        if (!deg) {
            real d, nhx, nhy, mm;
            msg_gauss_newton(MODEL_WALL, P, c0[k], P->n == 2 ? 6 : 12, &kk[k]);
            mm = msg_hyp(kk[k].p[0], kk[k].p[1]);
            d = HALF(mm);
            if (kk[k].ok && d > 0) {
                nhx = DIV(kk[k].p[0], mm);
                nhy = DIV(kk[k].p[1], mm);
                for (t = 0; t < P->n; t++)
                    if (!(MUL(nhx, P->c[t].x) + MUL(nhy, P->c[t].y) < d)) kk[k].ok = 0;
            } else {
                kk[k].ok = 0;
            }
        } else {
            msg_no_fit(MODEL_WALL, P, c0[k], &kk[k]);
        }
    }
    if (pre == MS_OK && deg) pre = MS_DEGEN;
    reason = msg_select(P, kk, pre, &idx);
    *best = kk[idx];
    return reason;
}

void msg_finish_wall(const prob *P, ms_vec2 src, int reason, const cand *c, ms_wall_fit *out)
{
    real mx = c->p[0], my = c->p[1];
    if (reason == MS_OK && !(ISFIN(mx) && ISFIN(my) && ISFIN(c->rms))) reason = MS_NOCONV;
    out->reason = (uint8_t)reason;
    out->valid = reason == MS_OK;
    if (!out->valid) {
        out->distance = out->foot_x = out->foot_y = out->residual = 0;
        out->normal_angle = 0;
        out->gdop = 0;
        return;
    }
    (void)P;
    out->distance = LEN_OUT(HALF(msg_hyp(mx, my)));
    out->normal_angle = ATAN2(my, mx);
    out->foot_x = LEN_OUT(HALF(mx) + LEN_IN(src.x));
    out->foot_y = LEN_OUT(HALF(my) + LEN_IN(src.y));
    out->residual = LEN_OUT(c->rms);
    out->gdop = c->gd_inf ? NUM_OUT(BIGV) : NUM_OUT(HALF(c->gd));
}

int ms_wall_prepared(const ms_array *a, const ms_len_t *path, ms_wall_fit *out)
{
    prob P;
    cand c = {{0, 0}, 0, 0, 1, 0};
    int reason;
    if (msg_fast_wall(a, path, out)) return out->valid;
    reason = msg_prepared_setup(a, path, 2, &P);
    /* the wall's max_gdop applies to the mirror image (2x the distance gdop), as Python */
    if (reason == MS_OK) reason = msg_wall_core(&P, &c);
    msg_finish_wall(&P, a->src, reason, &c, out);
    return out->valid;
}

int ms_solve_wall(const ms_vec2 *rx, const ms_len_t *path, int n, ms_vec2 src, const ms_opts *opts,
                  ms_wall_fit *out)
{
    ms_array a;
    ms_prepare(&a, rx, n, src, opts, NULL, 1);
    return ms_wall_prepared(&a, path, out);
}
