"""In-process pyusb backend: the unchanged pyusb API (usb.core.find, read, write,
ctrl_transfer, usb.util.get_string) on :class:`~multisonar.usb.function.UsbFunction` objects
in the same process. No sockets, no threads; a read with no data waits for the device up to
the timeout and raises usb.core.USBTimeoutError, like libusb.
"""

from __future__ import annotations

import errno
from typing import Iterator

import usb.backend
import usb.core

from .function import Disconnected, ParsedConfig, Stall, UsbFunction, UsbTimeout, parse_config_descriptor, \
    parse_device_descriptor


class _Dev:
    def __init__(self, fn: UsbFunction, address: int) -> None:
        self.fn = fn
        self.desc = parse_device_descriptor(fn.descriptors.device, bus=1, address=address, speed=fn.speed)
        self.cfg: ParsedConfig = parse_config_descriptor(fn.descriptors.config)
        self.unplugged = False


def _err(e: Exception) -> usb.core.USBError:
    if isinstance(e, UsbTimeout):
        return usb.core.USBTimeoutError(str(e) or "timeout", errno.ETIMEDOUT, errno.ETIMEDOUT)
    if isinstance(e, Stall):
        return usb.core.USBError(f"pipe error (STALL): {e}", errno.EPIPE, errno.EPIPE)
    return usb.core.USBError(f"no such device (it may have been disconnected): {e}", errno.ENODEV, errno.ENODEV)


class InProcessBackend(usb.backend.IBackend):
    """pyusb backend over a list of UsbFunction objects (``plug``/``unplug`` at will)."""

    def __init__(self, *functions: UsbFunction) -> None:
        self._devs: list[_Dev] = []
        for f in functions:
            self.plug(f)

    def plug(self, fn: UsbFunction) -> None:
        self._devs.append(_Dev(fn, address=len(self._devs) + 1))

    def unplug(self, fn: UsbFunction) -> None:
        for d in self._devs:
            if d.fn is fn:
                d.unplugged = True
        self._devs = [d for d in self._devs if d.fn is not fn]

    # -- enumeration / descriptors ----------------------------------------------------
    def enumerate_devices(self) -> Iterator[_Dev]:
        return iter(list(self._devs))

    def get_device_descriptor(self, dev: _Dev):
        return dev.desc

    def get_configuration_descriptor(self, dev: _Dev, config: int):
        if config != 0:
            raise IndexError(config)
        return dev.cfg.config

    def get_interface_descriptor(self, dev: _Dev, intf: int, alt: int, config: int):
        if config != 0 or alt != 0:
            raise IndexError((intf, alt, config))
        return dev.cfg.interfaces[intf]

    def get_endpoint_descriptor(self, dev: _Dev, ep: int, intf: int, alt: int, config: int):
        if config != 0 or alt != 0:
            raise IndexError((ep, intf, alt, config))
        return dev.cfg.endpoints[intf][ep]

    # -- handle -----------------------------------------------------------------------
    def open_device(self, dev: _Dev) -> _Dev:
        if dev.unplugged:
            raise _err(Disconnected("device unplugged"))
        return dev

    def close_device(self, dev_handle: _Dev) -> None:
        pass

    def _ctl(self, h: _Dev, setup: bytes, data: bytes = b"") -> bytes:
        if h.unplugged:
            raise _err(Disconnected("device unplugged"))
        try:
            return h.fn.control(setup, data)
        except (Stall, UsbTimeout, Disconnected) as e:
            raise _err(e) from None

    def set_configuration(self, dev_handle: _Dev, config_value: int) -> None:
        self._ctl(dev_handle, bytes([0, 9, config_value & 0xFF, config_value >> 8, 0, 0, 0, 0]))

    def get_configuration(self, dev_handle: _Dev) -> int:
        return self._ctl(dev_handle, bytes([0x80, 8, 0, 0, 0, 0, 1, 0]))[0]

    def set_interface_altsetting(self, dev_handle: _Dev, intf: int, altsetting: int) -> None:
        self._ctl(dev_handle, bytes([1, 11, altsetting, 0, intf, 0, 0, 0]))

    def claim_interface(self, dev_handle: _Dev, intf: int) -> None:
        if dev_handle.unplugged:
            raise _err(Disconnected("device unplugged"))

    def release_interface(self, dev_handle: _Dev, intf: int) -> None:
        pass

    def clear_halt(self, dev_handle: _Dev, ep: int) -> None:
        self._ctl(dev_handle, bytes([2, 1, 0, 0, ep, 0, 0, 0]))

    def reset_device(self, dev_handle: _Dev) -> None:
        dev_handle.fn.reset()

    def is_kernel_driver_active(self, dev_handle: _Dev, intf: int) -> bool:
        return False

    def detach_kernel_driver(self, dev_handle: _Dev, intf: int) -> None:
        pass

    def attach_kernel_driver(self, dev_handle: _Dev, intf: int) -> None:
        pass

    # -- transfers ----------------------------------------------------------------------
    def bulk_write(self, dev_handle: _Dev, ep: int, intf: int, data, timeout: int) -> int:
        if dev_handle.unplugged:
            raise _err(Disconnected("device unplugged"))
        try:
            dev_handle.fn.bulk_out(ep, bytes(data))
        except (Stall, UsbTimeout, Disconnected) as e:
            raise _err(e) from None
        return len(data)

    def bulk_read(self, dev_handle: _Dev, ep: int, intf: int, buff, timeout: int) -> int:
        if dev_handle.unplugged:
            raise _err(Disconnected("device unplugged"))
        try:
            data = dev_handle.fn.bulk_in(ep, len(buff), (timeout or 60_000) / 1000.0)
        except (Stall, UsbTimeout, Disconnected) as e:
            raise _err(e) from None
        n = min(len(data), len(buff))
        buff[:n] = type(buff)("B", data[:n]) if hasattr(buff, "typecode") else data[:n]
        return n

    def ctrl_transfer(self, dev_handle: _Dev, bmRequestType: int, bRequest: int, wValue: int, wIndex: int, data,
                      timeout: int) -> int:
        is_in = bool(bmRequestType & 0x80)
        length = len(data) if data is not None else 0
        setup = bytes([bmRequestType, bRequest, wValue & 0xFF, wValue >> 8, wIndex & 0xFF, wIndex >> 8,
                       length & 0xFF, length >> 8])
        if is_in:
            out = self._ctl(dev_handle, setup)
            n = min(len(out), length)
            data[:n] = type(data)("B", out[:n]) if hasattr(data, "typecode") else out[:n]
            return n
        self._ctl(dev_handle, setup, bytes(data) if data is not None else b"")
        return length
