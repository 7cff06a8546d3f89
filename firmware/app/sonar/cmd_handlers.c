/* One handler per opcode (docs/protocol.md section 3), registered in cmd_handlers[]. A handler
 * runs while the sonar core fires (but START and STOP): each is bounded by its payload (at most
 * 1024 bytes). */
#include "cmd.h"

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
    return MS_ST_BAD_ADDRESS;
}

static uint32_t cmd_device_info(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    (void)pl;
    (void)len;
    uint32_t caps = MS_SONAR(CAPS);
    rbuf[3] = MS_PROTOCOL_VERSION | (MS_MAX_PAYLOAD << 16);
    rbuf[4] = MS_SONAR(TICK_HZ);
    rbuf[5] = (caps & SONAR_REGS__CAPS__NUM_CH_bm) >> SONAR_REGS__CAPS__NUM_CH_bp
            | ((caps & SONAR_REGS__CAPS__NUM_VS_bm) >> SONAR_REGS__CAPS__NUM_VS_bp) << 8
            | ((caps & SONAR_REGS__CAPS__MAX_ORDER_bm) >> SONAR_REGS__CAPS__MAX_ORDER_bp) << 16;
    rbuf[6] = MS_SONAR(VERSION);
    rbuf[7] = APP_BUILD_ID;
    rbuf[8] = caps;
    *rlen = MS_DEVICE_INFO_SIZE;
    return MS_ST_OK;
}

static uint32_t cmd_write_regs(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    if (len % 8u)
        return MS_ST_BAD_LENGTH;
    if (running)
        return MS_ST_BUSY;
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
    return MS_ST_OK;
}

static uint32_t cmd_read_regs(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    if (len % 4u)
        return MS_ST_BAD_LENGTH;
    for (uint32_t i = 0; i < len / 4u; i++) {
        uint32_t a = pl[i];
        if (!readable(a))
            return bad_address(i, a, rlen);
        /* the event FIFO's read port pops: READ_REGS answers 0 there */
        rbuf[3 + i] = (a == SONAR_OFF(EVT_LO) || a == SONAR_OFF(EVT_HI)) ? 0u : SONAR_AT(a);
    }
    *rlen = len;
    return MS_ST_OK;
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
        return MS_ST_BUSY;
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
        return MS_ST_CFG_REJECTED;
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
            return MS_ST_INTERNAL;
        }
    }
    running = 1;
    busy_acc = 0;
    rbuf[3] = frame_seq;
    *rlen = 4u;
    return MS_ST_OK;
}

static uint32_t cmd_stop(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    (void)pl;
    (void)len;
    stop_run();
    rbuf[3] = frame_seq;
    *rlen = 4u;
    return MS_ST_OK;
}

static uint32_t cmd_read_counters(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    (void)pl;
    (void)len;
    uint32_t *c = &rbuf[3];
    c[MS_COUNTER_FRAMES_SENT] = MS_SOC(FRAMES_SENT);
    c[MS_COUNTER_FRAMES_DROPPED] = MS_SOC(FRAMES_DROPPED);
    c[MS_COUNTER_EVENTS] = MS_SONAR(EVENTS);
    c[MS_COUNTER_PULSES] = MS_SONAR(PULSES);
    c[MS_COUNTER_FIFO_OVERFLOWS] = MS_SONAR(OVERFLOWS);
    c[MS_COUNTER_WATCHDOG] = MS_SOC(WDT_RESETS) - wdt_base;
    c[MS_COUNTER_BAD_COMMANDS] = bad_commands;
    c[MS_COUNTER_TX_COLLISIONS] = MS_SONAR(TX_COLLISIONS);
    c[MS_COUNTER_TIMESTAMP] = now32();
    *rlen = 4u * MS_COUNTER_COUNT;
    return MS_ST_OK;
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
    for (int i = 0; i < MS_FW_STAT_COUNT; i++)
        fw_stats[i] = 0;
    return MS_ST_OK;
}

static uint32_t cmd_fw_stats(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    (void)pl;
    (void)len;
    for (int i = 0; i < MS_FW_STAT_COUNT; i++)
        rbuf[3 + i] = fw_stats[i];
    *rlen = 4u * MS_FW_STAT_COUNT;
    return MS_ST_OK;
}

static uint32_t param_get(uint32_t id, int32_t *v)
{
    switch (id) {
    case MS_PARAM_TEMPERATURE_CC: *v = temperature_cc; return 1;
    case MS_PARAM_GEOMETRY: *v = par_geometry; return 1;
    case MS_PARAM_TOF_RECORDS: *v = par_tof; return 1;
    case MS_PARAM_MAX_ECHOES: *v = par_max_echoes; return 1;
    case MS_PARAM_GLITCH_MIN: *v = (int32_t)(MS_SONAR(RX_FILTER) & SONAR_REGS__RX_FILTER__GLITCH_MIN_bm); return 1;
    default: return 0;
    }
}

static uint32_t param_set(uint32_t id, int32_t v)
{
    static const int32_t lo[MS_PARAM_COUNT] = MS_PARAM_MINS, hi[MS_PARAM_COUNT] = MS_PARAM_MAXS;
    if (id < 1 || id >= MS_PARAM_COUNT || v < lo[id] || v > hi[id])
        return MS_ST_BAD_PARAM;
    if (running && ((MS_PARAM_BUSY_WHILE_RUNNING >> id) & 1u))
        return MS_ST_BUSY;
    switch (id) {
    case MS_PARAM_TEMPERATURE_CC:
        temperature_cc = v;
        update_path_k();
        break;
    case MS_PARAM_GEOMETRY: par_geometry = (uint8_t)v; break;
    case MS_PARAM_TOF_RECORDS: par_tof = (uint8_t)v; break;
    case MS_PARAM_MAX_ECHOES: par_max_echoes = (uint8_t)v; break;
    default:
        MS_SONAR(RX_FILTER) = (MS_SONAR(RX_FILTER) & ~SONAR_REGS__RX_FILTER__GLITCH_MIN_bm) | (uint32_t)v;
        break;
    }
    return MS_ST_OK;
}

static uint32_t cmd_set_param(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    if (len != 8u)
        return MS_ST_BAD_LENGTH;
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
        return MS_ST_BAD_LENGTH;
    rbuf[3] = pl[0] & 0xFFFFu;
    if (!param_get(pl[0] & 0xFFFFu, &v)) {
        *rlen = 2u;
        return MS_ST_BAD_PARAM;
    }
    rbuf[4] = (uint32_t)v;
    *rlen = 8u;
    return MS_ST_OK;
}

static uint32_t cmd_echo(const uint32_t *pl, uint32_t len, uint32_t *rlen)
{
    for (uint32_t i = 0; i < (len + 3u) / 4u; i++) /* word aligned in both packets */
        rbuf[3 + i] = pl[i];
    *rlen = len;
    return MS_ST_OK;
}

const cmd_handler_t cmd_handlers[MS_OP_COUNT] = {
    [MS_OP_DEVICE_INFO] = {cmd_device_info, 0},
    [MS_OP_WRITE_REGS] = {cmd_write_regs, 1},
    [MS_OP_READ_REGS] = {cmd_read_regs, 1},
    [MS_OP_START] = {cmd_start, 0},
    [MS_OP_STOP] = {cmd_stop, 0},
    [MS_OP_READ_COUNTERS] = {cmd_read_counters, 0},
    [MS_OP_CLEAR_COUNTERS] = {cmd_clear_counters, 0},
    [MS_OP_SET_PARAM] = {cmd_set_param, 1},
    [MS_OP_GET_PARAM] = {cmd_get_param, 1},
    [MS_OP_ECHO] = {cmd_echo, 1},
    [MS_OP_FW_STATS] = {cmd_fw_stats, 0},
};
