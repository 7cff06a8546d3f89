/*
 * ms_geom_q_arith.h - the fixed-point format's layer of the general path (MS_ARITH_Q);
 * included through ms_geom_internal.h. No float anywhere.
 *
 * real: Q32.32 in int64 (32 fraction bits; lengths in metres, LSB 2^-32 m = 0.23 nm),
 * saturating at +-QSAT (2^59, i.e. +-2^27); ang: binary angle in int32 (2^32 per turn,
 * INT32_MIN = -pi; wraps for free). Interface types (ms_geom.h): lengths int32 micrometres,
 * numbers int32 Q16.16. The functions are in ms_geom_q_math.c, where each states the format
 * of its arguments and result.
 */
#ifndef MS_GEOM_Q_ARITH_H
#define MS_GEOM_Q_ARITH_H

#if MS_GEOM_ARITH != MS_ARITH_Q
#error "ms_geom_q_arith.h: MS_GEOM_ARITH must be MS_ARITH_Q (float formats: ms_geom_f_arith.h)"
#endif

typedef int64_t real; /* Q32.32 */
typedef int32_t ang;  /* binary angle */
#define QONE ((int64_t)1 << 32)
#define QSAT ((int64_t)1 << 59)
#define K(x) ((int64_t)((x) * 4294967296.0 + ((x) >= 0 ? 0.5 : -0.5))) /* constant -> Q32.32 */
#define MUL(a, b) q_mul((a), (b))
#define DIV(a, b) q_div((a), (b))
#define SQRT(a) q_sqrt(a)
#define ATAN2(y, x) q_atan2((y), (x))
#define HALF(a) ((a) / 2)
#define ISFIN(a) ((a) < QSAT && (a) > -QSAT)
#define ANG_ISFIN(a) 1 /* a binary angle is always finite */
#define BIGV QSAT
/* cost is |f| here; accept steps equal within rounding (see the float formats) */
#define ACCEPT(tc, c) ((tc) <= (c) + ((c) >> 22) + 8)
#define ANG_LE(a, b) ((uint32_t)(a) <= (uint32_t)(b))
#define SETTLED(moved, c_old, c_new, scale) ((moved) <= 0 || (c_old) - (c_new) <= ((c_old) >> 27))
/* point_pair: a root beyond 1000 m is outside the fixed-point range: not a candidate */
#define FAR_ROOT(num, den) (ABS(num) >= MUL(ABS(den), K(1000.0)))
/* two polished candidates are one answer when closer than this (geometry._select) */
#define PAIR_SAME(scale, k) MUL(K(1e-6), (scale))
/* interface conversions: um <-> Q32.32 metres, Q16.16 <-> Q32.32 */
#define LEN_IN(v) q_from_um(v)
#define LEN_OUT(v) q_to_um(v)
#define NUM_IN(v) ((real)(v) * 65536)
#define NUM_OUT(v) q_to_num(v)
/* cylinder: bearings in Q32.32 radians inside the fit, binary angles at the interface */
#define CYL_TINY ((real)1)
#define CYL_DET_MIN 0
#define CYL_ATAN2(y, x) q_rad_of_ang(q_atan2((y), (x)))
#define ANG_OF_RAD(th) q_ang_of_rad(th)
/* two cylinder fits are one solution when closer than this; the fits stop ~ precision * gdop *
 * scale apart (gdop capped at 100) */
#define CYL_SAME(scale, gd) \
    (MUL(K(1e-6), (scale)) + MUL(MUL(K(CYL_SAME_K), (scale)), (gd) < K(100) ? (gd) : K(100)))
/* option defaults at the interface (ms_opts_default, ms_class_opts_default) */
#define DEF_TOL 1000 /* 1 mm in um */
#define DEF_MAX_GDOP MS_Q_NUM(1e4)
#define DEF_FOV MS_Q_ANG_FROM_DEG(60.0)
#define DEF_Z MS_Q_NUM(3.090232306167813)

/* ms_geom_q_math.c */
int64_t q_mul(int64_t a, int64_t b);          /* Q32.32 x Q32.32 -> Q32.32, rounded, saturating */
int64_t q_div(int64_t a, int64_t b);          /* Q32.32 / Q32.32 -> Q32.32, rounded, saturating */
int64_t q_sqrt(int64_t a);                    /* Q32.32 -> Q32.32 */
ang q_atan2(int64_t y, int64_t x);            /* y, x one common Q -> binary angle */
void q_cossin(ang th, int32_t *c, int32_t *s); /* binary angle -> cos, sin Q30 */
int64_t q_from_um(int32_t v);                 /* int32 um -> Q32.32 metres */
int32_t q_to_um(int64_t v);                   /* Q32.32 metres -> int32 um */
int64_t q_rad_of_ang(ang a);                  /* binary angle -> Q32.32 radians */
ang q_ang_of_rad(int64_t th);                 /* Q32.32 radians -> binary angle */

/* half chord of the circles (0, R1), (D, R2), D > 0: Q32.32 metres -> Q32.32 metres (0 where
 * they do not meet); sqrt(p1 p2) / (2 D) with the two factor pairs rooted separately (no
 * overflow): ms_geom_wall.c circle_pair */
static inline real half_chord(real D, real R1, real R2)
{
    real p1 = MUL(D + R1 - R2, D - R1 + R2), p2 = MUL(R1 + R2 - D, R1 + R2 + D);
    return (p1 > 0 && p2 > 0) ? DIV(MUL(SQRT(p1), SQRT(p2)), 2 * D) : 0;
}
/* v: Q32.32 -> Q16.16 (truncated toward -inf), saturating at +-INT32_MAX (32767.99) */
static inline ms_num_t q_to_num(int64_t v)
{
    v >>= 16;
    return (ms_num_t)(v > INT32_MAX ? INT32_MAX : v < -INT32_MAX ? -INT32_MAX : v);
}

#endif
