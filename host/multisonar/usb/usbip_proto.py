"""USB/IP wire format (protocol version 1.1.1, as Linux ``usbip``) shared by our server
(:mod:`multisonar.usb.usbip_server`) and pyusb client backend
(:mod:`multisonar.usb.usbip_client`), so that neither imports the other.

All multi-byte fields on the wire are big-endian (network order).
"""

from __future__ import annotations

import socket
import struct

USBIP_VERSION = 0x0111
OP_REQ_DEVLIST, OP_REP_DEVLIST = 0x8005, 0x0005
OP_REQ_IMPORT, OP_REP_IMPORT = 0x8003, 0x0003
CMD_SUBMIT, CMD_UNLINK, RET_SUBMIT, RET_UNLINK = 1, 2, 3, 4
DIR_OUT, DIR_IN = 0, 1
OP_HDR = struct.Struct(">HHI")
URB_HDR = struct.Struct(">IIIII")  # command, seqnum, devid, direction, ep
SUBMIT_HDR = struct.Struct(">IIIiI8s")  # flags, buffer length, start frame, packets, interval, setup
RET_SUBMIT_TAIL = struct.Struct(">iiiii8x")  # status, actual length, start frame, packets, errors
#: number_of_packets of a transfer that is not isochronous (CMD_SUBMIT and RET_SUBMIT: 0xffffffff)
NOT_ISO = -1
UDEV = struct.Struct(">256s32sIIIHHHBBBBBB")


def recv_exact(sock: socket.socket, n: int) -> bytes:
    buf = bytearray()
    while len(buf) < n:
        chunk = sock.recv(n - len(buf))
        if not chunk:
            raise ConnectionError("USB/IP peer closed the connection")
        buf += chunk
    return bytes(buf)
