/*
 * ms_geom_reasons.c - the names of the reason codes (enum ms_reason, ms_geom.h), numbered
 * exactly as host/multisonar/geometry.py REASONS (tests/test_fw_geometry.py checks the names
 * against Python). Every number format.
 */
#include "ms_geom.h"

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
