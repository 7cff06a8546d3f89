"""One source per contract (issue #29): the generated firmware header, RTL packages and USB
descriptor ROM agree with multisonar.protocol / multisonar.usb.descriptors, and the simulated
device answers as the board does (descriptors, power-up table)."""

from __future__ import annotations

import re
import shutil
import struct
import subprocess
from pathlib import Path

import pytest

from multisonar import protocol as P
from multisonar.simdevice import SimDevice
from multisonar.tools import gen_contracts
from multisonar.tools.fw_schedule import TEMPERATURE_C, power_up_writes
from multisonar.usb.descriptors import (DescriptorSet, multisonar_descriptors, read_descriptor_set,
                                        serial_string)

ROOT = Path(__file__).resolve().parents[1]
GEN = ROOT / "build" / "gen"


def _control_in(fn):
    return lambda rt, req, value, index, length: fn.control(struct.pack("<BBHHH", rt, req, value, index, length))


def _rom_image() -> tuple[bytes, dict[str, tuple[int, int]], int]:
    """The generated ROM image and the offsets package as the RTL reads them."""
    image = bytes(int(line, 16) for line in (GEN / "rtl/ms_usb_desc.hex").read_text().split())
    pkg = (GEN / "rtl/ms_usb_desc_pkg.sv").read_text()
    vals = {k: int(v) for k, v in re.findall(r"localparam int (\w+) = (\d+);", pkg)}
    offsets = {k[5:-4].lower(): (v, vals[k[:-4] + "_LEN"]) for k, v in vals.items()
               if k.startswith("DESC_") and k.endswith("_OFF") and k != "DESC_SERIAL_OFF"}
    return image, offsets, vals["DESC_SERIAL_OFF"]


def test_generated_files_are_current(tmp_path):
    """build/gen holds exactly what the generator writes from today's sources (make's gen step
    ran after the last change); only the ROM path inside the package differs."""
    gen_contracts.generate(tmp_path)
    for rel in ("firmware/ms_protocol.h", "firmware/ms_geom_reasons.h", "rtl/ms_protocol_pkg.sv",
                "rtl/ms_usb_desc.hex", "firmware/ms_event_word.h", "rtl/ms_event_pkg.sv"):
        assert (tmp_path / rel).read_text() == (GEN / rel).read_text(), rel
    strip = re.compile(r'DESC_HEX = "[^"]*"')
    assert strip.sub("", (tmp_path / "rtl/ms_usb_desc_pkg.sv").read_text()) == \
        strip.sub("", (GEN / "rtl/ms_usb_desc_pkg.sv").read_text())


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs a host C compiler")
def test_firmware_header_values_equal_the_protocol_module(tmp_path):
    """Compile ms_protocol.h and print every constant: each equals multisonar.protocol's."""
    want: dict[str, int] = {"MS_PROTOCOL_VERSION": P.PROTOCOL_VERSION, "MS_MAX_PAYLOAD": P.MAX_PAYLOAD,
                            "MS_HEADER_SIZE": P.HEADER_SIZE, "MS_CRC_SIZE": P.CRC_SIZE,
                            "MS_FRAME_TYPE": P.FRAME_TYPE, "MS_REPLY_BIT": P.REPLY_BIT,
                            "MS_ERROR_REPLY_TYPE": P.ERROR_REPLY_TYPE, "MS_DEVICE_INFO_SIZE": P.INFO.size,
                            "MS_MAGIC_COMMAND": struct.unpack("<H", P.MAGIC_COMMAND)[0],
                            "MS_MAGIC_REPLY": struct.unpack("<H", P.MAGIC_REPLY)[0],
                            "MS_MAGIC_FRAME": struct.unpack("<H", P.MAGIC_FRAME)[0],
                            "MS_TOF_GATED": P.TOF_GATED, "MS_TOF_INIT_PING": P.TOF_INIT_PING,
                            "MS_FRAME_GEO": P.FRAME_GEO, "MS_FRAME_CUT": P.FRAME_CUT,
                            "MS_OP_COUNT": max(P.Opcode) + 1, "MS_COUNTER_COUNT": len(P.COUNTERS_FIELDS),
                            "MS_FW_STAT_COUNT": len(P.FW_STATS_FIELDS)}
    want |= {f"MS_OP_{m.name}": int(m) for m in P.Opcode}
    want |= {f"MS_ST_{m.name}": int(m) for m in P.Status}
    want |= {f"MS_PARAM_{m.name}": int(m) for m in P.Param}
    want |= {f"MS_CFG_ERROR_{m.name}": int(m) for m in P.CfgError}
    want |= {f"MS_COUNTER_{f.upper()}": i for i, f in enumerate(P.COUNTERS_FIELDS)}
    want |= {f"MS_FW_STAT_{f.upper()}": i for i, f in enumerate(P.FW_STATS_FIELDS)}
    for p, (lo, hi) in P.PARAM_RANGE.items():
        want |= {f"MS_PARAM_{p.name}_MIN": lo, f"MS_PARAM_{p.name}_MAX": hi}
    want["MS_PARAM_BUSY_WHILE_RUNNING"] = sum(1 << p for p in P.PARAM_BUSY_WHILE_RUNNING)
    src = tmp_path / "dump.c"
    src.write_text('#include <stdio.h>\n#include "ms_protocol.h"\n'
                   "static const long long lo[MS_PARAM_COUNT] = MS_PARAM_MINS, hi[MS_PARAM_COUNT] = MS_PARAM_MAXS;\n"
                   "int main(void) {\n"
                   + "".join(f'    printf("{k} %lld\\n", (long long)({k}));\n' for k in want)
                   + '    for (int i = 0; i < MS_PARAM_COUNT; i++) printf("range%d %lld %lld\\n", i, lo[i], hi[i]);\n'
                   + "    return 0;\n}\n")
    exe = tmp_path / "dump"
    subprocess.run(["gcc", "-std=c11", "-Wall", "-Werror", f"-I{GEN / 'firmware'}", str(src), "-o", str(exe)],
                   check=True)
    got = dict(line.split(" ", 1) for line in subprocess.run([str(exe)], check=True, capture_output=True,
                                                             text=True).stdout.splitlines())
    assert {k: int(got[k]) for k in want} == want
    for p, (lo, hi) in P.PARAM_RANGE.items():
        assert got[f"range{int(p)}"] == f"{lo} {hi}"


def test_rtl_package_values_equal_the_protocol_module():
    pkg = (GEN / "rtl/ms_protocol_pkg.sv").read_text()
    vals = {k: int(v.replace("'h", ""), 16 if "'h" in v else 10)
            for k, v in re.findall(r"localparam int (\w+)\s*= ([0-9'hA-Fa-f]+);", pkg)}
    assert vals == {"PROTOCOL_VERSION": P.PROTOCOL_VERSION, "HEADER_SIZE": P.HEADER_SIZE, "CRC_SIZE": P.CRC_SIZE,
                    "MAX_PAYLOAD": P.MAX_PAYLOAD, "USB_VID": P.USB_VID, "USB_PID": P.USB_PID,
                    "USB_MPS": P.USB_MPS}


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs a host C compiler")
def test_firmware_event_word_reader_unpacks_what_the_model_packs(tmp_path):
    """ms_event_word.h's readers, compiled, take random ToF events, pulse and cancel records packed
    by the golden model (the scheduler's program writes the same words: RTL = model) apart field
    by field, as the firmware's two 32-bit halves; the flag bits and the overflow bit too."""
    import random

    from multisonar import event_word as E
    from multisonar.fastfiring import PulseStart, SensorCancel, ToFEvent

    rng = random.Random(29)
    words: list[tuple[str, int, dict[str, int]]] = []
    for _ in range(200):
        ev = ToFEvent(0, rng.randrange(8), rng.randrange(256), rng.randrange(24), rng.randrange(1 << 24),
                      *(bool(rng.getrandbits(1)) for _ in range(5)))
        w = ev.pack() | (E.EVENT_OVERFLOW_BIT if rng.getrandbits(1) else 0)
        kind = sum(int(getattr(ev, n)) << k for k, n in enumerate(("in_window", "first_echo", "window_empty",
                                                                   "init_ping")))
        words.append(("EV", w, {"TOF": ev.tof, "RX": ev.rx, "SEQ": ev.seq, "SENSOR": ev.sensor, "KIND": kind}))
        ps = PulseStart(0, rng.randrange(8), rng.randrange(1 << 16), rng.randrange(1 << 32), bool(rng.getrandbits(1)),
                        rng.randrange(32))
        words.append(("PULSE", ps.pack(), {"T0": ps.t0, "N_WIN": ps.n_win, "SENSOR": ps.sensor,
                                           "INIT_PING": int(ps.init_ping), "ID": ps.pulse_id}))
        sc = SensorCancel(rng.randrange(1 << 32), rng.randrange(8))
        words.append(("CANCEL", sc.pack(), {"TICK": sc.tick, "SENSOR": sc.sensor}))
    bits = ("RECORD", "CANCEL", "OVF", "GATED")
    src = tmp_path / "ev.c"
    body = []
    for i, (kind, w, fields) in enumerate(words):
        lo, hi = w & 0xFFFFFFFF, w >> 32
        for f in fields:
            body.append(f'    printf("{i} {f} %lu\\n", (unsigned long)MS_{kind}_{f}({lo}u, {hi}u));')
        for b in bits:
            body.append(f'    printf("{i} {b} %d\\n", ({hi}u & MS_EVH_{b}) != 0);')
    src.write_text('#include <stdio.h>\n#include "ms_event_word.h"\nint main(void) {\n' + "\n".join(body)
                   + "\n    return 0;\n}\n")
    exe = tmp_path / "ev"
    subprocess.run(["gcc", "-std=c11", "-Wall", "-Werror", f"-I{GEN / 'firmware'}", str(src), "-o", str(exe)],
                   check=True)
    got = {tuple(line.split()[:2]): int(line.split()[2]) for line in
           subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout.splitlines()}
    for i, (kind, w, fields) in enumerate(words):
        for f, v in fields.items():
            assert got[(str(i), f)] == v, (kind, hex(w), f)
        want = {"RECORD": w >> 62 & 1, "CANCEL": w >> 61 & 1, "OVF": int(bool(w & E.EVENT_OVERFLOW_BIT)),
                "GATED": w >> E.EVENT_FIELDS["gated"][0] & 1}  # (a ToF event's; a record's pulse id bit)
        assert {b: got[(str(i), b)] for b in bits} == want, (kind, hex(w))
    pkg = (GEN / "rtl/ms_event_pkg.sv").read_text()
    vals = {k: int(v) for k, v in re.findall(r"localparam int (\w+)\s*= (\d+);", pkg)}
    assert vals == {"OVF_BIT": 44, "RECORD_BIT": 62, "CANCEL_BIT": 61}
    assert 1 << vals["OVF_BIT"] == E.EVENT_OVERFLOW_BIT


def test_descriptor_rom_is_the_source():
    """The RTL's ROM image and offsets hold exactly the source's descriptors (the cocotb test
    tests/rtl/test_usb_device.py reads them through the RTL's control endpoint too)."""
    image, offsets, serial_off = _rom_image()
    src = multisonar_descriptors()
    for name, b in src.parts():
        off, n = offsets[name]
        assert image[off:off + n] == b, name
    assert image[serial_off:serial_off + 16:2].decode() == serial_string(1)


def test_simulated_device_serves_the_boards_descriptors():
    """Read as a host does (GET_DESCRIPTOR, BOS, the MS OS 2.0 vendor request): byte for byte the
    RTL ROM's, with the board's serial number; every standard descriptor parses."""
    image, offsets, _ = _rom_image()
    sim = SimDevice("empty", source="replay", serial=0x00C0FFEE)
    got = read_descriptor_set(_control_in(sim))
    want = multisonar_descriptors(0x00C0FFEE)
    assert got == want
    assert got.device[2:4] == b"\x01\x02"  # bcdUSB 2.01: a BOS descriptor is there to read
    for name, b in multisonar_descriptors().parts():
        if name != "str3":  # the serial string: the board's
            off, n = offsets[name]
            assert b == image[off:off + n], name
    assert got.strings[3][2:].decode("utf-16-le") == "00C0FFEE"


def test_twin_serves_the_same_descriptors():
    """The twin's descriptor table is read from the RTL ROM at enumeration: the source's bytes."""
    from multisonar.twin import BOOT_CLOCKS, TwinSim, TwinUsbFunction

    sim = TwinSim(None)
    try:
        sim.reset()
        sim.run(BOOT_CLOCKS)
        fn = TwinUsbFunction(sim)
        assert fn.descriptors == multisonar_descriptors()
        # and through its control endpoint, as the simulated device is read above
        assert read_descriptor_set(_control_in(fn)) == multisonar_descriptors()
    finally:
        sim.close()


def _regs_of(sim: SimDevice) -> dict[int, int]:
    return {a: v for a, v in sim.regs.values.items() if a in sim.regs.writable_mask}


def test_simulated_device_powers_up_with_the_compiled_in_table():
    """docs/protocol.md section 8: at power-up the registers hold the firmware's compiled-in table;
    START runs it. Without one (power_up_table=None) START is refused with EMPTY_TABLE."""
    from multisonar.device import Device

    sim = SimDevice("corridor")
    regs = _regs_of(sim)
    for a, v in power_up_writes("scene", sim.layout):
        assert regs[a] == v & sim.regs.writable_mask[a], hex(a)
    with Device.attach(sim, url="sim://corridor") as dev:
        assert dev.get_param(P.Param.TEMPERATURE_CC) == round(TEMPERATURE_C * 100)
        dev.start()
        frames = list(dev.stream(max_frames=20))
        dev.stop()
    assert {int(f.head["vs"]) for f in frames} == {0, 1}, "both sensors of the compiled-in table fire"
    empty = SimDevice("corridor", power_up_table=None)
    with Device.attach(empty, url="sim://corridor") as dev:
        with pytest.raises(P.CfgRejected, match="EMPTY_TABLE"):
            dev.start()


def test_descriptor_set_reader_round_trip():
    """read_descriptor_set over a DescriptorSet's own answers gives it back (strings by index)."""
    src = multisonar_descriptors(0xDEADBEEF)

    def control_in(rt, req, value, index, length):
        if (rt, req) == (0xC0, src.vendor_code):
            return src.ms_os_20[:length]
        b = src.get_descriptor(value >> 8, value & 0xFF)
        assert b is not None
        return b[:length]

    assert read_descriptor_set(control_in) == src
    assert isinstance(src, DescriptorSet) and len(src.strings) == 5


def test_usbip_replies_follow_the_kernels_protocol_document():
    """Linux Documentation/usb/usbip_protocol.rst: in RET_SUBMIT the server sets devid,
    direction and ep to 0, number_of_packets to 0xffffffff (not isochronous), start_frame,
    error_count and padding to 0; actual_length counts the data (IN) or the bytes taken (OUT).
    Checked on raw bytes, as a kernel vhci client reads them."""
    import socket

    from multisonar.usb.usbip_proto import OP_HDR, OP_REP_IMPORT, OP_REQ_IMPORT, UDEV, USBIP_VERSION, recv_exact
    from multisonar.usb.usbip_server import UsbipServer

    sim = SimDevice("empty", source="replay")
    with UsbipServer(sim) as srv, socket.create_connection((srv.host, srv.port), timeout=10) as s:
        s.sendall(OP_HDR.pack(USBIP_VERSION, OP_REQ_IMPORT, 0) + b"1-1".ljust(32, b"\0"))
        assert OP_HDR.unpack(recv_exact(s, OP_HDR.size))[1:] == (OP_REP_IMPORT, 0)
        rec = UDEV.unpack(recv_exact(s, UDEV.size))
        devid = rec[2] << 16 | rec[3]

        def submit(seq, direction, ep, length, setup=bytes(8), data=b""):
            s.sendall(struct.pack(">IIIII", 1, seq, devid, direction, ep)
                      + struct.pack(">IIIiI8s", 0, length, 0, -1, 0, setup) + data)
            head = recv_exact(s, 48)
            fields = struct.unpack(">IIIIIiiIII8s", head)
            n = fields[6] if direction == 1 else 0
            return fields, recv_exact(s, n) if n else b""

        fields, data = submit(7, 1, 0, 18, struct.pack("<BBHHH", 0x80, 6, 0x0100, 0, 18))
        assert fields == (3, 7, 0, 0, 0, 0, 18, 0, 0xFFFFFFFF, 0, bytes(8)), fields
        assert data == multisonar_descriptors().device
        fields, _ = submit(8, 0, 0, 0, struct.pack("<BBHHH", 0x00, 9, 1, 0, 0))  # SET_CONFIGURATION(1)
        assert fields == (3, 8, 0, 0, 0, 0, 0, 0, 0xFFFFFFFF, 0, bytes(8)), fields
        cmd = P.encode_command(P.Opcode.DEVICE_INFO, seq=1)
        fields, _ = submit(9, 0, 1, len(cmd), data=cmd)  # bulk OUT 0x01
        assert fields == (3, 9, 0, 0, 0, 0, len(cmd), 0, 0xFFFFFFFF, 0, bytes(8)), fields
        fields, data = submit(10, 1, 1, P.READ_SIZE)  # bulk IN 0x81: the reply
        assert fields[:6] == (3, 10, 0, 0, 0, 0) and fields[7:] == (0, 0xFFFFFFFF, 0, bytes(8)), fields
        assert P.decode_packet(data).status == P.Status.OK
