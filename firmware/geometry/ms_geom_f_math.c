/*
 * ms_geom_f_math.c - the float formats' implementation of the format interface of
 * ms_geom_internal.h (MS_ARITH_F64 and MS_ARITH_F32 through `real`; the build lists this file
 * for those two). Lengths metres, angles radians.
 */
#include "ms_geom_internal.h"

#if MS_GEOM_ARITH == MS_ARITH_Q
#error "ms_geom_f_math.c is the float formats': the Q build lists ms_geom_q_math.c instead"
#endif

/* numpy (a + pi) % (2 pi) - pi */
static real wrap(real a)
{
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
ang msg_ang_absdiff(ang a, ang b)
{
    real d = wrap(a - b);
    return d < 0 ? -d : d;
}
real msg_hyp(real x, real y) { return SQRT(x * x + y * y); }
real msg_hyp3(real x, real y, real z) { return SQRT(x * x + y * y + z * z); }
/* sum of squared residuals */
real msg_cost(const real *f, int n)
{
    real s = 0;
    int i;
    for (i = 0; i < n; i++) s += f[i] * f[i];
    return s;
}
real msg_rms(real cost, int n) { return SQRT(cost / (real)n); }

/* Gauss-Newton step (ms_geom_fit.c): the column-scaled normal equations solved by their
 * determinant; singular below 1e-28 */
void msg_ls_step(real (*J)[2], const real *f, int n, real step[2], real *gd, int *gd_inf)
{
    real s0, s1, a, b, d, g0, g1, x0, x1, det, idet, tr;
    msg_ls_normal(J, f, n, &s0, &s1, &a, &b, &d, &g0, &g1);
    det = a * d - b * b;
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

void msg_cossin(real th, real *c, real *s)
{
    *c = COS(th);
    *s = SIN(th);
}
int msg_off_axis(real th, ang axis, ang fov)
{
    return !(msg_ang_absdiff(th, axis) <= fov + K(1.5707963267948966));
}
