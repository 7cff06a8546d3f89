/* Register access for Multisonar firmware.
 *
 * Every address comes from the generated ms_soc_map.h (PeakRDL, from the RDL files in rtl/regs). Its
 * structs are packed, and GCC reads packed members byte by byte; a byte-wise read of EVT_HI
 * would pop the event FIFO four times. MS_REG() therefore turns a member's offset into an
 * aligned 32-bit volatile access (one lw / sw). */
#ifndef MS_HW_H
#define MS_HW_H

#include <stddef.h>
#include <stdint.h>

#include "ms_soc_map.h"

/* Registers are reached through their alias with bit 31 set (rtl/soc/ms_soc.sv decodes both):
 * VexRiscv's data cache does not cache that half of the address space, PicoRV32 has no cache. */
#define MS_IO_UNCACHED 0x80000000u
#define MS_REG(path) (*(volatile uint32_t *)(MS_IO_UNCACHED | (uintptr_t)offsetof(ms_soc_map_t, path)))

#define MS_SONAR(reg) MS_REG(sonar.reg)
#define MS_SOC(reg) MS_REG(soc.reg)

static inline void ms_report(uint32_t value) { MS_SOC(SIM_OUT) = value; }
static inline void ms_wdt_kick(void) { MS_SOC(WDT_KICK) = 1u; }

static inline uint64_t ms_cycles(void) {
    uint32_t hi, lo;
    do {
        hi = MS_SOC(TIMER_HI);
        lo = MS_SOC(TIMER_LO);
    } while (hi != MS_SOC(TIMER_HI));
    return ((uint64_t)hi << 32) | lo;
}

#endif
