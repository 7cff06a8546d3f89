/*
 * ms_geom.c - reflector geometry (point, wall, edge/wall classification) for the RV32IM
 * soft-core; the algorithm of host/multisonar/geometry.py step by step (see ms_geom.h).
 * One source for all arithmetic variants: `real` is double, float or Q32.32 int64 and
 * every product / quotient / root goes through MUL / DIV / SQRT.
 */
#include "ms_geom.h"

#include <stddef.h>

const char *const ms_reason_names[MS_NREASONS] = {
    "",
    "path shorter than baseline",
    "no intersection",
    "degenerate receiver geometry",
    "ambiguous",
    "ill-conditioned",
    "not physical",
    "inconsistent data",
    "invalid input",
    "no convergence",
};
/* C99 static assert: the table has exactly MS_NREASONS entries */
typedef char ms_reason_table_check[(sizeof ms_reason_names / sizeof ms_reason_names[0]) == MS_NREASONS ? 1 : -1];

/* ======================================================================================
 * arithmetic variants
 * ====================================================================================== */
#if MS_GEOM_ARITH == MS_ARITH_F64 || MS_GEOM_ARITH == MS_ARITH_F32
#include <math.h>
#if MS_GEOM_ARITH == MS_ARITH_F64
typedef double real;
#define SQRT(a) sqrt(a)
#define ATAN2(y, x) atan2((y), (x))
#define BIGNUM 1e30
#else
typedef float real;
#define SQRT(a) sqrtf(a)
#define ATAN2(y, x) atan2f((y), (x))
#define BIGNUM 1e30f
#endif
#define BIGV BIGNUM
#if MS_GEOM_ARITH == MS_ARITH_F64
#define ACCEPT(tc, c) ((tc) <= (c)) /* geometry._gauss_newton */
#else
/* float: a step is also taken when the cost is equal within rounding, else the fit stops
 * up to gdop*sqrt(eps)*misfit short of the minimum on the flat bottom of the cost */
#define ACCEPT(tc, c) ((tc) <= (c) + (c) * K(5e-7))
#endif
#define ANG_LE(a, b) ((a) <= (b))
typedef real ang;
#define K(x) ((real)(x))
#define MUL(a, b) ((a) * (b))
#define DIV(a, b) ((a) / (b))
#define HALF(a) (K(0.5) * (a))
#define ISFIN(a) ((a) - (a) == 0)
#define PI_R K(3.14159265358979323846)
#define TWO_PI_R K(6.28318530717958647692)

static real wrap(real a)
{ /* numpy (a + pi) % (2 pi) - pi */
    real t = a + PI_R;
    real q = t / TWO_PI_R;
    real fl, r;
    if (!(q < K(1e15) && q > K(-1e15))) return K(0.0);
    fl = (real)(long long)q;
    if (fl > q) fl -= K(1.0);
    r = t - fl * TWO_PI_R;
    if (r < 0) r += TWO_PI_R;
    if (r >= TWO_PI_R) r -= TWO_PI_R;
    return r - PI_R;
}
static ang ang_absdiff(ang a, ang b)
{
    real d = wrap(a - b);
    return d < 0 ? -d : d;
}
static real hyp(real x, real y) { return SQRT(x * x + y * y); }
static real cost_of(const real *f, int n)
{
    real s = 0;
    int i;
    for (i = 0; i < n; i++) s += f[i] * f[i];
    return s;
}
static real rms_of(real cost, int n) { return SQRT(cost / (real)n); }
#define SETTLED(moved, c_old, c_new, scale) \
    ((moved) <= K(1e-13) * (scale) || (c_old) - (c_new) <= K(1e-8) * (c_old) + K(1e-32) * (scale) * (scale))
/* interface conversions */
#define LEN_IN(v) ((real)(v))
#define LEN_OUT(v) ((ms_len_t)(v))
#define NUM_IN(v) ((real)(v))
#define NUM_OUT(v) ((ms_num_t)((v) > BIGNUM ? BIGNUM : (v)))

#else /* ---------------------------------------------------------------- Q32.32 */
typedef int64_t real;
typedef int32_t ang; /* binary angle */
#define QONE ((int64_t)1 << 32)
#define QSAT ((int64_t)1 << 59)
#define K(x) ((int64_t)((x) * 4294967296.0 + ((x) >= 0 ? 0.5 : -0.5)))
#define MUL(a, b) q_mul((a), (b))
#define DIV(a, b) q_div((a), (b))
#define SQRT(a) q_sqrt(a)
#define ATAN2(y, x) q_atan2((y), (x))
#define HALF(a) ((a) / 2)
#define ISFIN(a) ((a) < QSAT && (a) > -QSAT)
#define BIGV QSAT
/* cost is |f| here; accept steps equal within rounding (see the float variant) */
#define ACCEPT(tc, c) ((tc) <= (c) + ((c) >> 22) + 8)
#define ANG_LE(a, b) ((uint32_t)(a) <= (uint32_t)(b))

static int clz64(uint64_t v)
{
    int n = 0;
    if (!(v >> 32)) { n += 32; v <<= 32; }
    if (!(v >> 48)) { n += 16; v <<= 16; }
    if (!(v >> 56)) { n += 8; v <<= 8; }
    if (!(v >> 60)) { n += 4; v <<= 4; }
    if (!(v >> 62)) { n += 2; v <<= 2; }
    if (!(v >> 63)) { n += 1; }
    return n;
}
static uint64_t uabs64(int64_t a) { return a < 0 ? (uint64_t)0 - (uint64_t)a : (uint64_t)a; }
static int64_t sgn(int neg, uint64_t u) { return neg ? -(int64_t)u : (int64_t)u; }

/* a*b >> 32, rounded, saturating at +-QSAT */
static int64_t q_mul(int64_t a, int64_t b)
{
    int neg = (a < 0) != (b < 0);
    uint64_t ua = uabs64(a), ub = uabs64(b), ah, al, bh, bl, hh, r;
    if (ua > (uint64_t)QSAT) ua = QSAT;
    if (ub > (uint64_t)QSAT) ub = QSAT;
    ah = ua >> 32; al = ua & 0xffffffffu; bh = ub >> 32; bl = ub & 0xffffffffu;
    hh = ah * bh;
    if (hh >= ((uint64_t)QSAT >> 32)) return sgn(neg, QSAT);
    r = (hh << 32) + ah * bl + al * bh + ((al * bl + 0x80000000u) >> 32);
    if (r > (uint64_t)QSAT) r = QSAT;
    return sgn(neg, r);
}
/* (a << 32) / b, rounded, saturating */
static int64_t q_div(int64_t a, int64_t b)
{
    int neg = (a < 0) != (b < 0);
    uint64_t ua = uabs64(a), ub = uabs64(b), qi, r, qf, res;
    if (ub == 0) return ua == 0 ? 0 : sgn(neg, QSAT);
    qi = ua / ub;
    if (qi >= ((uint64_t)QSAT >> 32)) return sgn(neg, QSAT);
    r = ua - qi * ub;
    while (ub >= ((uint64_t)1 << 32)) { ub >>= 1; r >>= 1; }
    qf = ((r << 32) + (ub >> 1)) / ub;
    res = (qi << 32) + qf;
    if (res > (uint64_t)QSAT) res = QSAT;
    return sgn(neg, res);
}
/* floor(sqrt(v)) rounded to nearest */
static uint64_t isqrt64(uint64_t v)
{
    uint64_t r = 0, b = (uint64_t)1 << 62, v0 = v;
    while (b > v) b >>= 2;
    while (b) {
        if (v >= r + b) { v -= r + b; r = (r >> 1) + b; }
        else r >>= 1;
        b >>= 2;
    }
    if (v0 - r * r > r) r++;
    return r;
}
static int64_t q_sqrt(int64_t a)
{
    int k;
    uint64_t r;
    if (a <= 0) return 0;
    k = clz64((uint64_t)a) / 2;
    r = isqrt64((uint64_t)a << (2 * k));
    if (k >= 16) return (int64_t)((k > 16) ? (r + ((uint64_t)1 << (k - 17))) >> (k - 16) : r);
    return (int64_t)(r << (16 - k));
}
/* Euclidean norm of n values, normalised so the squares never overflow (~30 bits kept) */
static int64_t q_vnorm(const int64_t *v, int n, int stride)
{
    uint64_t m = 0, s = 0, a, r;
    int i, tb = n <= 2 ? 30 : n <= 8 ? 29 : 28, sh;
    for (i = 0; i < n; i++) {
        a = uabs64(v[i * stride]);
        if (a > m) m = a;
    }
    if (m == 0) return 0;
    sh = (63 - clz64(m)) - tb;
    for (i = 0; i < n; i++) {
        a = uabs64(v[i * stride]);
        a = sh > 0 ? (a + ((uint64_t)1 << (sh - 1))) >> sh : a << -sh;
        s += a * a;
    }
    r = isqrt64(s);
    if (sh >= 0) {
        r <<= sh;
        if (r > (uint64_t)QSAT) r = QSAT;
        return (int64_t)r;
    }
    return (int64_t)((r + ((uint64_t)1 << (-sh - 1))) >> -sh);
}
static real hyp(real x, real y)
{
    int64_t v[2];
    v[0] = x; v[1] = y;
    return q_vnorm(v, 2, 1);
}
/* atan(2^-i) in 2^-48 turns */
static const int64_t cordic_tab[40] = {
    35184372088832LL, 20770547670515LL, 10974586953444LL, 5570871696862LL,
    2796246208089LL, 1399486241028LL, 699913886760LL, 349978300884LL,
    174991820497LL, 87496244017LL, 43748163730LL, 21874087080LL,
    10937044192LL, 5468522177LL, 2734261099LL, 1367130551LL,
    683565276LL, 341782638LL, 170891319LL, 85445659LL,
    42722830LL, 21361415LL, 10680707LL, 5340354LL,
    2670177LL, 1335088LL, 667544LL, 333772LL,
    166886LL, 83443LL, 41722LL, 20861LL,
    10430LL, 5215LL, 2608LL, 1304LL,
    652LL, 326LL, 163LL, 81LL};
static ang q_atan2(int64_t y, int64_t x)
{
    uint64_t ax = uabs64(x), ay = uabs64(y), m = ax > ay ? ax : ay;
    int64_t acc = 0, t, xs;
    int sh, i;
    if (m == 0) return 0;
    sh = (63 - clz64(m)) - 40;
    if (sh > 0) { x >>= sh; y >>= sh; }
    else { x = (int64_t)((uint64_t)x << -sh); y = (int64_t)((uint64_t)y << -sh); }
    if (x < 0) {
        if (y >= 0) { acc = (int64_t)1 << 46; t = x; x = y; y = -t; }
        else { acc = -((int64_t)1 << 46); t = x; x = -y; y = t; }
    }
    for (i = 0; i < 40; i++) {
        xs = x >> i;
        if (y > 0) { x += y >> i; y -= xs; acc += cordic_tab[i]; }
        else { x -= y >> i; y += xs; acc -= cordic_tab[i]; }
    }
    return (ang)(uint32_t)(uint64_t)((acc + (1 << 15)) >> 16);
}
static ang ang_absdiff(ang a, ang b)
{
    int32_t d = (int32_t)((uint32_t)a - (uint32_t)b);
    return d < 0 ? (ang)((uint32_t)0 - (uint32_t)d) : d; /* INT32_MIN stays: compared unsigned */
}
static real cost_of(const real *f, int n) { return q_vnorm(f, n, 1); } /* |f|, not |f|^2 */
static const int64_t sqrt_n_tab[MS_MAX_RX + 1] = {
    K(1.0), K(1.0), K(1.4142135623730951), K(1.7320508075688772), K(2.0),
    K(2.23606797749979), K(2.449489742783178), K(2.6457513110645907), K(2.8284271247461903)};
static real rms_of(real cost, int n) { return DIV(cost, sqrt_n_tab[n]); }
#define SETTLED(moved, c_old, c_new, scale) ((moved) <= 0 || (c_old) - (c_new) <= ((c_old) >> 27))
static real um_to_q(int32_t v)
{ /* v * 2^32 / 1e6 = (v << 26) / 15625, rounded */
    int64_t n = (int64_t)v * ((int64_t)1 << 26);
    return (n >= 0 ? n + 7812 : n - 7812) / 15625;
}
static int32_t q_to_um(real v)
{
    int64_t u;
    if (v > ((int64_t)1 << 49)) v = (int64_t)1 << 49;
    if (v < -((int64_t)1 << 49)) v = -((int64_t)1 << 49);
    u = v * 15625;
    u = (u >= 0 ? u + ((int64_t)1 << 25) : u - ((int64_t)1 << 25)) / ((int64_t)1 << 26);
    if (u > INT32_MAX) u = INT32_MAX;
    if (u < -INT32_MAX) u = -INT32_MAX;
    return (int32_t)u;
}
static ms_num_t q_to_num(real v)
{
    v >>= 16;
    return (ms_num_t)(v > INT32_MAX ? INT32_MAX : v < -INT32_MAX ? -INT32_MAX : v);
}
#define LEN_IN(v) um_to_q(v)
#define LEN_OUT(v) q_to_um(v)
#define NUM_IN(v) ((real)(v) * 65536)
#define NUM_OUT(v) q_to_num(v)
#endif

#define ABS(a) ((a) < 0 ? -(a) : (a))

/* ======================================================================================
 * problem set-up
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

/* returns MS_OK or MS_BADIN; fills P (without opts) */
static int setup(prob *P, const ms_vec2 *rx, const ms_len_t *path, int n, ms_vec2 src, int min_n)
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

static void set_axis(prob *P, const ms_vec2 *rx, int mode, ms_ang_t axis)
{
    int i, cnt = 0;
    real mx = 0, my = 0;
    P->has_axis = 0;
    P->axis = 0;
    if (mode == MS_AXIS_SET) {
#if MS_GEOM_ARITH != MS_ARITH_Q
        if (!ISFIN(axis)) return;
#endif
        P->has_axis = 1;
        P->axis = axis;
        return;
    }
    if (mode != MS_AXIS_AUTO) return;
    for (i = 0; i < P->n; i++) {
        real cx = LEN_IN(rx[i].x), cy = LEN_IN(rx[i].y), nr = hyp(cx, cy);
        if (nr > K(1e-9)) {
            mx += DIV(cx, nr);
            my += DIV(cy, nr);
            cnt++;
        }
    }
    if (cnt == 0) cnt = 1;
    mx /= cnt;
    my /= cnt;
    if (hyp(mx, my) >= K(0.3)) {
        P->has_axis = 1;
        P->axis = ATAN2(my, mx);
    }
}

static void apply_opts(prob *P, const ms_vec2 *rx, const ms_opts *o)
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
    set_axis(P, rx, o->axis_mode, o->axis);
}

/* ======================================================================================
 * models and Gauss-Newton
 * ====================================================================================== */
static int model_eval(int kind, const prob *P, const real p[2], real *f, real (*J)[2])
{
    int i;
    real x = p[0], y = p[1], r0 = hyp(x, y), u0x = 0, u0y = 0;
    if (kind == MODEL_POINT && r0 > 0) {
        u0x = DIV(x, r0);
        u0y = DIV(y, r0);
    }
    for (i = 0; i < P->n; i++) {
        real dx = x - P->c[i].x, dy = y - P->c[i].y, r1 = hyp(dx, dy), ux = 0, uy = 0;
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

/* Gauss-Newton step minimising |J d + f| (column-scaled normal equations) and
 * gdop = sqrt(trace((J^T J)^-1)); *gd_inf when J^T J is singular. */
static void ls_step(real (*J)[2], const real *f, int n, real step[2], real *gd, int *gd_inf)
{
    real s0 = 0, s1 = 0, a = 0, b = 0, d = 0, g0 = 0, g1 = 0, j0, j1, x0, x1;
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
#if MS_GEOM_ARITH != MS_ARITH_Q
    {
        real det = a * d - b * b, idet, tr;
        if (det > K(1e-28)) {
            idet = K(1.0) / det;
            x0 = (d * g0 - b * g1) * idet;
            x1 = (a * g1 - b * g0) * idet;
            tr = (d / (s0 * s0) + a / (s1 * s1)) * idet;
            step[0] = x0 / s0;
            step[1] = x1 / s1;
            *gd = SQRT(tr > 0 ? tr : K(0.0));
            *gd_inf = 0;
        } else {
            step[0] = step[1] = 0;
            *gd = 0;
            *gd_inf = 1;
        }
    }
#else
    {
        /* det(J^T J) by Cauchy-Binet: sum of squared 2x2 minors (no cancellation);
         * the scaled determinant is m^2 with m = |minors| / (s0 s1) */
        int64_t minors[MS_MAX_RX * (MS_MAX_RX - 1) / 2];
        int j, k = 0;
        real mn, m, st;
        for (i = 0; i < n; i++)
            for (j = i + 1; j < n; j++) minors[k++] = MUL(J[i][0], J[j][1]) - MUL(J[i][1], J[j][0]);
        mn = q_vnorm(minors, k, 1);
        m = DIV(mn, MUL(s0, s1));
        if (m > 0) {
            x0 = DIV(DIV(MUL(d, g0) - MUL(b, g1), m), m);
            x1 = DIV(DIV(MUL(a, g1) - MUL(b, g0), m), m);
            step[0] = DIV(x0, s0);
            step[1] = DIV(x1, s1);
            st = hyp(s0, s1); /* sqrt(sum J^2) */
            *gd = DIV(st, mn);
            *gd_inf = *gd >= QSAT;
        } else {
            step[0] = step[1] = 0;
            *gd = 0;
            *gd_inf = 1;
        }
    }
#endif
}

typedef struct {
    real p[2];
    real f[MS_MAX_RX];
    real J[MS_MAX_RX][2];
    real cost;
    int ok;
} gstate;

static void gauss_newton(int kind, const prob *P, const real p0[2], int iters, cand *out)
{
    gstate cur, trial;
    int it, h, n = P->n;
    real step[2], gd;
    int gd_inf;
    cur.p[0] = p0[0];
    cur.p[1] = p0[1];
    cur.ok = model_eval(kind, P, cur.p, cur.f, cur.J);
    cur.cost = cost_of(cur.f, n);
    for (it = 0; it < iters; it++) {
        real po0 = cur.p[0], po1 = cur.p[1], c_old = cur.cost, t0, t1, moved;
        int done = 0;
        ls_step(cur.J, cur.f, n, step, &gd, &gd_inf);
        t0 = step[0];
        t1 = step[1];
        for (h = 0; h < 5; h++) {
            trial.p[0] = cur.p[0] + t0;
            trial.p[1] = cur.p[1] + t1;
            trial.ok = model_eval(kind, P, trial.p, trial.f, trial.J);
            trial.cost = cost_of(trial.f, n);
            if (ACCEPT(trial.cost, cur.cost) && trial.ok && ISFIN(trial.p[0]) && ISFIN(trial.p[1])) {
                cur = trial;
                done = 1;
                break;
            }
            t0 = HALF(t0);
            t1 = HALF(t1);
        }
        moved = hyp(cur.p[0] - po0, cur.p[1] - po1);
        if (!done || SETTLED(moved, c_old, cur.cost, P->scale)) break;
    }
    ls_step(cur.J, cur.f, n, step, &gd, &gd_inf);
    out->p[0] = cur.p[0];
    out->p[1] = cur.p[1];
    out->ok = cur.ok;
    out->rms = rms_of(cur.cost, n);
    out->gd = gd;
    out->gd_inf = gd_inf;
}

/* misfit at a point without iterating (for candidates that are not physical anyway) */
static void no_fit(int kind, const prob *P, const real p0[2], cand *out)
{
    gstate s;
    s.p[0] = p0[0];
    s.p[1] = p0[1];
    model_eval(kind, P, s.p, s.f, s.J);
    out->p[0] = p0[0];
    out->p[1] = p0[1];
    out->ok = 0;
    out->rms = rms_of(cost_of(s.f, P->n), P->n);
    out->gd = 0;
    out->gd_inf = 1;
}

/* ======================================================================================
 * candidate pairs
 * ====================================================================================== */
static void cross3(const real *a, const real *b, real *o)
{
    o[0] = MUL(a[1], b[2]) - MUL(a[2], b[1]);
    o[1] = MUL(a[2], b[0]) - MUL(a[0], b[2]);
    o[2] = MUL(a[0], b[1]) - MUL(a[1], b[0]);
}
static real dot3(const real *a, const real *b) { return MUL(a[0], b[0]) + MUL(a[1], b[1]) + MUL(a[2], b[2]); }
static real lor(const real *a, const real *b) { return MUL(a[0], b[0]) + MUL(a[1], b[1]) - MUL(a[2], b[2]); }

/* Two candidate points from two ellipses sharing the focus at the origin */
static int point_pair(v2 c1, v2 c2, real R1, real R2, real cand[2][2], int ok[2])
{
    real n1 = hyp(c1.x, c1.y), n2 = hyp(c2.x, c2.y);
    real r1[3], r2[3], n[3], nh[3], w[3], z0[3], a1, a2, nn, scale, nns, A, B, Cq, disc, sq, q, t1, t2;
    real z1r, z2r;
    int deg, okq, okA, i;
#if MS_GEOM_ARITH == MS_ARITH_Q
    int far1, far2;
#endif
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
#if MS_GEOM_ARITH == MS_ARITH_Q
    /* a root beyond 1000 m is outside the fixed-point range: not a candidate */
    far1 = okA && ABS(q) >= MUL(ABS(A), K(1000.0));
    far2 = okq && ABS(Cq) >= MUL(ABS(q), K(1000.0));
    t1 = okA && !far1 ? DIV(q, A) : 0;
    t2 = okq && !far2 ? DIV(Cq, q) : 0;
#else
    t1 = okA ? DIV(q, A) : 0;
    t2 = okq ? DIV(Cq, q) : 0;
#endif
    cand[0][0] = z0[0] + MUL(t1, nh[0]);
    cand[0][1] = z0[1] + MUL(t1, nh[1]);
    z1r = z0[2] + MUL(t1, nh[2]);
    cand[1][0] = z0[0] + MUL(t2, nh[0]);
    cand[1][1] = z0[1] + MUL(t2, nh[1]);
    z2r = z0[2] + MUL(t2, nh[2]);
    ok[0] = z1r > 0 && (okA || !okq) && !deg;
    ok[1] = z2r > 0 && !deg;
#if MS_GEOM_ARITH == MS_ARITH_Q
    if (far1) ok[0] = 0;
    if (far2) ok[1] = 0;
#endif
    return deg;
}

/* Intersections of circles (c1, R1), (c2, R2) */
static int circle_pair(v2 c1, v2 c2, real R1, real R2, real cand[2][2])
{
    real ex = c2.x - c1.x, ey = c2.y - c1.y, D = hyp(ex, ey), Ds, ehx, ehy, a, h2, h, bx, by;
    int deg = D <= MUL(K(1e-12), K(1.0) + hyp(c1.x, c1.y) + hyp(c2.x, c2.y));
    Ds = deg ? K(1.0) : D;
    ehx = DIV(ex, Ds);
    ehy = DIV(ey, Ds);
    a = DIV(MUL(R1 - R2, R1 + R2), 2 * Ds) + HALF(Ds);
#if MS_GEOM_ARITH == MS_ARITH_Q
    /* h = sqrt(p1 p2) / (2 D) with the two factor pairs rooted separately (no overflow) */
    {
        real p1 = MUL(Ds + R1 - R2, Ds - R1 + R2), p2 = MUL(R1 + R2 - Ds, R1 + R2 + Ds);
        h = (p1 > 0 && p2 > 0) ? DIV(MUL(SQRT(p1), SQRT(p2)), 2 * Ds) : 0;
        (void)h2;
    }
#else
    h2 = (Ds + R1 - R2) * (Ds - R1 + R2) * (R1 + R2 - Ds) * (R1 + R2 + Ds) / (4 * Ds * Ds);
    h = SQRT(h2 > 0 ? h2 : K(0.0));
#endif
    bx = c1.x + MUL(a, ehx);
    by = c1.y + MUL(a, ehy);
    cand[0][0] = bx - MUL(h, ehy);
    cand[0][1] = by + MUL(h, ehx);
    cand[1][0] = bx + MUL(h, ehy);
    cand[1][1] = by - MUL(h, ehx);
    return deg;
}

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

/* ======================================================================================
 * candidate selection shared by point and wall (geometry._select)
 * ====================================================================================== */
static int select_cand(const prob *P, const cand *k, int pre, int *idx_out)
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
        real dist = hyp(k[0].p[0] - k[1].p[0], k[0].p[1] - k[1].p[1]);
#if MS_GEOM_ARITH == MS_ARITH_F32
        /* two float fits of one minimum differ by ~eps * scale * gdop: widen 'same' by that */
        real gmin = k[0].gd_inf ? k[1].gd : k[1].gd_inf ? k[0].gd : k[0].gd < k[1].gd ? k[0].gd : k[1].gd;
        real lim = K(1e-6) * P->scale + K(3e-7) * P->scale * gmin;
#else
        real lim = MUL(K(1e-6), P->scale);
#endif
        if (dist > lim) {
            int inside[2];
            for (i = 0; i < 2; i++)
                inside[i] = P->has_axis && ANG_LE(ang_absdiff(ATAN2(k[i].p[1], k[i].p[0]), P->axis), P->fov);
            if (inside[0] + inside[1] == 1) idx = inside[0] ? 0 : 1;
            else reason = MS_AMBIG;
        }
    }
    if (reason == MS_OK && !P->no_gdop && (k[idx].gd_inf || !(k[idx].gd <= P->max_gdop))) reason = MS_ILLCOND;
    if (pre != MS_OK) reason = pre;
    *idx_out = idx;
    return reason;
}

static int short_check(const prob *P)
{
    int i;
    for (i = 0; i < P->n; i++) {
        real cn = hyp(P->c[i].x, P->c[i].y);
        if (P->r[i] <= MUL(cn, K(1.0 + 1e-15))) return MS_SHORT;
    }
    return MS_OK;
}

/* returns the reason; *best gets the chosen candidate */
static int point_core(const prob *P, cand *best)
{
    int pre = short_check(P), i = 0, j = 1, deg, ok0[2], k, idx, reason;
    real c0[2][2];
    cand kk[2];
    if (P->n > 2) pick_pair_point(P, &i, &j);
    deg = point_pair(P->c[i], P->c[j], P->r[i], P->r[j], c0, ok0);
    for (k = 0; k < 2; k++) {
        if (ok0[k]) {
            gauss_newton(MODEL_POINT, P, c0[k], P->n == 2 ? 6 : 12, &kk[k]);
            kk[k].ok = kk[k].ok && hyp(kk[k].p[0], kk[k].p[1]) > 0;
        } else {
            no_fit(MODEL_POINT, P, c0[k], &kk[k]);
        }
    }
    if (pre == MS_OK && deg) pre = MS_DEGEN;
    reason = select_cand(P, kk, pre, &idx);
    *best = kk[idx];
    return reason;
}

static int wall_core(const prob *P, cand *best)
{
    int pre = short_check(P), i = 0, j = 1, deg, k, idx, reason, t;
    real c0[2][2];
    cand kk[2];
    if (P->n > 2) pick_pair_far(P, &i, &j);
    deg = circle_pair(P->c[i], P->c[j], P->r[i], P->r[j], c0);
    for (k = 0; k < 2; k++) {
        if (!deg) {
            real d, nhx, nhy, mm;
            gauss_newton(MODEL_WALL, P, c0[k], P->n == 2 ? 6 : 12, &kk[k]);
            mm = hyp(kk[k].p[0], kk[k].p[1]);
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
            no_fit(MODEL_WALL, P, c0[k], &kk[k]);
        }
    }
    if (pre == MS_OK && deg) pre = MS_DEGEN;
    reason = select_cand(P, kk, pre, &idx);
    *best = kk[idx];
    return reason;
}

/* ======================================================================================
 * public API
 * ====================================================================================== */
void ms_opts_default(ms_opts *o)
{
#if MS_GEOM_ARITH == MS_ARITH_Q
    o->tol = 1000;
    o->max_gdop = MS_Q_NUM(1e4);
    o->fov = MS_Q_ANG_FROM_DEG(60.0);
#else
    o->tol = (ms_len_t)1e-3;
    o->max_gdop = (ms_num_t)1e4;
    o->fov = (ms_ang_t)(60.0 * 3.14159265358979323846 / 180.0);
#endif
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
#if MS_GEOM_ARITH == MS_ARITH_Q
    o->z = MS_Q_NUM(3.090232306167813);
#else
    o->z = (ms_num_t)3.090232306167813;
#endif
}

static void finish_point(const prob *P, ms_vec2 src, int reason, const cand *c, ms_point_fit *out)
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
    out->range = LEN_OUT(hyp(x, y));
    out->bearing = ATAN2(y, x);
    out->residual = LEN_OUT(c->rms);
    out->gdop = c->gd_inf ? NUM_OUT(BIGV) : NUM_OUT(c->gd);
}

static void finish_wall(const prob *P, ms_vec2 src, int reason, const cand *c, ms_wall_fit *out)
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
    out->distance = LEN_OUT(HALF(hyp(mx, my)));
    out->normal_angle = ATAN2(my, mx);
    out->foot_x = LEN_OUT(HALF(mx) + LEN_IN(src.x));
    out->foot_y = LEN_OUT(HALF(my) + LEN_IN(src.y));
    out->residual = LEN_OUT(c->rms);
    out->gdop = c->gd_inf ? NUM_OUT(BIGV) : NUM_OUT(HALF(c->gd));
}

int ms_solve_point(const ms_vec2 *rx, const ms_len_t *path, int n, ms_vec2 src, const ms_opts *opts,
                   ms_point_fit *out)
{
    prob P;
    cand c = {{0, 0}, 0, 0, 1, 0};
    int reason = setup(&P, rx, path, n, src, 2);
    if (reason == MS_OK) {
        apply_opts(&P, rx, opts);
        reason = point_core(&P, &c);
    }
    finish_point(&P, src, reason, &c, out);
    return out->valid;
}

int ms_solve_wall(const ms_vec2 *rx, const ms_len_t *path, int n, ms_vec2 src, const ms_opts *opts,
                  ms_wall_fit *out)
{
    prob P;
    cand c = {{0, 0}, 0, 0, 1, 0};
    int reason = setup(&P, rx, path, n, src, 2);
    if (reason == MS_OK) {
        apply_opts(&P, rx, opts);
        /* the wall's max_gdop applies to the mirror image (2x the distance gdop), as Python */
        reason = wall_core(&P, &c);
    }
    finish_wall(&P, src, reason, &c, out);
    return out->valid;
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

int ms_classify(const ms_vec2 *rx, const ms_len_t *path, int n, ms_vec2 src, ms_len_t noise_sigma,
                const ms_class_opts *opts, ms_class *out)
{
    prob P;
    ms_class_opts d;
    cand cp = {{0, 0}, 0, 0, 1, 0}, cw = {{0, 0}, 0, 0, 1, 0};
    int reason, sp = MS_BADIN, sw = MS_BADIN, i, e, w;
    real sig = LEN_IN(noise_sigma), x2[2], z, thr[3];
    if (!opts) {
        ms_class_opts_default(&d);
        opts = &d;
    }
    z = NUM_IN(opts->z);
    thr[0] = thr[1] = chi2_quantile(z, n - 2);
    thr[2] = n == 3 ? K(1e-6) : chi2_quantile(z, n - 3);
    out->kind = MS_KIND_UNCERTAIN;
    out->accepted = 0;
    for (i = 0; i < 3; i++) {
        out->chi2[i] = 0;
        out->thr[i] = NUM_OUT(thr[i]);
    }
    reason = setup(&P, rx, path, n, src, 3);
    if (reason == MS_OK && !(sig > 0 && ISFIN(sig))) reason = MS_BADIN;
    out->reason = (uint8_t)reason;
    if (reason == MS_OK) {
        P.no_tol = P.no_gdop = 1;
        P.tol = P.max_gdop = 0;
        P.fov = opts->fov;
        set_axis(&P, rx, opts->axis_mode, opts->axis);
        sp = point_core(&P, &cp);
        sw = wall_core(&P, &cw);
        for (i = 0; i < 2; i++) {
            real q = DIV(i == 0 ? cp.rms : cw.rms, sig);
            x2[i] = MUL(q, q) * n;
            if (!ISFIN(x2[i]) || x2[i] > BIGV) x2[i] = BIGV;
            out->chi2[i] = NUM_OUT(x2[i]);
        }
        e = (sp == MS_OK || sp == MS_AMBIG) && x2[0] <= thr[0];
        w = (sw == MS_OK || sw == MS_AMBIG) && x2[1] <= thr[1];
        out->accepted = (uint8_t)(e | (w << 1));
        if (e && !w) out->kind = MS_KIND_EDGE;
        else if (w && !e) out->kind = MS_KIND_WALL;
        else if (e && w) {
            real gap = x2[0] - x2[1];
            if (gap < K(-9.21)) out->kind = MS_KIND_EDGE;
            else if (gap > K(9.21)) out->kind = MS_KIND_WALL;
        }
    }
    finish_point(&P, src, sp, &cp, &out->point);
    finish_wall(&P, src, sw, &cw, &out->wall);
    return out->kind;
}
