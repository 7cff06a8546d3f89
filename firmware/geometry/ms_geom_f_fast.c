/*
 * ms_geom_f_fast.c - the float formats' (MS_ARITH_F64, MS_ARITH_F32) side of the fast-path
 * interface of ms_geom_internal.h: there is no fast path (it is the Q format's,
 * ms_geom_q_fast.c), so every prepared call and every fix takes the general path, and
 * ms_fix_fast declines every fix after the input check. The build lists this file for those two.
 */
#include "ms_geom_internal.h"

#if MS_GEOM_ARITH == MS_ARITH_Q
#error "ms_geom_f_fast.c is the float formats': the Q build lists ms_geom_q_fast.c instead"
#endif

int msg_fast_prepare(ms_array *a)
{
    return a->fast; /* 0: ms_prepare cleared it */
}

int msg_fast_point(const ms_array *a, const ms_len_t *path, ms_point_fit *out)
{
    (void)a;
    (void)path;
    (void)out;
    return 0;
}

int msg_fast_wall(const ms_array *a, const ms_len_t *path, ms_wall_fit *out)
{
    (void)a;
    (void)path;
    (void)out;
    return 0;
}

MS_HOT int msg_fix_fast(const ms_array *a, const ms_len_t *path, ms_class *out, int *reason_out)
{
    *reason_out = fix_begin(a, path, out);
    return MS_FIX_DECLINED;
}

MS_HOT int ms_fix_fast(const ms_array *a, const ms_len_t *path, ms_class *out)
{
    int reason;
    return msg_fix_fast(a, path, out, &reason);
}
