/*
 * ms_geom_cylinder.c - the cylinder solver, every number format: a specular circle (pillar,
 * person) of unknown radius, N >= 3; geometry._specular, _cyl_model, _gauss_newton (3
 * parameters), _cylinder_core. The general path only: Gauss-Newton over (bearing, r0, radius)
 * from the point and the wall fit, Newton on the reflection angle inside the model; millions of
 * cycles on the soft-core, not a per-pulse call. Inside the fit, bearings are radians in `real`
 * (Q: Q32.32 radians); per-format constants and cos / sin: ms_geom_{f,q}_arith.h, msg_cossin.
 */
#include "ms_geom_internal.h"

#define CYL_A_MAX K(1000.0)

/* specular reflection off the circle (centre p, radius a) from the origin to c */
static int cyl_specular(real px, real py, real a, real cx, real cy, int iters, real *L, real *nxo, real *nyo,
                        real *cio)
{
    real ds = msg_hyp(px, py), dc = msg_hyp(cx - px, cy - py), usx = 0, usy = 0, ucx = 0, ucy = 0, bx, by, bn;
    real phi0, half, dphi = 0, nx, ny, qx, qy, l1, l2, ci;
    int it, s, ok = ds > a && dc > a;
    if (ds > 0) { usx = DIV(-px, ds); usy = DIV(-py, ds); }
    if (dc > 0) { ucx = DIV(cx - px, dc); ucy = DIV(cy - py, dc); }
    bx = usx + ucx;
    by = usy + ucy;
    bn = msg_hyp(bx, by);
    if (bn > K(1e-12)) { bx = DIV(bx, bn); by = DIV(by, bn); }
    else { bx = -usy; by = usx; }
    phi0 = CYL_ATAN2(by, bx);
    half = HALF(CYL_ATAN2(ABS(MUL(usx, ucy) - MUL(usy, ucx)), MUL(usx, ucx) + MUL(usy, ucy)));
    for (it = 0; it < iters; it++) {
        real g = 0, gp = 0, tx, ty, step;
        msg_cossin(phi0 + dphi, &nx, &ny);
        qx = px + MUL(a, nx);
        qy = py + MUL(a, ny);
        tx = -MUL(a, ny);
        ty = MUL(a, nx);
        for (s = 0; s < 2; s++) {
            real ex = qx - (s ? cx : 0), ey = qy - (s ? cy : 0), le = msg_hyp(ex, ey), te;
            if (!(le > CYL_TINY)) le = CYL_TINY;
            ex = DIV(ex, le);
            ey = DIV(ey, le);
            te = MUL(tx, ex) + MUL(ty, ey);
            g += te;
            gp += DIV(MUL(a, a) - MUL(te, te), le) - MUL(a, MUL(nx, ex) + MUL(ny, ey));
        }
        step = gp > 0 ? -DIV(g, gp) : 0;
        dphi += step;
        if (dphi > half) dphi = half;
        if (dphi < -half) dphi = -half;
    }
    msg_cossin(phi0 + dphi, &nx, &ny);
    qx = px + MUL(a, nx);
    qy = py + MUL(a, ny);
    l1 = msg_hyp(qx, qy);
    l2 = msg_hyp(qx - cx, qy - cy);
    ci = -DIV(MUL(nx, qx) + MUL(ny, qy), l1 > CYL_TINY ? l1 : CYL_TINY);
    *L = l1 + l2;
    *nxo = nx;
    *nyo = ny;
    *cio = ci;
    return ok && ci > 0;
}

typedef struct {
    real th[3];
    real f[MS_MAX_RX];
    real J[MS_MAX_RX][3];
    real cost;
    int ok;
} cstate;

static void cyl_project(real th[3])
{
    if (th[1] < K(1e-6)) th[1] = K(1e-6);
    if (th[2] < 0) th[2] = 0;
    if (th[2] > CYL_A_MAX) th[2] = CYL_A_MAX;
}

static int cyl_model(const prob *P, const real th[3], real *f, real (*J)[3])
{
    real ux, uy, d = th[1] + th[2], px, py;
    int k, ok = 1;
    msg_cossin(th[0], &ux, &uy);
    px = MUL(d, ux);
    py = MUL(d, uy);
    for (k = 0; k < P->n; k++) {
        real L, nx, ny, ci, g, nu, np;
        if (!cyl_specular(px, py, th[2], P->c[k].x, P->c[k].y, 4, &L, &nx, &ny, &ci)) ok = 0;
        f[k] = L - P->r[k];
        g = -2 * ci;
        nu = MUL(nx, ux) + MUL(ny, uy);
        np = MUL(ny, ux) - MUL(nx, uy);
        J[k][0] = MUL(MUL(g, d), np);
        J[k][1] = MUL(g, nu);
        J[k][2] = MUL(g, nu + K(1.0));
    }
    return ok;
}

/* Gauss-Newton step for three parameters (column-scaled normal equations, cofactors) */
static void ls_step3(real (*J)[3], const real *f, int n, real step[3], real *gd, int *gd_inf)
{
    real s[3], A[3][3], g[3], C00, C01, C02, C11, C12, C22, det, tr;
    int i, j, k;
    for (j = 0; j < 3; j++) {
        real t = 0;
        for (k = 0; k < n; k++) t += MUL(J[k][j], J[k][j]);
        t = SQRT(t);
        s[j] = t > 0 ? t : K(1.0);
    }
    for (i = 0; i < 3; i++) {
        g[i] = 0;
        for (j = 0; j < 3; j++) A[i][j] = 0;
    }
    for (k = 0; k < n; k++) {
        real js[3];
        for (j = 0; j < 3; j++) js[j] = DIV(J[k][j], s[j]);
        for (i = 0; i < 3; i++) {
            g[i] -= MUL(js[i], f[k]);
            for (j = i; j < 3; j++) A[i][j] += MUL(js[i], js[j]);
        }
    }
    C00 = MUL(A[1][1], A[2][2]) - MUL(A[1][2], A[1][2]);
    C01 = -(MUL(A[0][1], A[2][2]) - MUL(A[0][2], A[1][2]));
    C02 = MUL(A[0][1], A[1][2]) - MUL(A[0][2], A[1][1]);
    C11 = MUL(A[0][0], A[2][2]) - MUL(A[0][2], A[0][2]);
    C12 = -(MUL(A[0][0], A[1][2]) - MUL(A[0][1], A[0][2]));
    C22 = MUL(A[0][0], A[1][1]) - MUL(A[0][1], A[0][1]);
    det = MUL(A[0][0], C00) + MUL(A[0][1], C01) + MUL(A[0][2], C02);
    if (det > CYL_DET_MIN) {
        real x0 = DIV(MUL(C00, g[0]) + MUL(C01, g[1]) + MUL(C02, g[2]), det);
        real x1 = DIV(MUL(C01, g[0]) + MUL(C11, g[1]) + MUL(C12, g[2]), det);
        real x2 = DIV(MUL(C02, g[0]) + MUL(C12, g[1]) + MUL(C22, g[2]), det);
        step[0] = DIV(x0, s[0]);
        step[1] = DIV(x1, s[1]);
        step[2] = DIV(x2, s[2]);
        tr = DIV(DIV(DIV(C00, s[0]), s[0]) + DIV(DIV(C11, s[1]), s[1]) + DIV(DIV(C22, s[2]), s[2]), det);
        *gd = SQRT(tr > 0 ? tr : 0);
        *gd_inf = !ISFIN(*gd);
    } else {
        step[0] = step[1] = step[2] = 0;
        *gd = 0;
        *gd_inf = 1;
    }
}

static void cyl_gn(const prob *P, const real th0[3], int iters, real th[3], real *rms, int *ok)
{
    static cstate cur, trial; /* large: kept off the small stack */
    int it, h, j, n = P->n;
    real step[3], gd;
    int gd_inf;
    for (j = 0; j < 3; j++) cur.th[j] = th0[j];
    cyl_project(cur.th);
    cur.ok = cyl_model(P, cur.th, cur.f, cur.J);
    cur.cost = msg_cost(cur.f, n);
    for (it = 0; it < iters; it++) {
        real po[3], c_old = cur.cost, t[3], moved;
        int done = 0;
        for (j = 0; j < 3; j++) po[j] = cur.th[j];
        ls_step3(cur.J, cur.f, n, step, &gd, &gd_inf);
        for (j = 0; j < 3; j++) t[j] = step[j];
        for (h = 0; h < 5; h++) {
            for (j = 0; j < 3; j++) trial.th[j] = cur.th[j] + t[j];
            cyl_project(trial.th);
            trial.ok = cyl_model(P, trial.th, trial.f, trial.J);
            trial.cost = msg_cost(trial.f, n);
            if (ACCEPT(trial.cost, cur.cost) && trial.ok && ISFIN(trial.th[0]) && ISFIN(trial.th[1]) &&
                ISFIN(trial.th[2])) {
                cur = trial;
                done = 1;
                break;
            }
            for (j = 0; j < 3; j++) t[j] = HALF(t[j]);
        }
        moved = msg_hyp3(cur.th[0] - po[0], cur.th[1] - po[1], cur.th[2] - po[2]);
        if (!done || SETTLED(moved, c_old, cur.cost, P->scale)) break;
    }
    for (j = 0; j < 3; j++) th[j] = cur.th[j];
    *rms = msg_rms(cur.cost, n);
    *ok = cur.ok;
}

/* returns the reason; th (bearing, r0, radius), rms, gdop */
static int cylinder_core(const prob *P, real th_b[3], real *rms_b, real *gd_b, int *gd_inf)
{
    prob P2 = *P;
    cand cp, cw;
    real starts[2][3], th[2][3], rms[2], cen[2][2], rp, dw, f[MS_MAX_RX], J[MS_MAX_RX][3], step[3], d;
    int ok[2], k, b, pre = msg_short_check(P), reason = MS_OK, n_distinct = 0, i;
    P2.no_tol = P2.no_gdop = 1;
    msg_point_core(&P2, &cp);
    msg_wall_core(&P2, &cw);
    rp = msg_hyp(cp.p[0], cp.p[1]);
    dw = HALF(msg_hyp(cw.p[0], cw.p[1]));
    if (!(rp > 0)) rp = HALF(P->scale);
    if (!(dw > 0)) dw = HALF(P->scale);
    starts[0][0] = CYL_ATAN2(cp.p[1], cp.p[0]);
    starts[0][1] = rp;
    starts[0][2] = MUL(K(0.1), rp);
    starts[1][0] = CYL_ATAN2(cw.p[1], cw.p[0]);
    starts[1][1] = dw;
    starts[1][2] = 3 * dw;
    for (k = 0; k < 2; k++) {
        cyl_gn(P, starts[k], 30, th[k], &rms[k], &ok[k]);
        d = th[k][1] + th[k][2];
        msg_cossin(th[k][0], &cen[k][0], &cen[k][1]);
        cen[k][0] = MUL(d, cen[k][0]);
        cen[k][1] = MUL(d, cen[k][1]);
    }
    b = (ok[1] && (!ok[0] || rms[1] < rms[0])) ? 1 : 0;
    for (i = 0; i < 3; i++) th_b[i] = th[b][i];
    *rms_b = rms[b];
    cyl_model(P, th_b, f, J);
    d = th_b[1] + th_b[2];
    for (k = 0; k < P->n; k++) J[k][0] = d > 0 ? DIV(J[k][0], d) : J[k][0];
    ls_step3(J, f, P->n, step, gd_b, gd_inf);
    for (k = 0; k < 2; k++) {
        real dist = msg_hyp(cen[k][0] - cen[b][0], cen[k][1] - cen[b][1]), da = ABS(th[k][2] - th[b][2]);
        if (da > dist) dist = da;
        if (ok[k] && (P->no_tol || rms[k] <= P->tol) && dist > CYL_SAME(P->scale, *gd_inf ? BIGV : *gd_b))
            n_distinct++;
    }
    if (!ok[b]) reason = MS_UNPHYS;
    else if (!(P->no_tol || rms[b] <= P->tol)) reason = P->n > 3 ? MS_INCONS : MS_NOINT;
    else if (n_distinct > 0) reason = MS_AMBIG;
    else if (!P->no_gdop && (*gd_inf || !(*gd_b <= P->max_gdop))) reason = MS_ILLCOND;
    else if (P->has_axis && msg_off_axis(th_b[0], P->axis, P->fov)) reason = MS_UNPHYS;
    if (pre != MS_OK) reason = pre;
    return reason;
}

int ms_solve_cylinder(const ms_vec2 *rx, const ms_len_t *path, int n, ms_vec2 src, const ms_opts *opts,
                      ms_cyl_fit *out)
{
    prob P;
    real th[3] = {0, 0, 0}, rms = 0, gd = 0, d, cx, cy;
    int gd_inf = 1, reason = msg_setup(&P, rx, path, n, src, 3);
    if (reason == MS_OK) {
        msg_apply_opts(&P, rx, opts);
        reason = cylinder_core(&P, th, &rms, &gd, &gd_inf);
    }
    if (reason == MS_OK && !(ISFIN(th[0]) && ISFIN(th[1]) && ISFIN(th[2]) && ISFIN(rms))) reason = MS_NOCONV;
    out->reason = (uint8_t)reason;
    out->valid = reason == MS_OK;
    if (!out->valid) {
        out->cx = out->cy = out->radius = out->range = out->residual = 0;
        out->bearing = 0;
        out->gdop = 0;
        return 0;
    }
    d = th[1] + th[2];
    msg_cossin(th[0], &cx, &cy);
    out->cx = LEN_OUT(MUL(d, cx) + LEN_IN(src.x));
    out->cy = LEN_OUT(MUL(d, cy) + LEN_IN(src.y));
    out->radius = LEN_OUT(th[2]);
    out->range = LEN_OUT(th[1]);
    out->bearing = ANG_OF_RAD(th[0]);
    out->residual = LEN_OUT(rms);
    out->gdop = gd_inf ? NUM_OUT(BIGV) : NUM_OUT(gd);
    return 1;
}
