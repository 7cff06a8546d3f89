/*
 * ms_geom_f_arith.h - the float formats' layer of the general path (MS_ARITH_F64: double,
 * MS_ARITH_F32: float); included through ms_geom_internal.h. Lengths metres, angles radians,
 * numbers dimensionless, all `real`. F64 and F32 share every line of code through the typedef;
 * the #if below picks the type, its libm functions and the few constants that differ.
 */
#ifndef MS_GEOM_F_ARITH_H
#define MS_GEOM_F_ARITH_H

#include <math.h>

#if MS_GEOM_ARITH == MS_ARITH_F64
typedef double real;
#define SQRT(a) sqrt(a)
#define ATAN2(y, x) atan2((y), (x))
#define BIGNUM 1e30
#define ACCEPT(tc, c) ((tc) <= (c)) /* geometry._gauss_newton */
#define CYL_TINY 1e-300
#define CYL_DET_MIN 1e-30
#define COS(a) cos(a)
#define SIN(a) sin(a)
/* two polished candidates are one answer when closer than this (geometry._select: 1e-6 * scale) */
#define PAIR_SAME(scale, k) MUL(K(1e-6), (scale))
/* two cylinder fits are one solution when closer than this (Python: 1e-6 * scale) */
#define CYL_SAME(scale, gd) MUL(K(1e-6), (scale))
#elif MS_GEOM_ARITH == MS_ARITH_F32
typedef float real;
#define SQRT(a) sqrtf(a)
#define ATAN2(y, x) atan2f((y), (x))
#define BIGNUM 1e30f
/* float: a step is also taken when the cost is equal within rounding, else the fit stops
 * up to gdop*sqrt(eps)*misfit short of the minimum on the flat bottom of the cost */
#define ACCEPT(tc, c) ((tc) <= (c) + (c) * K(5e-7))
#define CYL_TINY 1e-30f
#define CYL_DET_MIN 1e-30f
#define COS(a) cosf(a)
#define SIN(a) sinf(a)
/* two float fits of one minimum differ by ~eps * scale * gdop: widen 'same' by that (GD_MIN:
 * the smaller finite gdop of the two candidates k[0], k[1]) */
#define PAIR_SAME(scale, k) (K(1e-6) * (scale) + K(3e-7) * (scale) * GD_MIN(k))
#define GD_MIN(k) \
    ((k)[0].gd_inf ? (k)[1].gd : (k)[1].gd_inf ? (k)[0].gd : (k)[0].gd < (k)[1].gd ? (k)[0].gd : (k)[1].gd)
/* the cylinder fits stop ~ precision * gdop * scale apart */
#define CYL_SAME(scale, gd) (K(1e-6) * (scale) + K(CYL_SAME_K) * (scale) * ((gd) < K(1e6) ? (gd) : K(1e6)))
#else
#error "ms_geom_f_arith.h: MS_GEOM_ARITH must be MS_ARITH_F64 or MS_ARITH_F32 (Q: ms_geom_q_arith.h)"
#endif

typedef real ang;
#define BIGV BIGNUM
#define ANG_LE(a, b) ((a) <= (b))
#define ANG_ISFIN(a) ISFIN(a) /* an angle from the caller may be NaN / Inf */
#define K(x) ((real)(x))
#define MUL(a, b) ((a) * (b))
#define DIV(a, b) ((a) / (b))
#define HALF(a) (K(0.5) * (a))
#define ISFIN(a) ((a) - (a) == 0)
#define PI_R K(3.14159265358979323846)
#define TWO_PI_R K(6.28318530717958647692)
#define SETTLED(moved, c_old, c_new, scale) \
    ((moved) <= K(1e-13) * (scale) || (c_old) - (c_new) <= K(1e-8) * (c_old) + K(1e-32) * (scale) * (scale))
/* point_pair: float keeps roots at any distance */
#define FAR_ROOT(num, den) 0
/* interface conversions */
#define LEN_IN(v) ((real)(v))
#define LEN_OUT(v) ((ms_len_t)(v))
#define NUM_IN(v) ((real)(v))
#define NUM_OUT(v) ((ms_num_t)((v) > BIGNUM ? BIGNUM : (v)))
/* cylinder: bearing in radians, at the interface as it is */
#define CYL_ATAN2(y, x) ATAN2((y), (x))
#define ANG_OF_RAD(th) (th)
/* option defaults at the interface (ms_opts_default, ms_class_opts_default) */
#define DEF_TOL ((ms_len_t)1e-3) /* 1 mm */
#define DEF_MAX_GDOP ((ms_num_t)1e4)
#define DEF_FOV ((ms_ang_t)(60.0 * 3.14159265358979323846 / 180.0))
#define DEF_Z ((ms_num_t)3.090232306167813)

/* half chord of the circles (0, R1), (D, R2), D > 0 (Heron's factored form; 0 where they do not
 * meet): ms_geom_wall.c circle_pair */
static inline real half_chord(real D, real R1, real R2)
{
    real h2 = (D + R1 - R2) * (D - R1 + R2) * (R1 + R2 - D) * (R1 + R2 + D) / (4 * D * D);
    return SQRT(h2 > 0 ? h2 : K(0.0));
}

#endif
