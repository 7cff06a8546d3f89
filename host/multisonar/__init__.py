"""Multisonar: host driver, golden model and tools for a 24-element ultrasonic ring."""

from __future__ import annotations

from ._version import __version__
from .constants import TICK_HZ, speed_of_sound
from .layout import Layout, LayoutError, load_layout
from .device import Device, DeviceDisconnected, DeviceNotFound, DeviceTimeout, read_recording

__all__ = ["TICK_HZ", "Layout", "LayoutError", "load_layout", "speed_of_sound", "__version__",
           "Device", "DeviceDisconnected", "DeviceNotFound", "DeviceTimeout", "read_recording"]
