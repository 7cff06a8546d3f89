"""A USB device as seen from its endpoints: descriptors, control requests, bulk callbacks.

:class:`UsbFunction` is what both transports serve: the in-process pyusb backend
(:mod:`multisonar.usb.inproc`) calls it directly, the USB/IP server
(:mod:`multisonar.usb.usbip_server`) calls it per URB. Subclasses implement
:meth:`bulk_out` and :meth:`bulk_in` (the simulated Multisonar: :mod:`multisonar.simdevice`;
an RTL twin can implement the same three methods at transaction level).

Descriptors are bytes (:class:`~multisonar.usb.descriptors.DescriptorSet`); hosts read them with
GET_DESCRIPTOR (and the MS OS 2.0 vendor request) like from a real device, and
:func:`parse_device_descriptor` / :func:`parse_config_descriptor` turn them into the objects
pyusb's backend API wants.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from types import SimpleNamespace

from .descriptors import MS_OS_20_INDEX, DescriptorSet


class Stall(Exception):
    """The endpoint answers STALL (unsupported or malformed request)."""


class UsbTimeout(Exception):
    """No data within the timeout (the device NAKed)."""


class Disconnected(Exception):
    """The device is gone (unplugged, server closed)."""


class UsbFunction:
    """Endpoint-level device model. Standard control requests are handled here."""

    speed: int = 2  # usb.util.SPEED_FULL

    def __init__(self, descriptors: DescriptorSet) -> None:
        self.descriptors = descriptors
        self.configuration = 0
        self.halted: set[int] = set()

    # -- control endpoint 0 -----------------------------------------------------------
    def control(self, setup: bytes, data: bytes = b"") -> bytes:
        """Handle one control transfer. ``setup`` is the 8-byte SETUP packet; returns the IN
        data stage (truncated to wLength) or b"" for OUT requests; raises Stall."""
        if len(setup) != 8:
            raise Stall(f"SETUP packet of {len(setup)} bytes")
        rt, req, value, index, length = struct.unpack("<BBHHH", setup)
        kind = (rt >> 5) & 3
        d = self.descriptors
        if (rt, req, index) == (0xC0, d.vendor_code, MS_OS_20_INDEX):  # MS OS 2.0 descriptor set
            return d.ms_os_20[:length]
        if kind != 0:
            return self.vendor_control(rt, req, value, index, length, data)
        if req == 6 and rt == 0x80:  # GET_DESCRIPTOR
            out = d.get_descriptor(value >> 8, value & 0xFF)
            if out is None:
                raise Stall(f"no descriptor type {value >> 8} index {value & 0xFF}")
            return out[:length]
        if req == 9 and rt == 0x00:  # SET_CONFIGURATION
            if value not in (0, 1):
                raise Stall(f"no configuration {value}")
            self.configuration = value
            self.on_configured(value)
            return b""
        if req == 8 and rt == 0x80:  # GET_CONFIGURATION
            return bytes([self.configuration])[:length]
        if req == 0 and rt in (0x80, 0x81, 0x82):  # GET_STATUS
            st = 1 if (rt == 0x82 and index in self.halted) else 0
            return struct.pack("<H", st)[:length]
        if req == 1 and rt == 0x02 and value == 0:  # CLEAR_FEATURE(ENDPOINT_HALT)
            self.halted.discard(index)
            return b""
        if req == 11 and rt == 0x01:  # SET_INTERFACE
            if index != 0 or value != 0:
                raise Stall("only interface 0 alternate setting 0")
            return b""
        if req == 10 and rt == 0x81:  # GET_INTERFACE
            return b"\x00"[:length]
        if req == 5 and rt == 0x00:  # SET_ADDRESS (meaningless here)
            return b""
        raise Stall(f"standard request 0x{req:02X} (bmRequestType 0x{rt:02X}) not supported")

    def vendor_control(self, rt: int, req: int, value: int, index: int, length: int, data: bytes) -> bytes:
        raise Stall("no vendor control requests")

    def on_configured(self, value: int) -> None:
        pass

    def reset(self) -> None:
        self.configuration = 0
        self.halted.clear()

    # -- bulk endpoints ----------------------------------------------------------------
    def bulk_out(self, ep: int, data: bytes) -> None:
        raise Stall(f"endpoint 0x{ep:02X}")

    def bulk_in(self, ep: int, length: int, timeout_s: float) -> bytes:
        raise Stall(f"endpoint 0x{ep:02X}")

    def close(self) -> None:
        pass


# ------------------------------------------------------------------------------------------
# descriptor bytes -> pyusb backend objects
# ------------------------------------------------------------------------------------------
@dataclass
class ParsedConfig:
    config: SimpleNamespace
    interfaces: list[SimpleNamespace]
    endpoints: list[list[SimpleNamespace]]  # per interface


def parse_device_descriptor(b: bytes, *, bus: int = 1, address: int = 1, speed: int = 2) -> SimpleNamespace:
    if len(b) < 18 or b[1] != 1:
        raise ValueError(f"not a device descriptor ({len(b)} bytes)")
    names = ("bLength", "bDescriptorType", "bcdUSB", "bDeviceClass", "bDeviceSubClass", "bDeviceProtocol",
             "bMaxPacketSize0", "idVendor", "idProduct", "bcdDevice", "iManufacturer", "iProduct",
             "iSerialNumber", "bNumConfigurations")
    d = SimpleNamespace(**dict(zip(names, struct.unpack("<BBHBBBBHHHBBBB", b[:18]))))
    d.bus, d.address, d.port_number, d.port_numbers, d.speed = bus, address, 1, (1,), speed
    return d


def parse_config_descriptor(b: bytes) -> ParsedConfig:
    if len(b) < 9 or b[1] != 2:
        raise ValueError(f"not a configuration descriptor ({len(b)} bytes)")
    names = ("bLength", "bDescriptorType", "wTotalLength", "bNumInterfaces", "bConfigurationValue",
             "iConfiguration", "bmAttributes", "bMaxPower")
    cfg = SimpleNamespace(**dict(zip(names, struct.unpack("<BBHBBBBB", b[:9]))), extra_descriptors=[])
    intfs: list[SimpleNamespace] = []
    eps: list[list[SimpleNamespace]] = []
    i = b[0]
    while i + 2 <= len(b):
        ln, ty = b[i], b[i + 1]
        if ln < 2 or i + ln > len(b):
            break
        chunk = b[i:i + ln]
        if ty == 4 and ln >= 9:
            n = ("bLength", "bDescriptorType", "bInterfaceNumber", "bAlternateSetting", "bNumEndpoints",
                 "bInterfaceClass", "bInterfaceSubClass", "bInterfaceProtocol", "iInterface")
            intfs.append(SimpleNamespace(**dict(zip(n, struct.unpack("<BBBBBBBBB", chunk[:9]))), extra_descriptors=[]))
            eps.append([])
        elif ty == 5 and ln >= 7 and eps:
            n = ("bLength", "bDescriptorType", "bEndpointAddress", "bmAttributes", "wMaxPacketSize", "bInterval")
            e = SimpleNamespace(**dict(zip(n, struct.unpack("<BBBBHB", chunk[:7]))), bRefresh=0, bSynchAddress=0,
                                extra_descriptors=[])
            eps[-1].append(e)
        i += ln
    return ParsedConfig(cfg, intfs, eps)
