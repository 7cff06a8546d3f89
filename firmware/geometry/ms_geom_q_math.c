/*
 * ms_geom_q_math.c - fixed-point arithmetic of the general path (MS_ARITH_Q only; the build
 * lists this file for the Q format): Q32.32 products, quotients and roots, vector norms, atan2
 * and cos / sin by CORDIC, the interface conversions, and the Q implementation of the format
 * interface of ms_geom_internal.h (the 2x2 Gauss-Newton solve, the circle half chord, ...).
 *
 * Q32.32: int64 with 32 fraction bits (lengths: metres, LSB 2^-32 m = 0.23 nm), saturating at
 * +-QSAT = 2^59 (2^27 m). Binary angle: int32, 2^32 per turn (INT32_MIN = -pi). Q30 / Q16.16:
 * int32 with 30 / 16 fraction bits. Products round to nearest unless stated.
 */
#include "ms_geom_internal.h"

#if MS_GEOM_ARITH != MS_ARITH_Q
#error "ms_geom_q_math.c is the Q format's: the float builds list ms_geom_f_math.c instead"
#endif

/* leading zero bits of v (64 for v = 0) */
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
/* |a| as uint64 (any Q); sgn: the magnitude u with the sign neg */
static uint64_t uabs64(int64_t a) { return a < 0 ? (uint64_t)0 - (uint64_t)a : (uint64_t)a; }
static int64_t sgn(int neg, uint64_t u) { return neg ? -(int64_t)u : (int64_t)u; }

/* a * b: a, b Q32.32 -> Q32.32 (a*b >> 32, rounded), saturating at +-QSAT (also the inputs) */
int64_t q_mul(int64_t a, int64_t b)
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
/* a / b: a, b one common Q (Q32.32) -> Q32.32 ((a << 32) / b, rounded), saturating at +-QSAT;
 * b = 0: 0 for a = 0, else +-QSAT. 64/64 long division. */
int64_t q_div(int64_t a, int64_t b)
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
/* sqrt(v): v an unsigned integer -> the integer root, rounded to nearest (bit by bit) */
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
/* sqrt(a): a Q32.32 -> Q32.32 (0 for a <= 0); a normalised first (~31 significant bits) */
int64_t q_sqrt(int64_t a)
{
    int k;
    uint64_t r;
    if (a <= 0) return 0;
    k = clz64((uint64_t)a) / 2;
    r = isqrt64((uint64_t)a << (2 * k));
    if (k >= 16) return (int64_t)((k > 16) ? (r + ((uint64_t)1 << (k - 17))) >> (k - 16) : r);
    return (int64_t)(r << (16 - k));
}
/* Euclidean norm of n values v[i * stride]: any one Q -> the same Q (Q32.32: saturating at
 * QSAT), normalised so the squares never overflow (~30 bits kept) */
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
/* |(x, y)|, |(x, y, z)|: Q32.32 -> Q32.32 */
real msg_hyp(real x, real y)
{
    int64_t v[2];
    v[0] = x; v[1] = y;
    return q_vnorm(v, 2, 1);
}
real msg_hyp3(real x, real y, real z)
{
    int64_t v[3];
    v[0] = x; v[1] = y; v[2] = z;
    return q_vnorm(v, 3, 1);
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
/* atan2(y, x): y, x one common Q (any scale) -> binary angle (0 for (0, 0)); 40-step CORDIC
 * vectoring in 2^-48 turns (< 1e-11 rad before rounding to the output LSB) */
ang q_atan2(int64_t y, int64_t x)
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
/* cos(th), sin(th): th binary angle -> *c, *s Q30 (clamped to +-2^30); CORDIC rotation,
 * 40 steps (per sensor set-up and the cylinder, not per pulse) */
void q_cossin(ang th, int32_t *c, int32_t *s)
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
/* |a - b|: binary angles -> binary angle (INT32_MIN stays: callers compare unsigned, ANG_LE) */
ang msg_ang_absdiff(ang a, ang b)
{
    int32_t d = (int32_t)((uint32_t)a - (uint32_t)b);
    return d < 0 ? (ang)((uint32_t)0 - (uint32_t)d) : d;
}
/* a fit's cost: residuals f Q32.32 metres -> |f| Q32.32 metres (the norm, not |f|^2, which
 * would underflow) */
real msg_cost(const real *f, int n) { return q_vnorm(f, n, 1); }
/* sqrt(n), Q32.32 */
static const int64_t sqrt_n_tab[MS_MAX_RX + 1] = {
    K(1.0), K(1.0), K(1.4142135623730951), K(1.7320508075688772), K(2.0),
    K(2.23606797749979), K(2.449489742783178), K(2.6457513110645907), K(2.8284271247461903)};
/* RMS residual: cost |f| Q32.32 metres, n residuals -> |f| / sqrt(n) Q32.32 metres */
real msg_rms(real cost, int n) { return DIV(cost, sqrt_n_tab[n]); }

/* v: int32 micrometres -> Q32.32 metres (v * 2^32 / 1e6 = (v << 26) / 15625, rounded) */
int64_t q_from_um(int32_t v)
{
    int64_t n = (int64_t)v * ((int64_t)1 << 26);
    return (n >= 0 ? n + 7812 : n - 7812) / 15625;
}
/* v: Q32.32 metres -> int32 micrometres, rounded, saturating at +-INT32_MAX */
int32_t q_to_um(int64_t v)
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
/* Gauss-Newton step (ms_geom_fit.c): J n rows of the Jacobian, Q32.32 (dimensionless), f the
 * residuals, Q32.32 metres -> step Q32.32 metres, *gd = gdop Q32.32; *gd_inf when singular or
 * gdop >= QSAT (1.3e8). Column-scaled normal equations; det(J^T J) by Cauchy-Binet: the sum
 * of squared 2x2 minors (no cancellation); the scaled determinant is m^2 with
 * m = |minors| / (s0 s1). */
void msg_ls_step(real (*J)[2], const real *f, int n, real step[2], real *gd, int *gd_inf)
{
    real s0, s1, a, b, d, g0, g1, x0, x1, mn, m, st;
    int64_t minors[MS_MAX_RX * (MS_MAX_RX - 1) / 2];
    int i, j, k = 0;
    msg_ls_normal(J, f, n, &s0, &s1, &a, &b, &d, &g0, &g1);
    for (i = 0; i < n; i++)
        for (j = i + 1; j < n; j++) minors[k++] = MUL(J[i][0], J[j][1]) - MUL(J[i][1], J[j][0]);
    mn = q_vnorm(minors, k, 1);
    m = DIV(mn, MUL(s0, s1));
    if (m > 0) {
        x0 = DIV(DIV(MUL(d, g0) - MUL(b, g1), m), m);
        x1 = DIV(DIV(MUL(a, g1) - MUL(b, g0), m), m);
        step[0] = DIV(x0, s0);
        step[1] = DIV(x1, s1);
        st = msg_hyp(s0, s1); /* sqrt(sum J^2) */
        *gd = DIV(st, mn);
        *gd_inf = *gd >= QSAT;
    } else {
        step[0] = step[1] = 0;
        *gd = 0;
        *gd_inf = 1;
    }
}

/* binary angle -> Q32.32 radians (in [-pi, pi)) */
int64_t q_rad_of_ang(ang a) { return q_mul((int64_t)a, K(6.283185307179586)); }
/* Q32.32 radians -> binary angle (wrapped) */
ang q_ang_of_rad(int64_t th) { return (ang)(uint32_t)(uint64_t)q_mul(th, K(0.15915494309189535)); }
/* cos(th), sin(th): th Q32.32 radians -> *c, *s Q32.32 (q_cossin's Q30 scaled up) */
void msg_cossin(real th, real *c, real *s)
{
    int32_t ci, si;
    q_cossin(q_ang_of_rad(th), &ci, &si);
    *c = (int64_t)ci * 4;
    *s = (int64_t)si * 4;
}
/* th Q32.32 radians, axis and fov binary angles -> 1 when th lies more than fov + 90 deg off
 * the axis (never when fov + 90 deg reaches half a turn) */
int msg_off_axis(real th, ang axis, ang fov)
{
    uint32_t lim = (uint32_t)fov + 0x40000000u;
    return lim < 0x80000000u && !ANG_LE(msg_ang_absdiff(q_ang_of_rad(th), axis), (ang)lim);
}
