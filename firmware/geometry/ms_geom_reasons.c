/*
 * ms_geom_reasons.c - the names of the reason codes (enum ms_reason): both generated from
 * host/multisonar/geometry.py REASON_SYMBOLS / REASONS into ms_geom_reasons.h (make's gen step;
 * tests/test_fw_geometry.py checks the names against Python). Every number format.
 */
#include "ms_geom.h"

const char *const ms_reason_names[MS_NREASONS] = MS_REASON_TEXTS;
/* C99 static assert: the table has exactly MS_NREASONS entries */
typedef char ms_reason_table_check[(sizeof ms_reason_names / sizeof ms_reason_names[0]) == MS_NREASONS ? 1 : -1];
