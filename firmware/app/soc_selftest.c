/* SoC self-test, run by tests/rtl/test_ms_soc.py: reports through the SIM_OUT mailbox.
 * 1st boot: identify the sonar core, exercise mul/div, the timer, the idle wait (WAIT: until WAKE_AT,
 * at once when WAKE_AT is past, until the bench raises wake_evt_i) and the host link (one frame
 * packet), then hang on purpose in a WAIT that nothing ends, with a short watchdog timeout. 2nd boot (after the watchdog reset of the CPU):
 * report the reset count and finish. The sequence of reported words is the test's oracle. */
#include "ms_hw.h"

#define MAGIC_HELLO 0x5E1F0000u
#define MAGIC_HANG 0xDEAD0001u
#define MAGIC_BACK 0xA1160000u
#define MAGIC_DONE 0x00000D0Eu
#define MAGIC_WAIT 0x3A170000u     /* | why << 8 | the wait took as long as it should */
#define MAGIC_WAIT_EVT 0x3A17E000u /* the bench raises wake_evt_i on seeing it */

/* WAKE_AT = TIMER_LO + ahead, read WAIT: its reasons and the cycles it took */
static uint32_t wait_for(uint32_t ahead, uint32_t *took)
{
    uint32_t t0 = MS_SOC(TIMER_LO);
    MS_SOC(WAKE_AT) = t0 + ahead;
    uint32_t why = MS_SOC(WAIT);
    *took = MS_SOC(TIMER_LO) - t0;
    return why;
}

int main(void) {
    uint32_t resets = MS_SOC(WDT_RESETS);
    ms_report(MAGIC_HELLO | resets);
    if (MS_SOC(SCRATCH) == 0) {
        ms_report(MS_SONAR(ID));
        ms_report(MS_SONAR(TICK_HZ));
        volatile uint32_t a = 123456789u, b = 1000u;
        volatile int32_t n = -77777;
        ms_report(a * 7u);
        ms_report(a / b);
        ms_report(a % b);
        ms_report((uint32_t)(n / 7));
        uint64_t t0 = ms_cycles();
        uint64_t t1 = ms_cycles();
        ms_report((uint32_t)(t1 > t0));
        uint32_t took, why = wait_for(1000u, &took);
        ms_report(MAGIC_WAIT | why << 8 | (took >= 1000u && took < 1040u));
        why = wait_for(-5u, &took);
        ms_report(MAGIC_WAIT | why << 8 | (took < 40u));
        ms_report(MAGIC_WAIT_EVT);
        why = wait_for(0x40000000u, &took);
        ms_report(MAGIC_WAIT | why << 8 | (took >= 300u && took < 3000u));
        /* one frame packet: "MF" v1 type 0x40, length 8, seq 0, two payload words; the host
         * link appends the CRC-32 when it is committed */
        MS_SOC(HOST_TX) = 0x4Du | (0x46u << 8) | (1u << 16) | (0x40u << 24);
        MS_SOC(HOST_TX) = 8u << 16;
        MS_SOC(HOST_TX) = 0u;
        for (uint32_t i = 0; i < 2; i++) MS_SOC(HOST_TX) = 0xC0DE0000u + i;
        ms_report(MS_SOC(HOST_STATUS) & SOC_REGS__HOST_STATUS__WAITING_bm);
        MS_SOC(HOST_CTRL) = SOC_REGS__HOST_CTRL__FRAME_END_bm;
        MS_SOC(SCRATCH) = 1u;
        MS_SOC(WDT_TIMEOUT) = 3000u;
        ms_wdt_kick();
        ms_report(MAGIC_HANG);
        for (;;) /* only the watchdog ends this WAIT; the registers must answer after it */
            (void)wait_for(0x40000000u, &took);
    }
    MS_SOC(WDT_TIMEOUT) = 0u;
    ms_report(MAGIC_BACK | resets);
    ms_report(MAGIC_DONE);
    for (;;) {
    }
}
