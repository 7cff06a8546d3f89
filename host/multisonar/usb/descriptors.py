"""The Multisonar USB descriptors: the one source of the device's identity on the bus.

The RTL core serves them from a ROM whose contents the ``make`` gen step writes from this
module (:mod:`multisonar.tools.gen_contracts`: ``ms_usb_desc.hex`` for ``$readmemh`` and the
offsets package ``ms_usb_desc_pkg.sv``); the simulated device serves the same bytes; the twin
reads them from the RTL ROM. USB 2.0 chapter 9 (device, configuration, interface, endpoint,
string, BOS descriptors) and Microsoft OS 2.0 Descriptors (platform capability in the BOS,
descriptor set with the WinUSB compatible ID and a DeviceInterfaceGUIDs registry property,
returned by the vendor request ``bRequest = MS_VENDOR_CODE, wIndex = 7``).

The serial number is the one per-board value: 8 upper-case hex digits of a 32-bit number (the
RTL's ``SERIAL`` parameter overlays them onto the ROM image at :attr:`DescriptorSet.serial_offset`).
"""

from __future__ import annotations

import struct
import uuid
from collections.abc import Callable
from dataclasses import dataclass

from .. import protocol as P

MANUFACTURER = "Multisonar"
PRODUCT = "Multisonar 24-element sonar"
INTERFACE = f"Multisonar protocol v{P.PROTOCOL_VERSION}"
#: bcdDevice: the protocol version as major.minor BCD (1 -> 0x0100)
BCD_DEVICE = P.PROTOCOL_VERSION << 8
#: bcdUSB 2.01: a USB 2.0 device with a BOS descriptor (USB 2.0 LPM ECN; Windows reads the BOS then)
BCD_USB = 0x0201
MAX_POWER_MA = 100
#: bRequest of the MS OS 2.0 descriptor-set vendor request (the BOS platform capability names it)
MS_VENDOR_CODE = 0x4D
MS_OS_20_INDEX = 7  #: wIndex of that request (MS_OS_20_DESCRIPTOR_INDEX)
MS_OS_20_PLATFORM_UUID = uuid.UUID("D8DD60DF-4589-4CC7-9CD2-659D9E648A9F")
WINDOWS_8_1 = 0x06030000  #: dwWindowsVersion: the minimum version for MS OS 2.0 descriptors
#: DeviceInterfaceGUIDs: WinUSB's interface class GUID for this device (fixed; libusb finds it)
DEVICE_INTERFACE_GUID = "{8C6A1E2D-5B3F-4A7E-9D21-6F0B3C4E5A71}"
LANGID_EN_US = 0x0409
DEFAULT_SERIAL = 1
ROM_BYTES = 512  #: the RTL ROM's size (9 address bits); the image is padded with zeros


def serial_string(serial: int) -> str:
    """The serial-number string of a board: 8 upper-case hex digits."""
    if not 0 <= serial <= 0xFFFFFFFF:
        raise ValueError(f"serial {serial} does not fit 32 bits")
    return f"{serial:08X}"


def string_descriptor(s: str) -> bytes:
    b = s.encode("utf-16-le")
    return bytes([2 + len(b), 3]) + b


def _ms_os_20_set() -> bytes:
    """MS OS 2.0 descriptor set (non-composite: features at set level): header, compatible ID
    WINUSB, registry property DeviceInterfaceGUIDs (REG_MULTI_SZ)."""
    compat = struct.pack("<HH8s8s", 20, 0x0003, b"WINUSB", b"")
    name = "DeviceInterfaceGUIDs\0".encode("utf-16-le")
    data = (DEVICE_INTERFACE_GUID + "\0\0").encode("utf-16-le")
    prop_len = 10 + len(name) + len(data)
    prop = struct.pack("<HHHH", prop_len, 0x0004, 7, len(name)) + name + struct.pack("<H", len(data)) + data
    total = 10 + len(compat) + len(prop)
    return struct.pack("<HHIH", 10, 0x0000, WINDOWS_8_1, total) + compat + prop


def _bos(ms_set_len: int) -> bytes:
    cap = (struct.pack("<BBBB", 28, 0x10, 0x05, 0) + MS_OS_20_PLATFORM_UUID.bytes_le
           + struct.pack("<IHBB", WINDOWS_8_1, ms_set_len, MS_VENDOR_CODE, 0))
    return struct.pack("<BBHB", 5, 0x0F, 5 + len(cap), 1) + cap


@dataclass(frozen=True)
class DescriptorSet:
    """Every descriptor the device answers, as bytes."""

    device: bytes
    config: bytes  #: configuration + interface + endpoints (wTotalLength bytes)
    strings: tuple[bytes, ...]  #: index 0: LANGID list; 1 manufacturer, 2 product, 3 serial, 4 interface
    bos: bytes
    ms_os_20: bytes  #: the MS OS 2.0 descriptor set (vendor request MS_VENDOR_CODE, wIndex 7)
    vendor_code: int = MS_VENDOR_CODE

    def parts(self) -> list[tuple[str, bytes]]:
        """The ROM's order: device, configuration, strings 0..n, BOS, MS OS 2.0 set."""
        return ([("dev", self.device), ("cfg", self.config)]
                + [(f"str{i}", s) for i, s in enumerate(self.strings)]
                + [("bos", self.bos), ("msos", self.ms_os_20)])

    def rom(self) -> tuple[bytes, dict[str, tuple[int, int]]]:
        """The ROM image (padded to ROM_BYTES) and each descriptor's (offset, length)."""
        image, offsets = b"", {}
        for name, b in self.parts():
            offsets[name] = (len(image), len(b))
            image += b
        if len(image) > ROM_BYTES:
            raise ValueError(f"descriptors need {len(image)} bytes, the ROM has {ROM_BYTES}")
        return image + bytes(ROM_BYTES - len(image)), offsets

    @property
    def serial_offset(self) -> int:
        """ROM offset of the serial string's first character (UTF-16LE: characters 2 bytes apart)."""
        return self.rom()[1]["str3"][0] + 2

    def get_descriptor(self, dtype: int, index: int) -> bytes | None:
        """GET_DESCRIPTOR's answer (whole descriptor) or None (the device STALLs)."""
        if dtype == 1 and index == 0:
            return self.device
        if dtype == 2 and index == 0:
            return self.config
        if dtype == 3 and index < len(self.strings):
            return self.strings[index]
        if dtype == 15 and index == 0:
            return self.bos
        return None


def multisonar_descriptors(serial: int = DEFAULT_SERIAL) -> DescriptorSet:
    """The Multisonar device's descriptors with board serial number ``serial``."""
    dev = struct.pack("<BBHBBBBHHHBBBB", 18, 1, BCD_USB, 0, 0, 0, P.USB_MPS, P.USB_VID, P.USB_PID, BCD_DEVICE,
                      1, 2, 3, 1)
    intf = struct.pack("<BBBBBBBBB", 9, 4, 0, 0, 2, P.INTERFACE_CLASS, 0, 0, 4)
    eps = b"".join(struct.pack("<BBBBHB", 7, 5, ep, 0x02, P.USB_MPS, 0) for ep in (P.EP_OUT, P.EP_IN))
    total = 9 + len(intf) + len(eps)
    cfg = struct.pack("<BBHBBBBB", 9, 2, total, 1, 1, 0, 0x80, MAX_POWER_MA // 2) + intf + eps
    strings = (struct.pack("<BBH", 4, 3, LANGID_EN_US),) + tuple(
        string_descriptor(s) for s in (MANUFACTURER, PRODUCT, serial_string(serial), INTERFACE))
    ms_set = _ms_os_20_set()
    return DescriptorSet(dev, cfg, strings, _bos(len(ms_set)), ms_set)


def read_descriptor_set(control_in: Callable[[int, int, int, int, int], bytes]) -> DescriptorSet:
    """Read a device's whole descriptor set the way a host does, through ``control_in(bmRequestType,
    bRequest, wValue, wIndex, wLength) -> bytes``: device, configuration (9 bytes, then
    wTotalLength), every string the device and interface descriptors name, the BOS and, when
    its MS OS 2.0 platform capability names a vendor code, the MS OS 2.0 descriptor set."""
    dev = control_in(0x80, 6, 0x0100, 0, 18)
    head = control_in(0x80, 6, 0x0200, 0, 9)
    cfg = control_in(0x80, 6, 0x0200, 0, struct.unpack_from("<H", head, 2)[0])
    n_strings = 1 + max(dev[14], dev[15], dev[16], cfg[9 + 8] if len(cfg) >= 18 else 0)
    strings = tuple(control_in(0x80, 6, 0x0300 | i, LANGID_EN_US if i else 0, 255) for i in range(n_strings))
    bos_head = control_in(0x80, 6, 0x0F00, 0, 5)
    bos = control_in(0x80, 6, 0x0F00, 0, struct.unpack_from("<H", bos_head, 2)[0])
    ms_set, code = b"", MS_VENDOR_CODE
    cap = bos[5:]
    if len(cap) >= 28 and cap[1:3] == b"\x10\x05" and cap[4:20] == MS_OS_20_PLATFORM_UUID.bytes_le:
        set_len, code = struct.unpack_from("<HB", cap, 24)
        ms_set = control_in(0xC0, code, 0, MS_OS_20_INDEX, set_len)
    return DescriptorSet(dev, cfg, strings, bos, ms_set, code)
