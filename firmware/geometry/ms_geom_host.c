/*
 * ms_geom_host.c - host-only batch shim over the geometry library (ms_geom.h) for tests and
 * benchmarks (ctypes); linked with the library's files of one format (firmware/Makefile).
 * Everything crosses the boundary as double (metres, radians); the shim converts to the
 * variant's interface types (Q: micrometres rounded to nearest, binary angles) and back.
 * Not part of the firmware image.
 */
#include <math.h>
#include <string.h>

#include "ms_geom.h"

#define PI 3.14159265358979323846

#if MS_GEOM_ARITH == MS_ARITH_Q
static ms_len_t len_in(double v)
{
    double u = floor(v * 1e6 + 0.5);
    if (!(u == u)) return 0; /* NaN -> 0 (an invalid path length) */
    if (u > 2147483647.0) u = 2147483647.0;
    if (u < -2147483647.0) u = -2147483647.0;
    return (ms_len_t)u;
}
static double len_out(ms_len_t v) { return v * 1e-6; }
static ms_ang_t ang_in(double a)
{
    double t = fmod(a, 2 * PI);
    long long b;
    if (t >= PI) t -= 2 * PI;
    if (t < -PI) t += 2 * PI;
    b = llround(t * (2147483648.0 / PI));
    return (ms_ang_t)(unsigned)(long long)b;
}
static double ang_out(ms_ang_t a) { return a * (PI / 2147483648.0); }
static ms_num_t num_in(double v) { return v * 65536.0 > 2147483647.0 ? 2147483647 : (ms_num_t)(v * 65536.0); }
static double num_out(ms_num_t v) { return v / 65536.0; }
#else
static ms_len_t len_in(double v) { return (ms_len_t)v; }
static double len_out(ms_len_t v) { return v; }
static ms_ang_t ang_in(double a) { return (ms_ang_t)a; }
static double ang_out(ms_ang_t a) { return a; }
static ms_num_t num_in(double v) { return (ms_num_t)v; }
static double num_out(ms_num_t v) { return v; }
#endif

int msh_arith(void) { return MS_GEOM_ARITH; }
#if MS_GEOM_ARITH == MS_ARITH_Q
extern unsigned long ms_geom_stat_fast, ms_geom_stat_general;
extern int ms_geom_stat_line;
/* the source line where the fast path last declined (diagnosis) */
int msh_stat_line(void) { return ms_geom_stat_line; }
/* calls answered by the fast 3-receiver path / by the general path since the last call */
void msh_stats(double *out)
{
    out[0] = (double)ms_geom_stat_fast;
    out[1] = (double)ms_geom_stat_general;
    ms_geom_stat_fast = ms_geom_stat_general = 0;
}
#else
void msh_stats(double *out) { out[0] = out[1] = 0; }
#endif
int msh_max_rx(void) { return MS_MAX_RX; }
int msh_nreasons(void) { return MS_NREASONS; }
const char *msh_reason_name(int i) { return (i >= 0 && i < MS_NREASONS) ? ms_reason_names[i] : 0; }

static void load(int N, const double *C, const double *R, const double *S, ms_vec2 *rx, ms_len_t *path,
                 ms_vec2 *src)
{
    int i;
    for (i = 0; i < N; i++) {
        rx[i].x = len_in(C[2 * i]);
        rx[i].y = len_in(C[2 * i + 1]);
        path[i] = len_in(R[i]);
    }
    src->x = len_in(S[0]);
    src->y = len_in(S[1]);
}

/* axis: NULL -> auto; NaN entry -> none */
static void axis_opts(const double *axis, int m, uint8_t *mode, ms_ang_t *ax)
{
    if (!axis) {
        *mode = MS_AXIS_AUTO;
    } else if (axis[m] != axis[m]) {
        *mode = MS_AXIS_NONE;
    } else {
        *mode = MS_AXIS_SET;
        *ax = ang_in(axis[m]);
    }
}

/* Solver options from the Python keyword arguments (infinity switches a check off). */
static void solver_opts(double tol, double max_gdop, double fov, ms_opts *o)
{
    ms_opts_default(o);
    if (tol == INFINITY) o->no_tol = 1;
    else o->tol = len_in(tol);
    if (max_gdop == INFINITY) o->no_gdop = 1;
    else o->max_gdop = num_in(max_gdop);
    o->fov = ang_in(fov);
}

/* out rows of 8: valid, reason, x, y, range, bearing, residual, gdop */
void msh_solve_point_batch(int M, int N, const double *C, const double *R, const double *S, const double *axis,
                           double tol, double max_gdop, double fov, double *out)
{
    int m;
    ms_vec2 rx[MS_MAX_RX + 1], src;
    ms_len_t path[MS_MAX_RX + 1];
    ms_opts o;
    ms_point_fit f;
    solver_opts(tol, max_gdop, fov, &o);
    for (m = 0; m < M; m++) {
        double *r = out + 8 * m;
        load(N > MS_MAX_RX ? MS_MAX_RX : N, C + 2 * N * m, R + N * m, S + 2 * m, rx, path, &src);
        axis_opts(axis, m, &o.axis_mode, &o.axis);
        ms_solve_point(rx, path, N, src, &o, &f);
        r[0] = f.valid; r[1] = f.reason; r[2] = len_out(f.x); r[3] = len_out(f.y);
        r[4] = len_out(f.range); r[5] = ang_out(f.bearing); r[6] = len_out(f.residual); r[7] = num_out(f.gdop);
    }
}

/* out rows of 8: valid, reason, distance, normal_angle, foot_x, foot_y, residual, gdop */
void msh_solve_wall_batch(int M, int N, const double *C, const double *R, const double *S, const double *axis,
                          double tol, double max_gdop, double fov, double *out)
{
    int m;
    ms_vec2 rx[MS_MAX_RX + 1], src;
    ms_len_t path[MS_MAX_RX + 1];
    ms_opts o;
    ms_wall_fit f;
    solver_opts(tol, max_gdop, fov, &o);
    for (m = 0; m < M; m++) {
        double *r = out + 8 * m;
        load(N > MS_MAX_RX ? MS_MAX_RX : N, C + 2 * N * m, R + N * m, S + 2 * m, rx, path, &src);
        axis_opts(axis, m, &o.axis_mode, &o.axis);
        ms_solve_wall(rx, path, N, src, &o, &f);
        r[0] = f.valid; r[1] = f.reason; r[2] = len_out(f.distance); r[3] = ang_out(f.normal_angle);
        r[4] = len_out(f.foot_x); r[5] = len_out(f.foot_y); r[6] = len_out(f.residual); r[7] = num_out(f.gdop);
    }
}

/* out rows of 10: kind, accepted bits, reason, chi2[3], thr[3], point.reason, wall.reason (11) */
void msh_classify_batch(int M, int N, const double *C, const double *R, const double *S, const double *axis,
                        double sigma, double z, double fov, double *out)
{
    int m, i;
    ms_vec2 rx[MS_MAX_RX + 1], src;
    ms_len_t path[MS_MAX_RX + 1];
    ms_class_opts o;
    ms_class k;
    ms_class_opts_default(&o);
    o.z = num_in(z);
    o.fov = ang_in(fov);
    for (m = 0; m < M; m++) {
        double *r = out + 11 * m;
        load(N > MS_MAX_RX ? MS_MAX_RX : N, C + 2 * N * m, R + N * m, S + 2 * m, rx, path, &src);
        axis_opts(axis, m, &o.axis_mode, &o.axis);
        ms_classify(rx, path, N, src, len_in(sigma), &o, &k);
        r[0] = k.kind; r[1] = k.accepted; r[2] = k.reason;
        for (i = 0; i < 3; i++) {
            r[3 + i] = num_out(k.chi2[i]);
            r[6 + i] = num_out(k.thr[i]);
        }
        r[9] = k.point.reason; r[10] = k.wall.reason;
    }
}

/* out rows of 9: valid, reason, cx, cy, radius, range, bearing, residual, gdop */
void msh_solve_cylinder_batch(int M, int N, const double *C, const double *R, const double *S, const double *axis,
                              double tol, double max_gdop, double fov, double *out)
{
    int m;
    ms_vec2 rx[MS_MAX_RX + 1], src;
    ms_len_t path[MS_MAX_RX + 1];
    ms_opts o;
    ms_cyl_fit f;
    solver_opts(tol, max_gdop, fov, &o);
    for (m = 0; m < M; m++) {
        double *r = out + 9 * m;
        load(N > MS_MAX_RX ? MS_MAX_RX : N, C + 2 * N * m, R + N * m, S + 2 * m, rx, path, &src);
        axis_opts(axis, m, &o.axis_mode, &o.axis);
        ms_solve_cylinder(rx, path, N, src, &o, &f);
        r[0] = f.valid; r[1] = f.reason; r[2] = len_out(f.cx); r[3] = len_out(f.cy); r[4] = len_out(f.radius);
        r[5] = len_out(f.range); r[6] = ang_out(f.bearing); r[7] = len_out(f.residual); r[8] = num_out(f.gdop);
    }
}
