"""A USB device as seen from its endpoints: descriptors, control requests, bulk callbacks.

:class:`UsbFunction` is what both transports serve: the in-process pyusb backend
(:mod:`multisonar.usb.inproc`) calls it directly, the USB/IP server
(:mod:`multisonar.usb.usbip_server`) calls it per URB. Subclasses implement
:meth:`bulk_out` and :meth:`bulk_in` (the simulated Multisonar: :mod:`multisonar.simdevice`;
an RTL twin can implement the same three methods at transaction level).

Descriptors are bytes, built once; hosts read them with GET_DESCRIPTOR like from a real
device, and :func:`parse_descriptors` turns them into the objects pyusb's backend API wants.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from types import SimpleNamespace


class Stall(Exception):
    """The endpoint answers STALL (unsupported or malformed request)."""


class UsbTimeout(Exception):
    """No data within the timeout (the device NAKed)."""


class Disconnected(Exception):
    """The device is gone (unplugged, server closed)."""


@dataclass
class Identity:
    vid: int
    pid: int
    manufacturer: str
    product: str
    serial: str
    interface: str = ""
    bcd_device: int = 0x0100
    interface_class: int = 0xFF
    ep_out: int = 0x01
    ep_in: int = 0x81
    mps: int = 64
    max_power_ma: int = 100


def _string_desc(s: str) -> bytes:
    b = s.encode("utf-16-le")
    return bytes([2 + len(b), 3]) + b


@dataclass
class Descriptors:
    device: bytes
    config: bytes
    strings: dict[int, bytes] = field(default_factory=dict)  # index -> descriptor (0 = langids)

    @classmethod
    def build(cls, ident: Identity) -> "Descriptors":
        strs = [ident.manufacturer, ident.product, ident.serial, ident.interface]
        dev = struct.pack("<BBHBBBBHHHBBBB", 18, 1, 0x0200, 0, 0, 0, 64, ident.vid, ident.pid, ident.bcd_device,
                          1, 2, 3, 1)
        intf = struct.pack("<BBBBBBBBB", 9, 4, 0, 0, 2, ident.interface_class, 0, 0, 4 if ident.interface else 0)
        eps = b"".join(struct.pack("<BBBBHB", 7, 5, ep, 0x02, ident.mps, 0) for ep in (ident.ep_out, ident.ep_in))
        total = 9 + len(intf) + len(eps)
        cfg = struct.pack("<BBHBBBBB", 9, 2, total, 1, 1, 0, 0x80, ident.max_power_ma // 2) + intf + eps
        strings = {0: bytes([4, 3, 0x09, 0x04])}
        for i, s in enumerate(strs, start=1):
            if s:
                strings[i] = _string_desc(s)
        return cls(dev, cfg, strings)


class UsbFunction:
    """Endpoint-level device model. Standard control requests are handled here."""

    speed: int = 2  # usb.util.SPEED_FULL

    def __init__(self, ident: Identity) -> None:
        self.ident = ident
        self.descriptors = Descriptors.build(ident)
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
        if kind != 0:
            return self.vendor_control(rt, req, value, index, length, data)
        d = self.descriptors
        if req == 6 and rt == 0x80:  # GET_DESCRIPTOR
            dtype, didx = value >> 8, value & 0xFF
            if dtype == 1:
                out = d.device
            elif dtype == 2 and didx == 0:
                out = d.config
            elif dtype == 3 and didx in d.strings:
                out = d.strings[didx]
            else:
                raise Stall(f"no descriptor type {dtype} index {didx}")
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
