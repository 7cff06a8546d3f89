/*
 * ms_geom.h - reflector geometry for the RV32IM soft-core (issue #5).
 *
 * The same math as the Python golden model host/multisonar/geometry.py (read its module
 * docstring): the source is shifted to the origin, a point reflector at x satisfies
 * R_i*rho - c_i.x = (R_i^2 - |c_i|^2)/2 (linear in (x, y, rho), two receivers give a line
 * cut by the cone rho^2 = x^2 + y^2), a wall is the mirror image m of the source with
 * |m - c_i| = R_i (circle-circle intersection, Heron's factored half-chord). Both candidates
 * of the best-conditioned receiver pair are polished by damped Gauss-Newton on the true
 * residuals; the candidate is chosen with the same rules, thresholds and reason codes as
 * Python (physical -> misfit <= tol -> axis within fov -> gdop <= max_gdop).
 * Nothing is allocated, no result is ever NaN/Inf: invalid answers are zeros + a reason.
 *
 * Arithmetic variant, chosen at build time with -DMS_GEOM_ARITH=... (the build compiles the
 * library's common files plus that format's, ms_geom_q_*.c or ms_geom_f_*.c: the list in
 * firmware/README.md); stated bounds are against multisonar.geometry (float64) on the same
 * inputs and are what tests/test_fw_geometry.py checks (>= 1e5 cases per solver):
 *
 *   MS_ARITH_F64  double, the reference. Step for step the Python algorithm (same pair
 *                 choice, damped Gauss-Newton, stopping rule, thresholds). Noise-free:
 *                 positions within 1e-9 relative (measured <= 3e-12); valid flags identical
 *                 except <= 1e-3 of noisy cases, all at a knife edge (a two-receiver pair
 *                 whose curves do not meet: the fit starts at the tangency, where the
 *                 Jacobian is singular to rounding), or misfit/gdop within 1% of the limit.
 *                 Lengths m, angles rad, numbers double. Uses sqrt() and atan2().
 *   MS_ARITH_F32  float, same code; sqrtf()/atan2f(). Lengths m, angles rad. A Gauss-Newton
 *                 step is also taken when the cost is equal within 5e-7 (else the fit stops
 *                 on the flat bottom of the cost), and two polished candidates count as one
 *                 when closer than 1e-6*scale + 3e-7*scale*gdop (Python: 1e-6*scale).
 *                 Bound: error <= 2e-6 m * max(1, gdop) + 2e-6 * range in >= 99.9% of the
 *                 cases; valid flags differ in <= 1.5% (ambiguity/threshold decisions at
 *                 float precision).
 *   MS_ARITH_Q    fixed point, no float at all (the soft-core has no FPU):
 *                 interface: lengths int32 micrometres (|v| < 2147 m), angles int32 binary
 *                 angle (2^32 = one turn, LSB 1.46e-9 rad, wraps for free), numbers (gdop,
 *                 chi2, max_gdop, z) int32 Q16.16 saturating at 32767.99.
 *                 internal: Q32.32 metres in int64 (LSB 2^-32 m = 0.23 nm, saturating at
 *                 +-2^27 m), products via 32x32->64 limbs (rounded), 64/64 long division,
 *                 bit-by-bit integer sqrt on normalised operands (~31 significant bits,
 *                 also for hypot and vector norms), atan2 by 40-step CORDIC in 2^-48 turns
 *                 (< 1e-11 rad before rounding to the output LSB). The fit's cost is |f|
 *                 (normalised norm, not |f|^2, which would underflow); gdop comes from
 *                 Cauchy-Binet (sum of squared 2x2 minors, no cancellation); internally
 *                 it saturates at 1.3e8 (= singular), the Q16.16 output at 32767.99.
 *                 Roots beyond 1000 m are dropped.
 *                 Bound (same micrometre inputs on both sides): error <= MS_Q_ERR_ABS_M +
 *                 MS_Q_ERR_GDOP_M * gdop^2 in >= 99.9% of the cases (measured p99.9
 *                 <= 11 um over the whole test domain, ~0.6 um at 1..4 m); valid flags
 *                 differ in <= 0.5%. Rounding the inputs to 1 um adds <= 0.5 um * gdop
 *                 (the 48 MHz tick is 7.1 um of path, far coarser).
 *                 Fast 3-receiver path (the per-pulse calls of a prepared array with N = 3;
 *                 ms_geom_q_fast.c: closed-form start, one Gauss-Newton step, 32-bit
 *                 integers with 64-bit products, no division): it answers
 *                 only where Python's decision reduces to its polished start, else the
 *                 general path above answers. Stated bound on typical geometry (3 adjacent
 *                 ring receivers, source at the middle element or the ring centre, edge or
 *                 wall 0.5..4 m beyond the ring, +-20 deg, 1 us noise): range error <=
 *                 MS_Q_FAST_ERR_RANGE_M, bearing error <= MS_Q_FAST_ERR_BEARING_RAD,
 *                 flags / reasons / kinds as Python in >= 99.9% (measured on 2e4 pulses:
 *                 0.94 um, 3.3 urad, 100% / 100% / 99.97%); elsewhere the Q bound above.
 *
 * Cylinder (ms_solve_cylinder, N >= 3, general path only, all variants): the algorithm of
 * geometry.solve_cylinder (Gauss-Newton over bearing, r0, radius from the point and the wall
 * fit, Newton on the reflection angle; same reasons). f64: centre / radius within 1e-9 * scale
 * * gdop of Python in >= 97% and always within 0.1 * gdop * sigma, flags identical in >=
 * 99.9%. f32 / q: error <= 1e-5 m (q: 2e-6 m) + 2e-5 * gdop * scale in >= 99.9%; two fits
 * count as one solution within 1e-6 * scale * (1 + gdop) (q: gdop capped at 100), so the
 * exactly determined N = 3 'ambiguous' decision on noisy data differs from Python in up to
 * 13% (q) / 22% (f32) of the cases (Python's own answer there depends on where its two
 * fits stop in a flat valley of the cost). Millions of cycles on the soft-core.
 *
 * All variants: N = 2..MS_MAX_RX receivers. Reason codes below are numbered exactly as
 * geometry.REASONS (tests/test_fw_geometry.py checks the names against Python).
 */
#ifndef MS_GEOM_H
#define MS_GEOM_H

#include <stdint.h>

#define MS_ARITH_F64 1
#define MS_ARITH_F32 2
#define MS_ARITH_Q 3

#ifndef MS_GEOM_ARITH
#define MS_GEOM_ARITH MS_ARITH_F64
#endif

#define MS_MAX_RX 8

#if MS_GEOM_ARITH == MS_ARITH_F64
typedef double ms_len_t; /* metres */
typedef double ms_ang_t; /* radians */
typedef double ms_num_t; /* dimensionless */
#elif MS_GEOM_ARITH == MS_ARITH_F32
typedef float ms_len_t;
typedef float ms_ang_t;
typedef float ms_num_t;
#elif MS_GEOM_ARITH == MS_ARITH_Q
typedef int32_t ms_len_t; /* micrometres */
typedef int32_t ms_ang_t; /* binary angle: 2^32 per turn, INT32_MIN = -pi */
typedef int32_t ms_num_t; /* Q16.16 */
#define MS_Q_UM_PER_M 1000000
#define MS_Q_ANG_FROM_DEG(d) ((ms_ang_t)((d) * (4294967296.0 / 360.0)))
#define MS_Q_NUM(x) ((ms_num_t)((x) * 65536.0))
/* stated error bounds of the Q variant against float64 on the same inputs (tested) */
#define MS_Q_ERR_ABS_M 2e-6    /* metres */
#define MS_Q_ERR_GDOP_M 1e-8   /* metres per unit gdop^2 (fixed-point normal equations) */
/* fast 3-receiver path on typical geometry (tests/test_fw_geometry.py::test_q_fast_path_typical) */
#define MS_Q_FAST_ERR_RANGE_M 5e-6     /* metres */
#define MS_Q_FAST_ERR_BEARING_RAD 5e-6 /* radians */
#else
#error "MS_GEOM_ARITH must be MS_ARITH_F64, MS_ARITH_F32 or MS_ARITH_Q"
#endif

/* reason codes (enum ms_reason, MS_NREASONS): index = geometry.REASONS index; generated from
 * multisonar.geometry by the gen step (build/gen/firmware, multisonar.tools.gen_contracts) */
#include "ms_geom_reasons.h"
extern const char *const ms_reason_names[MS_NREASONS];

enum ms_kind { MS_KIND_EDGE = 0, MS_KIND_WALL = 1, MS_KIND_CYLINDER = 2, MS_KIND_UNCERTAIN = 3 };

enum ms_axis_mode {
    MS_AXIS_AUTO = 0, /* mean outward direction of the receivers seen from the robot origin */
    MS_AXIS_SET = 1,  /* use opts.axis */
    MS_AXIS_NONE = 2  /* no axis: two distinct exact answers are 'ambiguous' */
};

typedef struct {
    ms_len_t x, y;
} ms_vec2;

typedef struct {
    ms_len_t tol;      /* RMS path misfit accepted; default 1 mm */
    ms_num_t max_gdop; /* default 1e4 */
    ms_ang_t fov;      /* half field of view round the axis; default 60 deg */
    uint8_t axis_mode; /* enum ms_axis_mode */
    uint8_t no_tol;    /* 1: tol = infinity (classify uses this) */
    uint8_t no_gdop;   /* 1: max_gdop = infinity */
    ms_ang_t axis;     /* used when axis_mode == MS_AXIS_SET */
} ms_opts;

typedef struct {
    uint8_t valid, reason;
    ms_len_t x, y;     /* robot frame */
    ms_len_t range;    /* |position - source| */
    ms_ang_t bearing;  /* atan2 of position - source */
    ms_len_t residual; /* RMS path misfit */
    ms_num_t gdop;     /* position error (m RMS) per metre of path noise */
} ms_point_fit;

typedef struct {
    uint8_t valid, reason;
    ms_len_t distance;     /* source -> wall line */
    ms_ang_t normal_angle; /* bearing of the foot of the perpendicular from the source */
    ms_len_t foot_x, foot_y;
    ms_len_t residual;
    ms_num_t gdop;
} ms_wall_fit;

typedef struct {
    uint8_t valid, reason;
    ms_len_t cx, cy;   /* centre, robot frame */
    ms_len_t radius;   /* 0 = an edge, 1000 m = a wall */
    ms_len_t range;    /* source -> nearest point of the circle */
    ms_ang_t bearing;  /* of the centre from the source (f64/f32: as fitted, not wrapped) */
    ms_len_t residual;
    ms_num_t gdop;
} ms_cyl_fit;

typedef struct {
    ms_ang_t fov;
    uint8_t axis_mode;
    ms_ang_t axis;
    ms_num_t z; /* standard normal quantile of the confidence; default 3.0902323 (0.999) */
} ms_class_opts;

typedef struct {
    uint8_t kind;        /* enum ms_kind */
    uint8_t accepted;    /* bit 0 edge, bit 1 wall, bit 2 cylinder (never set: not in the decision) */
    uint8_t reason;      /* MS_BADIN for bad input / N < 3, else MS_OK */
    ms_num_t chi2[3];    /* edge, wall, cylinder (cylinder: 0, not in the decision) */
    ms_num_t thr[3];     /* acceptance thresholds (chi-square quantiles) */
    ms_point_fit point;  /* fits with tol = max_gdop = infinity (as Python's classify) */
    ms_wall_fit wall;
} ms_class;

/* A virtual sensor's receiver array with its options, prepared once (when the sensor is
 * configured) for the per-pulse calls ms_fix / ms_point_prepared / ms_wall_prepared.
 * MS_ARITH_Q with N = 3: the closed-form path below (ms_geom_q_fast.c, the fast 3-receiver path):
 * per pulse a fix (point + wall + classification) costs a few thousand cycles on the
 * soft-core; the general N-receiver path (any variant, any N, and every case the closed form
 * declines) is the step-by-step port of the Python algorithm. Fields are private. */
typedef struct {
    int n;
    ms_vec2 rx[MS_MAX_RX];
    ms_vec2 src;
    ms_opts opts;
    ms_len_t sigma;   /* classify: path noise */
    ms_num_t thr[3];  /* classify: chi-square thresholds (edge, wall, cylinder) */
    uint8_t bad;      /* n out of range or sigma <= 0: every call answers MS_BADIN */
    uint8_t fast;     /* the closed-form 3-receiver path applies (Q only) */
#if MS_GEOM_ARITH == MS_ARITH_Q /* the fast path's fields (ms_geom_q_fast.c): the struct is per format */
    int32_t cx[3], cy[3];  /* receivers - source, internal unit 2^-2 um */
    int64_t cc[3];         /* |c|^2, internal units squared */
    uint8_t pi, pj;        /* receiver pair of the closed-form starts */
    int32_t ex, ey;        /* unit vector c_pj - c_pi, Q30 */
    int32_t dd;            /* |c_pj - c_pi|, internal units */
    uint32_t dinv;         /* 1/dd = dinv * 2^-dsh */
    int32_t dsh;
    int32_t ax, ay;        /* unit axis, Q30 */
    int32_t cos_fov;       /* cos(fov), Q30 */
    int32_t cos_mir;       /* a mirror candidate must be off the axis by more than fov + 20 deg */
    uint32_t sinv;         /* 1/sigma^2 = sinv * 2^-ssh (internal units) */
    int32_t ssh;
#endif
} ms_array;

void ms_opts_default(ms_opts *o);
void ms_class_opts_default(ms_class_opts *o);

/* rx: n receivers (robot frame), path: n path lengths source -> reflector -> receiver i,
 * src: the (virtual) source. opts may be NULL (defaults). Return out->valid. */
int ms_solve_point(const ms_vec2 *rx, const ms_len_t *path, int n, ms_vec2 src,
                   const ms_opts *opts, ms_point_fit *out);
int ms_solve_wall(const ms_vec2 *rx, const ms_len_t *path, int n, ms_vec2 src,
                  const ms_opts *opts, ms_wall_fit *out);
/* Edge / wall / uncertain decision (N >= 3), the rule of geometry.classify without the
 * cylinder model: where Python answers 'cylinder' this answers 'uncertain' (the cylinder fit
 * costs millions of cycles; ms_solve_cylinder is there when wanted).
 * noise_sigma: path-length noise (default in Python 1 us of sound, 0.343 mm). Returns kind.
 * Same as ms_prepare (opts from these opts) + ms_fix. */
int ms_classify(const ms_vec2 *rx, const ms_len_t *path, int n, ms_vec2 src,
                ms_len_t noise_sigma, const ms_class_opts *opts, ms_class *out);

/* Specular circle (pillar, person), radius unknown, N >= 3: geometry.solve_cylinder (Gauss-
 * Newton over bearing, r0, radius from the point and the wall fit; same reasons). General
 * path only: millions of cycles on the soft-core, not a per-pulse call. Not reentrant (its
 * two fit states are static: kept off the 8 KiB stack). */
int ms_solve_cylinder(const ms_vec2 *rx, const ms_len_t *path, int n, ms_vec2 src, const ms_opts *opts,
                      ms_cyl_fit *out);

/* Prepare once: rx, n, src as for the solvers; opts (NULL: defaults) sets tol, max_gdop, fov and
 * the axis for every prepared call; copts (NULL: defaults; only z is used) and noise_sigma
 * set the classification thresholds. Returns 1 when the fast path applies. */
int ms_prepare(ms_array *a, const ms_vec2 *rx, int n, ms_vec2 src, const ms_opts *opts,
               const ms_class_opts *copts, ms_len_t noise_sigma);
/* Per pulse (path: a->n path lengths): same results as ms_solve_point / ms_solve_wall. */
int ms_point_prepared(const ms_array *a, const ms_len_t *path, ms_point_fit *out);
int ms_wall_prepared(const ms_array *a, const ms_len_t *path, ms_wall_fit *out);
/* Per pulse: one fix = both fits and the edge / wall / uncertain decision, as ms_classify
 * (fits with tol = max_gdop = infinity, as Python's classify; the array's fov and axis). */
int ms_fix(const ms_array *a, const ms_len_t *path, ms_class *out);
/* ms_fix's bounded part: the closed-form fast path (Q, N = 3) only. Returns the kind as ms_fix
 * would, or MS_FIX_DECLINED where ms_fix would take the general path (millions of cycles):
 * the real-time firmware skips those fixes (counted) instead of stalling its event path. */
#define MS_FIX_DECLINED (-1)
int ms_fix_fast(const ms_array *a, const ms_len_t *path, ms_class *out);

#endif
