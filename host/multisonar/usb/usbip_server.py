"""A small USB/IP server (protocol version 1.1.1, as Linux ``usbip``) for UsbFunction objects.

It exports one device (bus id ``1-1``) on a TCP port of 127.0.0.1 by default. Linux's
``usbip attach`` or our pyusb client (:mod:`multisonar.usb.usbip_client`) import it; one
importer at a time, and the device is exportable again when that connection closes. A
client that closes and at once re-imports is not refused for the old connection: an import
that finds the holder's socket already at end-of-file waits (at most ``RELEASE_GRACE_S``)
for that connection's teardown instead of racing it.

URB handling: control and bulk OUT URBs run at once in the connection's reader thread; bulk
IN URBs queue per connection and a worker thread polls the function (``bulk_in`` with a short
timeout, i.e. the device NAKs) until data arrives or the host unlinks the URB. An unlink that
races a completion answers the completion first and then RET_UNLINK with status 0, so no IN
data is ever lost.

All multi-byte fields on the wire are big-endian (network order).
"""

from __future__ import annotations

import errno
import select
import socket
import struct
import sys
import threading
import traceback
from collections import deque
from dataclasses import dataclass

from ..stopsignals import stop_on_signals
from .function import Disconnected, Stall, UsbFunction, UsbTimeout, parse_config_descriptor, parse_device_descriptor

# the wire format, shared with the client (multisonar.usb.usbip_proto)
from .usbip_proto import (CMD_SUBMIT, CMD_UNLINK, DIR_IN, DIR_OUT, OP_HDR, OP_REP_DEVLIST,  # noqa: F401 - re-exported
                          OP_REP_IMPORT, OP_REQ_DEVLIST, OP_REQ_IMPORT, RET_SUBMIT, RET_SUBMIT_TAIL, RET_UNLINK,
                          SUBMIT_HDR, UDEV, URB_HDR, USBIP_VERSION, NOT_ISO, recv_exact)

RELEASE_GRACE_S = 2.0  # longest wait for a closed importer's teardown (unlink the IN URB, reset)


def udev_record(fn: UsbFunction, busid: str, busnum: int, devnum: int) -> bytes:
    d = parse_device_descriptor(fn.descriptors.device)
    c = parse_config_descriptor(fn.descriptors.config)
    return UDEV.pack(f"/sys/devices/multisonar/{busid}".encode(), busid.encode(), busnum, devnum, fn.speed,
                     d.idVendor, d.idProduct, d.bcdDevice, d.bDeviceClass, d.bDeviceSubClass, d.bDeviceProtocol,
                     c.config.bConfigurationValue, d.bNumConfigurations, c.config.bNumInterfaces)


@dataclass
class _InUrb:
    seqnum: int
    ep: int
    length: int
    state: str = "queued"  # queued | polling | done
    unlink_seq: int | None = None  # seqnum of a CMD_UNLINK waiting for this URB


class UsbipServer:
    """Serve ``function`` over USB/IP on ``host:port`` (port 0: a free port, see ``.port``)."""

    def __init__(self, function: UsbFunction, host: str = "127.0.0.1", port: int = 0, busid: str = "1-1") -> None:
        self.fn, self.busid = function, busid
        self.busnum, self.devnum = 1, 2
        self._sock = socket.create_server((host, port))
        self._sock.settimeout(0.1)  # the accept loop polls the stop flag
        self.host, self.port = self._sock.getsockname()[:2]
        self._stop = threading.Event()
        self._imported = threading.Lock()
        self._importer: socket.socket | None = None  # the connection holding ``_imported``
        self._threads: list[threading.Thread] = []
        self._conns: list[socket.socket] = []
        self.urbs = 0
        #: the function's first unexpected exception; from then on every URB is answered
        #: -ESHUTDOWN (the client sees the device gone) without calling the function again
        self.failure: BaseException | None = None

    def _status(self, e: Exception) -> int:
        """The URB status for the function's exception: a stall or time-out EPIPE, a disconnect
        ESHUTDOWN; anything else is a broken function (kept in ``failure``, printed once): also
        ESHUTDOWN, for this URB and every later one."""
        if isinstance(e, (Stall, UsbTimeout)):
            return -errno.EPIPE
        if not isinstance(e, Disconnected) and self.failure is None:
            self.failure = e
            sys.stderr.write(f"usbip server: the device function failed, answering -ESHUTDOWN from now on: "
                             f"{''.join(traceback.format_exception_only(e)).strip()}\n")
        return -errno.ESHUTDOWN

    @property
    def url(self) -> str:
        return f"usbip://{self.host}:{self.port}"

    def start(self) -> "UsbipServer":
        t = threading.Thread(target=self._accept_loop, name=f"usbip-accept-{self.port}", daemon=True)
        t.start()
        self._threads.append(t)
        return self

    def close(self) -> None:
        self._stop.set()
        try:
            self._sock.close()
        except OSError:
            pass
        for c in list(self._conns):
            try:
                c.shutdown(socket.SHUT_RDWR)
                c.close()
            except OSError:
                pass
        for t in self._threads:
            if t is not threading.current_thread():
                t.join(timeout=2.0)

    def __enter__(self) -> "UsbipServer":
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def request_stop(self) -> None:
        """Make serve_forever return (within 0.5 s) and close the server; safe in a signal handler."""
        self._stop.set()

    def serve_forever(self) -> None:
        self.start()
        try:
            while not self._stop.wait(0.5):
                pass
        finally:
            self.close()

    # -- connections -------------------------------------------------------------------------
    def _accept_loop(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._sock.accept()
            except socket.timeout:
                continue
            except OSError:
                return
            conn.settimeout(None)
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._conns.append(conn)
            t = threading.Thread(target=self._serve_conn, args=(conn,), name="usbip-conn", daemon=True)
            t.start()
            self._threads = [x for x in self._threads if x.is_alive()] + [t]

    def _serve_conn(self, conn: socket.socket) -> None:
        try:
            version, code, _status = OP_HDR.unpack(recv_exact(conn, OP_HDR.size))
            if code == OP_REQ_DEVLIST:
                rec = udev_record(self.fn, self.busid, self.busnum, self.devnum)
                c = parse_config_descriptor(self.fn.descriptors.config)
                intfs = b"".join(struct.pack(">BBBx", i.bInterfaceClass, i.bInterfaceSubClass, i.bInterfaceProtocol)
                                 for i in c.interfaces)
                conn.sendall(OP_HDR.pack(USBIP_VERSION, OP_REP_DEVLIST, 0) + struct.pack(">I", 1) + rec + intfs)
            elif code == OP_REQ_IMPORT:
                busid = recv_exact(conn, 32).rstrip(b"\0").decode(errors="replace")
                if busid != self.busid or not self._acquire_import():
                    conn.sendall(OP_HDR.pack(USBIP_VERSION, OP_REP_IMPORT, 1))
                    return
                self._importer = conn
                try:
                    conn.sendall(OP_HDR.pack(USBIP_VERSION, OP_REP_IMPORT, 0)
                                 + udev_record(self.fn, self.busid, self.busnum, self.devnum))
                    self._urb_loop(conn)
                finally:
                    self.fn.reset()
                    self._imported.release()  # ``_importer`` keeps the closed socket: see _acquire_import
        except (ConnectionError, OSError, struct.error):
            pass
        finally:
            try:
                conn.close()
            except OSError:
                pass
            if conn in self._conns:
                self._conns.remove(conn)

    def _acquire_import(self) -> bool:
        """Take the one import slot; refuse a live holder at once, wait out a closed one."""
        if self._imported.acquire(blocking=False):
            return True
        holder = self._importer
        return holder is not None and _peer_closed(holder) and self._imported.acquire(timeout=RELEASE_GRACE_S)

    def _urb_loop(self, conn: socket.socket) -> None:
        send_lock = threading.Lock()
        cv = threading.Condition()
        queue: deque[_InUrb] = deque()
        gone = threading.Event()

        def send(b: bytes) -> None:
            with send_lock:
                conn.sendall(b)

        def ret_submit(seqnum: int, ep: int, direction: int, status: int, data: bytes = b"", actual: int = 0) -> None:
            # devid, direction and ep "shall be set to 0" in a reply (usbip_protocol.rst); the
            # URB's direction only decides actual_length (OUT: bytes taken; IN: bytes returned)
            send(URB_HDR.pack(RET_SUBMIT, seqnum, 0, 0, 0)
                 + RET_SUBMIT_TAIL.pack(status, actual if direction == DIR_OUT else len(data), 0, NOT_ISO, 0) + data)

        def ret_unlink(seqnum: int, status: int) -> None:
            send(URB_HDR.pack(RET_UNLINK, seqnum, 0, 0, 0) + struct.pack(">i24x", status))

        def worker() -> None:
            while not gone.is_set() and not self._stop.is_set():
                with cv:
                    while not queue and not gone.is_set():
                        cv.wait(0.2)
                    if gone.is_set():
                        return
                    urb = queue[0]
                    urb.state = "polling"
                data, status = b"", 0
                while True:
                    if self.failure is not None:
                        data, status = b"", -errno.ESHUTDOWN
                        break
                    try:
                        data = self.fn.bulk_in(urb.ep | 0x80, urb.length, 0.02)
                        break
                    except UsbTimeout:
                        with cv:
                            if urb.unlink_seq is not None or gone.is_set() or self._stop.is_set():
                                data, status = b"", None  # type: ignore[assignment]
                                break
                    except Exception as e:  # noqa: BLE001 (a stall, a disconnect or a broken function)
                        data, status = b"", self._status(e)
                        break
                with cv:
                    queue.popleft()
                    urb.state = "done"
                    unlink = urb.unlink_seq
                try:
                    if status is not None:
                        ret_submit(urb.seqnum, urb.ep, DIR_IN, status, data)
                        if unlink is not None:
                            ret_unlink(unlink, 0)
                    elif unlink is not None:
                        ret_unlink(unlink, -errno.ECONNRESET)
                except OSError:
                    gone.set()
                    return

        wt = threading.Thread(target=worker, name="usbip-in", daemon=True)
        wt.start()
        try:
            while not self._stop.is_set():
                cmd, seqnum, devid, direction, ep = URB_HDR.unpack(recv_exact(conn, URB_HDR.size))
                self.urbs += 1
                if cmd == CMD_SUBMIT:
                    flags, length, _sf, _np, _iv, setup = SUBMIT_HDR.unpack(recv_exact(conn, SUBMIT_HDR.size))
                    data = recv_exact(conn, length) if direction == DIR_OUT and length > 0 else b""
                    if self.failure is not None and (ep == 0 or direction == DIR_OUT):
                        ret_submit(seqnum, ep, direction, -errno.ESHUTDOWN)
                    elif ep == 0:
                        try:
                            out = self.fn.control(setup, data)
                            ret_submit(seqnum, 0, direction, 0, out[:length] if direction == DIR_IN else b"", len(data))
                        except Exception as e:  # noqa: BLE001
                            ret_submit(seqnum, 0, direction, self._status(e))
                    elif direction == DIR_OUT:
                        try:
                            self.fn.bulk_out(ep, data)
                            ret_submit(seqnum, ep, DIR_OUT, 0, actual=len(data))
                        except Exception as e:  # noqa: BLE001
                            ret_submit(seqnum, ep, DIR_OUT, self._status(e))
                    else:
                        with cv:
                            queue.append(_InUrb(seqnum, ep, length))
                            cv.notify()
                elif cmd == CMD_UNLINK:
                    (target,) = struct.unpack(">I24x", recv_exact(conn, 28))
                    with cv:
                        urb = next((u for u in queue if u.seqnum == target), None)
                        if urb is None:
                            reply = 0  # already completed
                        elif urb.state == "queued":
                            queue.remove(urb)
                            reply = -errno.ECONNRESET
                        else:
                            urb.unlink_seq = seqnum  # the worker answers
                            reply = None
                    if reply is not None:
                        ret_unlink(seqnum, reply)
                else:
                    return  # protocol violation: drop the connection
        finally:
            gone.set()
            with cv:
                cv.notify_all()
            wt.join(timeout=2.0)


def _peer_closed(conn: socket.socket) -> bool:
    """True if the peer has closed ``conn`` (end-of-file is waiting) or it is already torn down.

    Only peeks: the connection's own reader thread still consumes the bytes."""
    try:
        readable, _, _ = select.select([conn], [], [], 0)
        return bool(readable) and conn.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) == b""
    except (OSError, ValueError):  # closed under us (fileno -1) or reset: gone either way
        return True


def main(argv: list[str] | None = None) -> int:
    """``python -m multisonar.usb.usbip_server --scene corridor --port 3240``"""
    import argparse
    from urllib.parse import quote, urlencode

    from ..urls import make_model

    ap = argparse.ArgumentParser(description="Serve the simulated Multisonar over USB/IP on 127.0.0.1")
    ap.add_argument("--scene", default="corridor")
    ap.add_argument("--port", type=int, default=3240)
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--rate", type=float, default=None, help="x real time (default: lock-step with the host)")
    ap.add_argument("--source", default="model", choices=("model", "replay"))
    a = ap.parse_args(argv)
    # the sim:// scheme's model (multisonar.urls), so that the server does not import the simulated device
    query = urlencode({"source": a.source, **({"rate": a.rate} if a.rate is not None else {})})
    srv = UsbipServer(make_model(f"sim://{quote(a.scene, safe='')}?{query}").function, a.host, a.port)
    with stop_on_signals(srv.request_stop):  # installed before the "serving" line a supervisor waits for
        print(f"serving simulated Multisonar ({a.scene}) at {srv.url}; Ctrl-C stops", flush=True)
        srv.serve_forever()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
