/* table.c: the virtual-sensor table on the board. sched_table.c's check and load run on the
 * CSRs: START and a re-aim check the table in the registers and report the verdict in
 * STATUS.cfg_error; an accepted table is loaded through LOAD_ADDR / LOAD_DATA while the
 * scheduler is stopped, then started (CTRL.enable | CTRL.start). */
#include "app.h"
#include "sched_table.h"

#include "ms_sched_layout.h"

#define DELAY_BITS 16u /* the DELAY memory keeps 16 bits of each word (rtl/ms_csr.sv DELAY_W) */

/* DELAY words last written with bits the memory does not keep, one bit per (entry, element):
 * the check refuses an enabled entry whose tx element has one (CfgError DELAY); the memory
 * alone would read back a wrong, truncated delay */
static uint32_t delay_over[8];

void table_note_delay(uint32_t i, uint32_t v)
{
    uint32_t bit = 1u << (i % 32u);
    if (v >> DELAY_BITS)
        delay_over[i / 32u] |= bit;
    else
        delay_over[i / 32u] &= ~bit;
}

void table_write_delay(uint32_t vs, uint32_t el, uint32_t v)
{
    DELAY_ENTRY(vs, el) = v;
    table_note_delay(32u * vs + el, v);
}

static void source(ms_table_src_t *t)
{
    uint32_t rx = MS_SONAR(RX_FILTER);
    t->vs = &MS_SONAR(VS[0].TX_MASK);
    t->delay = &DELAY_ENTRY(0u, 0u);
    for (int i = 0; i < 8; i++)
        t->delay_over[i] = delay_over[i];
    t->burst_half_period = (MS_SONAR(BURST) & SONAR_REGS__BURST__HALF_PERIOD_bm)
                           >> SONAR_REGS__BURST__HALF_PERIOD_bp;
    t->lead = MS_SCHED_DECISION_LEAD;
    t->glitch_min = (rx & SONAR_REGS__RX_FILTER__GLITCH_MIN_bm)
                    >> SONAR_REGS__RX_FILTER__GLITCH_MIN_bp;
    t->miss_gate = (rx & SONAR_REGS__RX_FILTER__MISS_GATE_bm) >> SONAR_REGS__RX_FILTER__MISS_GATE_bp;
    t->miss_hold = (rx & SONAR_REGS__RX_FILTER__MISS_HOLD_bm)
                   >> SONAR_REGS__RX_FILTER__MISS_HOLD_bp;
}

uint32_t table_check(void)
{
    ms_table_src_t t;
    uint32_t entry = 0u;
    source(&t);
    uint32_t code = ms_table_check(&t, &entry);
    MS_SONAR(STATUS) = (code << SONAR_REGS__STATUS__CFG_ERROR_bp)
                       | (entry << SONAR_REGS__STATUS__CFG_ERROR_VS_bp);
    return code ? code | entry << 8 : 0u;
}

static void put(void *ctx, uint32_t addr, uint32_t word)
{
    (void)ctx;
    MS_SONAR(LOAD_ADDR) = addr;
    MS_SONAR(LOAD_DATA) = word;
}

void table_load_start(void)
{
    ms_table_src_t t;
    source(&t);
    ms_table_load(&t, put, 0);
    MS_SONAR(CTRL) = SONAR_REGS__CTRL__ENABLE_bm | SONAR_REGS__CTRL__START_bm;
}
