/*
 * ms_geom_q_fast.c - the fast 3-receiver path and the per-pulse fix of the Q format
 * (MS_ARITH_Q only; the build lists this file for the Q format).
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
 *
 * The end of the file connects the fast path to the public calls: its part of ms_prepare
 * (msg_fast_prepare), its answers to ms_point_prepared / ms_wall_prepared, and ms_fix's fast
 * half (msg_fix_fast, ms_fix_fast). The per-pulse code (fq_*, msg_fix_fast, ms_fix_fast) is one
 * translation unit on purpose: its helpers are inlined, or called knowing which registers they
 * leave alone, and it lies in one section, .text.ms_hot (MS_HOT, ms_geom_internal.h).
 *
 * Units (the fixed-point formats of the functions below): lengths int32 in the internal unit
 * 2^-2 um ("units"; FQ_SH), path lengths at the interface int32 um; unit vectors Q30 (int32,
 * 2^30 = 1); Jacobians Q29; products int64 with the sum of the operands' fraction bits;
 * angles binary (int32, 2^32 per turn); gdop^2 Q16 (int64); chi-squares and numbers at the
 * interface Q16.16.
 */
#include "ms_geom_internal.h"

#if MS_GEOM_ARITH != MS_ARITH_Q
#error "ms_geom_q_fast.c is the Q format's: the float builds list ms_geom_f_fast.c instead"
#endif

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
/* leading zero bits of a byte */
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

/* a * b exact, int32 x int32 -> int64 (fq_sumul: int32 x uint32); the product's fraction bits are
 * the sum of the operands' (Q30 x Q30 -> Q60). MUL + MULH (GCC otherwise widens some to 64 x 64,
 * 3-4 MULs) */
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

/* leading zero bits of v (v != 0) */
FQ_INLINE int fq_clz32(uint32_t v)
{
    int n = 0;
    if (!(v >> 16)) { n = 16; v <<= 16; }
    if (!(v >> 24)) { n += 8; v <<= 8; }
    return n + fq_clz8[v >> 24];
}
/* m: a magnitude (int64 of any unit) -> the right shift that brings it below 2^30 (0 if it is) */
FQ_INLINE int fq_drop30(uint64_t m)
{
    uint32_t h = (uint32_t)(m >> 32), l = (uint32_t)m;
    if (h) return 34 - fq_clz32(h);
    return (l >> 30) ? 2 - fq_clz32(l) : 0;
}
/* 1/sqrt(s) for 0 < s < 2^64 (s: the square of a length, any unit): y in [2^30, 2^31] with
 * 1/sqrt(s) = y * 2^(k2 - 62) (relative error < 2^-28); *hi = the top 32 bits of s normalised by
 * an even shift (for the root: fq_root) */
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
/* round(sqrt(s)) from fq_rsqrt's results (hi, y, k2 of s) -> int32 in the root's unit */
FQ_INLINE int32_t fq_root(uint32_t hi, uint32_t y, int k2)
{
    uint32_t p = (uint32_t)(((uint64_t)hi * y) >> 32); /* sqrt(s) * 2^(k2 - 2) */
    if (k2 >= 3) return (int32_t)((p + (1u << (k2 - 3))) >> (k2 - 2));
    return (int32_t)(p << (2 - k2));
}
/* round(sqrt(s)): s the square of a length (any unit) -> int32 in that unit; 0 for s = 0 */
FQ_INLINE int32_t fq_sqrt(uint64_t s)
{
    int k2;
    uint32_t hi, y;
    if (!s) return 0;
    y = fq_rsqrt(s, &k2, &hi);
    return fq_root(hi, y, k2);
}
/* (p >> sh) as int32 (any unit; the result must fit), 0 < sh < 32 */
FQ_INLINE int32_t fq_sr(int64_t p, int sh)
{
    return (int32_t)(((uint32_t)p >> sh) | ((uint32_t)(p >> 32) << (32 - sh)));
}
/* v / sqrt(s) in Q30 (|v| <= sqrt(s), v in the unit of sqrt(s)), from fq_rsqrt's y, k2 of s */
FQ_INLINE int32_t fq_unit(int32_t v, uint32_t y, int k2) { return fq_sr(fq_sumul(v, y), 32 - k2); }
/* (x * r) >> sh, floor, for |x| < 2^62, r < 2^32, 32 <= sh < 96 (the caller tracks the units) */
FQ_INLINE int64_t fq_mulr(int64_t x, uint32_t r, int sh)
{
    int64_t t = fq_sumul((int32_t)(x >> 32), r) + (int64_t)(((uint64_t)(uint32_t)x * r) >> 32);
    sh -= 32;
    return sh < 63 ? t >> sh : (t < 0 ? -1 : 0);
}
/* 1/s = r * 2^-e, r in [2^29, 2^31] (s an unsigned integer, 0 < s < 2^64) */
FQ_INLINE uint32_t fq_recip(uint64_t s, int *e)
{
    int k2;
    uint32_t hi, y = fq_rsqrt(s, &k2, &hi);
    *e = 93 - 2 * k2;
    return (uint32_t)(((uint64_t)y * y) >> 31);
}
/* fq_in: int32 um -> units (2^-2 um); fq_out: units -> int32 um, rounded; fq_sq: x^2 + y^2
 * (int64, the square of x's unit); fq_dot30: x ux + y uy with u Q30 -> x's unit (floor) */
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
/* atan2(y, x): y, x int32 in one common unit -> binary angle (2^32 per turn; 0 for (0, 0)),
 * error < 3e-8 rad */
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

/* distances L from p to the receivers (units), their unit vectors (Q30) and 1/sqrt factors
 * (fq_rsqrt's y, k2 of L^2) */
typedef struct {
    int32_t L[3], ux[3], uy[3];
    uint32_t y[3];
    int8_t k2[3];
} fqd;

/* p (units) -> *d; 0 (general path) when p lies on a receiver */
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
/* |d + step| (units) from |d| = L (units), unit u (Q30), 1/L = y 2^(k2-62), the step (sx, sy)
 * (units) and s2 = |step|^2 (units^2): second order in the step, |step| <= L/128 */
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

/* One Gauss-Newton step for three residuals f (units) and J (Q29). Returns 0 when singular or
 * beyond the fast path's range; else step (units) and gdop^2 (*gd2, Q16). Normal equations
 * through the three 2x2 minors m_kl of J (Cauchy-Binet): det = sum m^2,
 * adj(J^T J) J^T f = sum m_kl e_kl. */
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
    int32_t x, y;  /* polished point / mirror image (units) */
    int32_t rho;   /* |x| (units) */
    int32_t rms;   /* RMS residual (units) */
    int64_t gd2;   /* gdop^2 Q16 (point: of x; wall: of m, i.e. 4x the distance gdop^2) */
    int ok;        /* physical */
    int inside;    /* inside the fov round the axis */
} fqfit;

/* polish the start p0 = (px, py) with |p0| = rho0 (units) and unit (ux, uy) (Q30), 1/rho0 =
 * y0 2^(k20 - 62), against the path lengths r (units); fill out; 0 -> general path.
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

/* a start for fq_polish: x, y and rho = |(x, y)| in units, (ux, uy) = (x, y) / rho Q30,
 * 1/rho = yr 2^(k2 - 62) */
typedef struct {
    int32_t x, y, rho, ux, uy;
    uint32_t yr;
    int k2;
} fqstart;

/* point start from the path lengths r (units): st[0] the candidate nearer the axis, st[1] (with
 * want_mirror) the other, for a second polish; 0 -> general path */
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

/* is the direction (x, y) (int64, any one unit) more than fov + 20 deg off the axis? */
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

/* wall start from the path lengths r (units): the mirror image candidates of the circle pair,
 * st[0] nearer the axis, st[1] (with want_mirror) the other; 0 -> general path */
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

/* The fast solve of the point (wall = 0) or wall model from the path lengths (int32 um), with
 * a->opts.tol (um) and max_gdop (Q16.16) unless no_tol / no_gdop: returns 0 -> general path;
 * else *reason and the chosen fit (units) */
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

/* a fit (units, gd2 Q16) -> the interface: um, binary angles, gdop Q16.16 */
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

/* the same for a wall (k: the mirror image): the foot is half the image, the gdop of the
 * distance half the image's */
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

/* chi-square of an rms misfit (units): rms^2 * 3 / sigma^2, Q16.16 in int64 (unsaturated) */
MS_HOT static int64_t fq_chi2(const ms_array *a, int32_t rms)
{
    return fq_mulr(fq_smul(rms, rms) * 3, a->sinv, a->ssh - 16);
}
#pragma GCC pop_options

/* ======================================================================================
 * the fast path's part of the public calls
 * ====================================================================================== */
/* ms_prepare's last step (ms_geom_setup.c), from the receivers, source (int32 um) and options
 * it stored in a: a->fast and the fields the fast path reads (ms_geom.h: receivers - source in
 * units, the closed-form pair, its chord unit vector (Q30) and 1/D, the axis and cos(fov) Q30,
 * 1/sigma^2); returns a->fast */
int msg_fast_prepare(ms_array *a)
{
    const ms_vec2 *rx = a->rx;
    ms_vec2 src = a->src;
    ms_len_t noise_sigma = a->sigma;
    int i, n = a->n;
    if (!a->bad && n == 3 && a->opts.axis_mode != MS_AXIS_NONE && noise_sigma > 0) {
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
        msg_set_axis(&P, rx, a->opts.axis_mode, a->opts.axis);
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
    return a->fast;
}

/* ms_point_prepared / ms_wall_prepared by the fast path (path: int32 um): 1 when it answered
 * (out at the interface), 0 -> the general path answers */
int msg_fast_point(const ms_array *a, const ms_len_t *path, ms_point_fit *out)
{
    fqfit k;
    int reason;
    if (path && fq_solve(0, a, path, a->opts.no_tol, a->opts.no_gdop, &k, &reason)) {
        FQ_STAT(ms_geom_stat_fast);
        fq_out_point(a, reason, &k, out);
        return 1;
    }
    FQ_STAT(ms_geom_stat_general);
    return 0;
}

int msg_fast_wall(const ms_array *a, const ms_len_t *path, ms_wall_fit *out)
{
    fqfit k;
    int reason;
    if (path && fq_solve(1, a, path, a->opts.no_tol, a->opts.no_gdop, &k, &reason)) {
        FQ_STAT(ms_geom_stat_fast);
        fq_out_wall(a, reason, &k, out);
        return 1;
    }
    FQ_STAT(ms_geom_stat_general);
    return 0;
}

/* ms_fix's fast path alone (path: int32 um): both fits, their chi-squares (Q16.16, saturated at
 * INT32_MAX) and the decision, or MS_FIX_DECLINED with *reason_out for the general path */
MS_HOT int msg_fix_fast(const ms_array *a, const ms_len_t *path, ms_class *out, int *reason_out)
{
    int reason = fix_begin(a, path, out);
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
    *reason_out = reason;
    return MS_FIX_DECLINED;
}

MS_HOT int ms_fix_fast(const ms_array *a, const ms_len_t *path, ms_class *out)
{
    int reason;
    return msg_fix_fast(a, path, out, &reason);
}
