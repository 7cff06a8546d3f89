// ms_twin.cpp: C harness of the full-system twin, loaded by host/multisonar/twin/sim.py (ctypes).
//
// Why C++: cocotb wakes Python per awaited edge (~80 k clocks/s); here the clock, the echo
// comparators and the USB packet layer run in C++ and Python is called only per pulse (to
// ask the acoustic model for its echoes) and per USB packet.
//
// Cycle convention (the same as the cocotb benches, tests/rtl/echo_driver.py): after the
// rising edge that starts cycle T, tick_o reads T. An echo pulse (rx, start, width) is high in
// cycles start .. start + width - 1, i.e. it is first sampled at the edge that ends cycle
// `start`. The scheduler's registered strobes (pulse_o, trig_valid_o) seen in cycle T belong
// to tick T; a trigger fires its element trig_delay_o ticks after T.
//
// A pulse is handed to Python ("fire") once all its elements have been armed: pulse_o gives
// t0, the sensor and its transmit mask; the elements' triggers follow one per clock in the
// order the pulses were decided. twin_run() returns as soon as a fire is ready (the decision
// is LEAD = 32768 ticks before t0, so Python adds the echoes before the first can start: at
// once, or from its echo thread when the clock reaches the fence, twin_set_fence).
#include <cstdint>
#include <cstdlib>
#include <algorithm>
#include <cstring>
#include <deque>
#include <memory>
#include <queue>
#include <string>
#include <type_traits>
#include <vector>

#include "Vms_twin_top.h"
#include "Vms_twin_top__Syms.h"
#include "verilated.h"
#include "verilated_syms.h"
#if VM_TRACE_FST
#include "verilated_fst_c.h"
#endif

// the model's settle pass (all combinational logic from the registers), run after a skip
void Vms_twin_top___024root___eval_settle(Vms_twin_top___024root* vlSelf);

namespace {

// Verilator's shadow of a register for its nonblocking assignment (`__Vdly__<name>`) is a member
// of the model where the rising edge's evaluation is split over functions. It is reloaded from
// the register at every rising edge, so a stale one changes nothing, but the skip sets it too:
// the twin's whole state after a skip then equals that of a run that simulated the clocks
// (tests/test_twin_skip.py). Each shadow is set only if this build of the model has it.
#define MS_TWIN_VDLY_SYNC(reg)                                                                    \
  template <class R>                                                                              \
  auto vdly_sync_##reg(R* r, int) -> decltype(r->__Vdly__##reg = r->reg, void()) {               \
    r->__Vdly__##reg = r->reg;                                                                    \
  }                                                                                               \
  template <class R>                                                                              \
  void vdly_sync_##reg(R*, long) {}
MS_TWIN_VDLY_SYNC(ms_twin_top__DOT__u_dev__DOT__u_sys__DOT__u_sonar__DOT__tick_q)
MS_TWIN_VDLY_SYNC(ms_twin_top__DOT__u_dev__DOT__u_sys__DOT__u_sonar__DOT__u_tx__DOT__now_nx_q)
MS_TWIN_VDLY_SYNC(ms_twin_top__DOT__u_dev__DOT__u_usb__DOT__u_xact__DOT__timer_q)
MS_TWIN_VDLY_SYNC(ms_twin_top__DOT__u_dev__DOT__u_sys__DOT__u_sonar__DOT__u_tx__DOT__phase_q)
MS_TWIN_VDLY_SYNC(ms_twin_top__DOT__u_dev__DOT__u_sys__DOT__u_sonar__DOT__u_tx__DOT__phase_nx_q)
#undef MS_TWIN_VDLY_SYNC

void vdly_sync(Vms_twin_top___024root* r) {
  vdly_sync_ms_twin_top__DOT__u_dev__DOT__u_sys__DOT__u_sonar__DOT__tick_q(r, 0);
  vdly_sync_ms_twin_top__DOT__u_dev__DOT__u_sys__DOT__u_sonar__DOT__u_tx__DOT__now_nx_q(r, 0);
  vdly_sync_ms_twin_top__DOT__u_dev__DOT__u_usb__DOT__u_xact__DOT__timer_q(r, 0);
  vdly_sync_ms_twin_top__DOT__u_dev__DOT__u_sys__DOT__u_sonar__DOT__u_tx__DOT__phase_q(r, 0);
  vdly_sync_ms_twin_top__DOT__u_dev__DOT__u_sys__DOT__u_sonar__DOT__u_tx__DOT__phase_nx_q(r, 0);
}

// The CPU's clock gate (rtl/soc/ms_soc.sv, MS_TWIN_CPU_GATE; mk/twin.mk defines it): the
// harness drives the CPU's clock, one rising edge per device clock, and holds it while the CPU
// is stalled in its WAIT read (kCpuQuiet clocks at least) and its inputs are those of its last
// edge: its state would not change (tests/test_twin_skip.py compares a run with the gate
// against one without). A model built without the gate compiles to nothing here.
#define MS_CPU(x) ms_twin_top__DOT__u_dev__DOT__u_sys__DOT__u_soc__DOT__g_vex__DOT__##x
#define MS_CPU_CLK_SEEN \
  __Vtrigprevexpr___TOP__ms_twin_top__DOT__u_dev__DOT__u_sys__DOT__u_soc__DOT__g_vex__DOT__twin_cpu_clk__0
template <class R, class = void>
struct CpuGate {
  static constexpr bool kPresent = false;
  static void edge(R*, bool) {}
  static void after(R*) {}
  struct Inputs {
    bool operator==(const Inputs&) const { return true; }
  };
  static Inputs inputs(const R*) { return {}; }
};
template <class R>
struct CpuGate<R, std::void_t<decltype(R::MS_CPU(twin_cpu_clk))>> {
  static constexpr bool kPresent = true;
  // before the evaluation of a device clock: a rising edge of the CPU's clock, or none
  static void edge(R* r, bool clocked) {
    r->MS_CPU(twin_cpu_clk) = clocked;
    r->MS_CPU_CLK_SEEN = 0;  // Verilator's record of the clock at the last evaluation
  }
  // after it: the clock and its record as a clocked evaluation leaves them (the state is then
  // the same as without the gate, byte for byte)
  static void after(R* r) {
    r->MS_CPU(twin_cpu_clk) = 1;
    r->MS_CPU_CLK_SEEN = 1;
  }
  // what the CPU samples at its next edge
  struct Inputs {
    uint32_t imiso = 0, dmiso = 0;
    uint8_t iack = 0, ierr = 0, dack = 0, derr = 0, reset = 0;
    bool operator==(const Inputs& o) const {
      return imiso == o.imiso && dmiso == o.dmiso && iack == o.iack && ierr == o.ierr &&
             dack == o.dack && derr == o.derr && reset == o.reset;
    }
  };
  static Inputs inputs(const R* r) {
    Inputs in;
    in.imiso = r->MS_CPU(u_cpu__DOT__iBusWishbone_DAT_MISO);
    in.dmiso = r->MS_CPU(u_cpu__DOT__dBusWishbone_DAT_MISO);
    in.iack = r->MS_CPU(u_cpu__DOT__iBusWishbone_ACK);
    in.ierr = r->MS_CPU(u_cpu__DOT__iBusWishbone_ERR);
    in.dack = r->MS_CPU(u_cpu__DOT__dBusWishbone_ACK);
    in.derr = r->MS_CPU(u_cpu__DOT__dBusWishbone_ERR);
    in.reset = r->MS_CPU(u_cpu__DOT__reset);
    return in;
  }
};
#undef MS_CPU
#undef MS_CPU_CLK_SEEN
using TwinCpuGate = CpuGate<Vms_twin_top___024root>;

// The receiver's and the transmitter's clock gates (mk/twin.mk defines both): the receive
// conditioners' one clock (rtl/ms_sonar_core.sv, MS_TWIN_RX_GATE), held while every conditioner has
// settled on its input (synchroniser, level, no rise, no run, its glitch length loaded) and
// neither an input nor twin_rx_key (the reset, the glitch length) changes; a clock per transmit
// element (rtl/tx/ms_tx_phaser.sv, MS_TWIN_TX_GATE), held while the element is idle (no pending
// trigger, no burst, its drive low) and no fire or reset reaches it (twin_wake). Their state
// would not change in those clocks (tests/test_twin_skip.py). The clocks stay high; the harness
// gives a rising edge by clearing Verilator's record of the clock at the last evaluation. A
// model built without the gates compiles to nothing here.
#define MS_SONAR(x) ms_twin_top__DOT__u_dev__DOT__u_sys__DOT__u_sonar__DOT__##x
#define MS_SONAR_SEEN(x) \
  __Vtrigprevexpr___TOP__ms_twin_top__DOT__u_dev__DOT__u_sys__DOT__u_sonar__DOT__##x##__0
#define MS_TX_BIND(i)                                                              \
  clk[i] = &r->MS_SONAR(u_tx__DOT__g_ch__BRA__##i##__KET____DOT__twin_ch_clk); \
  seen[i] = &r->MS_SONAR_SEEN(u_tx__DOT__g_ch__BRA__##i##__KET____DOT__twin_ch_clk);
// Gate<R>::bind: the clocks and Verilator's records of them; returns what wakes them
template <class R, class = void>
struct RxGate {
  static const void* bind(R*, uint8_t**, uint8_t**) { return nullptr; }
};
template <class R>
struct RxGate<R, std::void_t<decltype(R::MS_SONAR(twin_rx_clk))>> {
  static const void* bind(R* r, uint8_t** clk, uint8_t** seen) {
    clk[0] = &r->MS_SONAR(twin_rx_clk);
    seen[0] = &r->MS_SONAR_SEEN(twin_rx_clk);
    return &r->MS_SONAR(twin_rx_key);  // {reset, glitch length} (16 bits)
  }
};
template <class R, class = void>
struct TxGate {
  static const void* bind(R*, uint8_t**, uint8_t**) { return nullptr; }
};
template <class R>
struct TxGate<
    R, std::void_t<decltype(R::MS_SONAR(u_tx__DOT__g_ch__BRA__0__KET____DOT__twin_ch_clk))>> {
  static const void* bind(R* r, uint8_t** clk, uint8_t** seen) {
    MS_TX_BIND(0) MS_TX_BIND(1) MS_TX_BIND(2) MS_TX_BIND(3) MS_TX_BIND(4) MS_TX_BIND(5)
    MS_TX_BIND(6) MS_TX_BIND(7) MS_TX_BIND(8) MS_TX_BIND(9) MS_TX_BIND(10) MS_TX_BIND(11)
    MS_TX_BIND(12) MS_TX_BIND(13) MS_TX_BIND(14) MS_TX_BIND(15) MS_TX_BIND(16) MS_TX_BIND(17)
    MS_TX_BIND(18) MS_TX_BIND(19) MS_TX_BIND(20) MS_TX_BIND(21) MS_TX_BIND(22) MS_TX_BIND(23)
    return &r->MS_SONAR(u_tx__DOT__twin_wake);  // elements a fire or the reset reaches (32 bits)
  }
};
#undef MS_SONAR
#undef MS_SONAR_SEEN
#undef MS_TX_BIND
template <class R, class = void>
struct UsbGate {
  static const void* bind(R*, uint8_t**, uint8_t**, const uint8_t**) { return nullptr; }
};
template <class R>
struct UsbGate<R, std::void_t<decltype(R::ms_twin_top__DOT__u_dev__DOT__twin_usb_clk)>> {
  // returns the device's inputs from the system (16 bits); *moves: a byte moves between the
  // device and the host link
  static const void* bind(R* r, uint8_t** clk, uint8_t** seen, const uint8_t** moves) {
    clk[0] = &r->ms_twin_top__DOT__u_dev__DOT__twin_usb_clk;
    seen[0] = &r->__Vtrigprevexpr___TOP__ms_twin_top__DOT__u_dev__DOT__twin_usb_clk__0;
    *moves = &r->ms_twin_top__DOT__u_dev__DOT__twin_usb_moves;
    return &r->ms_twin_top__DOT__u_dev__DOT__twin_usb_in;
  }
};
// The sonar core's clock gate (rtl/ms_system.sv, MS_TWIN_SONAR_GATE): its clock, the replay of
// the SoC's outputs into it, and those outputs.
template <class T>
struct SonarPort {
  const T* live = nullptr;  // the SoC's output
  T* replay = nullptr;      // what the core sees instead while twin_replay is set
};
struct SonarRefs {
  uint8_t *clk = nullptr, *seen = nullptr, *replay = nullptr;
  SonarPort<uint8_t> rst, req, is_wr;
  SonarPort<uint16_t> addr;
  SonarPort<uint32_t> wdata, biten;
};
struct SonarIn {
  uint8_t rst = 0, req = 0, is_wr = 0;
  uint16_t addr = 0;
  uint32_t wdata = 0, biten = 0;
};
#define MS_SYS(x) ms_twin_top__DOT__u_dev__DOT__u_sys__DOT__##x
template <class R, class = void>
struct SonarGate {
  static void bind(R*, SonarRefs*) {}
};
template <class R>
struct SonarGate<R, std::void_t<decltype(R::MS_SYS(twin_sonar_clk))>> {
  static void bind(R* r, SonarRefs* g) {
    g->clk = &r->MS_SYS(twin_sonar_clk);
    g->seen =
        &r->__Vtrigprevexpr___TOP__ms_twin_top__DOT__u_dev__DOT__u_sys__DOT__twin_sonar_clk__0;
    g->replay = &r->MS_SYS(twin_replay);
    g->rst = {&r->MS_SYS(rst_sonar), &r->MS_SYS(twin_r_rst)};
    g->req = {&r->MS_SYS(req), &r->MS_SYS(twin_r_req)};
    g->is_wr = {&r->MS_SYS(req_is_wr), &r->MS_SYS(twin_r_is_wr)};
    g->addr = {&r->MS_SYS(addr), &r->MS_SYS(twin_r_addr)};
    g->wdata = {&r->MS_SYS(wr_data), &r->MS_SYS(twin_r_wdata)};
    g->biten = {&r->MS_SYS(wr_biten), &r->MS_SYS(twin_r_biten)};
  }
};
#undef MS_SYS
using TwinSonarGate = SonarGate<Vms_twin_top___024root>;
using TwinRxGate = RxGate<Vms_twin_top___024root>;
using TwinUsbGate = UsbGate<Vms_twin_top___024root>;
using TwinTxGate = TxGate<Vms_twin_top___024root>;

constexpr int kNumCh = 24;
// A bank of gated clocks (up to 24): which are held, and the rising edges of the others.
struct GatedClocks {
  int n = 0;           // the model has them (they must then be driven)
  bool on = true;      // hold clocks (off: every one has its edge in every clock)
  uint8_t* clk[kNumCh] = {};
  uint8_t* seen[kNumCh] = {};
  uint32_t held = 0;   // clocks held now
  uint64_t held_clocks = 0;  // clocks held (one per gated clock and device clock)
  uint32_t counted = 0, held_n = 0;  // (the count of `held`, recounted when it changes)
  // before a device clock's evaluation: wake the clocks in `wake`, a rising edge for the others;
  // returns those given it
  uint32_t edges(uint32_t wake) {
    held = on ? held & ~wake : 0;
    if (held != counted) {
      counted = held;
      held_n = static_cast<uint32_t>(__builtin_popcount(held));
    }
    held_clocks += held_n;
    const uint32_t clocked = ~held & ((1u << n) - 1);
    for (uint32_t m = clocked; m; m &= m - 1) {
      const int i = __builtin_ctz(m);
      *clk[i] = 1;
      *seen[i] = 0;
    }
    return clocked;
  }
  void level(uint8_t v) {  // (tracing: both edges evaluated, nothing held)
    for (int i = 0; i < n; ++i) *clk[i] = v;
  }
};

constexpr uint8_t kPidNak = 0x5A;  // the NAK handshake: PID 1010b and its complement

struct Fire {
  int64_t t0 = 0;
  int vs = 0;
  uint32_t mask = 0;
  int need = 0;
  int got = 0;
  int64_t decided = 0;
  int elements[kNumCh] = {};
  int64_t trigger[kNumCh] = {};
};

struct EchoEdge {
  int64_t tick;
  int rx;
  int delta;
  bool operator>(const EchoEdge& o) const { return tick > o.tick; }
};

// Activity profile (twin_profile): what each clock holds, counted per clock while enabled. A
// clock is "calm" for a unit when the unit's state changes in it only in counters that advance
// with time (the tick, the phaser's phase, the CPU's cycle timer): the engine spins in its poll
// loop, no burst runs, every receive conditioner has settled on its input, no USB packet is in
// flight, the CPU is stalled in a read of WAIT (the firmware's idle wait, ms_soc). Those are
// the clocks an exact skip could leave out (issue #30); the rest bound its gain.
enum Act { kActClocks, kActEngine, kActTxRun, kActRxSettle, kActUsb, kActCpu, kActSonar, kActAny,
           kActSimCpuOnly, kActSimSonarOnly, kActSimBoth, kActSimCalm, kActN };

// A register the profile reads in place (public_flat_rd in sim/twin/ms_twin.vlt).
struct Probe {
  const void* p = nullptr;
  int bytes = 0;
  uint32_t get() const {
    switch (bytes) {
      case 1: return *static_cast<const uint8_t*>(p);
      case 2: return *static_cast<const uint16_t*>(p);
      case 4: return *static_cast<const uint32_t*>(p);
      default: return 0;
    }
  }
  uint8_t u8() const { return *static_cast<const uint8_t*>(p); }  // (a register of 8 bits or fewer)
};

bool ends_with(const std::string& s, const char* tail) {
  const size_t n = std::strlen(tail);
  return s.size() >= n && s.compare(s.size() - n, n, tail) == 0;
}

Probe probe(const VerilatedScope* sc, const char* var) {
  Probe pr;
  const VerilatedVar* v = sc->varFind(var);
  if (!v) return pr;
  pr.p = v->datap();
  switch (v->vltype()) {
    case VLVT_UINT8: pr.bytes = 1; break;
    case VLVT_UINT16: pr.bytes = 2; break;
    case VLVT_UINT32: pr.bytes = 4; break;
    default: pr.p = nullptr;
  }
  return pr;
}

struct RxProbe { Probe meta, sync, level, rise, run, gm1; };
struct TxProbe { Probe trig, p_cyc, cyc, pend, due, tgt, phi, drive; };

// A variable the exact skip reads or writes in place (public_flat_rw in ms_twin.vlt): its data
// (an array's elements follow each other) and its size in bytes.
struct Ref {
  void* p = nullptr;
  size_t bytes = 0;
  uint32_t* w() const { return static_cast<uint32_t*>(p); }
  uint64_t get() const {
    switch (bytes) {
      case 1: return *static_cast<const uint8_t*>(p);
      case 2: return *static_cast<const uint16_t*>(p);
      case 4: return *static_cast<const uint32_t*>(p);
      case 8: return *static_cast<const uint64_t*>(p);
      default: return 0;
    }
  }
  void set(uint64_t v) const {
    switch (bytes) {
      case 1: *static_cast<uint8_t*>(p) = static_cast<uint8_t>(v); break;
      case 2: *static_cast<uint16_t*>(p) = static_cast<uint16_t>(v); break;
      case 4: *static_cast<uint32_t*>(p) = static_cast<uint32_t>(v); break;
      case 8: *static_cast<uint64_t*>(p) = v; break;
      default: break;
    }
  }
};

Ref ref(const VerilatedScope* sc, const char* var, size_t bytes) {
  Ref r;
  const VerilatedVar* v = sc->varFind(var);
  if (v && v->totalSize() == bytes) {
    r.p = v->datap();
    r.bytes = bytes;
  }
  return r;
}

// What the exact skip reads and advances (sim/twin/ms_twin.vlt; the inventory of the registers
// that run with time is in docs/twin.md, "Exact skip of calm clocks").
struct SkipRefs {
  Ref tick, tick_prev, rf, blk_c, blk_n, cur, nxt, vld, lo, hi, eq, now, now_nx, phase, phase_nx,
      hm1, cycles, wdt_cnt,
      readback, beat, err_cnt, drive_cnt, mbox_cnt, usb_phase, xact_timer, xact_state, tl_stage,
      wake_at, wdt_timeout, cpu_rst, q_empty;
  int count() const {
    int n = 0;
    for (const Ref* r : {&tick, &tick_prev, &rf, &blk_c, &blk_n, &cur, &nxt, &vld, &lo, &hi, &eq,
                         &now, &now_nx, &phase, &phase_nx, &hm1, &cycles, &wdt_cnt, &readback,
                         &beat, &err_cnt, &drive_cnt,
                         &mbox_cnt, &usb_phase, &xact_timer, &xact_state, &tl_stage, &wake_at,
                         &wdt_timeout, &cpu_rst, &q_empty})
      n += r->p != nullptr;
    return n;
  }
  static constexpr int kAll = 31;
};

struct Twin {
  std::unique_ptr<VerilatedContext> ctx;
  std::unique_ptr<Vms_twin_top> top;
#if VM_TRACE_FST
  std::unique_ptr<VerilatedFstC> fst;
#endif
  bool tracing = false;
  uint64_t cycles = 0;
  int64_t tick = 0;  // tick_o after the last rising edge
  std::deque<Fire> pending;
  std::deque<Fire> ready;
  int64_t ready_n = 0;  // ready.size(), where the host reads it in place (twin_field)
  std::priority_queue<EchoEdge, std::vector<EchoEdge>, std::greater<EchoEdge>> edges;
  int echo_count[kNumCh] = {};
  uint32_t echo_level = 0;
  uint64_t echoes_late = 0;      // pulses added after their start tick (clipped)
  uint64_t trig_orphans = 0;     // triggers without a pending pulse (should stay 0)
  uint64_t fires_incomplete = 0; // pulses whose triggers never all came (should stay 0)
  // The echo fence (twin_set_fence): no clock from tick `fence` on is simulated before
  // `at_fence` has been called (it adds the echoes computed meanwhile and sets the next fence).
  int64_t fence = INT64_MAX;
  void (*at_fence)(void) = nullptr;
  bool running = false;
  int64_t run_start = -1;        // tick before the scheduler's running_o rose (its start tick)
  int64_t first_start = -1;      // the same for the first rise
  uint64_t run_starts = 0;       // rises of running_o (START, re-aims restart the schedule)
  bool profiling = false;
  uint32_t poll_lo = 0, poll_hi = 0;  // the engine's poll loop, [lo, hi)
  std::vector<uint64_t> pc_clocks;    // per firmware word (from 0): clocks its instruction was last
  RxProbe rx_probe[kNumCh];
  TxProbe tx_probe[kNumCh];
  Probe eng_pc, cpu_pc, cpu_wait;
  Probe sonar_bridge;  // the SoC's bridge to the sonar core: 0 idle, else a request in progress
  uint64_t act[kActN] = {};
  bool usb_busy = false;
  // exact skip of calm clocks (twin_skip)
  bool skipping = false;
  bool skip_stop = false;           // twin_run returns right after each skip (on = 2)
  SkipRefs sk;
  uint32_t anchor = 0;              // the engine's poll-loop address a skip starts and ends at
  uint64_t eng_busy_at = 0;         // the last clock the engine was outside its poll loop
  uint64_t cpu_busy_at = 0;         // the last clock the CPU was not stalled in WAIT (skip, gate)
  bool cpu_gate = true;             // hold the CPU's clock where its state cannot change
  uint64_t cpu_held = 0;            // clocks the CPU's clock was held
  TwinCpuGate::Inputs cpu_in;       // the CPU's inputs at its last edge
  // the receiver's and the transmitter's clock gates, when the model has them
  GatedClocks rx_gate, tx_gate;
  const uint32_t* tx_wake = nullptr;  // elements a fire or the reset reaches in this cycle
  const uint16_t* rx_key = nullptr;   // {reset, glitch length}: a change wakes the conditioners
  uint16_t rx_key_last = 0xFFFF;      // its value in the last clock
  uint32_t rx_level = 0;              // the inputs the held conditioners have settled on
  // the USB device's clock gate: held while it is idle with unchanged inputs; its two counters
  // that run with time are brought up to date when it is clocked again (usb_catch_up)
  GatedClocks usb_gate;
  const uint16_t* usb_in = nullptr;   // its inputs from the system
  const uint8_t* usb_moves = nullptr; // a byte moves between it and the host link
  uint16_t usb_in_last = 0;           // the inputs at its last edge
  uint64_t usb_busy_at = 0;           // the last clock with a packet or a byte moving
  uint64_t usb_run = 0;               // clocks held since its last edge, not yet caught up
  // the sonar core's clock gate: held from the engine's anchor while the core is calm and the
  // CPU works (where the whole device is calm the skip leaves the clocks out instead)
  SonarRefs sg;
  bool sonar_gate = true;             // hold it where it can
  bool sonar_held = false;
  uint64_t sonar_from = 0;            // the clock count when it was held (its state is of then)
  uint64_t sonar_until = 0;           // clocked again from this clock count at the latest
  uint64_t sonar_turn = 0;            // the engine's poll-loop turn
  uint32_t sonar_tick0 = 0;           // its tick when held
  bool sonar_tx_pending = false;      // a transmit element's trigger was pending (the phase runs)
  static constexpr uint64_t kReplay = 6;
  static constexpr int kSonarInputs = 128;  // (more than kMinSkip + a turn + kReplay)
  SonarIn sonar_in[kSonarInputs];     // the SoC's outputs to it in the held clocks
  uint64_t sonar_held_clocks = 0, sonar_holds = 0;
  uint64_t sonar_bus_at = 0;          // the last clock the SoC's bridge to it was not idle
  uint64_t anchor_at[3] = {};       // the last three clocks at the anchor (newest first)
  uint64_t skips = 0, skipped = 0;
  uint32_t mailbox[4096];
  uint32_t mailbox_n = 0;
  uint64_t mailbox_total = 0;

  void dump() {
#if VM_TRACE_FST
    if (tracing) fst->dump(ctx->time());
#endif
  }

  // Up to `cycles` clocks; stops early when a fire is ready. Returns the clocks run.
  uint64_t run(uint64_t cycles) {
    uint64_t n = 0;
    while (n < cycles && ready.empty()) {
      step();
      ++n;
      if (skipping && n < cycles) {
        const uint64_t to_fence = fence > tick ? static_cast<uint64_t>(fence - tick) : 0;
        const uint64_t k = skip_check(std::min(cycles - n, to_fence));
        n += k;
        if (k && skip_stop) break;  // (checking a skip: the caller compares the state now)
      }
    }
    return n;
  }

  // A clock of a USB packet: the skip's check watches it too (no skip while a packet is under
  // way, but its record of the engine's anchor passes stays current, so a skip can follow the
  // packet at once, and the sonar core's clock can be held through it)
  void usb_step() {
    step();
    if (skipping) skip_check(0);
  }

  // One USB packet from the host into the packet layer (twin_usb_packet).
  int usb_packet(const uint8_t* tx, int len, int listen, uint8_t* rx, int cap, int* delay) {
    Vms_twin_top* const dut = top.get();
    usb_busy = true;
    dut->tl_rx_start_i = 1;
    usb_step();
    dut->tl_rx_start_i = 0;
    for (int i = 0; i < len; ++i) {
      dut->tl_rx_valid_i = 1;
      dut->tl_rx_byte_i = tx[i];
      usb_step();
    }
    dut->tl_rx_valid_i = 0;
    dut->tl_rx_end_i = 1;
    usb_step();
    dut->tl_rx_end_i = 0;
    int n = 0;
    *delay = -1;
    bool receiving = false;
    for (int waited = 0; waited <= listen || receiving; ++waited) {
      if (listen <= 0) break;
      usb_step();
      if (dut->tl_tx_valid_o) {
        if (!receiving) *delay = waited;
        receiving = true;
        if (n < cap) rx[n] = dut->tl_tx_byte_o;
        ++n;
      }
      if (receiving && dut->tl_tx_end_o) break;
      if (waited > listen + 4096) break;  // a device that never ends its packet
    }
    usb_busy = false;
    return n;
  }

  // The fence is reached: cleared, then the caller's callback adds what it waited for and sets
  // the next one (a callback that fails leaves it cleared; the caller reports its error).
  void reach_fence() {
    fence = INT64_MAX;
    if (at_fence) at_fence();
  }

  // One clock: inputs for cycle `tick` are already set; falling edge, rising edge, observe.
  void step() {
    if (__builtin_expect(tick >= fence, 0)) reach_fence();
    while (!edges.empty() && edges.top().tick <= tick) {
      const EchoEdge e = edges.top();
      edges.pop();
      echo_count[e.rx] += e.delta;
      if (echo_count[e.rx] > 0) echo_level |= 1u << e.rx;
      else echo_level &= ~(1u << e.rx);
    }
    top->echo_i = echo_level;
    Vms_twin_top___024root* const root = top->rootp;
    if (tracing) {  // both edges in the waveform (and the CPU's clock never held)
      top->clk_i = 0;
      TwinCpuGate::edge(root, false);
      tx_gate.level(0);
      rx_gate.level(0);
      usb_gate.level(0);
      if (sg.clk) *sg.clk = 0;
      top->eval();
      ctx->timeInc(10417);
      dump();
      top->clk_i = 1;
      TwinCpuGate::edge(root, true);
      tx_gate.level(1);
      rx_gate.level(1);
      usb_gate.level(1);
      if (sg.clk) *sg.clk = 1;
      top->eval();
      ctx->timeInc(10416);
      dump();
    } else {
      if (cpu_wait.p && cpu_wait.get() == 0) cpu_busy_at = cycles;  // (as skip_check records it)
      if (sonar_bridge.p && sonar_bridge.get() != 0) sonar_bus_at = cycles;
      // the sonar core's clock: held (sonar_hold) until the SoC addresses it or resets it, its
      // calm ends, or the CPU waits again (where the skip takes over); brought up to date first
      // (its catch-up evaluates the model)
      if (sonar_held) {
        const SonarIn in = sonar_inputs();
        if (in.req || in.rst || cycles >= sonar_until || !sonar_gate || cpu_waited()) {
          sonar_catch_up();
        } else {
          sonar_in[(cycles + 1 - sonar_from) % kSonarInputs] = in;
          ++sonar_held_clocks;
        }
      }
      // the CPU's clock: held while it waits with its inputs as at its last edge
      const TwinCpuGate::Inputs in = TwinCpuGate::inputs(root);
      const bool hold = TwinCpuGate::kPresent && cpu_gate && cpu_waited() && in == cpu_in;
      if (!hold) cpu_in = in;
      cpu_held += hold;
      TwinCpuGate::edge(root, !hold);
      // One evaluation per clock: the design has no logic on the falling edge or the clock's
      // level, so the falling edge's evaluation computes nothing the rising edge's does not
      // (the input logic runs again at the rising edge). Verilator finds a rising edge by the
      // clock's value at its last evaluation: that is set low instead.
      root->__Vtrigprevexpr___TOP__clk_i__0 = 0;
      // the receiver's clock stays held until an input or the key changes, a transmit element's
      // until a fire or the reset reaches it
      bool rx_clocked = false;
      if (rx_gate.n) {
        const uint16_t key = *rx_key;
        rx_clocked = rx_gate.edges(key != rx_key_last || echo_level != rx_level) != 0;
        rx_key_last = key;
      }
      const uint32_t tx_clocked = tx_gate.n ? tx_gate.edges(*tx_wake) : 0;
      // the USB device's clock: held while no packet is in flight, no byte moves and its inputs
      // are those of its last edge (kUsbQuiet clocks after the last activity)
      if (usb_gate.n) {
        const uint16_t in = *usb_in;
        const bool active = usb_busy || top->tl_bus_reset_i || *usb_moves || sk.xact_state.get() ||
                            sk.tl_stage.get();
        if (active) usb_busy_at = cycles;
        const bool hold = usb_gate.on && !active && usb_busy_at + kUsbQuiet <= cycles &&
                          in == usb_in_last;
        if (!hold) {
          usb_catch_up();
          usb_in_last = in;
        }
        usb_gate.held = hold;
        usb_gate.edges(0);
        usb_run += hold;
      }
      if (sg.clk && !sonar_held) {
        *sg.clk = 1;
        *sg.seen = 0;
      }
      top->clk_i = 1;
      top->eval();
      if (hold) TwinCpuGate::after(root);
      if (tx_gate.on)
        for (uint32_t m = tx_clocked; m; m &= m - 1) {
          const int i = __builtin_ctz(m);
          const TxProbe& t = tx_probe[i];
          if (!(t.pend.u8() | t.trig.u8() | t.cyc.u8() | t.drive.u8())) tx_gate.held |= 1u << i;
        }
      if (rx_gate.on && rx_clocked) {
        const uint8_t gm = static_cast<uint8_t>(rx_key_last), gm1 = gm - (gm != 0);
        uint32_t level = 0;
        bool settled = true;
        for (int i = 0; i < kNumCh && settled; ++i) {
          const RxProbe& r = rx_probe[i];
          const uint8_t meta = r.meta.u8();
          settled = meta == r.sync.u8() && meta == r.level.u8() && !r.rise.u8() && !r.run.u8() &&
                    r.gm1.u8() == gm1;
          level |= static_cast<uint32_t>(meta) << i;
        }
        if (settled) {
          rx_gate.held = 1;
          rx_level = level;
        }
      }
      ctx->timeInc(20833);
    }
    ++cycles;
    tick = sonar_held ? tick + 1 : static_cast<int64_t>(top->tick_o);  // (tick_o stands still)
    observe();
  }

  // The profiled registers by scope name (the conditioners', transmit channels', the engine's,
  // the CPU's PC and the SoC's WAIT state); the number found (24 + 24 + 3 when all are there).
  int bind_probes() {
    int found = 0;
    for (const auto& kv : *ctx->scopeNameMap()) {
      const std::string name = kv.first;
      const VerilatedScope* sc = kv.second;
      const size_t br = name.rfind('[');
      const int i = br == std::string::npos ? -1 : std::atoi(name.c_str() + br + 1);
      auto ends = [&](const char* tail) { return ends_with(name, tail); };
      if (ends(".u_rx") && i >= 0 && i < kNumCh) {
        rx_probe[i] = {probe(sc, "meta_q"), probe(sc, "sync_q"), probe(sc, "level_q"),
                       probe(sc, "rise_q"), probe(sc, "run_q"), probe(sc, "gm1_q")};
        found += rx_probe[i].meta.p && rx_probe[i].sync.p && rx_probe[i].level.p &&
                 rx_probe[i].rise.p;
      } else if (ends(".u_ch") && i >= 0 && i < kNumCh) {
        tx_probe[i] = {probe(sc, "trig_q"), probe(sc, "p_cyc_q"), probe(sc, "cyc_q"),
                       probe(sc, "pend_q"), probe(sc, "due_q"), probe(sc, "tgt_q"),
                       probe(sc, "phi_q"), probe(sc, "drive_q")};
        found += tx_probe[i].trig.p && tx_probe[i].p_cyc.p && tx_probe[i].cyc.p &&
                 tx_probe[i].pend.p && tx_probe[i].due.p && tx_probe[i].tgt.p &&
                 tx_probe[i].phi.p && tx_probe[i].drive.p;
      } else if (ends(".u_sched.u_eng")) {
        eng_pc = probe(sc, "pc_q");
        found += eng_pc.p != nullptr;
      } else if (ends(".g_vex.u_cpu")) {
        cpu_pc = probe(sc, "lastStagePc");
        found += cpu_pc.p != nullptr;
      } else if (ends(".u_soc")) {
        cpu_wait = probe(sc, "wait_q");
        found += cpu_wait.p != nullptr;
      } else if (ends(".u_soc.u_sonar_bridge")) {
        sonar_bridge = probe(sc, "state_q");  // (the sonar core's gate: not counted here)
      }
    }
    return found;
  }

  // The clock gates of the receiver, the transmitter, the USB device and the sonar core, when the
  // model has them (their clocks must then be driven); the receiver's or the transmitter's never
  // holds its clock unless the registers its test reads are 8-bit ones.
  void bind_gates() {
    bind_probes();
    Vms_twin_top___024root* const root = top->rootp;
    rx_key = static_cast<const uint16_t*>(TwinRxGate::bind(root, rx_gate.clk, rx_gate.seen));
    tx_wake = static_cast<const uint32_t*>(TwinTxGate::bind(root, tx_gate.clk, tx_gate.seen));
    rx_gate.n = rx_key ? 1 : 0;
    tx_gate.n = tx_wake ? kNumCh : 0;
    gate(rx_gate, true);
    gate(tx_gate, true);
    // the USB device's: its catch-up writes two of the skip's variables
    usb_in = static_cast<const uint16_t*>(
        TwinUsbGate::bind(root, usb_gate.clk, usb_gate.seen, &usb_moves));
    usb_gate.n = usb_in ? 1 : 0;
    bind_skip();
    gate(usb_gate, true);
    TwinSonarGate::bind(root, &sg);  // (held only by the skip's check: it needs the skip's refs)
  }
  // on or off; returns whether the model has the gate
  bool gate(GatedClocks& g, bool on) {
    bool ok = g.n != 0;
    for (int i = 0; i < kNumCh; ++i) {
      const RxProbe& r = rx_probe[i];
      const TxProbe& t = tx_probe[i];
      if (&g == &rx_gate)
        for (const Probe* x : {&r.meta, &r.sync, &r.level, &r.rise, &r.run, &r.gm1})
          ok &= x->bytes == 1;
      else if (&g == &tx_gate)
        for (const Probe* x : {&t.pend, &t.trig, &t.cyc, &t.drive}) ok &= x->bytes == 1;
    }
    if (&g == &usb_gate)
      for (const Ref* x : {&sk.usb_phase, &sk.xact_timer, &sk.xact_state, &sk.tl_stage})
        ok &= x->p != nullptr;
    g.on = on && ok;
    return g.n != 0;
  }

  // Receive conditioner i has settled on its input: synchroniser and level equal to it, no rise.
  bool rx_settled(int i) const {
    const RxProbe& r = rx_probe[i];
    const uint32_t meta = r.meta.get(), sync = r.sync.get();
    return meta == ((top->echo_i >> i) & 1u) && sync == meta && r.level.get() == sync &&
           r.rise.get() == 0;
  }

  // The skip's variables by scope name; the number found (SkipRefs::kAll when all are there).
  int bind_skip() {
    sk = SkipRefs();
    for (const auto& kv : *ctx->scopeNameMap()) {
      const std::string name = kv.first;
      const VerilatedScope* sc = kv.second;
      auto ends = [&](const char* tail) { return ends_with(name, tail); };
      if (ends(".u_sys.u_sonar")) {
        sk.tick = ref(sc, "tick_q", 4);
      } else if (ends(".u_sonar.u_sched")) {
        sk.tick_prev = ref(sc, "tick_prev_q", 4);
        sk.q_empty = ref(sc, "q_empty", 1);
      } else if (ends(".u_sched.u_eng")) {
        sk.rf = ref(sc, "rf_q", 32 * 4);
      } else if (ends(".u_sched.u_closes")) {
        sk.blk_c = ref(sc, "blk_c_q", 4);
        sk.blk_n = ref(sc, "blk_n_q", 4);
        sk.cur = ref(sc, "cur_q", 4);
        sk.nxt = ref(sc, "nxt_q", 4);
        sk.vld = ref(sc, "vld_q", 4);
        sk.lo = ref(sc, "lo_q", 16);      // 24 x 5 bits, packed
        sk.hi = ref(sc, "hi_m", 32 * 4);  // 32 x 21 bits
        sk.eq = ref(sc, "eq_q", 4);
      } else if (ends(".u_sonar.u_tx")) {
        sk.now = ref(sc, "now_q", 4);
        sk.now_nx = ref(sc, "now_nx_q", 4);
        sk.phase = ref(sc, "phase_q", 2);
        sk.phase_nx = ref(sc, "phase_nx_q", 2);
        sk.hm1 = ref(sc, "hm1_q", 2);
      } else if (ends(".u_sys.u_soc")) {
        sk.cycles = ref(sc, "cycles_q", 8);
        sk.wdt_cnt = ref(sc, "wdt_cnt_q", 4);
        sk.cpu_rst = ref(sc, "cpu_rst_q", 1);
      } else if (ends(".u_soc.u_regs")) {
        sk.readback = ref(sc, "readback_data_rt", 8 * 4);
      } else if (ends(".u_dev.u_sys")) {
        sk.beat = ref(sc, "beat_q", 4);
        sk.err_cnt = ref(sc, "bus_err_cnt_q", 2);
        sk.drive_cnt = ref(sc, "drive_cnt_q", 2);
        sk.mbox_cnt = ref(sc, "mbox_cnt_q", 2);
      } else if (ends(".u_usb.u_rx")) {
        sk.usb_phase = ref(sc, "phase_q", 1);
      } else if (ends(".u_usb.u_xact")) {
        sk.xact_timer = ref(sc, "timer_q", 1);
        sk.xact_state = ref(sc, "state_q", 1);
      } else if (ends(".u_usb.u_tx_tl")) {
        sk.tl_stage = ref(sc, "stage_q", 1);
      } else if (ends(".ms_twin_top")) {
        sk.wake_at = ref(sc, "wake_at", 4);
        sk.wdt_timeout = ref(sc, "wdt_timeout", 4);
      }
    }
    return sk.count();
  }

  // Clocks kept before the first thing that can happen (more than a poll-loop turn plus the
  // engine's 3-tick decision test; before a window close two blocks of the close detector, whose
  // scan then sees the head in the next block; before a transmit element's trigger or half
  // period's end two, the element compares the phaser's registered counts and nothing else
  // reads them ahead; before an echo edge two, the receivers see it at its tick, the rest of
  // the core later through them); clocks the CPU must have waited (its pipeline drained); the
  // shortest skip (the detector's block flags are set from the tick after 64).
  static constexpr int64_t kMargin = 24, kCloseMargin = 64, kTxMargin = 2, kEdgeMargin = 2,
                           kMinSkip = 96;
  // the shortest hold of the sonar core's clock (its catch-up simulates up to kMinSkip + a turn +
  // kReplay clocks) and the longest where nothing in the core limits it (it ends when the SoC
  // addresses it)
  static constexpr int64_t kMinHold = 128, kHoldMax = int64_t{1} << 40;
  static constexpr uint64_t kCpuQuiet = 16, kUsbQuiet = 16;

  // The CPU has waited in its WAIT read for kCpuQuiet clocks (cpu_busy_at brought up to date
  // for the current clock): the skip's and the CPU gate's test, and where a sonar hold ends.
  bool cpu_waited() const {
    return cpu_wait.p && cpu_wait.get() != 0 && cpu_busy_at + kCpuQuiet <= cycles;
  }

  // Registers written in place (the skip, the catch-ups): their nonblocking-assignment shadows
  // set too, then Verilator's settle pass recomputes the combinational logic from them.
  void settle() {
    vdly_sync(top->rootp);
    Vms_twin_top___024root___eval_settle(&top->rootp->vlSymsp->TOP);
  }

  // The USB device's two counters that run with time, N clocks on: its receive bit phase and its
  // transaction timer (the skip's advance and the USB gate's catch-up).
  void advance_usb(uint64_t N) {
    sk.usb_phase.set((sk.usb_phase.get() + N) & 3u);
    sk.xact_timer.set(std::min<uint64_t>(255, sk.xact_timer.get() + N));
  }

  // The USB device's state after the clocks its clock was held: they change only those counters
  void usb_catch_up() {
    if (!usb_run) return;
    advance_usb(usb_run);
    usb_run = 0;
    settle();
  }

  // Called after every clock while skipping is on: at the engine's anchor, when every unit is
  // calm, jump over whole turns of the poll loop (at most `budget` clocks) and return how many.
  uint64_t skip_check(uint64_t budget) {
    if (sonar_held) return 0;
    const uint32_t pc = eng_pc.get();
    if (pc < poll_lo || pc >= poll_hi) eng_busy_at = cycles;
    if (cpu_wait.get() == 0) cpu_busy_at = cycles;
    if (pc != anchor) return 0;
    anchor_at[2] = anchor_at[1];
    anchor_at[1] = anchor_at[0];
    anchor_at[0] = cycles;
    const uint64_t turn = anchor_at[0] - anchor_at[1];
    if (turn != anchor_at[1] - anchor_at[2] || turn < 8 || turn > 20) return 0;
    if (eng_busy_at >= anchor_at[2] || !pending.empty() || sk.eq.get() || !sk.q_empty.get())
      return 0;
    // the whole device calm: skip; the sonar core calm while the CPU runs: hold its clock
    const bool quiet = cpu_waited() && !usb_busy && !sk.cpu_rst.get() &&
                       !sk.xact_state.get() && !sk.tl_stage.get();
    // (a hold needs no request of the SoC's in progress: its answer would wait for the catch-up)
    const bool hold = !quiet && sonar_gate && sg.clk && !tracing && cpu_wait.get() == 0 &&
                      sonar_bridge.p && sonar_bus_at + kReplay <= cycles && !*sg.rst.live &&
                      !*sg.req.live;
    if (!quiet && !hold) return 0;
    // the first clock something can happen in, less a margin: a pending trigger, a burst's next
    // half period, an echo edge, the engine's armed decision (td), a window close; for a skip
    // also the CPU's wake-up, the watchdog and the caller's budget
    const int64_t T = tick;
    int64_t limit = T + (quiet ? static_cast<int64_t>(budget) : kHoldMax);
    bool tx_busy = false, tx_run = false;
    const uint32_t h = static_cast<uint32_t>(sk.hm1.get()) + 1;
    const uint32_t phase_nx = static_cast<uint32_t>(sk.phase_nx.get());
    for (int i = 0; i < kNumCh; ++i) {
      const TxProbe& t = tx_probe[i];
      if (t.due.get() || t.trig.get()) return 0;
      if (t.cyc.get() != 0) {  // a burst runs: its drive toggles when the phase comes round to phi
        const uint32_t phi = static_cast<uint32_t>(t.phi.get());
        const uint32_t since = (phase_nx + h - phi) % h, ahead = (phi + h - phase_nx) % h;
        if (since < 4 || phi >= h) return 0;  // (and the drive's registered copies settled)
        tx_busy = tx_run = true;
        limit = std::min(limit, T + static_cast<int64_t>(ahead) - kTxMargin);
      }
      if (t.pend.get()) {  // due in the clock after the one with T = tgt - 1 (mod 2^17)
        tx_busy = true;
        const uint32_t tgt = static_cast<uint32_t>(t.tgt.get());
        const uint32_t ahead = (tgt - 1u - static_cast<uint32_t>(T)) & 0x1FFFFu;
        limit = std::min(limit, T + static_cast<int64_t>(ahead) - kTxMargin);
      }
      if (!rx_settled(i)) return 0;
    }
    // all idle: the phaser's count must have been reset already (it is, one idle clock after
    // the last busy one)
    if (!tx_busy && (sk.phase.get() != 0 || sk.phase_nx.get() != (sk.hm1.get() != 0 ? 1u : 0u)))
      return 0;
    if (!edges.empty()) limit = std::min(limit, edges.top().tick - kEdgeMargin);
    const uint32_t* rf = sk.rf.w();
    const bool armed = rf[6] != 0;
    if (armed)
      limit = std::min(limit, T + static_cast<int32_t>(rf[5] - static_cast<uint32_t>(T)) - kMargin);
    const uint32_t vld = static_cast<uint32_t>(sk.vld.get());
    const uint32_t* lo = sk.lo.w();
    const uint32_t* hi = sk.hi.w();
    for (int e = 0; e < kNumCh; ++e) {
      if (!((vld >> e) & 1u)) continue;
      const int b = 5 * e;
      uint32_t l = lo[b / 32] >> (b % 32);
      if (b % 32 > 27) l |= lo[b / 32 + 1] << (32 - b % 32);
      const uint32_t close = (hi[e] << 5 | (l & 31u)) & 0x3FFFFFFu;
      const uint32_t ahead = (close - static_cast<uint32_t>(T)) & 0x3FFFFFFu;
      if (ahead >= (1u << 25)) return 0;
      limit = std::min(limit, T + static_cast<int64_t>(ahead) - kCloseMargin);
    }
    if (hold) {
      // (a running burst's or a pending trigger's phase counter is advanced as in a skip; the
      // elements stay clocked and compare it frozen, short of their next edge within the limit)
      if (limit - T >= kMinHold)
        sonar_hold(cycles + static_cast<uint64_t>(limit - T), turn, tx_busy);
      return 0;
    }
    const uint32_t cyc_lo = static_cast<uint32_t>(sk.cycles.get());
    limit = std::min(limit, T + static_cast<int32_t>(sk.wake_at.get() - cyc_lo) - kMargin);
    const uint32_t wdt_to = static_cast<uint32_t>(sk.wdt_timeout.get());
    if (wdt_to)
      limit = std::min(limit, T + static_cast<int64_t>(wdt_to) -
                                  static_cast<int64_t>(sk.wdt_cnt.get()) - kMargin);
    const int64_t n = (limit - T) / static_cast<int64_t>(turn) * static_cast<int64_t>(turn);
    if (n < kMinSkip) return 0;
    advance(static_cast<uint32_t>(n), armed, cyc_lo, tx_busy, tx_run);
    anchor_at[0] += n;
    anchor_at[1] += n;
    anchor_at[2] += n;
    eng_busy_at += n;  // still before the oldest anchor, as checked above
    cpu_busy_at += n;
    ++skips;
    skipped += n;
    return static_cast<uint64_t>(n);
  }

  // The state of N calm clocks later: the counters that run with time and what follows the
  // tick (the close detector's block flags, the engine's loaded tick), then the combinational
  // logic recomputed from it.
  void advance(uint32_t N, bool armed, uint32_t cyc_lo, bool tx_busy, bool tx_run) {
    advance_sonar(N, static_cast<uint32_t>(tick), armed, tx_busy);
    sk.cycles.set(sk.cycles.get() + N);
    sk.wdt_cnt.set(sk.wdt_cnt.get() + N);
    uint32_t* rb = sk.readback.w();
    if (rb[0] == cyc_lo - 1u) rb[0] += N;  // the retimed read-back slot tracking TIMER_LO
    sk.beat.set((sk.beat.get() + N) & 0x7FFFFu);
    for (const Ref* c : {&sk.err_cnt, &sk.drive_cnt, &sk.mbox_cnt}) {
      if (c == &sk.drive_cnt && top->drive_o != 0) continue;  // reloaded while a drive is high
      c->set(c->get() > N ? c->get() - N : 0);
    }
    advance_usb(N);
    if (profiling) {  // calm clocks but for a running burst; the CPU's PC stays at its WAIT read
      act[kActClocks] += N;
      if (tx_run) {
        act[kActTxRun] += N;
        act[kActSonar] += N;
        act[kActAny] += N;
      }
      const uint32_t w = cpu_pc.get() >> 2;
      if (w < pc_clocks.size()) pc_clocks[w] += N;
    }
    settle();
    ctx->timeInc(static_cast<uint64_t>(N) * 20833);
    cycles += N;
    tick += N;
  }

  // The sonar core's part of it, from its tick t0: the tick and what follows it (the phaser's
  // counters, the engine's loaded tick, the close detector's block flags).
  void advance_sonar(uint32_t N, uint32_t t0, bool armed, bool tx_busy) {
    const uint32_t t1 = t0 + N;
    sk.tick.set(sk.tick.get() + N);
    sk.tick_prev.set(sk.tick_prev.get() + N);
    sk.now.set((sk.now.get() + N) & 0x1FFFFu);
    sk.now_nx.set((sk.now_nx.get() + N) & 0x1FFFFu);
    if (tx_busy) {  // the half-period phase counts modulo H while a trigger waits or a burst runs
      const uint64_t h = sk.hm1.get() + 1;
      const uint64_t nx = sk.phase_nx.get();
      sk.phase_nx.set((nx + N) % h);
      sk.phase.set((nx + N - 1) % h);
    }
    uint32_t* rf = sk.rf.w();
    rf[10] += N;
    if (armed) rf[13] += N;
    auto blk = [](uint32_t x) { return (x & 0x3FFFFFFu) >> 5; };
    const uint32_t b1 = blk(t1);
    sk.blk_c.set(blk(t1 + 1));
    sk.blk_n.set((blk(t1 + 1) + 1) & 0x1FFFFFu);
    const uint32_t* hi = sk.hi.w();
    uint32_t cur = 0, nxt = 0;
    for (int e = 0; e < kNumCh; ++e) {
      cur |= static_cast<uint32_t>(hi[e] == b1) << e;
      const uint32_t want = (b1 + (static_cast<uint32_t>(e) < (t1 & 31u) ? 1u : 0u)) & 0x1FFFFFu;
      nxt |= static_cast<uint32_t>(hi[e] == want) << e;
    }
    sk.cur.set(cur);
    sk.nxt.set(nxt);
  }

  // Hold the sonar core's clock from now (the engine at its anchor, the core calm) until `until`
  // device clocks at the latest.
  void sonar_hold(uint64_t until, uint64_t turn, bool tx_pending) {
    sonar_held = true;
    sonar_from = cycles;
    sonar_until = until;
    sonar_turn = turn;
    sonar_tx_pending = tx_pending;
    sonar_tick0 = static_cast<uint32_t>(tick);
    ++sonar_holds;
  }

  // Bring the held sonar core up to date and clock it again from the next device clock: the
  // held clocks' whole turns of the engine's poll loop by the skip's advance (kMinSkip clocks at
  // least, as a skip), the rest simulated (kReplay clocks at least), the core alone, with the
  // SoC's outputs of those clocks.
  // Its register block latches the bus lines in every clock and reads through them up to four
  // registers deep (address, table word, table read, read-back), whatever the request.
  void sonar_catch_up() {
    if (!sonar_held) return;
    sonar_held = false;
    const uint64_t h = cycles - sonar_from;
    // the engine stayed in its poll loop: it passed its anchor every turn since the hold began
    // (the skip's record of the last three passes, as if it had watched them)
    anchor_at[0] = sonar_from + h / sonar_turn * sonar_turn;
    anchor_at[1] = anchor_at[0] - sonar_turn;
    anchor_at[2] = anchor_at[1] - sonar_turn;
    uint64_t whole = h >= sonar_turn + kReplay ? (h - kReplay) / sonar_turn * sonar_turn : 0;
    if (whole < static_cast<uint64_t>(kMinSkip)) whole = 0;  // (the skip's shortest advance)
    Vms_twin_top___024root* const root = top->rootp;
    if (whole) {
      advance_sonar(static_cast<uint32_t>(whole), sonar_tick0, sk.rf.w()[6] != 0, sonar_tx_pending);
      settle();
    }
    for (uint64_t j = whole + 1; j <= h; ++j) {
      sonar_replay(true, sonar_in[j % kSonarInputs]);
      root->__Vtrigprevexpr___TOP__clk_i__0 = 1;  // no device clock edge, no CPU edge
      TwinCpuGate::edge(root, false);
      *sg.clk = 1;
      *sg.seen = 0;
      top->eval();
      TwinCpuGate::after(root);
    }
    if (h > whole) {  // the replay's registers as an ungated run leaves them (zero), settled
      sonar_replay(false, SonarIn());
      Vms_twin_top___024root___eval_settle(&root->vlSymsp->TOP);
    }
  }

  // The SoC's outputs to the sonar core now, and the replay of some (on) or none
  SonarIn sonar_inputs() const {
    return {*sg.rst.live, *sg.req.live, *sg.is_wr.live, *sg.addr.live, *sg.wdata.live,
            *sg.biten.live};
  }
  void sonar_replay(bool on, const SonarIn& in) {
    *sg.replay = on;
    *sg.rst.replay = in.rst;
    *sg.req.replay = in.req;
    *sg.is_wr.replay = in.is_wr;
    *sg.addr.replay = in.addr;
    *sg.wdata.replay = in.wdata;
    *sg.biten.replay = in.biten;
  }

  void profile() {
    const uint32_t pc = eng_pc.get();
    const bool eng = pc < poll_lo || pc >= poll_hi;
    bool tx = false, rx = false;
    for (int i = 0; i < kNumCh; ++i) {
      const TxProbe& t = tx_probe[i];
      tx |= t.trig.get() ? t.p_cyc.get() != 0 : t.cyc.get() != 0;  // ms_tx_channel's run
      rx |= !rx_settled(i);
    }
    const uint32_t w = cpu_pc.get() >> 2;
    const bool cpu = cpu_wait.get() == 0;
    if (w < pc_clocks.size()) ++pc_clocks[w];
    const bool sonar = eng || tx || rx || usb_busy;
    ++act[kActClocks];
    act[kActEngine] += eng;
    act[kActTxRun] += tx;
    act[kActRxSettle] += rx;
    act[kActUsb] += usb_busy;
    act[kActCpu] += cpu;
    act[kActSonar] += sonar;
    act[kActAny] += sonar || cpu;
    // the clocks simulated (not skipped) by who works in them
    act[kActSimCpuOnly] += cpu && !sonar;
    act[kActSimSonarOnly] += sonar && !cpu;
    act[kActSimBoth] += cpu && sonar;
    act[kActSimCalm] += !cpu && !sonar;
  }

  void observe() {
    if (profiling) profile();
    if (top->running_o && !running) {
      run_start = tick - 1;
      if (first_start < 0) first_start = run_start;
      ++run_starts;
    }
    running = top->running_o;
    if (top->pulse_o) {
      Fire f;
      f.t0 = static_cast<int64_t>(top->pulse_t0_o);
      f.vs = top->pulse_vs_o;
      f.mask = top->pulse_tx_mask_o & 0xFFFFFFu;
      f.need = __builtin_popcount(f.mask);
      f.decided = tick;
      if (f.need == 0) ready.push_back(f);
      else pending.push_back(f);
    }
    if (top->trig_valid_o) {
      const int el = top->trig_el_o;
      const int64_t at = tick + static_cast<int64_t>(top->trig_delay_o);
      bool placed = false;
      for (Fire& f : pending) {
        if ((f.mask >> el) & 1u) {
          bool dup = false;
          for (int k = 0; k < f.got; ++k) dup |= f.elements[k] == el;
          if (dup) continue;
          f.elements[f.got] = el;
          f.trigger[f.got] = at;
          ++f.got;
          placed = true;
          break;
        }
      }
      if (!placed) ++trig_orphans;
      while (!pending.empty() && pending.front().got == pending.front().need) {
        ready.push_back(pending.front());
        pending.pop_front();
      }
    }
    // a pulse whose triggers stop coming (a schedule stop between decision and arming) is
    // handed over with the elements it has, and counted
    while (!pending.empty() && tick - pending.front().decided > 1024) {
      ++fires_incomplete;
      ready.push_back(pending.front());
      pending.pop_front();
    }
    ready_n = static_cast<int64_t>(ready.size());
    if (top->sim_out_strobe_o) {
      if (mailbox_n < 4096) mailbox[mailbox_n++] = top->sim_out_o;
      ++mailbox_total;
    }
  }
};

}  // namespace

extern "C" {

void* twin_new(const char* fst_path) {
  auto* t = new Twin;
  t->ctx = std::make_unique<VerilatedContext>();
  t->ctx->timeunit(-12);
  t->ctx->timeprecision(-12);
  if (fst_path && fst_path[0]) {
#if VM_TRACE_FST
    t->ctx->traceEverOn(true);
#endif
  }
  t->top = std::make_unique<Vms_twin_top>(t->ctx.get(), "TOP");
  t->bind_gates();
#if VM_TRACE_FST
  if (fst_path && fst_path[0]) {
    t->fst = std::make_unique<VerilatedFstC>();
    t->top->trace(t->fst.get(), 99);
    t->fst->open(fst_path);
    t->tracing = true;
  }
#endif
  return t;
}

int twin_has_fst(void) {
#if VM_TRACE_FST
  return 1;
#else
  return 0;
#endif
}

void twin_free(void* p) {
  auto* t = static_cast<Twin*>(p);
  // final() goes through Verilator's per-thread current context, which is the context made
  // last; with two twins alive, freeing the newer first left it dangling (the older one's
  // free then hung on its freed mutex)
  Verilated::threadContextp(t->ctx.get());
#if VM_TRACE_FST
  if (t->tracing) t->fst->close();
#endif
  t->top->final();
  delete t;
}

// Hold reset for `cycles` clocks, then release it (inputs idle).
void twin_reset(void* p, int cycles) {
  auto* t = static_cast<Twin*>(p);
  t->sonar_catch_up();
  Vms_twin_top* top = t->top.get();
  top->rst_i = 1;
  top->tl_bus_reset_i = 0;
  top->tl_rx_start_i = 0;
  top->tl_rx_valid_i = 0;
  top->tl_rx_byte_i = 0;
  top->tl_rx_end_i = 0;
  for (int i = 0; i < cycles; ++i) t->step();
  top->rst_i = 0;
  t->pending.clear();
  t->ready.clear();
  t->ready_n = 0;
}

// The address of a harness variable the host reads in place between calls, without a call
// per read: 0 the tick (int64), 1 the clock count (uint64), 2 the fires ready (int64), 3 the
// mailbox words waiting (uint32).
void* twin_field(void* p, int which) {
  auto* t = static_cast<Twin*>(p);
  switch (which) {
    case 0: return &t->tick;
    case 1: return &t->cycles;
    case 2: return &t->ready_n;
    case 3: return &t->mailbox_n;
    default: return nullptr;
  }
}

int twin_trap(void* p) { return static_cast<Twin*>(p)->top->trap_o; }
int twin_configured(void* p) { return static_cast<Twin*>(p)->top->configured_o; }
int twin_led(void* p) { return static_cast<Twin*>(p)->top->led_o; }

// Counters: 0 echoes_late, 1 trig_orphans, 2 fires_incomplete, 3 mailbox words seen,
// 4 the scheduler's last start tick (running_o rise - 1; -1: never), 5 running_o rises,
// 6 its first start tick, 7 skips of calm clocks, 8 clocks skipped, 9 clocks the CPU's clock was
// held, 10 clocks the receive conditioners' clock was held, 11 transmit element clocks held (one
// per element and clock), 12 clocks the USB device's clock was held, 13 clocks the sonar core's
// clock was held, 14 its holds.
uint64_t twin_counter(void* p, int which) {
  auto* t = static_cast<Twin*>(p);
  switch (which) {
    case 0: return t->echoes_late;
    case 1: return t->trig_orphans;
    case 2: return t->fires_incomplete;
    case 3: return t->mailbox_total;
    case 4: return static_cast<uint64_t>(t->run_start);
    case 5: return t->run_starts;
    case 6: return static_cast<uint64_t>(t->first_start);
    case 7: return t->skips;
    case 8: return t->skipped;
    case 9: return t->cpu_held;
    case 10: return t->rx_gate.held_clocks;
    case 11: return t->tx_gate.held_clocks;
    case 12: return t->usb_gate.held_clocks;
    case 13: return t->sonar_held_clocks;
    case 14: return t->sonar_holds;
    default: return 0;
  }
}

// The CPU's clock gate on or off (on by default); returns whether the model has it.
int twin_cpu_gate(void* p, int on) {
  auto* t = static_cast<Twin*>(p);
  t->cpu_gate = on != 0;
  if (!t->cpu_wait.p) t->bind_probes();
  return TwinCpuGate::kPresent ? 1 : 0;
}

// The receiver's (bank 0), the transmitter's (1), the USB device's (2) or the sonar core's (3)
// clock gates on or off (on by default; off: clocked in every clock). Returns whether the model
// has them. The sonar core's is held only while the skip is on (twin_skip).
int twin_clock_gate(void* p, int bank, int on) {
  auto* t = static_cast<Twin*>(p);
  if (bank == 3) {
    t->sonar_gate = on != 0;
    if (!on) t->sonar_catch_up();
    return t->sg.clk ? 1 : 0;
  }
  return t->gate(bank == 0 ? t->rx_gate : bank == 1 ? t->tx_gate : t->usb_gate, on != 0) ? 1 : 0;
}

// The activity profile: on (the engine's poll loop is ROM [poll_lo, poll_hi); the PC histogram
// covers `words` firmware words from address 0) or off (on = 0). Counters and PC clocks start
// at 0. Returns the number of registers found for it (51: 24 conditioners, 24 transmit
// channels, the engine's PC, the CPU's, the SoC's WAIT state); it stays off unless all are.
int twin_profile(void* p, int on, uint32_t poll_lo, uint32_t poll_hi, int words) {
  auto* t = static_cast<Twin*>(p);
  t->sonar_catch_up();
  const int found = t->bind_probes();
  t->profiling = on != 0 && found == 2 * kNumCh + 3;
  t->poll_lo = poll_lo;
  t->poll_hi = poll_hi;
  t->pc_clocks.assign(words > 0 ? words : 0, 0);
  std::memset(t->act, 0, sizeof(t->act));
  return found;
}

// Copy out the activity counters (enum Act order, up to n) and, with pc_clocks, the clocks per
// firmware word (as many as the profile's words).
int twin_activity(void* p, uint64_t* out, int n, uint64_t* pc_clocks) {
  auto* t = static_cast<Twin*>(p);
  const int k = n < kActN ? n : kActN;
  std::memcpy(out, t->act, sizeof(uint64_t) * k);
  if (pc_clocks && !t->pc_clocks.empty())
    std::memcpy(pc_clocks, t->pc_clocks.data(), sizeof(uint64_t) * t->pc_clocks.size());
  return k;
}

// The model's whole state, every module instance Verilator holds in its symbol table (signals,
// memories, its scheduler's flags), copied out as bytes (up to cap) for comparing two runs
// clock for clock; returns its size. Pointers to the model's own objects differ between two
// twins: compare against a snapshot of both taken where they must agree (multisonar.twin.sim).
int64_t twin_state(void* p, uint8_t* out, int64_t cap) {
  auto* t = static_cast<Twin*>(p);
  t->usb_catch_up();  // (its clock stays held)
  t->sonar_catch_up();
  const int64_t n = static_cast<int64_t>(sizeof(Vms_twin_top__Syms));
  const void* syms = t->top->rootp->vlSymsp;  // (the bytes, its vtable pointers too)
  if (out) std::memcpy(out, syms, static_cast<size_t>(std::min(n, cap)));
  return n;
}

// Copy out (and clear) the firmware's mailbox words (sim_out_o strobes), up to cap.
int twin_mailbox(void* p, uint32_t* out, int cap) {
  auto* t = static_cast<Twin*>(p);
  int n = static_cast<int>(t->mailbox_n) < cap ? static_cast<int>(t->mailbox_n) : cap;
  std::memcpy(out, t->mailbox, sizeof(uint32_t) * n);
  t->mailbox_n = 0;
  return n;
}

// Run up to `cycles` clocks; stop early when a fire is ready. Returns the clocks run.
uint64_t twin_run(void* p, uint64_t cycles) { return static_cast<Twin*>(p)->run(cycles); }

// The exact skip of calm clocks (docs/twin.md): on (the engine's poll loop is ROM [poll_lo,
// poll_hi), a skip starts and ends with the engine at `anchor`; on = 2: twin_run also returns
// after each skip, for checking it) or off. Returns the variables found for it plus the
// profile's registers, and in *want how many there are (SkipRefs::kAll + 51); it stays off
// unless all are found.
int twin_skip(void* p, int on, uint32_t poll_lo, uint32_t poll_hi, uint32_t anchor, int* want) {
  auto* t = static_cast<Twin*>(p);
  t->sonar_catch_up();
  const int found = t->bind_skip() + t->bind_probes();
  *want = SkipRefs::kAll + 2 * kNumCh + 3;
  t->skipping = on != 0 && found == *want;
  t->skip_stop = on == 2;
  t->poll_lo = poll_lo;
  t->poll_hi = poll_hi;
  t->anchor = anchor;
  t->eng_busy_at = t->cpu_busy_at = t->cycles;
  std::memset(t->anchor_at, 0, sizeof(t->anchor_at));
  return found;
}

// Pop the oldest ready fire: returns its element count (-1 if none); t0, sensor, elements and
// their absolute trigger ticks.
int twin_pop_fire(void* p, int64_t* t0, int* vs, int* elements, int64_t* trigger) {
  auto* t = static_cast<Twin*>(p);
  if (t->ready.empty()) return -1;
  const Fire f = t->ready.front();
  t->ready.pop_front();
  t->ready_n = static_cast<int64_t>(t->ready.size());
  *t0 = f.t0;
  *vs = f.vs;
  for (int k = 0; k < f.got; ++k) {
    elements[k] = f.elements[k];
    trigger[k] = f.trigger[k];
  }
  return f.got;
}

// Comparator pulses: rows of (rx, start tick, width ticks), n rows. A pulse whose start is
// already past is clipped to the next cycle and counted in echoes_late.
void twin_add_echoes(void* p, const int64_t* rows, int n) {
  auto* t = static_cast<Twin*>(p);
  for (int i = 0; i < n; ++i) {
    const int rx = static_cast<int>(rows[3 * i]);
    int64_t start = rows[3 * i + 1];
    const int64_t end = rows[3 * i + 1] + rows[3 * i + 2];
    if (rx < 0 || rx >= kNumCh || end <= start) continue;
    if (start <= t->tick) {
      ++t->echoes_late;
      start = t->tick + 1;
      if (end <= start) continue;
    }
    t->edges.push({start, rx, +1});
    t->edges.push({end, rx, -1});
    // a held sonar core is clocked again before the edge reaches its receivers
    if (t->sonar_held) {
      const int64_t ahead = start - Twin::kEdgeMargin - t->tick;
      if (ahead <= 0) t->sonar_catch_up();
      else t->sonar_until = std::min(t->sonar_until, t->cycles + static_cast<uint64_t>(ahead));
    }
  }
}

// The echo fence: before the clock of tick `fence` (or a skip past it) `callback` is called,
// from inside whichever call runs the clocks; it may add echoes and set the next fence.
// INT64_MAX: none. (The host computes echoes on another thread meanwhile; docs/twin.md.)
void twin_set_fence(void* p, int64_t fence, void (*callback)(void)) {
  auto* t = static_cast<Twin*>(p);
  t->fence = fence;
  t->at_fence = callback;
}

// Hold the USB bus in reset for `cycles` clocks (transaction level: tl_bus_reset_i).
void twin_bus_reset(void* p, int cycles) {
  auto* t = static_cast<Twin*>(p);
  t->top->tl_bus_reset_i = 1;
  for (int i = 0; i < cycles; ++i) t->step();
  t->top->tl_bus_reset_i = 0;
  for (int i = 0; i < 16; ++i) t->step();
}

// One USB packet from the host (PID first, CRC included) into the device's packet layer, one
// byte per clock; then, with listen > 0, wait up to `listen` clocks for the device's packet.
// Returns the answer's length (0: no answer), its bytes in rx (up to cap) and the clocks from
// the end of the host packet to the answer's first byte in *delay.
int twin_usb_packet(void* p, const uint8_t* tx, int len, int listen, uint8_t* rx, int cap,
                    int* delay) {
  return static_cast<Twin*>(p)->usb_packet(tx, len, listen, rx, cap, delay);
}

// The host's bulk-IN polling while the endpoint NAKs, as multisonar.twin.usbhost's
// TwinUsbFunction.bulk_in does it, without a return to Python per NAK: the IN token (`token`,
// `len` bytes) and `listen` clocks for the answer; a NAK's transaction lasts its bus time from
// the token on (`nak_bus` clocks plus the answer's delay in whole bits), then the bus idles
// `poll` clocks before the next token. Ends at the first answer that is not a NAK (returns its
// length, bytes in rx, delay in *delay, out[0] = the clock count before its token: the caller
// finishes that transaction), or returns -1 where Python takes over, exactly where its own loop
// would have run Python code: a fire is ready (after a packet or within a wait: serve it), a wait
// starts where Python adds noise (the tick passed `noise_at`), or `max_clocks` have passed
// since the call (at a token). out[1], out[2]: the settle and poll clocks left to run, in that
// order; out[3]: NAKs; out[4]: their bus clocks.
int twin_usb_in_poll(void* p, const uint8_t* token, int len, int listen, uint8_t* rx, int cap,
                     int* delay, uint64_t nak_bus, uint64_t poll, uint64_t noise_at,
                     uint64_t max_clocks, uint64_t* out) {
  auto* t = static_cast<Twin*>(p);
  const uint64_t start = t->cycles;
  out[3] = out[4] = 0;
  auto hand_over = [&](uint64_t settle, uint64_t idle) {
    out[1] = settle;
    out[2] = idle;
    return -1;
  };
  // one wait of `clocks`; false: Python takes over with `left` clocks of it still to run
  auto wait = [&](uint64_t clocks, uint64_t& left) {
    left = clocks;
    if (clocks == 0) return true;
    if (static_cast<uint64_t>(t->tick) >= noise_at) return false;
    left -= t->run(clocks);
    return left == 0;
  };
  for (;;) {
    if (t->cycles - start >= max_clocks) return hand_over(0, 0);
    out[0] = t->cycles;
    const int n = t->usb_packet(token, len, listen, rx, cap, delay);
    if (n != 1 || rx[0] != kPidNak) return n;
    const uint64_t owed = nak_bus + 4u * static_cast<uint64_t>(std::max(*delay, 0) / 4);
    const uint64_t spent = t->cycles - out[0];
    const uint64_t settle = owed > spent ? owed - spent : 0;
    ++out[3];
    out[4] += owed;
    if (!t->ready.empty()) return hand_over(settle, poll);
    uint64_t left;
    if (static_cast<uint64_t>(t->tick) + settle < noise_at) {
      // no noise due at either wait's start: one call, so the skip runs through the boundary
      const uint64_t both = settle + poll, done = t->run(both);
      if (done < both)
        return done < settle ? hand_over(settle - done, poll) : hand_over(0, both - done);
      continue;
    }
    if (!wait(settle, left)) return hand_over(left, poll);
    if (!wait(poll, left)) return hand_over(0, left);
  }
}

}  // extern "C"
