/* The ToF path: event-FIFO words -> pulse groups -> ToF frames (firmware/README.md, "Main loop").
 *
 * A pulse record (bit 62: sensor, 16-bit pulse id, the exact t0, the number of windows; written
 * by the scheduler before any event of its pulse) opens the pulse's group, keyed (sensor, pulse
 * id mod 256) in the sensor's GROUP_SLOTS slots; a ToF event goes into its group. A group is
 * complete when each of its windows has its terminal event (first echo or window_empty). A
 * cancel record (bits 62, 61) or an init ping's record closes the open pulses of its sensor
 * (their windows were cancelled: CUT); a group also goes when the sensor's maximum time of
 * flight plus 1 ms has passed since t0 (CUT).
 * An overflow flag on a word marks every open group LOST (no fix); an event whose record was
 * lost gets an estimated t0 (pop time - tof - edge latency) and LOST. A complete group becomes
 * its ToF frame at once and, with its first echoes, a geometry job (geo.c). */
#include "app.h"
#include "ms_event_word.h"

group_t groups[MAX_GROUPS];
static uint32_t fbuf[3 + 5 + 2 * MAX_EV + 4];
uint32_t word_aside; /* cycles of frames and a re-aim's hand-over, taken out of the word's figure */

/* one frame (docs/protocol.md sections 2, 6): header 12 bytes, head 20 bytes, records; the host
 * link appends the CRC-32 at the commit and drops the frame whole (FRAMES_DROPPED) if the frame
 * queue has no room for it */
APP_HOT void send_packet(uint32_t flags, uint32_t t0, uint32_t vs, uint32_t seq, uint32_t n_tof,
                 const uint32_t *tof, uint32_t gated, uint32_t n_geo, const uint32_t *geo)
{
    uint32_t *w = fbuf;
    uint32_t plen = MS_FRAME_HEAD_SIZE + MS_TOF_RECORD_SIZE * n_tof + MS_GEO_RECORD_SIZE * n_geo;
    uint32_t nwords = (MS_HEADER_SIZE + plen) / 4u;
    w[0] = MS_MAGIC_FRAME | (MS_PROTOCOL_VERSION << 16) | (MS_FRAME_TYPE << 24);
    w[1] = flags | (0u << 8) | (plen << 16);
    w[2] = frame_seq;
    w[3] = now32();              /* timestamp */
    w[4] = t0;                   /* the pulse record's trigger tick */
    w[5] = vs | (seq << 8) | (n_tof << 16) | (n_geo << 24);
    w[6] = MS_SOC(FRAMES_DROPPED);
    w[7] = (MS_SONAR(OVERFLOWS) & 0xFFFFu) | (((MS_SOC(WDT_RESETS) - wdt_base) & 0xFFFFu) << 16);
    uint32_t *p = &w[8];
    uint32_t word1 = (seq << 8) | (vs << 16) | ((flags & MS_FRAME_INIT_PING) ? (MS_TOF_INIT_PING << 24) : 0u);
    for (uint32_t i = 0; i < n_tof; i++) { /* group_t.rec -> the wire's two words */
        uint32_t rx = (tof[i] >> 24) & 0x1Fu, fl = tof[i] >> 29;
        if ((fl & MS_TOF_FIRST_ECHO) && ((gated >> rx) & 1u)) /* the first echo of a receiver in `gated` */
            fl |= MS_TOF_GATED;
        *p++ = tof[i] & 0xFFFFFFu;
        *p++ = word1 | rx | (fl << 24);
    }
    for (uint32_t i = 0; i < 4u * n_geo; i++)
        *p++ = geo[i];
    frame_seq++;
    for (uint32_t i = 0; i < nwords; i++)
        MS_SOC(HOST_TX) = w[i];
    MS_SOC(HOST_CTRL) = SOC_REGS__HOST_CTRL__FRAME_END_bm;
}

/* the group's ToF frame at once, then its geometry job; the mailbox and stats */
APP_HOT static void close_group(group_t *g)
{
    uint32_t t = now32();
    send_packet(g->flags, g->t0, g->vs, g->seq, par_tof ? g->n_ev : 0u, g->rec, g->gated, 0u, 0);
    g->used = 0;
    geo_enqueue(g);
    /* mailbox 0x2: from the pulse's completion (the detection tick of its last window's
     * terminal event, or of the cancel that cut it; the pop when its record was lost) */
    uint32_t from = (g->flags & MS_FRAME_LOST) ? g->t_pop : g->t_done, now = now32(), lat = now - from;
    ms_report(0x20000000u | (lat & 0x0FFFFFFFu));
    stat_max(MS_FW_STAT_LATENCY_MAX_TICKS, lat);
    fw_stats[MS_FW_STAT_LATENCY_OVER_1MS] += lat > MS_TICK_HZ / 1000u;
    fw_stats[MS_FW_STAT_FRAMES_CUT] += (g->flags & MS_FRAME_CUT) != 0;
    fw_stats[MS_FW_STAT_FRAMES_LOST] += (g->flags & MS_FRAME_LOST) != 0;
    stat_max(MS_FW_STAT_CYCLES_FRAME_MAX, now - t);
    word_aside += now - t;
    /* mailbox 0x4: the main loop's busy cycles since the previous ToF frame */
    ms_report(0x40000000u | (busy_acc & 0x0FFFFFFFu));
    busy_acc = 0;
}

/* The earliest time-out of the open groups (at most: a group's t0 set later, or a group closed
 * since, leaves it early, and the scan it brings about recomputes it). */
static uint32_t tmo_at;
static int tmo_armed;

/* a group's t0 was set or lowered: its time-out may be the earliest */
APP_HOT static void timeout_note(const group_t *g)
{
    uint32_t at = g->t0 + cfgs[vs_index[g->vs]].max_tof + CLOSE_MARGIN;
    if (!tmo_armed || (int32_t)(at - tmo_at) < 0) {
        tmo_at = at;
        tmo_armed = 1;
    }
}

APP_HOT int timeout_due(uint32_t now) { return tmo_armed && (int32_t)(now - tmo_at) > 0; }

int timeout_next(uint32_t *at)
{
    *at = tmo_at;
    return tmo_armed;
}

APP_HOT static group_t *group_for(uint32_t vs, uint32_t seq, uint32_t t0, int init)
{
    group_t *free_g = 0, *oldest = 0;
    for (int i = 0; i < GROUP_SLOTS; i++) {
        group_t *g = &groups[vs * GROUP_SLOTS + i];
        if (g->used) {
            if (g->seq == seq) /* the sensor's own slots */
                return g;
            if (!oldest || (int32_t)(g->t0 - oldest->t0) < 0)
                oldest = g;
        } else if (!free_g) {
            free_g = g;
        }
    }
    if (!free_g) { /* no room: the sensor's oldest pulse goes out as it is */
        oldest->flags |= MS_FRAME_CUT;
        close_group(oldest);
        free_g = oldest;
    }
    /* first_tof / rec are read only where firsts / n_ev say they were written */
    free_g->n_ev = free_g->has_rec = free_g->n_win = free_g->n_term = 0;
    free_g->done = free_g->firsts = free_g->gated = 0;
    free_g->used = 1;
    free_g->vs = (uint8_t)vs;
    free_g->seq = (uint8_t)seq;
    free_g->t0 = t0;
    free_g->flags = init ? MS_FRAME_INIT_PING : 0u;
    timeout_note(free_g);
    return free_g;
}

APP_HOT static int group_complete(const group_t *g)
{
    const sensor_t *s = &sens[vs_index[g->vs]];
    if (g->has_rec)
        return g->n_term >= g->n_win;
    return (g->done & s->rx_mask) == s->rx_mask; /* no record (lost): every receiver reported */
}

/* The open pulses of sensor vs (vs < 0: of every sensor) go out, cut (MS_FRAME_CUT): their
 * windows ended at `tick` without reporting. A cancel record says so for one sensor (a
 * re-initialisation cancelled its pending windows); so does an init ping's record (a sensor
 * re-initialises only after its windows were cancelled or closed); an apply taken (the new
 * table's first record, reaim.c) or STOP drops them all. */
APP_HOT void cut_open(int vs, uint32_t tick)
{
    int from = vs < 0 ? 0 : vs * GROUP_SLOTS, to = vs < 0 ? MAX_GROUPS : from + GROUP_SLOTS;
    for (int i = from; i < to; i++) {
        group_t *o = &groups[i];
        if (o->used) {
            o->flags |= MS_FRAME_CUT;
            o->t_done = tick;
            close_group(o);
        }
    }
}

/* A pulse record: the pulse's group with the hardware's t0 and window count. */
APP_HOT static group_t *take_record(uint32_t lo, uint32_t hi, uint32_t now)
{
    uint32_t vs = MS_PULSE_SENSOR(lo, hi), init = MS_PULSE_INIT_PING(lo, hi);
    uint32_t id = MS_PULSE_ID(lo, hi);
    if (vs_index[vs] < 0)
        return 0;
    if (hi & MS_EVH_CANCEL) { /* a cancel record: its sensor field is the pulse record's */
        cut_open((int)vs, MS_CANCEL_TICK(lo, hi));
        return 0;
    }
    reaim_restart_seen(id, init, now); /* a taken apply: the old table's pulses go out */
    last_pulse_id[vs] = (uint16_t)id;
    if (init)
        cut_open((int)vs, now);
    group_t *g = group_for(vs, id & 0xFFu, lo, (int)init);
    g->has_rec = 1;
    g->t0 = MS_PULSE_T0(lo, hi);
    timeout_note(g);
    g->t_done = g->t_pop = now;
    g->n_win = (uint8_t)MS_PULSE_N_WIN(lo, hi);
    return group_complete(g) ? g : 0;
}

/* one event word; returns the completed group or 0 */
APP_HOT static group_t *take_event(uint32_t lo, uint32_t hi, uint32_t now)
{
    if (hi & MS_EVH_OVF) /* words were lost just before this one: every open pulse may miss some */
        for (int i = 0; i < MAX_GROUPS; i++)
            if (groups[i].used)
                groups[i].flags |= MS_FRAME_LOST;
    if (hi & MS_EVH_RECORD)
        return take_record(lo, hi, now);
    uint32_t tof = MS_EV_TOF(lo, hi), rx = MS_EV_RX(lo, hi);
    /* fl: the MS_TOF_* flags in_window, first_echo, window_empty, init_ping */
    uint32_t seq = MS_EV_SEQ(lo, hi), vs = MS_EV_SENSOR(lo, hi), fl = MS_EV_KIND(lo, hi);
    if (vs_index[vs] < 0)
        return 0;
    /* an event without its pulse's record: the record went in an overflow; t0 estimated from
     * the pop time (late by the polling delay), and the frame says so */
    uint32_t t0c = now - tof - ((fl & MS_TOF_WINDOW_EMPTY) ? 0u : edge_lat);
    group_t *g = group_for(vs, seq, t0c, (fl & MS_TOF_INIT_PING) != 0);
    if (!g->has_rec) {
        g->flags |= MS_FRAME_LOST;
        if ((int32_t)(t0c - g->t0) < 0) {
            g->t0 = t0c;
            timeout_note(g);
        }
    }
    g->t_pop = now;
    if (g->n_ev < MAX_EV) {
        g->rec[g->n_ev++] = tof | (rx << 24) | ((fl & 7u) << 29);
    } else {
        g->flags |= MS_FRAME_TRUNCATED;
    }
    const sensor_t *s = &sens[vs_index[vs]];
    const app_sensor_t *c = &cfgs[vs_index[vs]];
    if ((fl & (MS_TOF_IN_WINDOW | MS_TOF_FIRST_ECHO)) == (MS_TOF_IN_WINDOW | MS_TOF_FIRST_ECHO)) {
        /* the window's first echo; one the gate rejected is no geometry input */
        if (hi & MS_EVH_GATED)
            g->gated |= 1u << rx;
        else
            for (int k = 0; k < c->n_rx; k++)
                if (s->rx[k] == rx) {
                    g->first_tof[k] = (int32_t)tof;
                    g->firsts |= 1u << rx;
                }
        g->done |= 1u << rx;
        g->n_term++;
        g->t_done = g->t0 + tof + edge_lat;         /* the edge's detection tick */
    } else if (fl & MS_TOF_WINDOW_EMPTY) {
        g->done |= 1u << rx;
        g->n_term++;
        g->t_done = g->t0 + tof - 1u + edge_lat;    /* the window's close */
    }
    return group_complete(g) ? g : 0;
}

/* a complete group goes out. Earlier pulses of its sensor without a record (lost in an
 * overflow) cannot be completed by count: they go first */
APP_HOT static void finish(group_t *g)
{
    for (int i = 0; i < GROUP_SLOTS; i++) {
        group_t *o = &groups[g->vs * GROUP_SLOTS + i];
        if (o->used && !o->has_rec && o != g && (int8_t)(uint8_t)(g->seq - o->seq) > 0)
            close_group(o);
    }
    close_group(g);
}

/* Pops at most max_words words, until the FIFO is empty, or until a finished group leaves a
 * host command waiting: under load the FIFO may never empty, and draining it first would
 * starve the command port (found by the full-system twin: no reply for seconds while frames
 * kept streaming). The main loop serves the command and comes back; the words wait in the
 * hardware FIFO (overflows are counted). */
APP_HOT void poll_events(uint32_t max_words)
{
    for (; max_words > 0u; max_words--) {
        uint32_t t = now32(), f0 = word_aside;
        uint32_t lo = MS_SONAR(EVT_LO);
        uint32_t hi = MS_SONAR(EVT_HI);
        if (!(hi & SONAR_REGS__EVT_HI__VALID_bm))
            return;
        uint32_t now = now32(); /* after the pop: the word was written before it */
        group_t *g = take_event(lo, hi, now);
        if (g)
            finish(g);
        stat_max(MS_FW_STAT_CYCLES_WORD_MAX, now32() - t - (word_aside - f0));
        if (g && (MS_SOC(CMD_STATUS) & SOC_REGS__CMD_STATUS__AVAIL_bm))
            return;
    }
}

/* every window of a pulse has closed max_tof after its t0: a group still open then is cut;
 * the earliest time-out of those left is the next */
APP_HOT void scan_timeouts(uint32_t now)
{
    tmo_armed = 0;
    for (int i = 0; i < MAX_GROUPS; i++) {
        group_t *g = &groups[i];
        if (!g->used)
            continue;
        if ((int32_t)(now - g->t0) > (int32_t)(cfgs[vs_index[g->vs]].max_tof + CLOSE_MARGIN)) {
            g->flags |= MS_FRAME_CUT;
            close_group(g);
        } else {
            timeout_note(g);
        }
    }
}

void groups_clear(void)
{
    for (int i = 0; i < MAX_GROUPS; i++)
        groups[i].used = 0;
}
