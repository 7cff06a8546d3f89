/*
 * ms_geom.c - reflector geometry (point, wall, cylinder, edge/wall classification) for the RV32IM
 * soft-core; the algorithm of host/multisonar/geometry.py step by step (see ms_geom.h).
 * One source for all arithmetic variants: `real` is double, float or Q32.32 int64 and
 * every product / quotient / root goes through MUL / DIV / SQRT.
 */
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
 * fast 3-receiver path (MS_ARITH_Q only)
 *
 * Per pulse, for N = 3 and a prepared array: a closed-form start on the far receiver pair,
 * one Gauss-Newton step on the true residuals with all three receivers, and the residuals
 * re-evaluated at the polished point. 32-bit integers with 64-bit products (MUL/MULH), one
 * reciprocal square root per vector norm (interpolated table + one Newton step, no
 * division), no 64-bit division. Internal length unit 2^-2 um (int32: |v| < 2^27 units =
 * 33.5 m); unit vectors Q30, Jacobians Q29.
 *
 * Point start: with the source at the origin, x = rho*u (|u| = 1), receiver i gives
 * rho = a_i / (R_i - u.c_i), a_i = (R_i^2 - |c_i|^2)/2, so a pair fixes u by the linear
 * relation u.v = s (v = a_i c_j - a_j c_i, s = a_i R_j - a_j R_i): two unit vectors
 * symmetric about v, the one nearer the axis is the start, the other the mirror candidate.
 * Wall start: the circle pair of geometry._circle_pair (chord unit vector and 1/D
 * prepared). Gauss-Newton: the 2x2 normal equations through the three 2x2 minors of J
 * (Cauchy-Binet: no cancellation), gdop = sqrt(sum |J|^2 / sum minor^2). The residuals at
 * the polished point come from the distances at the start by a second-order expansion in
 * the step (|step| <= distance/128: remainder < 5e-9 of the distance; a longer step is
 * taken and the model re-evaluated, at most three steps).
 *
 * The answer is Python's whenever its decision rules reduce to "the polished start": the
 * start is physical, its misfit is within tol, it lies inside the fov round the axis and
 * the mirror candidate lies more than fov + 20 deg off the axis (then Python's other
 * candidate can neither win nor make the answer ambiguous). If the start's misfit exceeds
 * tol the mirror is polished too and must not explain the data either ('inconsistent
 * data'). Anything else (no axis, N != 3, lengths beyond 33 m, a pair whose curves do not
 * meet, gdop > 1000, still a step > distance/128 after three steps, a step that raises the
 * cost, a residual > 0.13 m, a misfit within 0.1% of tol) is handed to the general path,
 * the step-by-step port of the Python algorithm. On typical pulses (3 ring receivers, 0.5..4
 * m, +-20 deg, 1 us noise) the fast path answers > 99.9% of the calls
 * (tests/test_fw_geometry.py::test_q_fast_path_typical).
 * ====================================================================================== */
#if MS_GEOM_ARITH == MS_ARITH_Q
/* the per-pulse path is compiled for speed even in a -Os image (inlined 64-bit shifts, no calls) */
#pragma GCC push_options
#pragma GCC optimize("O2")
#define FQ_SH 2                            /* internal unit 2^-FQ_SH um */
#define FQ_LIM ((int32_t)1 << 27)          /* |length| limit, internal units */
#define FQ_FMAX ((int32_t)1 << 19)         /* |residual| and |step| limit (0.13 m) */
#define FQ_GDOP2_MAX ((int64_t)1000000)    /* gdop <= 1000 on the fast path */
#ifdef MS_GEOM_STATS
unsigned long ms_geom_stat_fast, ms_geom_stat_general; /* host builds: which path answered */
int ms_geom_stat_line;                                 /* the last line where the fast path declined */
#define FQ_STAT(x) ((x)++)
#define FQ_FAIL do { ms_geom_stat_line = __LINE__; return 0; } while (0)
#else
#define FQ_STAT(x) ((void)0)
#define FQ_FAIL return 0
#endif
#define FQ_INLINE static inline __attribute__((always_inline))
#define FQ_NOINLINE MS_HOT static __attribute__((noinline))

/* 2^34 / sqrt(i), i = 64..256: 1/sqrt(x) in Q2.30 at x = i/256 (first entry clamped) */
static const uint32_t fq_rsq_tab[193] = {
    2147483647u, 2130900515u, 2114695713u, 2098855072u, 2083365155u, 2068213208u,
    2053387115u, 2038875364u, 2024667000u, 2010751598u, 1997119227u, 1983760420u,
    1970666148u, 1957827796u, 1945237133u, 1932886296u, 1920767767u, 1908874354u,
    1897199172u, 1885735628u, 1874477404u, 1863418444u, 1852552937u, 1841875310u,
    1831380208u, 1821062491u, 1810917218u, 1800939636u, 1791125178u, 1781469447u,
    1771968208u, 1762617387u, 1753413056u, 1744351429u, 1735428857u, 1726641819u,
    1717986918u, 1709460876u, 1701060526u, 1692782810u, 1684624773u, 1676583559u,
    1668656406u, 1660840642u, 1653133683u, 1645533028u, 1638036256u, 1630641020u,
    1623345051u, 1616146146u, 1609042172u, 1602031062u, 1595110809u, 1588279468u,
    1581535151u, 1574876026u, 1568300315u, 1561806289u, 1555392273u, 1549056637u,
    1542797797u, 1536614214u, 1530504391u, 1524466875u, 1518500250u, 1512603139u,
    1506774204u, 1501012140u, 1495315679u, 1489683584u, 1484114654u, 1478607716u,
    1473161629u, 1467775280u, 1462447584u, 1457177486u, 1451963954u, 1446805984u,
    1441702596u, 1436652834u, 1431655765u, 1426710480u, 1421816090u, 1416971728u,
    1412176548u, 1407429723u, 1402730445u, 1398077927u, 1393471397u, 1388910104u,
    1384393311u, 1379920300u, 1375490368u, 1371102827u, 1366757007u, 1362452250u,
    1358187913u, 1353963368u, 1349778000u, 1345631207u, 1341522400u, 1337451002u,
    1333416450u, 1329418191u, 1325455684u, 1321528399u, 1317635818u, 1313777432u,
    1309952745u, 1306161267u, 1302402522u, 1298676040u, 1294981364u, 1291318043u,
    1287685637u, 1284083712u, 1280511845u, 1276969620u, 1273456629u, 1269972473u,
    1266516759u, 1263089103u, 1259689126u, 1256316458u, 1252970736u, 1249651603u,
    1246358707u, 1243091706u, 1239850262u, 1236634043u, 1233442724u, 1230275986u,
    1227133513u, 1224014999u, 1220920139u, 1217848637u, 1214800200u, 1211774541u,
    1208771378u, 1205790433u, 1202831433u, 1199894112u, 1196978204u, 1194083452u,
    1191209601u, 1188356400u, 1185523604u, 1182710970u, 1179918260u, 1177145240u,
    1174391680u, 1171657354u, 1168942037u, 1166245512u, 1163567563u, 1160907976u,
    1158266544u, 1155643060u, 1153037323u, 1150449133u, 1147878294u, 1145324612u,
    1142787899u, 1140267967u, 1137764631u, 1135277711u, 1132807028u, 1130352405u,
    1127913670u, 1125490652u, 1123083182u, 1120691096u, 1118314230u, 1115952423u,
    1113605518u, 1111273357u, 1108955787u, 1106652658u, 1104363818u, 1102089122u,
    1099828424u, 1097581581u, 1095348453u, 1093128899u, 1090922784u, 1088729972u,
    1086550331u, 1084383727u, 1082230034u, 1080089122u, 1077960865u, 1075845140u,
    1073741824u,
};
static const uint8_t fq_clz8[256] = {
    8, 7, 6, 6, 5, 5, 5, 5, 4, 4, 4, 4, 4, 4, 4, 4,
    3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3,
    2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2,
    2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2,
    1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1,
    1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1,
    1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1,
    1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1,
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
};

/* 32 x 32 -> 64-bit products: MUL + MULH (GCC otherwise widens some to 64 x 64, 3-4 MULs) */
#if defined(__riscv) && __riscv_xlen == 32
FQ_INLINE int64_t fq_smul(int32_t a, int32_t b)
{
    int32_t hi;
    __asm__("mulh %0, %1, %2" : "=r"(hi) : "r"(a), "r"(b));
    return (int64_t)(((uint64_t)(uint32_t)hi << 32) | (uint32_t)((uint32_t)a * (uint32_t)b));
}
FQ_INLINE int64_t fq_sumul(int32_t a, uint32_t b) /* signed x unsigned */
{
    int32_t hi;
    __asm__("mulhsu %0, %1, %2" : "=r"(hi) : "r"(a), "r"(b));
    return (int64_t)(((uint64_t)(uint32_t)hi << 32) | (uint32_t)((uint32_t)a * b));
}
#else
FQ_INLINE int64_t fq_smul(int32_t a, int32_t b) { return (int64_t)a * b; }
FQ_INLINE int64_t fq_sumul(int32_t a, uint32_t b) { return (int64_t)a * (int64_t)b; }
#endif

FQ_INLINE int fq_clz32(uint32_t v) /* v != 0 */
{
    int n = 0;
    if (!(v >> 16)) { n = 16; v <<= 16; }
    if (!(v >> 24)) { n += 8; v <<= 8; }
    return n + fq_clz8[v >> 24];
}
/* bits to drop so that |v| < 2^30 */
FQ_INLINE int fq_drop30(uint64_t m)
{
    uint32_t h = (uint32_t)(m >> 32), l = (uint32_t)m;
    if (h) return 34 - fq_clz32(h);
    return (l >> 30) ? 2 - fq_clz32(l) : 0;
}
/* 1/sqrt(s) for 0 < s < 2^64: y in [2^30, 2^31] with 1/sqrt(s) = y * 2^(k2 - 62) (relative
 * error < 2^-28); *hi = the top 32 bits of s normalised by an even shift (for the root) */
FQ_INLINE uint32_t fq_rsqrt_body(uint64_t s, int *k2, uint32_t *hio)
{
    uint32_t h = (uint32_t)(s >> 32), l = (uint32_t)s, hi, y0, y1, i, y, y2, xy2;
    int k;
    if (h) {
        k = fq_clz32(h) & ~1;
        hi = k ? (h << k) | (l >> (32 - k)) : h;
    } else {
        k = 32 + (fq_clz32(l) & ~1);
        hi = l << (k - 32);
    }
    i = (hi >> 24) - 64;
    y0 = fq_rsq_tab[i];
    y1 = fq_rsq_tab[i + 1];
    y = y0 - (((y0 - y1) * ((hi >> 16) & 0xFFu)) >> 8);
    y2 = (uint32_t)(((uint64_t)y * y) >> 32);
    xy2 = (uint32_t)(((uint64_t)hi * y2) >> 32);
    y = (uint32_t)(((uint64_t)y * ((3u << 28) - xy2)) >> 29);
    *k2 = k >> 1;
    *hio = hi;
    return y;
}
/* one copy (not inlined at its ~18 uses per fix): the per-pulse code stays small enough to
 * share a 16 KiB instruction cache with the application's loop (firmware/README.md) */
FQ_NOINLINE uint32_t fq_rsqrt(uint64_t s, int *k2, uint32_t *hio) { return fq_rsqrt_body(s, k2, hio); }
/* round(sqrt(s)) from fq_rsqrt's results */
FQ_INLINE int32_t fq_root(uint32_t hi, uint32_t y, int k2)
{
    uint32_t p = (uint32_t)(((uint64_t)hi * y) >> 32); /* sqrt(s) * 2^(k2 - 2) */
    if (k2 >= 3) return (int32_t)((p + (1u << (k2 - 3))) >> (k2 - 2));
    return (int32_t)(p << (2 - k2));
}
FQ_INLINE int32_t fq_sqrt(uint64_t s)
{
    int k2;
    uint32_t hi, y;
    if (!s) return 0;
    y = fq_rsqrt(s, &k2, &hi);
    return fq_root(hi, y, k2);
}
/* (p >> sh) as int32, 0 < sh < 32 */
FQ_INLINE int32_t fq_sr(int64_t p, int sh)
{
    return (int32_t)(((uint32_t)p >> sh) | ((uint32_t)(p >> 32) << (32 - sh)));
}
/* v / sqrt(s) in Q30 (|v| <= sqrt(s)), from fq_rsqrt */
FQ_INLINE int32_t fq_unit(int32_t v, uint32_t y, int k2) { return fq_sr(fq_sumul(v, y), 32 - k2); }
/* (x * r) >> sh for |x| < 2^62, r < 2^32, 32 <= sh < 96 */
FQ_INLINE int64_t fq_mulr(int64_t x, uint32_t r, int sh)
{
    int64_t t = fq_sumul((int32_t)(x >> 32), r) + (int64_t)(((uint64_t)(uint32_t)x * r) >> 32);
    sh -= 32;
    return sh < 63 ? t >> sh : (t < 0 ? -1 : 0);
}
/* 1/s = r * 2^-e, r in [2^29, 2^31] */
FQ_INLINE uint32_t fq_recip(uint64_t s, int *e)
{
    int k2;
    uint32_t hi, y = fq_rsqrt(s, &k2, &hi);
    *e = 93 - 2 * k2;
    return (uint32_t)(((uint64_t)y * y) >> 31);
}
FQ_INLINE int32_t fq_in(int32_t um) { return um * (1 << FQ_SH); }
FQ_INLINE int32_t fq_out(int32_t v) { return (v + (1 << (FQ_SH - 1))) >> FQ_SH; }
FQ_INLINE int64_t fq_sq(int32_t x, int32_t y) { return fq_smul(x, x) + fq_smul(y, y); }
FQ_INLINE int32_t fq_dot30(int32_t x, int32_t y, int32_t ux, int32_t uy)
{
    return (int32_t)((fq_smul(x, ux) + fq_smul(y, uy)) >> 30);
}

/* 1/D for D in [1, 2) at the midpoints of 64 intervals, Q30 */
static const uint32_t fq_rcp_tab[64] = {
    1065418244u, 1049152317u, 1033375590u, 1018066322u, 1003204040u, 988769449u, 974744351u, 961111563u,
    947854852u, 934958867u, 922409084u, 910191745u, 898293814u, 886702926u, 875407347u, 864395934u,
    853658096u, 843183764u, 832963354u, 822987745u, 813248245u, 803736570u, 794444818u, 785365448u,
    776491263u, 767815383u, 759331235u, 751032533u, 742913262u, 734967666u, 727190230u, 719575673u,
    712118930u, 704815146u, 697659662u, 690648007u, 683775888u, 677039180u, 670433919u, 663956297u,
    657602648u, 651369448u, 645253303u, 639250946u, 633359233u, 627575130u, 621895717u, 616318177u,
    610839793u, 605457945u, 600170102u, 594973825u, 589866753u, 584846611u, 579911196u, 575058383u,
    570286114u, 565592401u, 560975320u, 556433010u, 551963669u, 547565552u, 543236970u, 538976288u,
};
/* 2^60 / d for d in [2^30, 2^31): 1/D in Q30 (table seed within 0.8%, two Newton steps) */
FQ_INLINE uint32_t fq_recip_q30(uint32_t d)
{
    uint32_t r = fq_rcp_tab[(d >> 24) & 63], e;
    e = (2u << 30) - (uint32_t)(((uint64_t)d * r) >> 30);
    r = (uint32_t)(((uint64_t)r * e) >> 30);
    e = (2u << 30) - (uint32_t)(((uint64_t)d * r) >> 30);
    return (uint32_t)(((uint64_t)r * e) >> 30);
}
/* atan(t)/t = sum c_k t^2k, Q30, |t| <= tan(pi/8): truncation < 2e-8 rad */
static const int32_t fq_atan_c[8] = {1073741824, -357913941, 214748365, -153391689,
                                     119304647,  -97612893,  82595525,  -71582788};
/* atan2 as a binary angle (2^32 per turn), error < 3e-8 rad */
MS_HOT static ms_ang_t fq_atan2(int32_t y, int32_t x)
{
    uint32_t ax = x < 0 ? (uint32_t)0 - (uint32_t)x : (uint32_t)x;
    uint32_t ay = y < 0 ? (uint32_t)0 - (uint32_t)y : (uint32_t)y;
    uint32_t mx = ax > ay ? ax : ay, mn = ax > ay ? ay : ax, t;
    int32_t acc, t2;
    int sh, i, red = 0;
    int64_t ang; /* Q30 radians */
    if (!mx) return 0;
    sh = fq_clz32(mx) - 1; /* mx -> [2^30, 2^31) */
    mx <<= sh;
    mn <<= sh;
    t = (uint32_t)(((uint64_t)mn * fq_recip_q30(mx)) >> 30); /* Q30, <= 1 */
    if (t > 444723848u) {                                     /* tan(pi/8): pi/4 - atan((1-t)/(1+t)) */
        t = (uint32_t)(((uint64_t)((1u << 30) - t) * fq_recip_q30((1u << 30) + t)) >> 30);
        red = 1;
    }
    t2 = (int32_t)(((uint64_t)t * t) >> 30);
    acc = fq_atan_c[7];
    for (i = 6; i >= 0; i--) acc = fq_atan_c[i] + (int32_t)(fq_smul(acc, t2) >> 30);
    ang = fq_smul(acc, (int32_t)t) >> 30;
    if (red) ang = 843314857 - ang;      /* pi/4 - a */
    if (ay > ax) ang = 1686629713 - ang;  /* pi/2 - a */
    if (x < 0) ang = 3373259426LL - ang; /* pi - a */
    if (y < 0) ang = -ang;
    /* Q30 radians -> 2^32 per turn: * 2/pi */
    return (ms_ang_t)(uint32_t)(int32_t)((ang * 683565276LL + ((int64_t)1 << 29)) >> 30);
}

/* distances from p to the receivers, their unit vectors (Q30) and 1/sqrt factors */
typedef struct {
    int32_t L[3], ux[3], uy[3];
    uint32_t y[3];
    int8_t k2[3];
} fqd;

FQ_INLINE int fq_dist(const ms_array *a, int32_t px, int32_t py, fqd *d)
{
    int k;
    for (k = 0; k < 3; k++) {
        int32_t dx = px - a->cx[k], dy = py - a->cy[k];
        uint32_t hi, y;
        int k2;
        if (!(dx | dy)) FQ_FAIL;
        y = fq_rsqrt_body((uint64_t)fq_sq(dx, dy), &k2, &hi); /* inlined in this loop only */
        d->L[k] = fq_root(hi, y, k2);
        d->ux[k] = fq_unit(dx, y, k2);
        d->uy[k] = fq_unit(dy, y, k2);
        d->y[k] = y;
        d->k2[k] = (int8_t)k2;
    }
    return 1;
}
/* |d + step| from |d| = L, unit u, 1/L = y 2^(k2-62): second order in the step, |step| <= L/128 */
FQ_INLINE int32_t fq_moved(int32_t L, int32_t ux, int32_t uy, uint32_t y, int k2, int32_t sx, int32_t sy,
                           int64_t s2)
{
    int32_t al = fq_dot30(sx, sy, ux, uy), corr, aL;
    int64_t b2 = s2 - fq_smul(al, al); /* step across u, squared */
    if (b2 < 0) b2 = 0;
    corr = (int32_t)(((uint64_t)(uint32_t)(b2 >> 8) * y) >> (55 - k2)); /* b2 / (2L) */
    aL = fq_unit(al, y, k2);                                               /* al / L, Q30 */
    return L + al + corr - (int32_t)(fq_smul(corr, aL) >> 30);
}

/* One Gauss-Newton step for three residuals f and J (Q29). Returns 0 when singular or
 * beyond the fast path's range; else step and gdop^2 (Q16). Normal equations through the
 * three 2x2 minors m_kl of J (Cauchy-Binet): det = sum m^2, adj(J^T J) J^T f = sum m_kl e_kl. */
#define FQ_MINOR(a0, a1, b0, b1) ((int32_t)((fq_smul(a0, b1) - fq_smul(a1, b0)) >> 30)) /* Q28 */
#define FQ_E(ja, fb, jb, fa) ((int32_t)((fq_smul(ja, fb) - fq_smul(jb, fa)) >> 20))    /* Q9 */
FQ_INLINE int fq_gn3(int32_t J[3][2], const int32_t f[3], int32_t step[2], int64_t *gd2)
{
    int32_t a0 = J[0][0], a1 = J[0][1], b0 = J[1][0], b1 = J[1][1], c0 = J[2][0], c1 = J[2][1];
    int32_t fa = f[0], fb = f[1], fc = f[2];
    int32_t m01 = FQ_MINOR(a0, a1, b0, b1), m02 = FQ_MINOR(a0, a1, c0, c1), m12 = FQ_MINOR(b0, b1, c0, c1);
    int64_t det, n0, n1, sj, s0, s1;
    uint32_t r;
    int e;
    det = fq_smul(m01, m01) + fq_smul(m02, m02) + fq_smul(m12, m12); /* Q56 */
    n0 = fq_smul(m01, FQ_E(b1, fa, a1, fb)) + fq_smul(m02, FQ_E(c1, fa, a1, fc)) + fq_smul(m12, FQ_E(c1, fb, b1, fc));
    n1 = fq_smul(m01, FQ_E(a0, fb, b0, fa)) + fq_smul(m02, FQ_E(a0, fc, c0, fa)) + fq_smul(m12, FQ_E(b0, fc, c0, fb));
    sj = (fq_sq(a0, a1) >> 2) + (fq_sq(b0, b1) >> 2) + (fq_sq(c0, c1) >> 2); /* Q56 */
    if (det < ((int64_t)1 << 24)) FQ_FAIL;
    r = fq_recip((uint64_t)det, &e);
    if (e - 16 < 32) FQ_FAIL;
    *gd2 = fq_mulr(sj, r, e - 16);
    if (*gd2 > (FQ_GDOP2_MAX << 16)) FQ_FAIL;
    /* step = -(J^T J)^-1 J^T f = -n / det * 2^(56 - 37) */
    s0 = -fq_mulr(n0, r, e - 19);
    s1 = -fq_mulr(n1, r, e - 19);
    if (s0 > FQ_FMAX || s0 < -FQ_FMAX || s1 > FQ_FMAX || s1 < -FQ_FMAX) FQ_FAIL;
    step[0] = (int32_t)s0;
    step[1] = (int32_t)s1;
    return 1;
}

typedef struct {
    int32_t x, y;  /* polished point / mirror image (internal units) */
    int32_t rho;   /* |x| */
    int32_t rms;
    int64_t gd2;   /* gdop^2 Q16 (point: of x; wall: of m, i.e. 4x the distance gdop^2) */
    int ok;        /* physical */
    int inside;    /* inside the fov round the axis */
} fqfit;

/* polish the start p0 = (px, py) with |p0| = rho0 and unit (ux, uy), fill out; 0 -> general path.
 * One Gauss-Newton step; up to two more (full re-evaluations) while the step is longer than
 * rho/128 (the wrong model's fit, e.g. a wall through an edge's echoes, starts further off). */
MS_HOT static int fq_polish(int wall, const ms_array *a, const int32_t *r, int32_t px, int32_t py, int32_t rho0,
                            int32_t ux, int32_t uy, uint32_t y0, int k20, fqfit *out)
{
    int32_t f[3], J[3][2], st[2];
    int64_t c0, c1 = 0, s2, c_prev = INT64_MAX;
    fqd d;
    int k, it;
    uint32_t hi;
    for (it = 0;; it++) {
        /* J = (u_k + u) / 2 as (u_k >> 1) + (u >> 1) + (u_k & u & 1): u_k + u overflows int32 when
         * both are exactly 1 (Q30 2^30: a perpendicular wall, a receiver at or in line with the source) */
        int32_t hx = wall ? 0 : ux >> 1, hy = wall ? 0 : uy >> 1, lx = wall ? 0 : ux & 1, ly = wall ? 0 : uy & 1;
        if (!fq_dist(a, px, py, &d)) return 0;
        c0 = 0;
        for (k = 0; k < 3; k++) {
            int32_t fk = (wall ? 0 : rho0) + d.L[k] - r[k];
            if (fk > FQ_FMAX || fk < -FQ_FMAX) FQ_FAIL;
            f[k] = fk;
            J[k][0] = (d.ux[k] >> 1) + hx + (d.ux[k] & lx); /* (u_k + u) / 2, floor, no overflow */
            J[k][1] = (d.uy[k] >> 1) + hy + (d.uy[k] & ly);
            c0 += fq_smul(fk, fk);
        }
        if (c0 > c_prev) FQ_FAIL; /* the long step did not lower the cost: Python damps it */
        if (!fq_gn3(J, f, st, &out->gd2)) return 0;
        s2 = fq_sq(st[0], st[1]);
        if ((s2 << 14) <= fq_smul(rho0, rho0)) break; /* |step| <= rho/128: the expansion holds */
        if (it == 2) FQ_FAIL;
        px += st[0];
        py += st[1];
        if (px >= FQ_LIM || px <= -FQ_LIM || py >= FQ_LIM || py <= -FQ_LIM) FQ_FAIL;
        y0 = fq_rsqrt((uint64_t)fq_sq(px, py), &k20, &hi);
        rho0 = fq_root(hi, y0, k20);
        ux = fq_unit(px, y0, k20);
        uy = fq_unit(py, y0, k20);
        c_prev = c0;
    }
    out->rho = fq_moved(rho0, ux, uy, y0, k20, st[0], st[1], s2);
    for (k = 0; k < 3; k++) {
        int32_t fk = (wall ? 0 : out->rho) - r[k] +
                     fq_moved(d.L[k], d.ux[k], d.uy[k], d.y[k], d.k2[k], st[0], st[1], s2);
        if (fk > FQ_FMAX || fk < -FQ_FMAX) FQ_FAIL;
        c1 += fq_smul(fk, fk);
    }
    if (c1 > c0 + (c0 >> 16) + 64) FQ_FAIL; /* Python would damp the step: let the general path do it */
    px += st[0];
    py += st[1];
    out->x = px;
    out->y = py;
    out->rms = (int32_t)(((int64_t)fq_sqrt((uint64_t)c1) * 619925131 + (1 << 29)) >> 30); /* / sqrt(3) */
    if (wall) {
        int64_t m2 = fq_sq(px, py);
        out->ok = m2 > 0;
        for (k = 0; k < 3; k++)
            if (!(2 * (fq_smul(px, a->cx[k]) + fq_smul(py, a->cy[k])) < m2)) out->ok = 0;
    } else {
        out->ok = out->rho > 0;
    }
    out->inside = (fq_smul(px, a->ax) + fq_smul(py, a->ay)) >= fq_smul(out->rho, a->cos_fov);
    return 1;
}

/* point start: fills x0, rho0, unit u0 (the candidate nearer the axis; mirror[] the other's
 * data for a second polish when asked); 0 -> general path */
typedef struct {
    int32_t x, y, rho, ux, uy;
    uint32_t yr;
    int k2;
} fqstart;

MS_HOT static int fq_point_start(const ms_array *a, const int32_t *r, int want_mirror, fqstart st[2])
{
    int i = a->pi, j = a->pj, ka, kv, k2, q;
    int64_t ai = (fq_smul(r[i], r[i]) - a->cc[i]) >> 1, aj = (fq_smul(r[j], r[j]) - a->cc[j]) >> 1;
    int64_t vx, vy, s, v2, disc, lhs;
    uint32_t hi, y, rr;
    int32_t Ai, Aj, vxs, vys, ss, sq, sg, p, pq;
    int e;
    if (ai <= 0 || aj <= 0) FQ_FAIL;
    ka = fq_drop30((uint64_t)(ai > aj ? ai : aj));
    Ai = (int32_t)(ai >> ka);
    Aj = (int32_t)(aj >> ka);
    vx = fq_smul(Ai, a->cx[j]) - fq_smul(Aj, a->cx[i]);
    vy = fq_smul(Ai, a->cy[j]) - fq_smul(Aj, a->cy[i]);
    s = fq_smul(Ai, r[j]) - fq_smul(Aj, r[i]);
    kv = fq_drop30((uint64_t)(vx < 0 ? -vx : vx) | (uint64_t)(vy < 0 ? -vy : vy) | (uint64_t)(s < 0 ? -s : s));
    vxs = (int32_t)(vx >> kv);
    vys = (int32_t)(vy >> kv);
    ss = (int32_t)(s >> kv);
    v2 = fq_sq(vxs, vys);
    if (v2 < ((int64_t)1 << 40)) FQ_FAIL; /* pair nearly degenerate */
    disc = v2 - fq_smul(ss, ss);
    if (disc <= 0) FQ_FAIL; /* the two ellipses do not meet (or touch): general path */
    sq = fq_sqrt((uint64_t)disc);
    /* u = (s v +- sq perp(v)) / |v|^2; the sign whose u is nearer the axis first */
    p = fq_dot30(vxs, vys, a->ax, a->ay);
    pq = fq_dot30(-vys, vxs, a->ax, a->ay);
    sg = pq >= 0 ? sq : -sq;
    /* the mirror (sign -sg) must be more than fov + 20 deg off the axis */
    lhs = fq_smul(ss, p) - fq_smul(sg, pq);
    if (!((lhs >> 30) < (((v2 >> 30) * a->cos_mir) >> 30))) FQ_FAIL;
    rr = fq_recip((uint64_t)v2, &e); /* 1/v2 = rr 2^-e */
    for (q = 0; q <= want_mirror; q++) {
        int32_t g = q ? -sg : sg, ux, uy, den;
        int64_t rho;
        ux = (int32_t)fq_mulr(fq_smul(ss, vxs) - fq_smul(g, vys), rr, e - 30);
        uy = (int32_t)fq_mulr(fq_smul(ss, vys) + fq_smul(g, vxs), rr, e - 30);
        den = r[i] - fq_dot30(a->cx[i], a->cy[i], ux, uy);
        if (den <= 0) FQ_FAIL;
        y = fq_rsqrt((uint64_t)den * (uint64_t)den, &k2, &hi); /* 1/den = y 2^(k2 - 62) */
        rho = fq_mulr(ai, y, 62 - k2);
        if (rho <= 0 || rho >= FQ_LIM) FQ_FAIL;
        st[q].x = (int32_t)(fq_smul((int32_t)rho, ux) >> 30);
        st[q].y = (int32_t)(fq_smul((int32_t)rho, uy) >> 30);
        st[q].rho = (int32_t)rho;
        st[q].ux = ux;
        st[q].uy = uy;
        /* 1/rho for the expansion of |x|: rho = a_i / den -> 1/rho = den / a_i; use the root */
        st[q].yr = fq_rsqrt((uint64_t)fq_sq(st[q].x, st[q].y), &st[q].k2, &hi);
    }
    return 1;
}

/* is the direction (x, y) more than fov + 20 deg off the axis? */
MS_HOT static int fq_far_off(const ms_array *a, int64_t x, int64_t y)
{
    int64_t d, n2;
    int sh = fq_drop30((uint64_t)(x < 0 ? -x : x) | (uint64_t)(y < 0 ? -y : y));
    x >>= sh;
    y >>= sh;
    d = (x * (a->ax >> 15) + y * (a->ay >> 15)) >> 15; /* |p| cos(off) */
    n2 = x * x + y * y;
    if (a->cos_mir >= 0) {
        if (d <= 0) return 1;
        return (d * d) < ((n2 >> 30) * (((int64_t)a->cos_mir * a->cos_mir) >> 30));
    }
    if (d >= 0) return 0;
    return (d * d) > ((n2 >> 30) * (((int64_t)a->cos_mir * a->cos_mir) >> 30));
}

MS_HOT static int fq_wall_start(const ms_array *a, const int32_t *r, int want_mirror, fqstart st[2])
{
    int i = a->pi, q, k2;
    int32_t ri = r[i], rj = r[a->pj], t, al, h, b[2], c[2][2];
    int64_t h2;
    uint32_t hi;
    t = (int32_t)fq_mulr((int64_t)(ri - rj) << 32, a->dinv, a->dsh + 2); /* (R_i - R_j)/D, Q30 */
    if (t > (1 << 30) || t < -(1 << 30)) FQ_FAIL;
    al = (int32_t)((fq_smul(t, ri + rj) >> 31) + (a->dd >> 1));
    h2 = fq_smul(ri, ri) - fq_smul(al, al);
    if (h2 <= 0) FQ_FAIL;
    h = fq_sqrt((uint64_t)h2);
    b[0] = a->cx[i] + (int32_t)(fq_smul(al, a->ex) >> 30);
    b[1] = a->cy[i] + (int32_t)(fq_smul(al, a->ey) >> 30);
    c[0][0] = b[0] - (int32_t)(fq_smul(h, a->ey) >> 30);
    c[0][1] = b[1] + (int32_t)(fq_smul(h, a->ex) >> 30);
    c[1][0] = 2 * b[0] - c[0][0];
    c[1][1] = 2 * b[1] - c[0][1];
    q = (fq_smul(c[0][0], a->ax) + fq_smul(c[0][1], a->ay)) < (fq_smul(c[1][0], a->ax) + fq_smul(c[1][1], a->ay));
    if (!fq_far_off(a, c[q ^ 1][0], c[q ^ 1][1])) FQ_FAIL;
    for (i = 0; i <= want_mirror; i++) {
        int32_t x = c[q ^ i][0], y = c[q ^ i][1];
        if (x >= FQ_LIM || x <= -FQ_LIM || y >= FQ_LIM || y <= -FQ_LIM) FQ_FAIL;
        st[i].x = x;
        st[i].y = y;
        st[i].yr = fq_rsqrt((uint64_t)fq_sq(x, y), &k2, &hi);
        st[i].k2 = k2;
        st[i].rho = fq_root(hi, st[i].yr, k2);
        st[i].ux = fq_unit(x, st[i].yr, k2);
        st[i].uy = fq_unit(y, st[i].yr, k2);
    }
    return 1;
}

/* The fast solve: returns 0 -> general path; else *reason and the chosen fit */
MS_HOT static int fq_solve(int wall, const ms_array *a, const ms_len_t *path, int no_tol, int no_gdop,
                           fqfit *best, int *reason)
{
    int32_t r[3], tol;
    fqstart st[2];
    fqfit k1;
    int q;
    if (!a->fast) FQ_FAIL;
    for (q = 0; q < 3; q++) {
        if (path[q] <= 0 || path[q] >= (FQ_LIM >> FQ_SH)) FQ_FAIL;
        r[q] = fq_in(path[q]);
        if (!(fq_smul(r[q], r[q]) > a->cc[q] + (a->cc[q] >> 20) + 1)) FQ_FAIL; /* short: general path */
    }
    if (!(wall ? fq_wall_start(a, r, 0, st) : fq_point_start(a, r, 0, st))) return 0;
    if (!fq_polish(wall, a, r, st[0].x, st[0].y, st[0].rho, st[0].ux, st[0].uy, st[0].yr, st[0].k2, best))
        return 0;
    if (!best->ok) FQ_FAIL;
    tol = a->opts.tol >= (FQ_LIM >> FQ_SH) ? FQ_LIM : fq_in(a->opts.tol);
    if (no_tol || best->rms <= tol - (tol >> 10)) {
        if (!best->inside) FQ_FAIL; /* Python's answer depends on the mirror: general path */
        *reason = MS_OK;
    } else {
        /* the start does not explain the data: Python takes the mirror if that does */
        if (best->rms < tol + (tol >> 10)) FQ_FAIL; /* knife edge: general path */
        if (!(wall ? fq_wall_start(a, r, 1, st) : fq_point_start(a, r, 1, st))) return 0;
        if (!fq_polish(wall, a, r, st[1].x, st[1].y, st[1].rho, st[1].ux, st[1].uy, st[1].yr, st[1].k2, &k1))
            return 0;
        if (k1.ok && k1.rms <= tol + (tol >> 2)) FQ_FAIL; /* the mirror may win: general path */
        *reason = MS_INCONS;
    }
    if (*reason == MS_OK && !no_gdop) {
        int64_t g2 = wall ? best->gd2 >> 2 : best->gd2, mg = a->opts.max_gdop;
        /* gdop^2 (Q16) against max_gdop^2 (Q16.16 -> Q16) */
        if (mg < (1 << 30) && g2 > ((mg * mg) >> 16)) *reason = MS_ILLCOND;
    }
    return 1;
}

MS_HOT static void fq_out_point(const ms_array *a, int reason, const fqfit *k, ms_point_fit *out)
{
    out->reason = (uint8_t)reason;
    out->valid = reason == MS_OK;
    if (!out->valid) {
        out->x = out->y = out->range = out->residual = 0;
        out->bearing = 0;
        out->gdop = 0;
        return;
    }
    out->x = fq_out(k->x) + a->src.x;
    out->y = fq_out(k->y) + a->src.y;
    out->range = fq_out(k->rho);
    out->bearing = fq_atan2(k->y, k->x);
    out->residual = fq_out(k->rms);
    out->gdop = fq_sqrt((uint64_t)(k->gd2 << 16)); /* Q16.16 */
}

MS_HOT static void fq_out_wall(const ms_array *a, int reason, const fqfit *k, ms_wall_fit *out)
{
    out->reason = (uint8_t)reason;
    out->valid = reason == MS_OK;
    if (!out->valid) {
        out->distance = out->foot_x = out->foot_y = out->residual = 0;
        out->normal_angle = 0;
        out->gdop = 0;
        return;
    }
    out->distance = fq_out(k->rho >> 1);
    out->normal_angle = fq_atan2(k->y, k->x);
    out->foot_x = fq_out(k->x >> 1) + a->src.x;
    out->foot_y = fq_out(k->y >> 1) + a->src.y;
    out->residual = fq_out(k->rms);
    out->gdop = fq_sqrt((uint64_t)((k->gd2 >> 2) << 16));
}

/* chi-square (Q16.16, unsaturated) of an rms misfit: rms^2 * 3 / sigma^2 */
MS_HOT static int64_t fq_chi2(const ms_array *a, int32_t rms)
{
    return fq_mulr(fq_smul(rms, rms) * 3, a->sinv, a->ssh - 16);
}
#pragma GCC pop_options
#endif /* MS_ARITH_Q fast path */

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

#if MS_GEOM_ARITH == MS_ARITH_Q
/* cos and sin of a binary angle, Q30 (CORDIC rotation, 40 steps; prepare only) */
static void q_cossin(ang th, int32_t *c, int32_t *s)
{
    int64_t z = (int64_t)th * 65536, x = 652032874LL, y = 0, t; /* z in 2^-48 turns; x = K * 2^30 */
    int i, flip = 0;
    if (z > ((int64_t)1 << 46)) { z -= (int64_t)1 << 47; flip = 1; }
    else if (z < -((int64_t)1 << 46)) { z += (int64_t)1 << 47; flip = 1; }
    for (i = 0; i < 40; i++) {
        if (z >= 0) { t = x - (y >> i); y += x >> i; x = t; z -= cordic_tab[i]; }
        else { t = x + (y >> i); y -= x >> i; x = t; z += cordic_tab[i]; }
    }
    if (flip) { x = -x; y = -y; }
    *c = (int32_t)(x > (1 << 30) ? (1 << 30) : x < -(1 << 30) ? -(1 << 30) : x);
    *s = (int32_t)(y > (1 << 30) ? (1 << 30) : y < -(1 << 30) ? -(1 << 30) : y);
}
#endif

int ms_prepare(ms_array *a, const ms_vec2 *rx, int n, ms_vec2 src, const ms_opts *opts,
               const ms_class_opts *copts, ms_len_t noise_sigma)
{
    ms_class_opts dc;
    real z, sig = LEN_IN(noise_sigma);
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
#if MS_GEOM_ARITH == MS_ARITH_Q
    if (!a->bad && n == 3 && a->opts.axis_mode != MS_AXIS_NONE && sig > 0) {
        prob P;
        int32_t cf, sf;
        int j, ok = 1;
        int64_t best = -1;
        uint64_t m;
        P.n = n;
        for (i = 0; i < 3; i++) {
            int64_t dx = (int64_t)rx[i].x - src.x, dy = (int64_t)rx[i].y - src.y;
            if (dx >= (FQ_LIM >> FQ_SH) || dx <= -(FQ_LIM >> FQ_SH) || dy >= (FQ_LIM >> FQ_SH) ||
                dy <= -(FQ_LIM >> FQ_SH))
                ok = 0;
            a->cx[i] = fq_in((int32_t)dx);
            a->cy[i] = fq_in((int32_t)dy);
            a->cc[i] = fq_sq(a->cx[i], a->cy[i]);
        }
        a->pi = 0;
        a->pj = 1;
        for (i = 0; ok && i < 3; i++)
            for (j = i + 1; j < 3; j++) {
                int64_t d2 = fq_sq(a->cx[j] - a->cx[i], a->cy[j] - a->cy[i]);
                if (d2 > best) { best = d2; a->pi = (uint8_t)i; a->pj = (uint8_t)j; }
            }
        if (ok && best > 0) {
            uint32_t hi, y;
            int k2;
            y = fq_rsqrt((uint64_t)best, &k2, &hi);
            a->dd = fq_root(hi, y, k2);
            a->ex = fq_unit(a->cx[a->pj] - a->cx[a->pi], y, k2);
            a->ey = fq_unit(a->cy[a->pj] - a->cy[a->pi], y, k2);
            a->dinv = y; /* 1/D = y 2^(k2 - 62) */
            a->dsh = 62 - k2;
        } else {
            ok = 0;
        }
        set_axis(&P, rx, a->opts.axis_mode, a->opts.axis);
        if (!P.has_axis) ok = 0;
        q_cossin(P.axis, &a->ax, &a->ay);
        q_cossin(a->opts.fov, &cf, &sf);
        a->cos_fov = cf;
        /* fov + 20 deg, at most half a turn */
        m = (uint64_t)(uint32_t)a->opts.fov + (uint64_t)(uint32_t)MS_Q_ANG_FROM_DEG(20.0);
        if ((uint32_t)a->opts.fov >= 0x80000000u || m >= 0x80000000u) a->cos_mir = -(1 << 30);
        else { q_cossin((ang)(uint32_t)m, &cf, &sf); a->cos_mir = cf; }
        if ((uint32_t)a->opts.fov >= 0x80000000u) ok = 0;
        {
            int64_t s2 = (int64_t)fq_in(noise_sigma > (FQ_LIM >> FQ_SH) ? 1 : noise_sigma);
            int e;
            a->sinv = fq_recip((uint64_t)(s2 * s2), &e);
            a->ssh = e;
            if (noise_sigma > (FQ_LIM >> FQ_SH)) ok = 0;
        }
        a->fast = (uint8_t)ok;
    }
#else
    (void)sig;
#endif
    return a->fast;
}

/* the general path's problem for a prepared array */
static int prepared_setup(const ms_array *a, const ms_len_t *path, int min_n, prob *P)
{
    int reason = a->bad ? MS_BADIN : setup(P, a->rx, path, a->n, a->src, min_n);
    if (reason == MS_OK) apply_opts(P, a->rx, &a->opts);
    return reason;
}

int ms_point_prepared(const ms_array *a, const ms_len_t *path, ms_point_fit *out)
{
    prob P;
    cand c = {{0, 0}, 0, 0, 1, 0};
    int reason;
#if MS_GEOM_ARITH == MS_ARITH_Q
    fqfit k;
    if (path && fq_solve(0, a, path, a->opts.no_tol, a->opts.no_gdop, &k, &reason)) {
        FQ_STAT(ms_geom_stat_fast);
        fq_out_point(a, reason, &k, out);
        return out->valid;
    }
    FQ_STAT(ms_geom_stat_general);
#endif
    reason = prepared_setup(a, path, 2, &P);
    if (reason == MS_OK) reason = point_core(&P, &c);
    finish_point(&P, a->src, reason, &c, out);
    return out->valid;
}

int ms_wall_prepared(const ms_array *a, const ms_len_t *path, ms_wall_fit *out)
{
    prob P;
    cand c = {{0, 0}, 0, 0, 1, 0};
    int reason;
#if MS_GEOM_ARITH == MS_ARITH_Q
    fqfit k;
    if (path && fq_solve(1, a, path, a->opts.no_tol, a->opts.no_gdop, &k, &reason)) {
        FQ_STAT(ms_geom_stat_fast);
        fq_out_wall(a, reason, &k, out);
        return out->valid;
    }
    FQ_STAT(ms_geom_stat_general);
#endif
    reason = prepared_setup(a, path, 2, &P);
    /* the wall's max_gdop applies to the mirror image (2x the distance gdop), as Python */
    if (reason == MS_OK) reason = wall_core(&P, &c);
    finish_wall(&P, a->src, reason, &c, out);
    return out->valid;
}

int ms_solve_point(const ms_vec2 *rx, const ms_len_t *path, int n, ms_vec2 src, const ms_opts *opts,
                   ms_point_fit *out)
{
    ms_array a;
    ms_prepare(&a, rx, n, src, opts, NULL, 1);
    return ms_point_prepared(&a, path, out);
}

int ms_solve_wall(const ms_vec2 *rx, const ms_len_t *path, int n, ms_vec2 src, const ms_opts *opts,
                  ms_wall_fit *out)
{
    ms_array a;
    ms_prepare(&a, rx, n, src, opts, NULL, 1);
    return ms_wall_prepared(&a, path, out);
}

/* the edge / wall / uncertain rule of geometry.classify on two chi-squares */
MS_HOT static void decide(ms_class *out, int sp, int sw, real x2p, real x2w, real tp, real tw, real gap_lim)
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

/* ms_fix's general path (the step-by-step port): out of the per-pulse section */
static __attribute__((noinline)) int fix_general(const ms_array *a, const ms_len_t *path, int reason, ms_class *out)
{
    prob P;
    cand cp = {{0, 0}, 0, 0, 1, 0}, cw = {{0, 0}, 0, 0, 1, 0};
    int sp = MS_BADIN, sw = MS_BADIN, i, n = a->n;
    real sig = LEN_IN(a->sigma), x2[2], thr[2];
    if (reason == MS_OK && !(sig > 0 && ISFIN(sig))) reason = MS_BADIN;
    if (reason == MS_OK) reason = setup(&P, a->rx, path, n, a->src, 3);
    out->reason = (uint8_t)reason;
    if (reason == MS_OK) {
        P.no_tol = P.no_gdop = 1;
        P.tol = P.max_gdop = 0;
        P.fov = a->opts.fov;
        set_axis(&P, a->rx, a->opts.axis_mode, a->opts.axis);
        sp = point_core(&P, &cp);
        sw = wall_core(&P, &cw);
        for (i = 0; i < 2; i++) {
            real q = DIV(i == 0 ? cp.rms : cw.rms, sig);
            x2[i] = MUL(q, q) * n;
            if (!ISFIN(x2[i]) || x2[i] > BIGV) x2[i] = BIGV;
            out->chi2[i] = NUM_OUT(x2[i]);
            thr[i] = NUM_IN(a->thr[i]);
        }
        decide(out, sp, sw, x2[0], x2[1], thr[0], thr[1], K(9.21));
    }
    finish_point(&P, a->src, sp, &cp, &out->point);
    finish_wall(&P, a->src, sw, &cw, &out->wall);
    return out->kind;
}

/* ms_fix's fast path alone: the kind, or MS_FIX_DECLINED (out's fields then unspecified) */
static MS_HOT int fix_fast(const ms_array *a, const ms_len_t *path, ms_class *out, int *reason_out)
{
    int reason, i;
    out->kind = MS_KIND_UNCERTAIN;
    out->accepted = 0;
    for (i = 0; i < 3; i++) {
        out->chi2[i] = 0;
        out->thr[i] = a->thr[i];
    }
    /* sigma > 0 <=> LEN_IN(sigma) > 0; LEN_IN (a 64-bit division in Q) only on the general path */
    reason = (a->bad || a->n < 3 || !path || a->sigma <= 0) ? MS_BADIN : MS_OK;
#if MS_GEOM_ARITH == MS_ARITH_Q
    if (reason == MS_OK) {
        fqfit kp, kw;
        int sp, sw;
        if (fq_solve(0, a, path, 1, 1, &kp, &sp) && fq_solve(1, a, path, 1, 1, &kw, &sw)) {
            int64_t y2p = fq_chi2(a, kp.rms), y2w = fq_chi2(a, kw.rms);
            out->reason = MS_OK;
            out->chi2[0] = (ms_num_t)(y2p > INT32_MAX ? INT32_MAX : y2p);
            out->chi2[1] = (ms_num_t)(y2w > INT32_MAX ? INT32_MAX : y2w);
            decide(out, sp, sw, y2p, y2w, a->thr[0], a->thr[1], MS_Q_NUM(9.21));
            fq_out_point(a, sp, &kp, &out->point);
            fq_out_wall(a, sw, &kw, &out->wall);
            FQ_STAT(ms_geom_stat_fast);
            return out->kind;
        }
        FQ_STAT(ms_geom_stat_general);
    }
#endif
    *reason_out = reason;
    return MS_FIX_DECLINED;
}

MS_HOT int ms_fix_fast(const ms_array *a, const ms_len_t *path, ms_class *out)
{
    int reason;
    return fix_fast(a, path, out, &reason);
}

int ms_fix(const ms_array *a, const ms_len_t *path, ms_class *out)
{
    int reason, kind = fix_fast(a, path, out, &reason);
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

/* ======================================================================================
 * cylinder: geometry._specular, _cyl_model, _gauss_newton (3 parameters), _cylinder_core.
 * The general path only (any variant, N >= 3): Gauss-Newton over (bearing, r0, radius) from
 * the point and the wall fit, Newton on the reflection angle inside the model.
 * ====================================================================================== */
#if MS_GEOM_ARITH == MS_ARITH_Q
#define CYL_TINY ((real)1)
static real rad_of_ang(ang a) { return q_mul((int64_t)a, K(6.283185307179586)); }
static ang ang_of_rad(real th) { return (ang)(uint32_t)(uint64_t)q_mul(th, K(0.15915494309189535)); }
static void cyl_cossin(real th, real *c, real *s)
{
    int32_t ci, si;
    q_cossin(ang_of_rad(th), &ci, &si);
    *c = (int64_t)ci * 4;
    *s = (int64_t)si * 4;
}
static real hyp3(real x, real y, real z)
{
    int64_t v[3];
    v[0] = x; v[1] = y; v[2] = z;
    return q_vnorm(v, 3, 1);
}
#define CYL_ATAN2(y, x) rad_of_ang(q_atan2((y), (x)))
#define CYL_DET_MIN 0
#else
#if MS_GEOM_ARITH == MS_ARITH_F64
#define CYL_TINY 1e-300
#define COS(a) cos(a)
#define SIN(a) sin(a)
#define CYL_DET_MIN 1e-30
#else
#define CYL_TINY 1e-30f
#define COS(a) cosf(a)
#define SIN(a) sinf(a)
#define CYL_DET_MIN 1e-30f
#endif
static void cyl_cossin(real th, real *c, real *s)
{
    *c = COS(th);
    *s = SIN(th);
}
static real hyp3(real x, real y, real z) { return SQRT(x * x + y * y + z * z); }
#define CYL_ATAN2(y, x) ATAN2((y), (x))
#endif
#define CYL_A_MAX K(1000.0)
#ifndef CYL_SAME_K
#define CYL_SAME_K 1e-6
#endif
/* two fits are one solution when closer than this (Python: 1e-6 * scale); the reduced-precision
 * variants stop their fits ~ precision * gdop * scale apart */
#if MS_GEOM_ARITH == MS_ARITH_F64
#define CYL_SAME(scale, gd) MUL(K(1e-6), (scale))
#elif MS_GEOM_ARITH == MS_ARITH_F32
#define CYL_SAME(scale, gd) (K(1e-6) * (scale) + K(CYL_SAME_K) * (scale) * ((gd) < K(1e6) ? (gd) : K(1e6)))
#else
#define CYL_SAME(scale, gd) (MUL(K(1e-6), (scale)) + MUL(MUL(K(CYL_SAME_K), (scale)), (gd) < K(100) ? (gd) : K(100)))
#endif

/* specular reflection off the circle (centre p, radius a) from the origin to c */
static int cyl_specular(real px, real py, real a, real cx, real cy, int iters, real *L, real *nxo, real *nyo,
                        real *cio)
{
    real ds = hyp(px, py), dc = hyp(cx - px, cy - py), usx = 0, usy = 0, ucx = 0, ucy = 0, bx, by, bn;
    real phi0, half, dphi = 0, nx, ny, qx, qy, l1, l2, ci;
    int it, s, ok = ds > a && dc > a;
    if (ds > 0) { usx = DIV(-px, ds); usy = DIV(-py, ds); }
    if (dc > 0) { ucx = DIV(cx - px, dc); ucy = DIV(cy - py, dc); }
    bx = usx + ucx;
    by = usy + ucy;
    bn = hyp(bx, by);
    if (bn > K(1e-12)) { bx = DIV(bx, bn); by = DIV(by, bn); }
    else { bx = -usy; by = usx; }
    phi0 = CYL_ATAN2(by, bx);
    half = HALF(CYL_ATAN2(ABS(MUL(usx, ucy) - MUL(usy, ucx)), MUL(usx, ucx) + MUL(usy, ucy)));
    for (it = 0; it < iters; it++) {
        real g = 0, gp = 0, tx, ty, step;
        cyl_cossin(phi0 + dphi, &nx, &ny);
        qx = px + MUL(a, nx);
        qy = py + MUL(a, ny);
        tx = -MUL(a, ny);
        ty = MUL(a, nx);
        for (s = 0; s < 2; s++) {
            real ex = qx - (s ? cx : 0), ey = qy - (s ? cy : 0), le = hyp(ex, ey), te;
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
    cyl_cossin(phi0 + dphi, &nx, &ny);
    qx = px + MUL(a, nx);
    qy = py + MUL(a, ny);
    l1 = hyp(qx, qy);
    l2 = hyp(qx - cx, qy - cy);
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
    cyl_cossin(th[0], &ux, &uy);
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
    cur.cost = cost_of(cur.f, n);
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
            trial.cost = cost_of(trial.f, n);
            if (ACCEPT(trial.cost, cur.cost) && trial.ok && ISFIN(trial.th[0]) && ISFIN(trial.th[1]) &&
                ISFIN(trial.th[2])) {
                cur = trial;
                done = 1;
                break;
            }
            for (j = 0; j < 3; j++) t[j] = HALF(t[j]);
        }
        moved = hyp3(cur.th[0] - po[0], cur.th[1] - po[1], cur.th[2] - po[2]);
        if (!done || SETTLED(moved, c_old, cur.cost, P->scale)) break;
    }
    for (j = 0; j < 3; j++) th[j] = cur.th[j];
    *rms = rms_of(cur.cost, n);
    *ok = cur.ok;
}

/* returns the reason; th (bearing, r0, radius), rms, gdop */
static int cylinder_core(const prob *P, real th_b[3], real *rms_b, real *gd_b, int *gd_inf)
{
    prob P2 = *P;
    cand cp, cw;
    real starts[2][3], th[2][3], rms[2], cen[2][2], rp, dw, f[MS_MAX_RX], J[MS_MAX_RX][3], step[3], d;
    int ok[2], k, b, pre = short_check(P), reason = MS_OK, n_distinct = 0, i;
    P2.no_tol = P2.no_gdop = 1;
    point_core(&P2, &cp);
    wall_core(&P2, &cw);
    rp = hyp(cp.p[0], cp.p[1]);
    dw = HALF(hyp(cw.p[0], cw.p[1]));
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
        cyl_cossin(th[k][0], &cen[k][0], &cen[k][1]);
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
        real dist = hyp(cen[k][0] - cen[b][0], cen[k][1] - cen[b][1]), da = ABS(th[k][2] - th[b][2]);
        if (da > dist) dist = da;
        if (ok[k] && (P->no_tol || rms[k] <= P->tol) && dist > CYL_SAME(P->scale, *gd_inf ? BIGV : *gd_b))
            n_distinct++;
    }
    if (!ok[b]) reason = MS_UNPHYS;
    else if (!(P->no_tol || rms[b] <= P->tol)) reason = P->n > 3 ? MS_INCONS : MS_NOINT;
    else if (n_distinct > 0) reason = MS_AMBIG;
    else if (!P->no_gdop && (*gd_inf || !(*gd_b <= P->max_gdop))) reason = MS_ILLCOND;
    else if (P->has_axis) {
#if MS_GEOM_ARITH == MS_ARITH_Q
        uint32_t lim = (uint32_t)P->fov + 0x40000000u;
        if (lim < 0x80000000u && !ANG_LE(ang_absdiff(ang_of_rad(th_b[0]), P->axis), (ang)lim)) reason = MS_UNPHYS;
#else
        if (!(ang_absdiff(th_b[0], P->axis) <= P->fov + K(1.5707963267948966))) reason = MS_UNPHYS;
#endif
    }
    if (pre != MS_OK) reason = pre;
    return reason;
}

int ms_solve_cylinder(const ms_vec2 *rx, const ms_len_t *path, int n, ms_vec2 src, const ms_opts *opts,
                      ms_cyl_fit *out)
{
    prob P;
    real th[3] = {0, 0, 0}, rms = 0, gd = 0, d, cx, cy;
    int gd_inf = 1, reason = setup(&P, rx, path, n, src, 3);
    if (reason == MS_OK) {
        apply_opts(&P, rx, opts);
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
    cyl_cossin(th[0], &cx, &cy);
    out->cx = LEN_OUT(MUL(d, cx) + LEN_IN(src.x));
    out->cy = LEN_OUT(MUL(d, cy) + LEN_IN(src.y));
    out->radius = LEN_OUT(th[2]);
    out->range = LEN_OUT(th[1]);
#if MS_GEOM_ARITH == MS_ARITH_Q
    out->bearing = ang_of_rad(th[0]);
#else
    out->bearing = th[0];
#endif
    out->residual = LEN_OUT(rms);
    out->gdop = gd_inf ? NUM_OUT(BIGV) : NUM_OUT(gd);
    return 1;
}
