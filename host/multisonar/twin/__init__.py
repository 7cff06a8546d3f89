"""The full-system twin: the device's RTL (Verilator) with the acoustic model in the loop,
reached by the unchanged host driver over USB/IP (or in-process).

    scene -> acoustics -> RTL sonar core + VexRiscv firmware -> RTL USB device
          -> TwinUsbFunction -> USB/IP on 127.0.0.1 -> pyusb -> multisonar.Device -> numpy

>>> from multisonar.twin import open_twin
>>> with open_twin("corridor") as tw:            # builds build/twin/ on first use (make twin)
...     tw.device.configure(sensors); tw.start()
...     for frame in tw.device.stream(): ...
...     tw.sim.seconds                           # device time simulated so far

Time: the device's clock is the simulation's (48 MHz); the driver's timeouts are wall-clock,
so the twin's Device gets long ones. Scene time 0 is the tick of :meth:`Twin.start`.
"""

from __future__ import annotations

import os
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Iterator

from ..constants import TICK_HZ
from ..errors import DeviceNotFound
from ..urls import DeviceUrl, Model, register_scheme
from .sim import TwinError, TwinSim, build, library_path
from .usbhost import TwinUsbFunction

#: clocks the firmware needs from reset to serving USB (it boots in ~3.5 ms)
BOOT_CLOCKS = 5 * TICK_HZ // 1000
#: the driver's command / read timeout for a twin, wall-clock seconds (the simulation runs
#: 20-100x slower than the device, by how calm it is)
TWIN_TIMEOUT_S = 120.0


@dataclass
class Twin:
    device: Any  #: multisonar.Device talking to the twin
    sim: TwinSim
    function: TwinUsbFunction
    echo_source: Any
    url: str
    server: Any = None

    def start(self, scene_t0: float = 0.0) -> int:
        """START the device; scene time ``scene_t0`` (s) = now. Returns the tick at START."""
        tick = self.sim.tick
        if self.echo_source is not None and hasattr(self.echo_source, "t_offset"):
            self.sim.wait_echoes()  # (the echo thread's calls so far use the old offset)
            self.echo_source.t_offset = float(scene_t0) - tick / TICK_HZ
        self.start_tick = tick
        self.device.start()
        return tick

    def scene_time(self, tick: int) -> float:
        """Scene time (s) of a device tick (u32 ticks from frames are unwrapped near now)."""
        base = getattr(self, "start_tick", 0)
        now = self.sim.tick
        t = (now & ~0xFFFFFFFF) | (int(tick) & 0xFFFFFFFF)
        if t > now + (1 << 31):
            t -= 1 << 32
        return (t - base) / TICK_HZ


@contextmanager
def open_twin(scene: Any = "corridor", *, usbip: bool = True, fst: str | os.PathLike[str] | None = None,
              build_first: bool = True, echo_source: Any = None, timeout_s: float = TWIN_TIMEOUT_S,
              seed: int | None = None, library: str | os.PathLike[str] | None = None,
              skip: bool | None = None) -> Iterator[Twin]:
    """Build (if needed) and boot the twin on a scene (name, path or Scene), enumerate it and
    open a Device on it: over our USB/IP server on 127.0.0.1 (default) or in-process.
    ``library``: another build of the harness (a profiling build, say) instead of make's.
    ``skip``: skip calm clocks exactly (TwinSim.set_skip; default on, off with ``fst``, whose
    waveform shows every clock)."""
    from ..device import Device
    from ..fastfiring import SceneEchoSource
    from ..scene import load_scene

    if echo_source is None:
        sc = load_scene(scene) if isinstance(scene, (str, os.PathLike)) else scene
        if seed is None:  # the scene's own seed, as the golden model
            echo_source = SceneEchoSource(sc)
        else:
            import numpy as np

            echo_source = SceneEchoSource(sc, rng=np.random.default_rng(seed))
    sim = TwinSim(echo_source, fst=fst, build_first=build_first and library is None, library=library)
    server = None
    try:
        sim.reset()
        sim.run(BOOT_CLOCKS)
        if sim.trapped:
            raise TwinError("the firmware trapped while booting")
        fn = TwinUsbFunction(sim)
        sim.set_skip(fst is None if skip is None else skip)
        if usbip:
            from ..usb.usbip_server import UsbipServer

            server = UsbipServer(fn, host="127.0.0.1", port=0).start()
            dev = Device.open(server.url, timeout_s=timeout_s)
            url = server.url
        else:
            dev = Device.attach(fn, url="twin://", timeout_s=timeout_s)
            url = "twin://"
        tw = Twin(dev, sim, fn, echo_source, url, server)
        try:
            yield tw
        finally:
            dev.close()
    finally:
        if server is not None:
            server.close()
        sim.close()


# -- the twin:// device URL scheme (multisonar.urls; found through the multisonar.schemes entry point)
def twin_model(url: DeviceUrl) -> Model:
    """twin://SCENE: the full-system twin in this process (the device's RTL in Verilator; 20-100x slower than real time)"""
    from ..fastfiring import SceneEchoSource

    tsim = None
    try:
        tsim = TwinSim(SceneEchoSource(url.target or "corridor"))
        tsim.reset()
        tsim.run(BOOT_CLOCKS)
        fn = TwinUsbFunction(tsim)
        tsim.set_skip(True)
    except (TwinError, KeyError, OSError) as e:
        if tsim is not None:
            tsim.close()
        raise DeviceNotFound(f"{url.url}: cannot build the twin: {e}") from None
    return Model(fn, close=tsim.close, min_timeout_s=TWIN_TIMEOUT_S)


register_scheme("twin", model=twin_model, help=twin_model.__doc__ or "")

__all__ = ["BOOT_CLOCKS", "Twin", "TwinError", "TwinSim", "TwinUsbFunction", "build", "library_path", "open_twin"]
