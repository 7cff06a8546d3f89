/* The running table's sensors: read from the VS registers at START (so a table written with
 * WRITE_REGS works as well as the compiled-in default), each with its groups moved by its
 * re-aim shift and its prepared geometry (ms_prepare). */
#include "app.h"
#include "ms_isqrt.h"

app_sensor_t cfgs[8];
sensor_t sens[8];
int n_sens;
int vs_index[8];

/* speed of sound 331.3 m/s * sqrt(1 + T / 273.15 degC), in um/s */
uint32_t sound_um_s(int32_t t_cc)
{
    const uint64_t a = 331300000ull * 331300000ull;
    int64_t c2 = (int64_t)a + (int64_t)(a / 27315u) * t_cc + ((int64_t)(a % 27315u) * t_cc) / 27315;
    return (uint32_t)ms_isqrt64((uint64_t)c2);
}

uint32_t mask_of(const uint8_t *el, int n)
{
    uint32_t m = 0;
    for (int i = 0; i < n; i++)
        m |= 1u << el[i];
    return m;
}

/* the temperature -> um of path per tick, Q32 */
void update_path_k(void)
{
    path_k = ((uint64_t)sound_um_s(temperature_cc) << 32) / MS_TICK_HZ;
}

/* RX_FILTER and the temperature -> the edge latency and um per tick */
void apply_rx_filter(void)
{
    uint32_t gm = MS_SONAR(RX_FILTER) & SONAR_REGS__RX_FILTER__GLITCH_MIN_bm;
    edge_lat = 1u + (gm > 1u ? gm : 1u);
    update_path_k();
}

/* the groups of sensor c moved by shift elements, and the axis (its middle transmit
 * element's; two middles: halfway between them) */
void sensor_place(sensor_t *s, const app_sensor_t *c, int shift)
{
    s->shift = shift;
    for (int k = 0; k < c->n_tx; k++)
        s->tx[k] = (uint8_t)((c->tx[k] + shift) % APP_RING_N);
    for (int k = 0; k < c->n_rx; k++)
        s->rx[k] = (uint8_t)((c->rx[k] + shift) % APP_RING_N);
    s->tx_mask = mask_of(s->tx, c->n_tx);
    s->rx_mask = mask_of(s->rx, c->n_rx);
    uint32_t a = app_elem_axis[s->tx[(c->n_tx - 1) / 2]];
    if (!(c->n_tx & 1))
        a += (uint32_t)((int32_t)(app_elem_axis[s->tx[c->n_tx / 2]] - a) / 2);
    s->axis = a;
}

/* the prepared geometry of a placed sensor (~80 k cycles; reaim.c runs it as a slice of its own) */
void sensor_prepare(const sensor_t *s, const app_sensor_t *c, ms_array *arr)
{
    ms_vec2 rx[APP_MAX_GROUP], src;
    ms_opts opts;
    ms_class_opts copts;
    for (int k = 0; k < c->n_rx; k++) {
        rx[k].x = ms_elem_x_um[s->rx[k]];
        rx[k].y = ms_elem_y_um[s->rx[k]];
    }
    src.x = c->src_um[s->shift][0];
    src.y = c->src_um[s->shift][1];
    ms_opts_default(&opts);
    ms_class_opts_default(&copts);
    ms_prepare(arr, rx, c->n_rx, src, &opts, &copts, (ms_len_t)((sound_um_s(2000) + 500000u) / 1000000u));
}

void sensor_setup(int i, int shift)
{
    sensor_t *s = &sens[i];
    sensor_place(s, &cfgs[i], shift);
    ms_wdt_kick();
    sensor_prepare(s, &cfgs[i], &s->arr);
    s->init_misses = 0;
}

/* elements of mask in ring order starting after a gap (a run wrapping round element 0 stays
 * one run), at most APP_MAX_GROUP */
static int ring_elems(uint32_t mask, uint8_t *el)
{
    int start = 0, n = 0;
    for (int e = 0; e < APP_RING_N; e++)
        if ((mask >> e & 1u) && !(mask >> ((e + APP_RING_N - 1) % APP_RING_N) & 1u)) {
            start = e;
            break;
        }
    for (int k = 0; k < APP_RING_N && n < APP_MAX_GROUP; k++) {
        int e = (start + k) % APP_RING_N;
        if (mask >> e & 1u)
            el[n++] = (uint8_t)e;
    }
    return n;
}

/* the compiled-in sensor whose groups, moved by some k elements, are this one's: its virtual
 * source (phased groups) and path offset apply; returns k or -1 */
static int compiled_match(const app_sensor_t *c, const app_sensor_t **m)
{
    for (int i = 0; i < APP_NUM_SENSORS; i++) {
        const app_sensor_t *a = &app_sensors[i];
        if (a->n_tx != c->n_tx || a->n_rx != c->n_rx)
            continue;
        for (int k = 0; k < APP_RING_N; k++) {
            uint32_t tm = 0, rm = 0;
            for (int j = 0; j < a->n_tx; j++)
                tm |= 1u << ((a->tx[j] + k) % APP_RING_N);
            for (int j = 0; j < a->n_rx; j++)
                rm |= 1u << ((a->rx[j] + k) % APP_RING_N);
            if (tm == mask_of(c->tx, c->n_tx) && rm == mask_of(c->rx, c->n_rx)) {
                int same = 1;
                for (int j = 0; j < a->n_tx; j++)
                    same &= a->delay[j] == c->delay[j];
                if (same) {
                    *m = a;
                    return k;
                }
            }
        }
    }
    return -1;
}

/* every enabled VS entry -> cfgs[] / sens[] (geometry prepared); returns the sensor count */
int load_sensors(void)
{
    n_sens = 0;
    for (int i = 0; i < 8; i++)
        vs_index[i] = -1;
    for (int vs = 0; vs < 8; vs++) {
        if (!(MS_SONAR(VS[vs].MODE) & SONAR_REGS__VS__MODE__MODE_bm))
            continue;
        app_sensor_t *c = &cfgs[n_sens];
        uint8_t rx[APP_MAX_GROUP];
        c->vs = (uint8_t)vs;
        c->n_tx = (uint8_t)ring_elems(MS_SONAR(VS[vs].TX_MASK), c->tx);
        uint32_t rm = MS_SONAR(VS[vs].RX_MASK);
        int n = 0;
        for (int e = 0; e < APP_RING_N && n < APP_MAX_GROUP; e++)
            if (rm >> e & 1u)
                rx[n++] = (uint8_t)e;
        c->n_rx = (uint8_t)n;
        for (int k = 0; k < n; k++)
            c->rx[k] = rx[k];
        for (int k = 0; k < c->n_tx; k++)
            c->delay[k] = (uint16_t)DELAY_ENTRY(vs, c->tx[k]);
        c->max_tof = (MS_SONAR(VS[vs].MAX_TOF) & SONAR_REGS__VS__MAX_TOF__TICKS_bm)
                   + ((MS_SONAR(VS[vs].WINDOW) & SONAR_REGS__VS__WINDOW__T_N_bm) >> SONAR_REGS__VS__WINDOW__T_N_bp);
        const app_sensor_t *m = 0;
        int k0 = c->n_tx > 1 ? compiled_match(c, &m) : -1;
        c->path_offset_um = k0 >= 0 ? m->path_offset_um : 0;
        for (int k = 0; k < APP_RING_N; k++) {
            if (k0 >= 0) { /* the compiled sensor's virtual source, moved with the groups */
                c->src_um[k][0] = m->src_um[(k0 + k) % APP_RING_N][0];
                c->src_um[k][1] = m->src_um[(k0 + k) % APP_RING_N][1];
            } else { /* one element: its own position; else the middle one (approximation) */
                int e = (c->tx[(c->n_tx - 1) / 2] + k) % APP_RING_N;
                c->src_um[k][0] = ms_elem_x_um[e];
                c->src_um[k][1] = ms_elem_y_um[e];
            }
        }
        vs_index[vs] = n_sens;
        sens[n_sens].last_side = 0;
        sens[n_sens].last_dev = 0;
        n_sens++;
    }
    for (int i = 0; i < n_sens; i++)
        sensor_setup(i, 0);
    return n_sens;
}
