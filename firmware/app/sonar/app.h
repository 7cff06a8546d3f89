/* sonar_app: the Multisonar firmware, split by job (firmware/README.md, "sonar_app").
 *
 *   main.c          boot, the main loop (one bounded slice per pass), time-outs, cycle stats
 *   pulses.c        the ToF path: event words and pulse / cancel records -> pulse groups,
 *                   exact completion, ToF frames (never waits for geometry)
 *   geo.c           the geometry path: jobs queued by pulses.c, ms_fix_fast, geometry frames
 *   sensors.c       the running table from the registers, each sensor's prepared geometry
 *   reaim.c         re-aiming in bounded slices (prepare, hold, load, hand-over in the event stream)
 *   table.c         the table's check and load on the CSRs (sched_table.c), the scheduler's start
 *   cmd.c           the command transport: a transfer -> section 4 checks -> handler -> reply
 *   cmd_handlers.c  one handler per opcode, registered in cmd_handlers[]
 *
 * Shared state is declared here and defined in the file of the job that owns it. */
#ifndef SONAR_APP_H
#define SONAR_APP_H

#include <stdint.h>

#include "ms_hw.h"
#include "ms_geom.h"
#include "ms_layout.h"
#include "ms_protocol.h"
#include "sonar_app_cfg.h"

#if MS_GEOM_ARITH != MS_ARITH_Q
#error "sonar_app is built with the Q geometry variant (integer interface)"
#endif

/* ---------------------------------------------------------------- tunables */
/* pulses of one sensor being collected at once: the order's N in flight, the next one whose
 * record is popped before the oldest one's last terminal event, and one popped late (the
 * twin's maximum-load run has N + 1 open per sensor at order 4). Each sensor has its own
 * slots, so one sensor's backlog never cuts another's pulses. */
#define GROUP_SLOTS (APP_MAX_ORDER + 2)
#define MAX_GROUPS (APP_NUM_VS * GROUP_SLOTS)
#define MAX_EV 16            /* ToF records per frame kept (protocol allows 64) */
#define REAIM_DEG 10         /* 2/3 of the 15 deg element pitch: after a one-element move the */
                             /* reflector is ~5 deg off the new axis, so it stays (no ping-pong) */
#define LOST_PINGS 3         /* init pings in a row without a fix = track lost */
#define REAIM_HOLDOFF 4800000u /* 100 ms between moves: each restarts every sensor's track */
#define CLOSE_MARGIN 48000u  /* 1 ms after the last window can close */
#define CMD_WORDS 272u       /* ms_link_cmd_rx keeps 1088 bytes of a transfer */
#define START_WAIT 200000u   /* cycles for the scheduler to stop or to start */
#ifndef APP_BUILD_ID
#define APP_BUILD_ID 0u
#endif
#define WDT_CYCLES 48000000u /* 1 s: far above any bounded slice */
#define APPLY_WAIT 2000000u  /* cycles for a re-aim's hold, or its restart to be seen */
#define ID_WRAP_MARGIN 256u  /* no re-aim while a pulse id is this close to its 16-bit wrap */
#define IDLE_TICKS 48000u    /* the longest idle wait, 1 ms: watchdog kicks, the busy window */
#define GEO_JOBS 8           /* closed pulses waiting for their fix */

#define SONAR_BASE (MS_IO_UNCACHED | (uintptr_t)offsetof(ms_soc_map_t, sonar))
#define SONAR_AT(off) (*(volatile uint32_t *)(SONAR_BASE + (off)))
#define VS_REG(vs, reg) MS_REG(sonar.VS[vs].reg)
#define SONAR_OFF(reg) ((uint32_t)offsetof(sonar_regs_t, reg))
#define VS_STRIDE ((uint32_t)sizeof(sonar_regs__VS__stride40_t))
#define DELAY_ENTRY(vs, el) \
    (*(volatile uint32_t *)(SONAR_BASE + offsetof(sonar_regs_t, DELAY) + 4u * ((vs) * 32u + (el))))
#define ST_FIELD(st, f) (((st) & SONAR_REGS__STATUS__##f##_bm) >> SONAR_REGS__STATUS__##f##_bp)

static inline uint32_t now32(void) { return MS_SOC(TIMER_LO); }

/* Per-pulse code shares the output section of the geometry fast path (ms_geom_q_fast.c MS_HOT)
 * and the link sorts sections by name (mk/firmware_app.mk), so the loop, the ToF path and the fix
 * are one contiguous run of ~16 KB: in VexRiscv's direct-mapped 16 KiB instruction cache they do
 * not evict each other (firmware/README.md, "Cycles per path"). */
#define APP_HOT __attribute__((section(".text.ms_hot")))

/* ---------------------------------------------------------------- types */
typedef struct {
    uint8_t used, vs, seq, flags; /* flags: frame header flags (MS_FRAME_*) */
    uint8_t n_ev;
    uint8_t has_rec;   /* the pulse record was seen: t0 and n_win are the hardware's */
    uint8_t n_win;     /* windows the pulse opened (pulse record) */
    uint8_t n_term;    /* their terminal events so far (first echo or window_empty) */
    uint32_t done;     /* receivers with their first-echo / window_empty event (element bits) */
    uint32_t firsts;   /* receivers with a first echo the geometry may use */
    uint32_t gated;    /* receivers whose first echo the gated miss rule rejected (no geometry) */
    uint32_t t0;       /* trigger tick: the pulse record's; without one (lost), an estimate */
    uint32_t t_done;   /* detection tick of the last terminal event so far */
    uint32_t t_pop;    /* timer at the last word taken for it */
    int32_t first_tof[APP_MAX_GROUP]; /* per receiver index of the sensor */
    uint32_t rec[MAX_EV]; /* ToF records: tof (24 bits) | rx << 24 | event flags 2:0 << 29 (in
                           * window, first echo, window empty; the init flag is the pulse's) */
} group_t;

typedef struct {
    int shift;               /* elements the groups are moved from the table's */
    uint32_t tx_mask, rx_mask;
    uint8_t tx[APP_MAX_GROUP], rx[APP_MAX_GROUP];
    uint32_t axis;           /* binary angle */
    ms_array arr;
    int8_t last_side;        /* sign of the last fix's offset from the axis (0: none yet) */
    int32_t last_dev;        /* the last fix's offset from the axis, binary angle */
    uint8_t init_misses;     /* init pings in a row without a fix */
} sensor_t;

/* FW_STATS, indexed by MS_FW_STAT_* (ms_protocol.h, generated from protocol.FW_STATS_FIELDS),
 * cleared by CLEAR_COUNTERS: geometry jobs by outcome, ToF frames cut / lost, ToF latency; then
 * the worst cycles of each bounded path (the firmware's cycle table) */
extern uint32_t fw_stats[MS_FW_STAT_COUNT];
static inline void stat_max(int i, uint32_t v)
{
    if (v > fw_stats[i])
        fw_stats[i] = v;
}

/* ---------------------------------------------------------------- state */
extern group_t groups[MAX_GROUPS];
extern app_sensor_t cfgs[8];   /* the running table's sensors (from the registers at START) */
extern sensor_t sens[8];
extern int n_sens;
extern int vs_index[8];        /* table index -> sensors[] index, -1 */
extern uint32_t frame_seq, reaims, running, bad_commands, wdt_base, busy_acc;
extern int32_t temperature_cc;
extern uint8_t par_geometry, par_tof, par_max_echoes;
extern uint64_t path_k;        /* um per tick, Q32 (~7.15 * 2^32) */
extern uint32_t edge_lat;      /* L = 1 + max(glitch_min, 1) */
extern uint16_t last_pulse_id[8]; /* per table entry, from its latest pulse record */
extern uint32_t word_aside;    /* pulses.c: cycles inside a word's handling that are not its own */

/* ---------------------------------------------------------------- jobs */
/* pulses.c */
void poll_events(uint32_t max_words);     /* pops up to max_words words (ALL_WORDS) */
#define ALL_WORDS 0xFFFFFFFFu
void cut_open(int vs, uint32_t tick);     /* open pulses of vs (< 0: all) go out, cut */
void scan_timeouts(uint32_t now);
int timeout_due(uint32_t now);            /* an open group's time-out has passed (maybe) */
int timeout_next(uint32_t *at);           /* the earliest time-out of the open groups, if any */
void groups_clear(void);
void send_packet(uint32_t flags, uint32_t t0, uint32_t vs, uint32_t seq, uint32_t n_tof,
                 const uint32_t *tof, uint32_t gated, uint32_t n_geo, const uint32_t *geo);
/* geo.c */
void geo_enqueue(const group_t *g);       /* a complete pulse's fix, or its no-fix outcome */
int geo_step(void);                       /* one job, if any; returns 1 when one ran */
int geo_pending(void);                    /* jobs wait in the queue */
void geo_clear(void);
/* sensors.c */
int load_sensors(void);
void sensor_setup(int i, int shift);
void sensor_place(sensor_t *s, const app_sensor_t *c, int shift);
void sensor_prepare(const sensor_t *s, const app_sensor_t *c, ms_array *arr);
uint32_t sound_um_s(int32_t t_cc);
uint32_t mask_of(const uint8_t *el, int n);
void apply_rx_filter(void);
void update_path_k(void);
/* reaim.c */
void sensor_outcome(int si, int init, int fixed); /* a pulse's verdict: may request a re-aim */
int reaim_step(int idle);               /* the pending re-aim's next slice; 1 when one ran */
int reaim_restart_seen(uint32_t id, uint32_t init, uint32_t now);
void reaim_cancel(void);
int reaim_idle(void);                   /* no re-aim under way (nothing for reaim_step) */
const sensor_t *placement_of(int si, int shift); /* the sensor's groups at shift, if known */
/* table.c */
uint32_t table_check(void);            /* 0 accepted, else CfgError | entry << 8 (and in STATUS) */
void table_load_start(void);           /* the scheduler stopped: load the table, start it */
void table_write_delay(uint32_t vs, uint32_t el, uint32_t v);
void table_note_delay(uint32_t i, uint32_t v); /* DELAY word i written with v (over-wide?) */
/* cmd.c */
void handle_command(void);
void stop_run(void);

#endif
