"""USB 2.0 full-speed packet bytes, independent of any RTL: PIDs, CRC5 / CRC16, token and data
packets, and the check a host applies to what a device sends (USB 2.0 §8.3-8.4).

Shared by the transaction-level host of the full-system twin (multisonar.twin) and the cocotb
host model (tests/rtl/usb_host.py)."""

from __future__ import annotations

PID_OUT, PID_IN, PID_SOF, PID_SETUP = 0x1, 0x9, 0x5, 0xD
PID_DATA0, PID_DATA1 = 0x3, 0xB
PID_ACK, PID_NAK, PID_STALL = 0x2, 0xA, 0xE
PID_NAMES = {PID_DATA0: "DATA0", PID_DATA1: "DATA1", PID_ACK: "ACK", PID_NAK: "NAK",
             PID_STALL: "STALL", PID_OUT: "OUT", PID_IN: "IN", PID_SETUP: "SETUP", PID_SOF: "SOF"}
MAX_PACKET = 64  # full-speed bulk / control max packet size


class UsbProtocolError(AssertionError):
    """The device put something on the bus that a USB host would reject."""


def crc5(addr: int, ep: int) -> int:
    """USB CRC5 of an 11-bit token field, as placed in token byte 2 bits [7:3]."""
    bits, c = addr | (ep << 7), 0x1F
    for i in range(11):
        c = (c >> 1) ^ 0x14 if (c ^ (bits >> i)) & 1 else c >> 1
    return c ^ 0x1F


def crc16(data: bytes) -> int:
    """USB CRC16 as transmitted (inverted), low byte first on the wire."""
    c = 0xFFFF
    for byte in data:
        for i in range(8):
            c = (c >> 1) ^ 0xA001 if (c ^ (byte >> i)) & 1 else c >> 1
    return c ^ 0xFFFF


def pid_byte(pid: int) -> int:
    return pid | ((pid ^ 0xF) << 4)


def token_bytes(pid: int, addr: int, ep: int, *, bad_crc: bool = False) -> bytes:
    c = crc5(addr, ep) ^ (0x01 if bad_crc else 0)
    return bytes([pid_byte(pid), addr | ((ep & 1) << 7), (ep >> 1) | (c << 3)])


def data_bytes(pid: int, payload: bytes, *, bad_crc: bool = False) -> bytes:
    c = crc16(payload) ^ (0x8000 if bad_crc else 0)
    return bytes([pid_byte(pid)]) + payload + bytes([c & 0xFF, c >> 8])


def parse_reply(raw: bytes) -> tuple[int, bytes]:
    """(PID, payload) of a device packet; UsbProtocolError for a bad PID, length or CRC16."""
    if not raw or (raw[0] >> 4) != (raw[0] & 0xF) ^ 0xF:
        raise UsbProtocolError(f"bad PID byte in {raw.hex()}")
    pid = raw[0] & 0xF
    if pid in (PID_ACK, PID_NAK, PID_STALL):
        if len(raw) != 1:
            raise UsbProtocolError(f"handshake of {len(raw)} bytes")
        return pid, b""
    if pid in (PID_DATA0, PID_DATA1):
        if len(raw) < 3:
            raise UsbProtocolError("data packet shorter than its CRC")
        payload, got = raw[1:-2], raw[-2] | (raw[-1] << 8)
        if crc16(payload) != got:
            raise UsbProtocolError(f"CRC16 {got:#06x} != {crc16(payload):#06x} for {payload.hex()}")
        if len(payload) > MAX_PACKET:
            raise UsbProtocolError(f"data packet of {len(payload)} bytes > {MAX_PACKET}")
        return pid, payload
    raise UsbProtocolError(f"device sent PID {pid:#x}")


def bus_bits(n_bytes: int) -> int:
    """Bit times a packet of n_bytes (PID .. CRC) holds the bus: SYNC, the bytes, EOP and the
    worst-case bit stuffing (one bit in six)."""
    bits = 8 + 8 * n_bytes
    return bits + bits // 6 + 3
