"""The verilated device (sim/twin/ms_twin.cpp through ctypes) with the acoustic model in the loop.

:class:`TwinSim` owns one simulation of ``ms_system_usb``: the VexRiscv SoC running
firmware/app/sonar, the sonar core (scheduler, phased transmitters, 24 gated receivers),
the host link and the USB device core. Time runs in C++; Python is called per pulse and per
USB packet:

* per pulse: the scheduler decides a pulse LEAD ticks before its t0; once its elements are
  armed, the harness hands (t0, elements, trigger ticks) to the echo source (the golden
  model's acoustics, :class:`multisonar.fastfiring.SceneEchoSource`), whose comparator pulses
  (rx, start tick, width) go back to C++ before the first of them can start;
* per USB packet: :meth:`usb_packet` puts one packet (PID .. CRC) into the device's packet
  layer and returns its answer (:mod:`multisonar.twin.usbhost` builds transactions on it).
"""

from __future__ import annotations

import ctypes
import fcntl
import os
import subprocess
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ..constants import TICK_HZ

_I64P = ctypes.POINTER(ctypes.c_int64)
_INTP = ctypes.POINTER(ctypes.c_int)
_U8P = ctypes.POINTER(ctypes.c_uint8)
_U64P = ctypes.POINTER(ctypes.c_uint64)

NUM_CH = 24
_FENCE_CB = ctypes.CFUNCTYPE(None)
_NO_FENCE = 2**63 - 1
#: clocks before a pulse's earliest start at which the harness waits for the echo thread: more
#: than the margin the skip keeps before an echo edge (kMargin, 24, in ms_twin.cpp), so an echo
#: is never added inside it
FENCE_LEAD = 32
_switch = {"users": 0, "saved": 0.0}
_switch_lock = threading.Lock()
#: counters of the harness (twin_counter): pulses added after their start (clipped), triggers
#: the harness could not attribute to a pulse, pulses whose triggers did not all come, mailbox
#: words, rises of the scheduler's running_o (START; a re-aim restarts the schedule)
COUNTERS = ("echoes_late", "trig_orphans", "fires_incomplete", "mailbox_words", "schedule_starts")
_COUNTER_INDEX = {"echoes_late": 0, "trig_orphans": 1, "fires_incomplete": 2, "mailbox_words": 3,
                  "schedule_starts": 5}


class TwinError(RuntimeError):
    """The twin cannot be built, loaded or run (the message says what to do)."""


def state_differences(a: bytes, b: bytes, a0: bytes, b0: bytes) -> list[int]:
    """Byte offsets (of 8-byte words) where two twins' states ``a`` and ``b`` differ, leaving
    out the words in which their snapshots ``a0`` and ``b0`` (taken where both held the same
    design state, e.g. just booted) already differed: pointers to each model's own objects."""
    wa, wb = (np.frombuffer(x[: len(x) // 8 * 8], np.uint64) for x in (a, b))
    wa0, wb0 = (np.frombuffer(x[: len(x) // 8 * 8], np.uint64) for x in (a0, b0))
    return [8 * int(i) for i in np.flatnonzero((wa != wb) & (wa0 == wb0))]


def repo_root() -> Path | None:
    """The repository this package runs from (an editable install), or None."""
    p = Path(__file__).resolve()
    for parent in p.parents:
        if (parent / "Makefile").exists() and (parent / "sim" / "twin" / "ms_twin.cpp").exists():
            return parent
    return None


def library_path(fst: bool = False) -> Path:
    root = repo_root()
    if root is None:
        raise TwinError("the twin needs the Multisonar repository (sim/twin, rtl/): run from a clone "
                        "with `pip install -e host`")
    return root / "build" / "twin" / ("fst" if fst else "fast") / "libmstwin.so"


_BUILT: set[bool] = set()


def build(fst: bool = False, *, quiet: bool = False) -> Path:
    """`make twin` (or twin-fst) in the repository: verilates the device when a source changed
    (once per process). Processes build one at a time (a lock file beside the libraries): two
    makes of the same files at once (pytest workers) broke each other's firmware image."""
    root = repo_root()
    lib = library_path(fst)
    assert root is not None
    if fst in _BUILT and lib.exists():
        return lib
    cmd = ["make", "-s", "--no-print-directory", "-C", str(root), "twin-fst" if fst else "twin"]
    lock = lib.parents[1] / "build.lock"
    lock.parent.mkdir(parents=True, exist_ok=True)
    with open(lock, "w") as held:
        fcntl.flock(held, fcntl.LOCK_EX)  # released when the file closes
        r = subprocess.run(cmd, capture_output=quiet, text=True)
    if r.returncode != 0:
        tail = (r.stdout or "")[-2000:] + (r.stderr or "")[-2000:] if quiet else ""
        raise TwinError(f"building the twin failed ({' '.join(cmd)}){': ' + tail if tail else ''}")
    if not lib.exists():
        raise TwinError(f"{lib} missing after {' '.join(cmd)}")
    _BUILT.add(fst)
    return lib


def _load(path: Path) -> ctypes.CDLL:
    lib = ctypes.CDLL(str(path))
    vp = ctypes.c_void_p
    sig: dict[str, tuple[Any, list[Any]]] = {
        "twin_new": (vp, [ctypes.c_char_p]),
        "twin_free": (None, [vp]),
        "twin_has_fst": (ctypes.c_int, []),
        "twin_reset": (None, [vp, ctypes.c_int]),
        "twin_field": (vp, [vp, ctypes.c_int]),
        "twin_trap": (ctypes.c_int, [vp]),
        "twin_configured": (ctypes.c_int, [vp]),
        "twin_led": (ctypes.c_int, [vp]),
        "twin_counter": (ctypes.c_uint64, [vp, ctypes.c_int]),
        "twin_mailbox": (ctypes.c_int, [vp, ctypes.POINTER(ctypes.c_uint32), ctypes.c_int]),
        "twin_run": (ctypes.c_uint64, [vp, ctypes.c_uint64]),
        "twin_pop_fire": (ctypes.c_int, [vp, _I64P, _INTP, _INTP, _I64P]),
        "twin_add_echoes": (None, [vp, _I64P, ctypes.c_int]),
        "twin_set_fence": (None, [vp, ctypes.c_int64, _FENCE_CB]),
        "twin_bus_reset": (None, [vp, ctypes.c_int]),
        "twin_usb_packet": (ctypes.c_int, [vp, _U8P, ctypes.c_int, ctypes.c_int, _U8P, ctypes.c_int, _INTP]),
        "twin_usb_in_poll": (ctypes.c_int, [vp, _U8P, ctypes.c_int, ctypes.c_int, _U8P, ctypes.c_int, _INTP,
                                            ctypes.c_uint64, ctypes.c_uint64, ctypes.c_uint64, ctypes.c_uint64,
                                            _U64P]),
        "twin_profile": (ctypes.c_int, [vp, ctypes.c_int, ctypes.c_uint32, ctypes.c_uint32, ctypes.c_int]),
        "twin_skip": (ctypes.c_int, [vp, ctypes.c_int, ctypes.c_uint32, ctypes.c_uint32, ctypes.c_uint32,
                                     ctypes.POINTER(ctypes.c_int)]),
        "twin_cpu_gate": (ctypes.c_int, [vp, ctypes.c_int]),
        "twin_clock_gate": (ctypes.c_int, [vp, ctypes.c_int, ctypes.c_int]),
        "twin_state": (ctypes.c_int64, [vp, _U8P, ctypes.c_int64]),
        "twin_activity": (ctypes.c_int, [vp, ctypes.POINTER(ctypes.c_uint64), ctypes.c_int,
                                         ctypes.POINTER(ctypes.c_uint64)]),
    }
    for name, (res, args) in sig.items():
        f = getattr(lib, name)
        f.restype, f.argtypes = res, args
    return lib


class InPoll(NamedTuple):
    """What :meth:`TwinSim.usb_in_poll` returns."""
    answer: bytes | None  #: the first answer other than a NAK (None: handed back to Python)
    delay: int            #: its delay after the token, in clocks
    token_at: int         #: the clock count before its token
    settle_left: int      #: (answer None) clocks of the last NAK's transaction still to run
    poll_left: int        #: (answer None) clocks of idle bus still to run, after those
    naks: int             #: NAKs meanwhile
    nak_clocks: int       #: their bus clocks


class TwinSim:
    """One running device. ``echo_source``: an object with ``fire(t0_tick, elements,
    delay_ticks) -> rows (rx, start, width)`` and optionally ``noise(t_start, t_end) -> rows``
    (:class:`multisonar.fastfiring.EchoSource`); None = no echoes.

    ``fst``: path of an FST waveform to write (needs the tracing build, ``make twin-fst``;
    several times slower). ``build_first``: run ``make twin`` before loading.

    ``echo_thread``: call the echo source on a worker thread while the device runs on (the
    default for sources whose ``rows_from_t0`` is true: every row ``fire(t0, ...)`` gives starts
    at or after t0, every row ``noise(a, b)`` gives at or after a). The calls keep their order
    (the source's random draws are those of one thread) and their rows reach the harness before
    the device's clock comes within :data:`FENCE_LEAD` of their earliest start: the run is the
    same, clock for clock; the thread overlaps the acoustic model with the simulation. Call
    :meth:`wait_echoes` before changing the source from another thread."""

    NOISE_CHUNK = 48_000  # ticks of noise pulses added ahead of time (1 ms)

    def __init__(self, echo_source: Any = None, *, fst: str | os.PathLike[str] | None = None,
                 library: str | os.PathLike[str] | None = None, build_first: bool = True,
                 echo_thread: bool | None = None) -> None:
        want_fst = fst is not None
        if library is not None:
            path = Path(library)
        else:
            path = build(want_fst, quiet=False) if build_first else library_path(want_fst)
        if not path.exists():
            raise TwinError(f"{path} not built: run `make {'twin-fst' if want_fst else 'twin'}`")
        self.lib = _load(path)
        if want_fst and not self.lib.twin_has_fst():
            raise TwinError(f"{path} was built without FST tracing: use `make twin-fst`")
        if want_fst:
            Path(fst).parent.mkdir(parents=True, exist_ok=True)  # type: ignore[arg-type]
        self._h = self.lib.twin_new(str(fst).encode() if want_fst else None)
        # the harness's tick, clock count, fires ready and mailbox words, read in place
        self._tick, self._cycles, self._ready, self._mail_n = (
            ctype.from_address(self.lib.twin_field(self._h, i))
            for i, ctype in enumerate((ctypes.c_int64, ctypes.c_uint64, ctypes.c_int64, ctypes.c_uint32)))
        self.set_cpu_gate(True)
        self.echo_source = echo_source
        self.fires: list[tuple[int, int, np.ndarray, np.ndarray]] = []  #: (t0, vs, elements, delays)
        self.keep_fires = True
        self.on_fire: Callable[[int, int, np.ndarray, np.ndarray], None] | None = None
        self.echo_thread = echo_thread
        self._echo_rows = 0
        self._pending: deque[tuple[int, Future[Any]]] = deque()  # (earliest start, rows)
        self._pool: ThreadPoolExecutor | None = None
        self._echo_error: BaseException | None = None
        #: the echo source's calls, those made on the echo thread, the fences the harness
        #: reached and the wall seconds it waited there for the thread
        self.echo_stats = {"calls": 0, "threaded": 0, "fences": 0, "waited_s": 0.0}
        self._fence_cb = _FENCE_CB(self._at_fence)
        self._fence = _NO_FENCE
        self._noise_until = 0
        self._t0 = np.zeros(1, np.int64)
        self._t0p = self._t0.ctypes.data_as(_I64P)
        self._vs = ctypes.c_int()
        self._el = (ctypes.c_int * NUM_CH)()
        self._trig = (ctypes.c_int64 * NUM_CH)()
        self._rx = (ctypes.c_uint8 * 1100)()
        self._delay = ctypes.c_int()
        self._poll_out = (ctypes.c_uint64 * 5)()
        self.usb_packets = 0
        self._mail: list[int] = []
        self._mailbuf = (ctypes.c_uint32 * 4096)()

    # ------------------------------------------------------------------ lifecycle
    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
            with _switch_lock:
                _switch["users"] -= 1
                if not _switch["users"]:
                    sys.setswitchinterval(_switch["saved"])
        self._pending.clear()
        if self._h:
            self.lib.twin_free(self._h)
            self._h = None

    def __enter__(self) -> "TwinSim":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:  # a forgotten close still flushes the FST file
        try:
            self.close()
        except Exception:  # noqa: BLE001
            pass

    def reset(self, cycles: int = 16) -> None:
        self.wait_echoes()
        self.lib.twin_reset(self._h, cycles)
        self._noise_until = self.tick

    # ------------------------------------------------------------------ state
    @property
    def tick(self) -> int:
        """The sonar core's tick counter in the current cycle (48 MHz)."""
        return self._tick.value

    @property
    def cycles(self) -> int:
        return self._cycles.value

    @property
    def seconds(self) -> float:
        return self.cycles / TICK_HZ

    @property
    def trapped(self) -> bool:
        return bool(self.lib.twin_trap(self._h))

    def counters(self) -> dict[str, int]:
        return {name: int(self.lib.twin_counter(self._h, _COUNTER_INDEX[name])) for name in COUNTERS}

    @property
    def schedule_start(self) -> int | None:
        """The scheduler's start tick (running_o rise - 1) of its last start, the tick the golden
        model's ``start_tick`` must be to reproduce it; None before the first START."""
        v = ctypes.c_int64(self.lib.twin_counter(self._h, 4)).value
        return None if v < 0 else v

    @property
    def first_schedule_start(self) -> int | None:
        """The start tick of the scheduler's first start (START); None before it."""
        v = ctypes.c_int64(self.lib.twin_counter(self._h, 6)).value
        return None if v < 0 else v

    def mailbox(self) -> list[int]:
        """Words the firmware wrote to its simulation mailbox (SIM_OUT; tags documented in
        firmware/app/sonar) since the last call."""
        self._drain_mailbox()
        out, self._mail = self._mail, []
        return out

    def _drain_mailbox(self) -> None:
        if not self._mail_n.value:
            return
        n = self.lib.twin_mailbox(self._h, self._mailbuf, len(self._mailbuf))
        if n:
            self._mail += self._mailbuf[:n]

    # ------------------------------------------------------------------ activity profile
    def start_profile(self, elf: str | os.PathLike[str] | None = None) -> None:
        """Count from now where the clocks go (:mod:`multisonar.twin.activity`); ``elf``: the
        firmware the twin runs (default: the twin's build/twin/fw/sonar_app.elf)."""
        from .activity import firmware_symbols, poll_range

        root = repo_root()
        path = Path(elf) if elf is not None else (root / "build/twin/fw/sonar_app.elf" if root else None)
        if path is None or not path.exists():
            raise TwinError(f"no firmware ELF for the profile ({path}): run `make twin`")
        self._symbols = firmware_symbols(path)
        words = max((s.start + s.size + 3) // 4 for s in self._symbols)
        lo, hi = poll_range()
        found = self.lib.twin_profile(self._h, 1, lo, hi, words)
        if found != 2 * NUM_CH + 3:
            raise TwinError(f"the activity profile found {found} of its {2 * NUM_CH + 3} registers in the model "
                            "(sim/twin/ms_twin.vlt names them): rebuild the twin (make twin)")
        self._profile_words = words

    def activity(self) -> Any:
        """The activity since :meth:`start_profile` (an :class:`~multisonar.twin.activity.Activity`)."""
        from .activity import COUNTERS, Activity, by_function

        words = getattr(self, "_profile_words", 0)
        if not words:
            raise TwinError("activity(): start_profile() first")
        counts = (ctypes.c_uint64 * len(COUNTERS))()
        pcs = (ctypes.c_uint64 * words)()
        self.lib.twin_activity(self._h, counts, len(COUNTERS), pcs)
        return Activity(dict(zip(COUNTERS, (int(c) for c in counts))), by_function(self._symbols, list(pcs)))

    # ------------------------------------------------------------------ exact skip
    def set_skip(self, on: bool = True, *, stop_after: bool = False) -> None:
        """Skip calm clocks exactly (docs/twin.md, "Exact skip of calm clocks"): while the CPU
        waits in its idle wait, the scheduler's engine spins in its poll loop and no burst, echo
        edge or USB packet is under way, the harness advances the clocks' counters to just
        before the next thing due instead of simulating the clocks. ``stop_after``: twin_run
        returns after each skip (run() then stops short), for comparing the state there."""
        from .activity import poll_labels

        lo, hi, anchor = poll_labels()
        want = ctypes.c_int()
        mode = (2 if stop_after else 1) if on else 0
        found = self.lib.twin_skip(self._h, mode, lo, hi, anchor, ctypes.byref(want))
        if on and found != want.value:
            raise TwinError(f"the exact skip found {found} of its {want.value} variables in the model "
                            "(sim/twin/ms_twin.vlt names them): rebuild the twin (make twin)")

    @property
    def skip_stats(self) -> tuple[int, int]:
        """(skips, clocks skipped) since the twin was made."""
        return int(self.lib.twin_counter(self._h, 7)), int(self.lib.twin_counter(self._h, 8))

    def set_cpu_gate(self, on: bool = True) -> bool:
        """Hold the CPU's clock in the clocks where it waits in WAIT and its inputs are those of
        its last edge (its state cannot change then; on by default, docs/twin.md). Returns
        whether this build of the model has the gate."""
        return bool(self.lib.twin_cpu_gate(self._h, int(on)))

    @property
    def cpu_held(self) -> int:
        """Clocks in which the CPU's clock was held."""
        return int(self.lib.twin_counter(self._h, 9))

    def set_sonar_gates(self, rx: bool = True, tx: bool = True) -> bool:
        """Hold the receiver's and the transmitter's clocks in the clocks where their state
        cannot change (on by default, docs/twin.md): the receive conditioners' (`rx`) while all
        have settled on their inputs and neither an input nor the glitch length changes, each
        transmit element's (`tx`) while it is idle and no fire or reset reaches it. Returns
        whether this build of the model has them."""
        has_rx = self.lib.twin_clock_gate(self._h, 0, int(rx))
        has_tx = self.lib.twin_clock_gate(self._h, 1, int(tx))
        return bool(has_rx and has_tx)

    def set_usb_gate(self, on: bool = True) -> bool:
        """Hold the USB device's clock while no packet is in flight, no byte moves between it
        and the host link and its inputs do not change (its two counters that run with time are
        brought up to date when it is clocked again; on by default, docs/twin.md). Returns
        whether this build of the model has the gate."""
        return bool(self.lib.twin_clock_gate(self._h, 2, int(on)))

    def set_sonar_core_gate(self, on: bool = True) -> bool:
        """Hold the sonar core's clock while it is calm and the CPU runs without addressing it
        (with the skip on only: the skip's checks decide it); it is brought up to date (its
        counters that run with time advanced, its last few clocks simulated) when the SoC
        addresses it, its calm ends or the CPU waits again (on by default, docs/twin.md).
        Returns whether this build of the model has the gate."""
        return bool(self.lib.twin_clock_gate(self._h, 3, int(on)))

    @property
    def clocks_held(self) -> dict[str, int]:
        """Clocks held by each clock gate: the CPU's, the receive conditioners', the transmit
        elements' (one per element and clock), the USB device's, the sonar core's."""
        return {name: int(self.lib.twin_counter(self._h, i))
                for name, i in (("cpu", 9), ("rx", 10), ("tx", 11), ("usb", 12), ("sonar", 13))}

    def state(self) -> bytes:
        """The model's whole state as bytes (every signal and memory; also pointers to the
        model's own objects, which differ between twins: see :func:`state_differences`)."""
        n = int(self.lib.twin_state(self._h, None, 0))
        buf = (ctypes.c_uint8 * n)()
        self.lib.twin_state(self._h, buf, n)
        return bytes(buf)

    # ------------------------------------------------------------------ time
    def run(self, cycles: int) -> None:
        """Let the device run `cycles` clocks, serving every pulse it fires meanwhile."""
        left = int(cycles)
        while left > 0:
            left -= self.run_chunk(min(left, self.NOISE_CHUNK))

    def run_chunk(self, cycles: int) -> int:
        """One call of the harness: up to ``cycles`` clocks, fewer when a pulse is ready to fire
        (or, with ``set_skip(stop_after=True)``, after a skip), serving what it fired; returns
        the clocks run."""
        self._noise_ahead()
        n = int(self.lib.twin_run(self._h, cycles))
        self._after_call()
        self._drain_mailbox()
        return n

    def run_seconds(self, seconds: float) -> None:
        self.run(int(round(seconds * TICK_HZ)))

    def _noise_ahead(self) -> None:
        src = self.echo_source
        if src is None or not hasattr(src, "noise"):
            return
        t = self.tick
        if self._noise_until < t + self.NOISE_CHUNK:
            start = max(self._noise_until, t + 1)
            end = start + 2 * self.NOISE_CHUNK
            self._echoes(start - 1, src.noise, start, end)  # (-1: the rows' rounding from seconds)
            self._noise_until = end

    def _serve_fires(self) -> None:
        while self._ready.value:
            n = self.lib.twin_pop_fire(self._h, self._t0p, ctypes.byref(self._vs), self._el, self._trig)
            if n < 0:
                return
            t0 = int(self._t0[0])
            elements = np.array(self._el[:n], dtype=np.int64)
            delays = np.array(self._trig[:n], dtype=np.int64) - t0
            if self.keep_fires:
                self.fires.append((t0, int(self._vs.value), elements, delays))
            if self.on_fire is not None:
                self.on_fire(t0, int(self._vs.value), elements, delays)
            if self.echo_source is not None and n:
                self._echoes(t0, self.echo_source.fire, t0, elements, delays)

    # ------------------------------------------------------------------ echoes
    @property
    def echo_rows(self) -> int:
        """Comparator pulses the echo source gave (waits for the echo thread)."""
        self.wait_echoes()
        return self._echo_rows

    def wait_echoes(self) -> None:
        """Hand every echo the source is computing to the harness now."""
        self._collect(_NO_FENCE)
        self._raise_echo_error()

    def _threaded(self) -> bool:
        on = self.echo_thread
        return bool(getattr(self.echo_source, "rows_from_t0", False)) if on is None else on

    def _echoes(self, earliest: int, call: Callable[..., Any], *args: Any) -> None:
        """The rows of ``call(*args)``, none starting before tick ``earliest``: added now, or
        computed on the echo thread and added before the clock reaches the fence."""
        self.echo_stats["calls"] += 1
        if not self._threaded():
            self.wait_echoes()  # (in the order of the calls)
            self._add_rows(call(*args))
            return
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="twin-echoes")
            # a thread waiting for the GIL gets it within this (Python's default: 5 ms)
            with _switch_lock:
                if not _switch["users"]:
                    _switch["saved"] = sys.getswitchinterval()
                    sys.setswitchinterval(min(_switch["saved"], 5e-5))
                _switch["users"] += 1
        self._pending.append((earliest, self._pool.submit(call, *args)))
        self.echo_stats["threaded"] += 1
        self._set_fence()

    def _set_fence(self) -> None:
        fence = min(e for e, _ in self._pending) - FENCE_LEAD if self._pending else _NO_FENCE
        if fence != self._fence:  # (the harness clears it when reached)
            self.lib.twin_set_fence(self._h, fence, self._fence_cb)
            self._fence = fence

    def _collect(self, tick: int) -> None:
        """Add the rows of every call whose fence is at or before ``tick`` (waiting for them,
        and for the calls before them), then of those already done; set the next fence."""
        if not self._pending:
            return
        due = [i for i, (e, _) in enumerate(self._pending) if e - FENCE_LEAD <= tick]
        last = due[-1] if due else -1
        i = 0
        while self._pending and (i <= last or self._pending[0][1].done()):
            earliest, fut = self._pending.popleft()
            try:
                rows = fut.result()
            except Exception as e:
                raise TwinError(f"the echo source failed on the echo thread: {e!r}") from e
            self._add_rows(rows, earliest)
            i += 1
        self._set_fence()

    def _at_fence(self) -> None:
        # called by the harness (from inside a ctypes call): an exception cannot cross back into
        # C++; it is kept and raised when that call returns (the fence stays cleared)
        try:
            self.echo_stats["fences"] += 1
            self._fence = _NO_FENCE
            t = time.perf_counter()
            self._collect(self.tick)
            self.echo_stats["waited_s"] += time.perf_counter() - t
        except BaseException as e:  # noqa: BLE001
            self._echo_error = e
            self._pending.clear()

    def _raise_echo_error(self) -> None:
        if self._echo_error is not None:
            e, self._echo_error = self._echo_error, None
            raise e

    def _after_call(self) -> None:
        """After a call into the harness: its error, the rows ready, the fires to serve."""
        self._raise_echo_error()
        if self._pending and self._pending[0][1].done():
            self._collect(-1)
        self._serve_fires()

    def _add_rows(self, rows: Any, earliest: int | None = None) -> None:
        from ..fastfiring import _rows

        r = np.ascontiguousarray(_rows(rows), dtype=np.int64)
        if not len(r):
            return
        if earliest is not None and int(r[:, 1].min()) < earliest:
            raise TwinError(f"the echo source gave a pulse starting at tick {int(r[:, 1].min())}, before "
                            f"tick {earliest} (its rows_from_t0 promise): use TwinSim(echo_thread=False)")
        self.lib.twin_add_echoes(self._h, r.ctypes.data_as(_I64P), len(r))
        self._echo_rows += len(r)

    # ------------------------------------------------------------------ USB
    def usb_packet(self, packet: bytes, listen_clocks: int) -> tuple[bytes, int]:
        """One host packet into the device's packet layer; (answer, clocks to its first byte)."""
        buf = (ctypes.c_uint8 * len(packet)).from_buffer_copy(packet) if packet else (ctypes.c_uint8 * 1)()
        n = self.lib.twin_usb_packet(self._h, buf, len(packet), listen_clocks, self._rx, len(self._rx),
                                     ctypes.byref(self._delay))
        self.usb_packets += 1
        self._after_call()
        return bytes(self._rx[:min(n, len(self._rx))]), int(self._delay.value)

    def usb_in_poll(self, token: bytes, listen_clocks: int, nak_bus: int, poll_clocks: int,
                    max_clocks: int) -> InPoll:
        """Bulk-IN polling inside the harness (``twin_usb_in_poll``): the IN ``token`` while the
        device NAKs, each NAK's transaction lasting ``nak_bus`` clocks plus the answer's delay, then
        ``poll_clocks`` of idle bus, as :meth:`usb_packet` and :meth:`run` called from Python would
        run them, but without a return to Python per NAK. Answer None: handed back where Python
        has work (a fire to serve, noise to add, or ``max_clocks`` passed) with the settle and
        poll clocks still to :meth:`run`, in order."""
        if poll_clocks > self.NOISE_CHUNK:  # run() would split the wait where noise may be added
            raise ValueError(f"usb_in_poll: poll_clocks {poll_clocks} > NOISE_CHUNK {self.NOISE_CHUNK}")
        src = self.echo_source
        noise_at = (max(self._noise_until - self.NOISE_CHUNK + 1, 0)
                    if src is not None and hasattr(src, "noise") else 2**64 - 1)  # as _noise_ahead
        buf = (ctypes.c_uint8 * len(token)).from_buffer_copy(token)
        out = self._poll_out
        n = self.lib.twin_usb_in_poll(self._h, buf, len(token), listen_clocks, self._rx, len(self._rx),
                                      ctypes.byref(self._delay), nak_bus, poll_clocks, noise_at, max_clocks, out)
        self.usb_packets += int(out[3]) + (n >= 0)
        self._after_call()
        self._drain_mailbox()
        if n < 0:
            return InPoll(None, 0, 0, int(out[1]), int(out[2]), int(out[3]), int(out[4]))
        return InPoll(bytes(self._rx[:min(n, len(self._rx))]), int(self._delay.value), int(out[0]), 0, 0,
                      int(out[3]), int(out[4]))

    def bus_reset(self, cycles: int = 256) -> None:
        self.lib.twin_bus_reset(self._h, cycles)
        self._after_call()
