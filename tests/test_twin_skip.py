"""The twin's exact skip of calm clocks (TwinSim.set_skip; docs/twin.md, "Exact skip of calm
clocks"): skipping must change nothing the device does.

* A whole session, with and without the skip: the same single-threaded session
  (multisonar.twin.check.fixed_session: START the compiled-in demo table, read bulk IN every
  0.5 ms of device time) on the noisy corridor gives the same bytes on bulk IN, the same mailbox
  words (they carry the firmware's cycle counts), the same pulses and, at the end, the same
  whole model state (every signal and memory).
* After every skip: two twins side by side, one skipping and stopping after each skip, the
  other simulating the same clocks; their whole states are equal after each one.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np
import pytest

from multisonar.constants import TICK_HZ
from multisonar.twin.check import booted_corridor, fixed_session, start_table
from multisonar.twin.sim import NUM_CH, TwinSim, state_differences

pytestmark = pytest.mark.sim


def test_a_session_is_the_same_with_and_without_the_skip():
    runs = {}
    for skip in (False, True):
        sim = booted_corridor(5)
        try:
            runs[skip] = fixed_session(sim, 0.1, skip=skip)
        finally:
            sim.close()
    a, b = runs[False], runs[True]
    assert a.skip_stats == (0, 0)
    skips, skipped = b.skip_stats
    assert skips > 100 and skipped > 0.3 * 0.1 * TICK_HZ, b.skip_stats  # it did skip
    assert len(a.fires) > 20 and len(a.bulk_in) > 2000 and len(a.mailbox) > 50
    assert a.tick == b.tick
    assert a.bulk_in == b.bulk_in
    assert a.mailbox == b.mailbox
    assert [(t0, vs, el.tolist(), d.tolist()) for t0, vs, el, d in a.fires] == \
           [(t0, vs, el.tolist(), d.tolist()) for t0, vs, el, d in b.fires]
    assert state_differences(a.state, b.state, a.boot_state, b.boot_state) == []


def test_the_state_after_every_skip_equals_the_simulated_clocks():
    plain, skipping = booted_corridor(7), booted_corridor(7)
    try:
        boot = (plain.state(), skipping.state())
        for sim in (plain, skipping):
            start_table(sim, skip=sim is skipping, stop_after=True)
        end = plain.tick + int(0.04 * TICK_HZ)
        while plain.tick < end:
            n = skipping.run_chunk(4000)  # returns right after a skip
            left = n
            while left > 0:
                left -= plain.run_chunk(left)
            assert plain.tick == skipping.tick
            diff = state_differences(plain.state(), skipping.state(), *boot)
            assert diff == [], f"after {skipping.skip_stats[0]} skips, at tick {plain.tick}: bytes {diff[:8]}"
        assert skipping.skip_stats[0] > 100, skipping.skip_stats
        assert plain.mailbox() == skipping.mailbox()
    finally:
        plain.close()
        skipping.close()


def test_the_harness_nak_loop_runs_what_the_python_loop_runs():
    """TwinUsbFunction.bulk_in retries a NAKed IN inside the harness (twin_usb_in_poll) instead of
    one Python round per NAK: the same packets at the same clocks, so the same device run."""
    runs = {}
    for harness in (False, True):
        sim = booted_corridor(11)
        try:
            boot = sim.state()
            fn = start_table(sim, skip=True, harness_poll=harness)
            end = sim.tick + int(0.06 * TICK_HZ)
            reads = []
            while sim.tick < end:
                reads.append(fn.bulk_in(0x81, 4096, timeout_s=600.0))
            runs[harness] = (reads, sim.tick, sim.mailbox(), fn.stats, fn.host.packets, fn.host.bus_clocks,
                             [(t0, vs, el.tolist(), d.tolist()) for t0, vs, el, d in sim.fires],
                             sim.state(), boot)
        finally:
            sim.close()
    a, b = runs[False], runs[True]
    assert sum(len(r) for r in a[0]) > 2000 and a[3]["in_naks"] > 100, a[3]
    assert a[0] == b[0]  # every read's bytes
    assert a[1:7] == b[1:7]  # end tick, mailbox, USB counts, bus time, pulses
    assert state_differences(a[7], b[7], a[8], b[8]) == []


def _gated_and_clocked(seed: int, gate: Callable[[TwinSim, bool], bool],
                       held: Callable[[TwinSim], Any]) -> tuple:
    """The same session without and with a clock gate of the twin: each run's result and the
    clocks the gate held."""
    runs = {}
    for on in (False, True):
        sim = booted_corridor(seed)
        try:
            assert gate(sim, on), "the twin was built without this clock gate (make twin)"
            before = held(sim)
            runs[on] = fixed_session(sim, 0.08, skip=True), held(sim) - before
        finally:
            sim.close()
    return runs[False], runs[True]


def _same_session(a, b) -> None:
    assert a.tick == b.tick and a.bulk_in == b.bulk_in and a.mailbox == b.mailbox
    assert [(t0, vs, el.tolist(), d.tolist()) for t0, vs, el, d in a.fires] == \
           [(t0, vs, el.tolist(), d.tolist()) for t0, vs, el, d in b.fires]
    assert state_differences(a.state, b.state, a.boot_state, b.boot_state) == []


def test_holding_the_cpus_clock_changes_nothing():
    """The CPU's clock gate (rtl/soc/ms_soc.sv, MS_TWIN_CPU_GATE; TwinSim.set_cpu_gate): held in
    the clocks where the CPU waits in WAIT with its inputs as at its last edge, it gives the same
    session, byte for byte and state for state, as a CPU clocked in every clock."""
    (a, a_held), (b, b_held) = _gated_and_clocked(
        13, lambda sim, on: sim.set_cpu_gate(on), lambda sim: sim.cpu_held)
    assert a_held == 0 and b_held > 0.05 * 0.08 * TICK_HZ, (a_held, b_held)  # it held the clock
    _same_session(a, b)


def test_holding_the_usb_devices_clock_changes_nothing():
    """The USB device's clock gate (rtl/link/ms_system_usb.sv, MS_TWIN_USB_GATE;
    TwinSim.set_usb_gate): held between the host's packets while no byte moves to or from the
    host link, its receive phase and transaction timer brought up to date when it is clocked
    again. The same session as with the device clocked in every clock, through enumeration-free
    bulk traffic (commands, frames, NAKed polls)."""
    (a, a_held), (b, b_held) = _gated_and_clocked(
        19, lambda sim, on: sim.set_usb_gate(on), lambda sim: sim.clocks_held["usb"])
    assert a_held == 0 and b_held > 0.1 * 0.08 * TICK_HZ, (a_held, b_held)
    _same_session(a, b)


def test_holding_the_sonar_cores_clock_changes_nothing():
    """The sonar core's clock gate (rtl/ms_system.sv, MS_TWIN_SONAR_GATE;
    TwinSim.set_sonar_core_gate): held from the engine's anchor while the core is calm and the
    CPU runs, brought up to date (whole turns advanced, the last clocks replayed with the SoC's
    outputs of those clocks) when the SoC addresses it, an echo comes near or the CPU waits. The
    same session, byte for byte and state for state, as with the core clocked in every clock."""
    (a, a_held), (b, b_held) = _gated_and_clocked(
        23, lambda sim, on: sim.set_sonar_core_gate(on), lambda sim: sim.clocks_held["sonar"])
    assert a_held == 0 and b_held > 0.02 * 0.08 * TICK_HZ, (a_held, b_held)
    _same_session(a, b)


def test_the_sonar_core_caught_up_at_any_clock_equals_the_clocked_one():
    """Lockstep: two twins, the sonar core's gate off in one; after every few hundred clocks
    both states are compared (a snapshot brings the held core up to date: after any number of
    held clocks, whole turns or not)."""
    plain, gated = booted_corridor(29), booted_corridor(29)
    try:
        plain.set_sonar_core_gate(False)
        boot = (plain.state(), gated.state())
        for sim in (plain, gated):
            start_table(sim, skip=True)
        end, k = plain.tick + int(0.02 * TICK_HZ), 0
        while plain.tick < end:
            k += 1
            for sim in (plain, gated):
                sim.run(173 + 37 * (k % 11))  # catch-ups at every phase of the engine's turn
            assert plain.tick == gated.tick
            diff = state_differences(plain.state(), gated.state(), *boot)
            assert diff == [], f"at tick {plain.tick}: bytes {diff[:8]}"
        assert gated.clocks_held["sonar"] > 0.02 * 0.02 * TICK_HZ, gated.clocks_held
        assert plain.mailbox() == gated.mailbox()
    finally:
        plain.close()
        gated.close()


def test_holding_the_sonar_clocks_changes_nothing():
    """The receiver's and the transmitter's clock gates (MS_TWIN_RX_GATE in ms_sonar_core,
    MS_TWIN_TX_GATE in ms_tx_phaser; TwinSim.set_sonar_gates): the conditioners held while all
    have settled on unchanged inputs, each transmit element while idle and not fired. The same
    session, byte for byte and state for state, as with every channel clocked in every clock;
    the echoes of a corridor and the bursts of its pulses wake them many times."""
    (a, a_held), (b, b_held) = _gated_and_clocked(
        17, lambda sim, on: sim.set_sonar_gates(on, on),
        lambda sim: np.array([sim.clocks_held["rx"], sim.clocks_held["tx"]]))
    clocks = 0.08 * TICK_HZ
    assert a_held.tolist() == [0, 0], a_held
    assert b_held[0] > 0.1 * clocks and b_held[1] > 0.1 * NUM_CH * clocks, b_held
    assert b.skip_stats[0] > 0 and len(b.fires) > 10  # the skip ran and the sonar fired
    _same_session(a, b)
