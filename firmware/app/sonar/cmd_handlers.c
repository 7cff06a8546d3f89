/* One handler per opcode (docs/protocol.md section 3), registered in cmd_handlers[]. A handler
 * runs while the sonar core fires (but START and STOP): each is bounded by its payload (at most
 * 1024 bytes). */
#include "cmd.h"

enum { PAR_TEMPERATURE_CC = 1, PAR_GEOMETRY, PAR_TOF_RECORDS, PAR_MAX_ECHOES, PAR_GLITCH_MIN };

static int writable(uint32_t a)
{
    if (a & 3u)
        return 0;
    if (a == SONAR_OFF(BURST) || a == SONAR_OFF(RX_FILTER))
        return 1;
    if (a >= SONAR_OFF(VS) && a < SONAR_OFF(VS) + 8u * VS_STRIDE)
        return (a - SONAR_OFF(VS)) % VS_STRIDE <= offsetof(sonar_regs__VS__stride40_t, PHASE);
    return a >= SONAR_OFF(DELAY) && a < SONAR_OFF(DELAY) + (uint32_t)sizeof(sonar_regs__DELAY_t);
}

static int readable(uint32_t a) { return !(a & 3u) && (a <= SONAR_OFF(EVT_HI) || writable(a)); }

static uint32_t bad_address(uint32_t i, uint32_t a, uint32_t *rlen)
{
    rbuf[3] = i;
    rbuf[4] = a;
    *rlen = 8u;
    return ST_BAD_ADDRESS;
}

static uint32_t cmd_device_info(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    (void)pl;
    (void)len;
    uint32_t caps = MS_SONAR(CAPS);
    rbuf[3] = 1u | (1024u << 16);
    rbuf[4] = MS_SONAR(TICK_HZ);
    rbuf[5] = (caps & SONAR_REGS__CAPS__NUM_CH_bm) >> SONAR_REGS__CAPS__NUM_CH_bp
            | ((caps & SONAR_REGS__CAPS__NUM_VS_bm) >> SONAR_REGS__CAPS__NUM_VS_bp) << 8
            | ((caps & SONAR_REGS__CAPS__MAX_ORDER_bm) >> SONAR_REGS__CAPS__MAX_ORDER_bp) << 16;
    rbuf[6] = MS_SONAR(VERSION);
    rbuf[7] = APP_BUILD_ID;
    rbuf[8] = caps;
    *rlen = 24u;
    return ST_OK;
}

static uint32_t cmd_write_regs(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    if (len % 8u)
        return ST_BAD_LENGTH;
    if (running)
        return ST_BUSY;
    for (uint32_t i = 0; i < len / 8u; i++) {
        uint32_t a = pl[2 * i];
        if (!writable(a))
            return bad_address(i, a, rlen);
        SONAR_AT(a) = pl[2 * i + 1];
        if (a >= SONAR_OFF(DELAY))
            table_note_delay((a - SONAR_OFF(DELAY)) / 4u, pl[2 * i + 1]);
    }
    rbuf[3] = len / 8u;
    *rlen = 2u;
    return ST_OK;
}

static uint32_t cmd_read_regs(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    if (len % 4u)
        return ST_BAD_LENGTH;
    for (uint32_t i = 0; i < len / 4u; i++) {
        uint32_t a = pl[i];
        if (!readable(a))
            return bad_address(i, a, rlen);
        /* the event FIFO's read port pops: READ_REGS answers 0 there */
        rbuf[3 + i] = (a == SONAR_OFF(EVT_LO) || a == SONAR_OFF(EVT_HI)) ? 0u : SONAR_AT(a);
    }
    *rlen = len;
    return ST_OK;
}

/* stop firing; every pulse collected so far becomes a frame, with its geometry (no frame
 * follows STOP's reply) */
void stop_run(void)
{
    MS_SONAR(CTRL) = 0u;
    running = 0;
    reaim_cancel();
    uint32_t t_stop = now32();
    poll_events(ALL_WORDS);
    cut_open(-1, t_stop);
    while (geo_step())
        ;
}

/* START: discard old frames; the table in the registers checked, loaded and started */
static uint32_t cmd_start(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    (void)pl;
    (void)len;
    if (running)
        return ST_BUSY;
    MS_SOC(HOST_CTRL) = SOC_REGS__HOST_CTRL__DISCARD_bm;
    groups_clear();
    geo_clear();
    reaim_cancel();
    MS_SONAR(CTRL) = 0u; /* stopped (a CPU-only watchdog reset can leave it running) */
    while (MS_SONAR(EVT_HI) & SONAR_REGS__EVT_HI__VALID_bm) /* drain */
        ;
    uint32_t refused = table_check();
    if (refused) {
        ms_report(0xE0000000u | (refused & 0xFu) << 4 | refused >> 8);
        rbuf[3] = refused;
        *rlen = 2u;
        return ST_CFG_REJECTED;
    }
    load_sensors();
    apply_rx_filter();
    for (int i = 0; i < 8; i++)
        last_pulse_id[i] = 0;
    table_load_start();
    uint32_t t = now32();
    while (!(MS_SONAR(STATUS) & SONAR_REGS__STATUS__RUNNING_bm)) {
        ms_wdt_kick();
        if (now32() - t > START_WAIT) {
            MS_SONAR(CTRL) = 0u;
            return ST_INTERNAL;
        }
    }
    running = 1;
    busy_acc = 0;
    rbuf[3] = frame_seq;
    *rlen = 4u;
    return ST_OK;
}

static uint32_t cmd_stop(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    (void)pl;
    (void)len;
    stop_run();
    rbuf[3] = frame_seq;
    *rlen = 4u;
    return ST_OK;
}

static uint32_t cmd_read_counters(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    (void)pl;
    (void)len;
    rbuf[3] = MS_SOC(FRAMES_SENT);
    rbuf[4] = MS_SOC(FRAMES_DROPPED);
    rbuf[5] = MS_SONAR(EVENTS);
    rbuf[6] = MS_SONAR(PULSES);
    rbuf[7] = MS_SONAR(OVERFLOWS);
    rbuf[8] = MS_SOC(WDT_RESETS) - wdt_base;
    rbuf[9] = bad_commands;
    rbuf[10] = MS_SONAR(TX_COLLISIONS);
    rbuf[11] = now32();
    *rlen = 36u;
    return ST_OK;
}

static uint32_t cmd_clear_counters(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    (void)pl;
    (void)len;
    (void)rlen;
    MS_SONAR(CTRL) = (running ? SONAR_REGS__CTRL__ENABLE_bm : 0u) | SONAR_REGS__CTRL__CLEAR_COUNTERS_bm;
    MS_SOC(HOST_CTRL) = SOC_REGS__HOST_CTRL__CLEAR_bm;
    wdt_base = MS_SOC(WDT_RESETS);
    bad_commands = 0;
    for (int i = 0; i < FW_NSTATS; i++)
        fw_stats[i] = 0;
    return ST_OK;
}

static uint32_t cmd_fw_stats(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    (void)pl;
    (void)len;
    for (int i = 0; i < FW_NSTATS; i++)
        rbuf[3 + i] = fw_stats[i];
    *rlen = 4u * FW_NSTATS;
    return ST_OK;
}

static uint32_t param_get(uint32_t id, int32_t *v)
{
    switch (id) {
    case PAR_TEMPERATURE_CC: *v = temperature_cc; return 1;
    case PAR_GEOMETRY: *v = par_geometry; return 1;
    case PAR_TOF_RECORDS: *v = par_tof; return 1;
    case PAR_MAX_ECHOES: *v = par_max_echoes; return 1;
    case PAR_GLITCH_MIN: *v = (int32_t)(MS_SONAR(RX_FILTER) & SONAR_REGS__RX_FILTER__GLITCH_MIN_bm); return 1;
    default: return 0;
    }
}

static uint32_t param_set(uint32_t id, int32_t v)
{
    static const int32_t lo[6] = {0, -4000, 0, 0, 1, 1}, hi[6] = {0, 8000, 1, 1, 15, 255};
    if (id < 1 || id > 5 || v < lo[id] || v > hi[id])
        return ST_BAD_PARAM;
    if (running && (id == PAR_MAX_ECHOES || id == PAR_GLITCH_MIN))
        return ST_BUSY;
    switch (id) {
    case PAR_TEMPERATURE_CC:
        temperature_cc = v;
        update_path_k();
        break;
    case PAR_GEOMETRY: par_geometry = (uint8_t)v; break;
    case PAR_TOF_RECORDS: par_tof = (uint8_t)v; break;
    case PAR_MAX_ECHOES: par_max_echoes = (uint8_t)v; break;
    default:
        MS_SONAR(RX_FILTER) = (MS_SONAR(RX_FILTER) & ~SONAR_REGS__RX_FILTER__GLITCH_MIN_bm) | (uint32_t)v;
        break;
    }
    return ST_OK;
}

static uint32_t cmd_set_param(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    if (len != 8u)
        return ST_BAD_LENGTH;
    uint32_t id = pl[0] & 0xFFFFu, st = param_set(id, (int32_t)pl[1]);
    rbuf[3] = pl[0];
    rbuf[4] = pl[1];
    *rlen = 8u;
    return st;
}

static uint32_t cmd_get_param(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    int32_t v = 0;
    if (len != 2u)
        return ST_BAD_LENGTH;
    rbuf[3] = pl[0] & 0xFFFFu;
    if (!param_get(pl[0] & 0xFFFFu, &v)) {
        *rlen = 2u;
        return ST_BAD_PARAM;
    }
    rbuf[4] = (uint32_t)v;
    *rlen = 8u;
    return ST_OK;
}

static uint32_t cmd_echo(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    for (uint32_t i = 0; i < (len + 3u) / 4u; i++) /* word aligned in both packets */
        rbuf[3 + i] = pl[i];
    *rlen = len;
    return ST_OK;
}

const cmd_handler_t cmd_handlers[OP_COUNT] = {
    [OP_DEVICE_INFO] = {cmd_device_info, 0},
    [OP_WRITE_REGS] = {cmd_write_regs, 1},
    [OP_READ_REGS] = {cmd_read_regs, 1},
    [OP_START] = {cmd_start, 0},
    [OP_STOP] = {cmd_stop, 0},
    [OP_READ_COUNTERS] = {cmd_read_counters, 0},
    [OP_CLEAR_COUNTERS] = {cmd_clear_counters, 0},
    [OP_SET_PARAM] = {cmd_set_param, 1},
    [OP_GET_PARAM] = {cmd_get_param, 1},
    [OP_ECHO] = {cmd_echo, 1},
    [OP_FW_STATS] = {cmd_fw_stats, 0},
};
