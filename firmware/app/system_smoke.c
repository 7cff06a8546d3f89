/* System smoke test and default board image (ms_system: SoC + sonar core).
 * Run by tests/rtl/test_ms_system.py, and the image `make synth` puts into the bitstream.
 * Identifies the sonar core through the SoC's sonar port, writes a sonar setting and reads it
 * back, then reports what it saw to the mailbox and, as the payload of one frame packet
 * ("MF", the host link appends the CRC), to the bulk IN side; finally it kicks the watchdog
 * forever (a hang shows as WDT_RESETS). */
#include "ms_hw.h"

#define MAGIC_START 0x5157E000u
#define MAGIC_DONE 0x5157E0FFu
#define N_WORDS 6u

static void out(uint32_t value) {
    MS_SOC(HOST_TX) = value;
    ms_report(value);
}

int main(void) {
    MS_SOC(HOST_TX) = 0x4Du | (0x46u << 8) | (1u << 16) | (0x40u << 24); /* "MF", v1, frame */
    MS_SOC(HOST_TX) = (4u * N_WORDS) << 16;                               /* payload length */
    MS_SOC(HOST_TX) = 0u;                                                 /* seq */
    out(MAGIC_START | (MS_SOC(WDT_RESETS) & 0xFFu));
    out(MS_SONAR(ID));
    out(MS_SONAR(VERSION));
    out(MS_SONAR(CAPS));
    uint32_t burst = MS_SONAR(BURST);
    MS_SONAR(BURST) = (burst & 0xFFFF0000u) | 0x0123u;
    out(MS_SONAR(BURST));
    MS_SONAR(BURST) = burst;
    out(MAGIC_DONE);
    MS_SOC(HOST_CTRL) = SOC_REGS__HOST_CTRL__FRAME_END_bm;
    MS_SOC(WDT_TIMEOUT) = 48000000u;  /* 1 s */
    for (;;) {
        ms_wdt_kick();
    }
}
