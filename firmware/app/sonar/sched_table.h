/* sched_table: the virtual-sensor table's check and the scheduler's load image.
 *
 * A pure function of the table (no MMIO of its own), so the host tests build the same code
 * (tests/test_fw_sched_table.py against multisonar.simdevice.decode_vs_table and
 * multisonar.tools.sched_program.system.load_image). All quantities are integer ticks of the
 * 48 MHz tick counter; words are the register words of rtl/regs/sonar_regs.rdl.
 */
#ifndef SCHED_TABLE_H
#define SCHED_TABLE_H

#include <stdint.h>

enum { MS_TABLE_ENTRIES = 8, MS_TABLE_ELEMENTS = 24 };

/* Where the table is read: the CSR block on the board, arrays in the host tests. */
typedef struct {
    const volatile uint32_t *vs;    /* VS[0].TX_MASK; entry i at vs + 16 i (sonar_regs VS stride) */
    const volatile uint32_t *delay; /* DELAY memory; entry i, element e at delay[32 i + e] */
    uint32_t delay_over[MS_TABLE_ENTRIES]; /* DELAY words written wider than 16 bits, bit e */
    uint32_t burst_half_period;     /* BURST.half_period, ticks */
    uint32_t lead;                  /* the scheduler's decision lead P, ticks */
    uint32_t glitch_min;            /* RX_FILTER.glitch_min, ticks */
    uint32_t miss_gate;             /* the gated miss rule, ticks (0: off) */
    uint32_t miss_hold;             /* the miss hold (0: off, 1: on) */
} ms_table_src_t;

/* The first refusal in the order of decode_vs_table: a MS_CFG_ERROR_* code (0: accepted) and,
 * through *entry, the refused table entry (0 for EMPTY_TABLE and for an accepted table). */
uint32_t ms_table_check(const ms_table_src_t *t, uint32_t *entry);

/* One word of the load image, at its address on ms_sched_uc's load port: the engine's data
 * memory and blank offsets, or the load's own tables (MS_SCHED_LD_*). */
typedef void (*ms_table_put_fn)(void *ctx, uint32_t addr, uint32_t word);

/* Every word a load writes for an accepted table (load_image: sensor words, blank offsets (a
 * before b), share words, window lengths, burst cycles, tx masks, the rx elements of all, the
 * main loop's constants; not the start tick). Returns the enabled entries, one bit each. */
uint32_t ms_table_load(const ms_table_src_t *t, ms_table_put_fn put, void *ctx);

#endif
