"""pyusb backend that speaks USB/IP as a client: ``usb.core.find(backend=UsbipBackend(host, port))``.

Unlike a DEVLIST-only backend it imports the device and reads its **real** descriptors with
GET_DESCRIPTOR control transfers (device, configuration, strings), so ``dev.product``,
``dev.serial_number`` etc. work as with libusb. Transfers are synchronous (pyusb's model):
one URB at a time; a bulk IN that times out is unlinked, and if the device completed it in the
meantime the data is returned rather than lost. Errors map to pyusb's: timeout ->
``USBTimeoutError`` (errno ETIMEDOUT), STALL -> ``USBError`` EPIPE, lost connection ->
``USBError`` ENODEV.
"""

from __future__ import annotations

import errno
import select
import socket
import struct
import threading
import time
from types import SimpleNamespace

import usb.backend
import usb.core

from .. import protocol as P
from ..errors import DeviceNotFound
from ..urls import Connection, DeviceUrl, register_scheme
from .function import ParsedConfig, parse_config_descriptor, parse_device_descriptor
from .usbip_proto import (CMD_SUBMIT, CMD_UNLINK, DIR_IN, DIR_OUT, OP_HDR, OP_REP_DEVLIST, OP_REP_IMPORT,
                          OP_REQ_DEVLIST, OP_REQ_IMPORT, RET_SUBMIT, NOT_ISO, RET_SUBMIT_TAIL, RET_UNLINK,
                          SUBMIT_HDR, UDEV, URB_HDR, USBIP_VERSION, recv_exact)


def _nodev(msg: str) -> usb.core.USBError:
    return usb.core.USBError(f"no such device (USB/IP: {msg})", errno.ENODEV, errno.ENODEV)


class _Session:
    """One imported device: a TCP connection in the URB phase."""

    def __init__(self, host: str, port: int, busid: str, timeout: float) -> None:
        self.lock = threading.Lock()
        self.seq = 0
        self.in_flight: dict[int, int] = {}  # seqnum -> direction of URBs without their RET_SUBMIT
        try:
            self.sock = socket.create_connection((host, port), timeout=timeout)
        except OSError as e:
            raise _nodev(f"cannot connect to {host}:{port}: {e}") from None
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        try:
            self.sock.sendall(OP_HDR.pack(USBIP_VERSION, OP_REQ_IMPORT, 0) + busid.encode().ljust(32, b"\0"))
            _v, code, status = OP_HDR.unpack(recv_exact(self.sock, OP_HDR.size))
            if code != OP_REP_IMPORT or status != 0:
                raise _nodev(f"import of {busid} refused (status {status}): already attached elsewhere?")
            rec = UDEV.unpack(recv_exact(self.sock, UDEV.size))
        except usb.core.USBError:
            self.close()
            raise
        except (OSError, ConnectionError, struct.error) as e:
            self.close()
            raise _nodev(f"import failed: {e}") from None
        self.busnum, self.devnum, self.speed = rec[2], rec[3], rec[4]
        self.devid = (self.busnum << 16) | self.devnum
        self.closed = False

    def close(self) -> None:
        self.closed = True
        try:
            self.sock.close()
        except OSError:
            pass

    def _send_submit(self, ep: int, direction: int, length: int, setup: bytes = b"\0" * 8, data: bytes = b"") -> int:
        self.seq = (self.seq + 1) & 0xFFFFFFFF or 1
        hdr = URB_HDR.pack(CMD_SUBMIT, self.seq, self.devid, direction, ep & 0x7F)
        self.in_flight[self.seq] = direction
        payload = data if direction == DIR_OUT else b""
        self.sock.sendall(hdr + SUBMIT_HDR.pack(0, length, 0, NOT_ISO, 0, setup) + payload)
        return self.seq

    def _recv_ret(self, deadline: float | None) -> tuple[int, int, int, int, bytes]:
        """(command, seqnum, status, actual, data) of the next RET_*; socket.timeout past deadline."""
        if deadline is not None:  # wait for the first byte only: never cut a message in half
            ready, _, _ = select.select([self.sock], [], [], max(deadline - time.monotonic(), 0.0))
            if not ready:
                raise socket.timeout("USB/IP: no answer yet")
        self.sock.settimeout(10.0)
        # devid, direction and ep of a reply are 0 (usbip_protocol.rst): the direction is the
        # submitted URB's, looked up by its sequence number as the kernel's vhci does
        cmd, seqnum, _devid, _direction, _ep = URB_HDR.unpack(recv_exact(self.sock, URB_HDR.size))
        if cmd == RET_SUBMIT:
            status, actual, _sf, _np, _ec = RET_SUBMIT_TAIL.unpack(recv_exact(self.sock, RET_SUBMIT_TAIL.size))
            direction = self.in_flight.pop(seqnum, DIR_OUT)
            data = recv_exact(self.sock, actual) if direction == DIR_IN and actual > 0 else b""
            return cmd, seqnum, status, actual, data
        if cmd == RET_UNLINK:
            (status,) = struct.unpack(">i24x", recv_exact(self.sock, 28))
            return cmd, seqnum, status, 0, b""
        raise ConnectionError(f"unexpected USB/IP command {cmd}")

    def transfer(self, ep: int, direction: int, length: int, timeout_s: float | None, setup: bytes = b"\0" * 8,
                 data: bytes = b"") -> tuple[int, int, bytes]:
        """Submit one URB and wait; returns (status, actual, data). Raises USBTimeoutError."""
        if self.closed:
            raise _nodev("connection closed")
        with self.lock:
            try:
                seq = self._send_submit(ep, direction, length, setup, data)
                deadline = None if timeout_s is None else time.monotonic() + timeout_s
                while True:
                    try:
                        cmd, rseq, status, actual, rdata = self._recv_ret(deadline)
                    except socket.timeout:
                        return self._unlink(seq)
                    if cmd == RET_SUBMIT and rseq == seq:
                        return status, actual, rdata
                    # stray RET_UNLINK of an earlier timed-out URB: ignore
            except (OSError, ConnectionError, struct.error) as e:
                if isinstance(e, usb.core.USBError):
                    raise
                self.close()
                raise _nodev(f"connection lost: {e}") from None

    def _unlink(self, target: int) -> tuple[int, int, bytes]:
        self.seq = (self.seq + 1) & 0xFFFFFFFF or 1
        useq = self.seq
        self.sock.sendall(URB_HDR.pack(CMD_UNLINK, useq, self.devid, 0, 0) + struct.pack(">I24x", target))
        deadline = time.monotonic() + 5.0
        while True:
            try:
                cmd, rseq, status, actual, rdata = self._recv_ret(deadline)
            except socket.timeout:
                self.close()
                raise _nodev("no answer to CMD_UNLINK") from None
            if cmd == RET_SUBMIT and rseq == target:  # completed before the unlink: keep the data
                return status, actual, rdata
            if cmd == RET_UNLINK and rseq == useq:
                self.in_flight.pop(target, None)  # unlinked: no RET_SUBMIT follows
                raise usb.core.USBTimeoutError("USB/IP transfer timed out", errno.ETIMEDOUT, errno.ETIMEDOUT)


class _RemoteDev:
    def __init__(self, backend: "UsbipBackend", busid: str, info: tuple) -> None:
        self.backend, self.busid, self.info = backend, busid, info
        self.session: _Session | None = None
        self.desc: SimpleNamespace | None = None
        self.cfg: ParsedConfig | None = None

    def ensure(self) -> _Session:
        if self.session is None or self.session.closed:
            self.session = _Session(self.backend.host, self.backend.port, self.busid, self.backend.timeout)
            self.desc = None
        if self.desc is None:
            d = _ctrl_in(self.session, 0x80, 6, 0x0100, 0, 18)
            self.desc = parse_device_descriptor(d, bus=self.session.busnum, address=self.session.devnum,
                                                speed=self.session.speed)
            head = _ctrl_in(self.session, 0x80, 6, 0x0200, 0, 9)
            total = struct.unpack_from("<H", head, 2)[0]
            self.cfg = parse_config_descriptor(_ctrl_in(self.session, 0x80, 6, 0x0200, 0, total))
        return self.session


def _ctrl_in(s: _Session, rt: int, req: int, value: int, index: int, length: int) -> bytes:
    setup = struct.pack("<BBHHH", rt, req, value, index, length)
    status, _actual, data = s.transfer(0, DIR_IN, length, 5.0, setup)
    if status != 0:
        raise usb.core.USBError(f"control request 0x{req:02X} failed (status {status})", errno.EPIPE, errno.EPIPE)
    return data


class UsbipBackend(usb.backend.IBackend):
    """pyusb backend for the devices exported by a USB/IP server at host:port."""

    def __init__(self, host: str = "127.0.0.1", port: int = 3240, timeout: float = 5.0) -> None:
        self.host, self.port, self.timeout = host, int(port), timeout
        self._devs: dict[str, _RemoteDev] = {}

    def close(self) -> None:
        for d in self._devs.values():
            if d.session is not None:
                d.session.close()

    def enumerate_devices(self):
        try:
            with socket.create_connection((self.host, self.port), timeout=self.timeout) as s:
                s.sendall(OP_HDR.pack(USBIP_VERSION, OP_REQ_DEVLIST, 0))
                _v, code, status = OP_HDR.unpack(recv_exact(s, OP_HDR.size))
                if code != OP_REP_DEVLIST or status != 0:
                    return iter(())
                (n,) = struct.unpack(">I", recv_exact(s, 4))
                found = []
                for _ in range(n):
                    rec = UDEV.unpack(recv_exact(s, UDEV.size))
                    recv_exact(s, 4 * rec[-1])
                    found.append((rec[1].rstrip(b"\0").decode(), rec))
        except (OSError, ConnectionError, struct.error):
            return iter(())
        out = []
        for busid, rec in found:
            d = self._devs.get(busid)
            if d is None:
                d = self._devs[busid] = _RemoteDev(self, busid, rec)
            out.append(d)
        return iter(out)

    # descriptors: read from the device itself (imports it on first use)
    def get_device_descriptor(self, dev: _RemoteDev):
        try:
            dev.ensure()
        except usb.core.USBError:
            # exported but not importable (attached elsewhere): DEVLIST data, no strings
            rec = dev.info
            return SimpleNamespace(bLength=18, bDescriptorType=1, bcdUSB=0x200, bDeviceClass=rec[8],
                                   bDeviceSubClass=rec[9], bDeviceProtocol=rec[10], bMaxPacketSize0=64,
                                   idVendor=rec[5], idProduct=rec[6], bcdDevice=rec[7], iManufacturer=0, iProduct=0,
                                   iSerialNumber=0, bNumConfigurations=rec[12], bus=rec[2], address=rec[3],
                                   port_number=1, port_numbers=(1,), speed=rec[4])
        return dev.desc

    def get_configuration_descriptor(self, dev: _RemoteDev, config: int):
        dev.ensure()
        if config != 0:
            raise IndexError(config)
        return dev.cfg.config

    def get_interface_descriptor(self, dev: _RemoteDev, intf: int, alt: int, config: int):
        dev.ensure()
        if config != 0 or alt != 0:
            raise IndexError((intf, alt, config))
        return dev.cfg.interfaces[intf]

    def get_endpoint_descriptor(self, dev: _RemoteDev, ep: int, intf: int, alt: int, config: int):
        dev.ensure()
        if config != 0 or alt != 0:
            raise IndexError((ep, intf, alt, config))
        return dev.cfg.endpoints[intf][ep]

    def open_device(self, dev: _RemoteDev) -> _RemoteDev:
        dev.ensure()
        return dev

    def close_device(self, dev_handle: _RemoteDev) -> None:
        if dev_handle.session is not None:
            dev_handle.session.close()
            dev_handle.session = None

    def _ctrl(self, h: _RemoteDev, rt: int, req: int, value: int, index: int, data: bytes = b"") -> None:
        s = h.ensure()
        setup = struct.pack("<BBHHH", rt, req, value, index, len(data))
        status, _a, _d = s.transfer(0, DIR_OUT, len(data), 5.0, setup, data)
        if status != 0:
            raise usb.core.USBError(f"control request 0x{req:02X} failed (status {status})", errno.EPIPE, errno.EPIPE)

    def set_configuration(self, dev_handle: _RemoteDev, config_value: int) -> None:
        self._ctrl(dev_handle, 0x00, 9, config_value, 0)

    def get_configuration(self, dev_handle: _RemoteDev) -> int:
        return _ctrl_in(dev_handle.ensure(), 0x80, 8, 0, 0, 1)[0]

    def set_interface_altsetting(self, dev_handle: _RemoteDev, intf: int, altsetting: int) -> None:
        self._ctrl(dev_handle, 0x01, 11, altsetting, intf)

    def claim_interface(self, dev_handle: _RemoteDev, intf: int) -> None:
        dev_handle.ensure()

    def release_interface(self, dev_handle: _RemoteDev, intf: int) -> None:
        pass

    def clear_halt(self, dev_handle: _RemoteDev, ep: int) -> None:
        self._ctrl(dev_handle, 0x02, 1, 0, ep)

    def reset_device(self, dev_handle: _RemoteDev) -> None:
        self.close_device(dev_handle)
        dev_handle.ensure()

    def is_kernel_driver_active(self, dev_handle, intf) -> bool:
        return False

    def detach_kernel_driver(self, dev_handle, intf) -> None:
        pass

    def attach_kernel_driver(self, dev_handle, intf) -> None:
        pass

    def bulk_write(self, dev_handle: _RemoteDev, ep: int, intf: int, data, timeout: int) -> int:
        s = dev_handle.ensure()
        status, actual, _ = s.transfer(ep, DIR_OUT, len(data), (timeout or 60_000) / 1000.0, data=bytes(data))
        if status != 0:
            raise usb.core.USBError(f"bulk OUT 0x{ep:02X} failed (status {status})", errno.EPIPE, errno.EPIPE)
        return actual

    def bulk_read(self, dev_handle: _RemoteDev, ep: int, intf: int, buff, timeout: int) -> int:
        s = dev_handle.ensure()
        status, _actual, data = s.transfer(ep | 0x80, DIR_IN, len(buff), (timeout or 60_000) / 1000.0)
        if status != 0:
            code = errno.ENODEV if status == -errno.ESHUTDOWN else errno.EPIPE
            raise usb.core.USBError(f"bulk IN 0x{ep:02X} failed (status {status})", code, code)
        n = min(len(data), len(buff))
        buff[:n] = type(buff)("B", data[:n]) if hasattr(buff, "typecode") else data[:n]
        return n

    def ctrl_transfer(self, dev_handle: _RemoteDev, bmRequestType: int, bRequest: int, wValue: int, wIndex: int,
                      data, timeout: int) -> int:
        s = dev_handle.ensure()
        length = len(data) if data is not None else 0
        setup = struct.pack("<BBHHH", bmRequestType, bRequest, wValue, wIndex, length)
        t = (timeout or 60_000) / 1000.0
        if bmRequestType & 0x80:
            status, _a, out = s.transfer(0, DIR_IN, length, t, setup)
            if status != 0:
                raise usb.core.USBError(f"control IN failed (status {status})", errno.EPIPE, errno.EPIPE)
            n = min(len(out), length)
            data[:n] = type(data)("B", out[:n]) if hasattr(data, "typecode") else out[:n]
            return n
        status, _a, _ = s.transfer(0, DIR_OUT, length, t, setup, bytes(data) if data is not None else b"")
        if status != 0:
            raise usb.core.USBError(f"control OUT failed (status {status})", errno.EPIPE, errno.EPIPE)
        return length


# -- the usbip:// device URL scheme (multisonar.urls; found through the multisonar.schemes entry point)
def open_usbip(url: DeviceUrl, *, timeout_s: float = 2.0) -> Connection:
    """usbip://HOST:PORT: a device exported over USB/IP (our simulated one: multisonar serve)"""
    host, port = url.hostname or "127.0.0.1", url.port or 3240
    be = UsbipBackend(host, port, timeout=timeout_s)
    try:
        dev = usb.core.find(idVendor=P.USB_VID, idProduct=P.USB_PID, backend=be)
    except usb.core.USBError as e:
        be.close()
        raise DeviceNotFound(f"{url.url}: {e}") from None
    if dev is None:
        be.close()
        raise DeviceNotFound(f"{url.url}: no Multisonar exported at {host}:{port} (is the server running? "
                             "'multisonar serve --port PORT'), or it is attached by another client")
    return Connection(dev, cleanup=be.close)


register_scheme("usbip", open_usbip, help=open_usbip.__doc__ or "")
