"""The driver's connection errors, below both the driver (:mod:`multisonar.device`) and the
URL-scheme openers (:mod:`multisonar.urls` and the modules that register schemes), so that
an opener can raise them without importing the driver. ``multisonar.device`` and the package
re-export them."""

from __future__ import annotations


class DeviceNotFound(ConnectionError):
    """No device at the URL (board not plugged / no permission / server not running)."""


class DeviceDisconnected(ConnectionError):
    """The device went away during use; Device.open() it again."""


class DeviceTimeout(TimeoutError):
    """The device did not answer (command reply or frames) in time."""
