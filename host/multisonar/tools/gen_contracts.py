"""Generate the contracts between host, firmware and RTL from their one Python source.

    python -m multisonar.tools.gen_contracts --out build/gen

writes, from :mod:`multisonar.protocol` (commands, statuses, parameters, configuration errors,
flags, frame layouts) and :mod:`multisonar.usb.descriptors` (the USB descriptors):

* ``firmware/ms_geom_reasons.h`` from :mod:`multisonar.geometry`: the reason codes and texts;
* ``firmware/ms_protocol.h``: the protocol constants for the firmware (``MS_OP_*``, ``MS_ST_*``,
  ``MS_PARAM_*`` with their ranges, ``MS_CFG_ERROR_*``, ToF-record and frame flags, reply and
  statistics field indices);
* ``rtl/ms_protocol_pkg.sv``: the constants the host link's RTL uses (header and payload sizes,
  USB identity);
* ``rtl/ms_usb_desc.hex``: the descriptor ROM image for ``$readmemh`` (one byte per line);
* ``rtl/ms_usb_desc_pkg.sv``: each descriptor's ROM offset and length, the serial string's
  offset, the MS OS 2.0 vendor code and the image's path (``DESC_HEX``);
* ``firmware/ms_event_word.h`` from :mod:`multisonar.event_word`: readers of the sonar core's
  event-FIFO word (ToF event, pulse and cancel record fields; the record, cancel, overflow and
  gated bits), and ``rtl/ms_event_pkg.sv``: the bits the RTL sets itself (the FIFO's overflow bit).

The ``make`` gen step runs it (like the register map), so no number is typed twice. Files are
rewritten only when their text changes (stable mtimes for ``make``).
"""

from __future__ import annotations

import argparse
from enum import IntEnum
from pathlib import Path

from .. import geometry as G
from .. import protocol as P
from ..usb import descriptors as D

BANNER = "Generated from {src} by multisonar.tools.gen_contracts. Do not edit."


def _c_enum(name: str, prefix: str, members: list[tuple[str, int]], count: str | None = None) -> list[str]:
    lines = [f"enum {name} {{"]
    lines += [f"    {prefix}{m} = {v}," for m, v in members]
    if count:
        lines.append(f"    {prefix}{count} = {max(v for _, v in members) + 1},")
    return lines + ["};"]


def _members(e: type[IntEnum]) -> list[tuple[str, int]]:
    return [(m.name, int(m)) for m in e]


def _magic(m: bytes) -> int:
    return m[0] | m[1] << 8


def c_header() -> str:
    """firmware/ms_protocol.h"""
    out = ["/* " + BANNER.format(src="multisonar.protocol") + " */",
           "/* The USB protocol's constants (docs/protocol.md); the host's codec is the same module. */",
           "#ifndef MS_PROTOCOL_H", "#define MS_PROTOCOL_H", "",
           f"#define MS_PROTOCOL_VERSION {P.PROTOCOL_VERSION}u",
           "/* magics as the little-endian u16 of the header's first two bytes */",
           *(f"#define MS_MAGIC_{n} 0x{_magic(m):04X}u /* \"{m.decode()}\" */"
             for n, m in (("COMMAND", P.MAGIC_COMMAND), ("REPLY", P.MAGIC_REPLY), ("FRAME", P.MAGIC_FRAME))),
           f"#define MS_HEADER_SIZE {P.HEADER_SIZE}u",
           f"#define MS_CRC_SIZE {P.CRC_SIZE}u",
           f"#define MS_MAX_PAYLOAD {P.MAX_PAYLOAD}u",
           f"#define MS_FRAME_TYPE 0x{P.FRAME_TYPE:02X}u",
           f"#define MS_REPLY_BIT 0x{P.REPLY_BIT:02X}u",
           f"#define MS_ERROR_REPLY_TYPE 0x{P.ERROR_REPLY_TYPE:02X}u",
           f"#define MS_MAX_TOF_RECORDS {P.MAX_TOF_RECORDS}u",
           f"#define MS_MAX_GEO_RECORDS {P.MAX_GEO_RECORDS}u",
           f"#define MS_FRAME_HEAD_SIZE {P.FRAME_HEAD_DTYPE.itemsize}u",
           f"#define MS_TOF_RECORD_SIZE {P.TOF_DTYPE.itemsize}u",
           f"#define MS_GEO_RECORD_SIZE {P.GEO_DTYPE.itemsize}u",
           f"#define MS_DEVICE_INFO_SIZE {P.INFO.size}u", "",
           "/* commands (section 3); MS_OP_COUNT: one past the highest opcode */",
           *_c_enum("ms_opcode", "MS_OP_", _members(P.Opcode), "COUNT"), "",
           "/* reply status (section 4) */",
           *_c_enum("ms_status", "MS_ST_", _members(P.Status)), "",
           "/* SET_PARAM / GET_PARAM ids and SET_PARAM's accepted range, inclusive */",
           *_c_enum("ms_param", "MS_PARAM_", _members(P.Param), "COUNT")]
    for p, (lo, hi) in P.PARAM_RANGE.items():
        out += [f"#define MS_PARAM_{p.name}_MIN ({lo})", f"#define MS_PARAM_{p.name}_MAX ({hi})"]
    for macro, side in (("MS_PARAM_MINS", 0), ("MS_PARAM_MAXS", 1)):  # array initialisers indexed by id
        items = ", ".join(f"[MS_PARAM_{p.name}] = ({r[side]})" for p, r in P.PARAM_RANGE.items())
        out.append(f"#define {macro} {{{items}}}")
    busy = " | ".join(f"(1u << MS_PARAM_{p.name})" for p in sorted(P.PARAM_BUSY_WHILE_RUNNING))
    out += ["/* parameters SET_PARAM refuses with BUSY while a table runs, as a bit mask of ids */",
            f"#define MS_PARAM_BUSY_WHILE_RUNNING ({busy})", "",
            "/* CFG_REJECTED detail: STATUS.cfg_error (section 5) */",
            *(f"#define MS_CFG_ERROR_{e.name} {int(e)}" for e in P.CfgError), "",
            "/* ToF record flags (section 6) */",
            *(f"#define MS_TOF_{n} 0x{v:02X}u" for n, v in (
                ("IN_WINDOW", P.TOF_IN_WINDOW), ("FIRST_ECHO", P.TOF_FIRST_ECHO),
                ("WINDOW_EMPTY", P.TOF_WINDOW_EMPTY), ("INIT_PING", P.TOF_INIT_PING), ("GATED", P.TOF_GATED))),
            "/* frame header flags (section 6) */",
            *(f"#define MS_FRAME_{n} 0x{v:02X}u" for n, v in (
                ("INIT_PING", P.FRAME_INIT_PING), ("TRUNCATED", P.FRAME_TRUNCATED),
                ("SIMULATED", P.FRAME_SIMULATED), ("LOST", P.FRAME_LOST), ("CUT", P.FRAME_CUT),
                ("GEO", P.FRAME_GEO))),
            "/* geometry record classes (GEO_DTYPE.cls) */",
            *(f"#define MS_GEO_CLASS_{c.upper()} {i}" for i, c in enumerate(P.GEO_CLASSES)), "",
            "/* READ_COUNTERS and FW_STATS reply words, in order (section 3) */",
            *_c_enum("ms_counter", "MS_COUNTER_", [(f.upper(), i) for i, f in enumerate(P.COUNTERS_FIELDS)],
                     "COUNT"),
            *_c_enum("ms_fw_stat", "MS_FW_STAT_", [(f.upper(), i) for i, f in enumerate(P.FW_STATS_FIELDS)],
                     "COUNT"),
            "", "#endif", ""]
    return "\n".join(out)


def geom_reasons_header() -> str:
    """firmware/ms_geom_reasons.h"""
    names = ", ".join(f'"{t}"' for t in G.REASONS)
    return "\n".join([
        "/* " + BANNER.format(src="multisonar.geometry") + " */",
        "/* The geometry's reason codes (why a solve gives no valid answer): the index into",
        " * geometry.REASONS, whose texts MS_REASON_TEXTS holds in the same order. */",
        "#ifndef MS_GEOM_REASONS_H", "#define MS_GEOM_REASONS_H", "",
        *_c_enum("ms_reason", "MS_", list(zip(G.REASON_SYMBOLS, range(len(G.REASONS))))),
        f"#define MS_NREASONS {len(G.REASONS)}",
        f"#define MS_REASON_TEXTS {{{names}}}", "", "#endif", ""])


def _c_field(prefix: str, name: str, lsb: int, width: int) -> str:
    """A macro reading bits lsb .. lsb+width-1 of a 64-bit word the firmware holds as two u32
    halves (lo = bits 31:0, hi = 63:32), also across the halves."""
    mask = f"0x{(1 << width) - 1:X}u" if width < 32 else "0xFFFFFFFFu"
    if lsb + width <= 32:
        expr = "(lo)" if (lsb, width) == (0, 32) else f"(((lo) >> {lsb}) & {mask})" if lsb else f"((lo) & {mask})"
    elif lsb >= 32:
        expr = f"(((hi) >> {lsb - 32}) & {mask})" if lsb > 32 else f"((hi) & {mask})"
    else:
        expr = f"((((lo) >> {lsb}) | ((hi) << {32 - lsb})) & {mask})"
    return f"#define {prefix}{name.upper()}(lo, hi) {expr}"


def event_word_header() -> str:
    """firmware/ms_event_word.h: the sonar core's event-FIFO word (docs/fast_firing.md section 6)."""
    from .. import event_word as F

    kinds = ("in_window", "first_echo", "window_empty", "init_ping")
    kind_lsb = F.EVENT_FIELDS[kinds[0]][0]
    tof_flags = (P.TOF_IN_WINDOW, P.TOF_FIRST_ECHO, P.TOF_WINDOW_EMPTY, P.TOF_INIT_PING)
    # the firmware keeps the four kind bits as they come and writes them out as the ToF record's
    # flags: both orders must agree, and the bits must be contiguous
    for k, (name, flag) in enumerate(zip(kinds, tof_flags)):
        if F.EVENT_FIELDS[name] != (kind_lsb + k, 1) or flag != 1 << k:
            raise ValueError(f"event kind bit {name} no longer matches ToF record flag bit {k}")

    def hi_bit(bit: int) -> str:
        if bit < 32:
            raise ValueError(f"bit {bit} is in the low half")
        return f"(1u << {bit - 32})"

    out = ["/* " + BANNER.format(src="multisonar.event_word") + " */",
           "/* The sonar core's event-FIFO word (docs/fast_firing.md section 6), read through EVT_LO",
           " * (bits 31:0: lo) and EVT_HI (bits 62:32: hi; bit 31 of hi is the register's VALID).",
           " * MS_EV_* read a ToF event, MS_PULSE_* a pulse record, MS_CANCEL_* a cancel record. */",
           "#ifndef MS_EVENT_WORD_H", "#define MS_EVENT_WORD_H", "",
           "/* a record (pulse, or with MS_EVH_CANCEL a sensor's cancel), not a ToF event */",
           f"#define MS_EVH_RECORD {hi_bit(F.PULSE_RECORD_BIT.bit_length() - 1)}",
           f"#define MS_EVH_CANCEL {hi_bit(F.CANCEL_RECORD_BIT.bit_length() - 1)}",
           "/* words were dropped (FIFO full) just before this one, in any kind of word */",
           f"#define MS_EVH_OVF {hi_bit(F.EVENT_OVERFLOW_BIT.bit_length() - 1)}",
           "/* a first echo the gated miss rule rejected */",
           f"#define MS_EVH_GATED {hi_bit(F.EVENT_FIELDS['gated'][0])}", ""]
    out += [_c_field("MS_EV_", n, lsb, w) for n, (lsb, w) in F.EVENT_FIELDS.items()
            if n not in kinds and n != "gated"]
    out += ["/* in_window, first_echo, window_empty, init_ping as bits 0..3: the ToF record's MS_TOF_* */",
            _c_field("MS_EV_", "kind", kind_lsb, len(kinds))]
    out += [_c_field("MS_PULSE_", n.removeprefix("pulse_"), lsb, w) for n, (lsb, w) in F.PULSE_FIELDS.items()]
    out += [_c_field("MS_CANCEL_", n, lsb, w) for n, (lsb, w) in F.CANCEL_FIELDS.items()]
    out += ["", "#endif", ""]
    return "\n".join(out)


def sv_package() -> str:
    """rtl/ms_protocol_pkg.sv"""
    return "\n".join([
        "// " + BANNER.format(src="multisonar.protocol"),
        "// The USB protocol's constants the host link uses (docs/protocol.md).",
        "package ms_protocol_pkg;",
        f"  localparam int PROTOCOL_VERSION = {P.PROTOCOL_VERSION};",
        f"  localparam int HEADER_SIZE      = {P.HEADER_SIZE};",
        f"  localparam int CRC_SIZE         = {P.CRC_SIZE};",
        f"  localparam int MAX_PAYLOAD      = {P.MAX_PAYLOAD};",
        f"  localparam int USB_VID          = 'h{P.USB_VID:04X};",
        f"  localparam int USB_PID          = 'h{P.USB_PID:04X};",
        f"  localparam int USB_MPS          = {P.USB_MPS};",
        "endpackage", ""])


def event_package() -> str:
    """rtl/ms_event_pkg.sv"""
    from .. import event_word as E

    return "\n".join([
        "// " + BANNER.format(src="multisonar.event_word"),
        "// The sonar core's event-FIFO word (docs/fast_firing.md section 6): the bits the RTL itself",
        "// sets (the scheduler's program packs the rest; the firmware reads them with ms_event_word.h).",
        "package ms_event_pkg;",
        f"  localparam int OVF_BIT    = {E.EVENT_OVERFLOW_BIT.bit_length() - 1};  // words were dropped before this one",
        f"  localparam int RECORD_BIT = {E.PULSE_RECORD_BIT.bit_length() - 1};  // a pulse (or cancel) record",
        f"  localparam int CANCEL_BIT = {E.CANCEL_RECORD_BIT.bit_length() - 1};  // with RECORD_BIT: a cancel record",
        "endpackage", ""])


def desc_hex(ds: D.DescriptorSet) -> str:
    """rtl/ms_usb_desc.hex: the ROM image, one byte per line, nothing else (every $readmemh reader
    takes it; the offsets are in ms_usb_desc_pkg)."""
    return "".join(f"{b:02X}\n" for b in ds.rom()[0])


def desc_package(ds: D.DescriptorSet, hex_path: Path) -> str:
    """rtl/ms_usb_desc_pkg.sv"""
    image, offsets = ds.rom()
    out = ["// " + BANNER.format(src="multisonar.usb.descriptors"),
           "// The descriptor ROM (ms_usb_desc_rom): each descriptor's byte offset and length, the",
           "// serial string's first character, the MS OS 2.0 vendor code, the image for $readmemh.",
           "package ms_usb_desc_pkg;",
           f"  localparam int DESC_BYTES = {len(image)};"]
    for name, (off, n) in offsets.items():
        key = name.upper()
        out.append(f"  localparam int DESC_{key}_OFF = {off};  localparam int DESC_{key}_LEN = {n};")
    out += [f"  localparam int DESC_NUM_STRINGS = {len(ds.strings)};",
            f"  localparam int DESC_SERIAL_OFF = {ds.serial_offset};  // 8 characters, 2 bytes apart",
            f"  localparam int MS_VENDOR_CODE = 'h{ds.vendor_code:02X};",
            f"  localparam int MS_OS_20_INDEX = {D.MS_OS_20_INDEX};",
            f'  localparam string DESC_HEX = "{hex_path.resolve().as_posix()}";',
            "endpackage", ""]
    return "\n".join(out)


def generate(out: Path) -> list[Path]:
    ds = D.multisonar_descriptors()
    hex_path = out / "rtl" / "ms_usb_desc.hex"
    files = {out / "firmware" / "ms_protocol.h": c_header(),
             out / "firmware" / "ms_geom_reasons.h": geom_reasons_header(),
             out / "firmware" / "ms_event_word.h": event_word_header(),
             out / "rtl" / "ms_protocol_pkg.sv": sv_package(),
             out / "rtl" / "ms_event_pkg.sv": event_package(),
             hex_path: desc_hex(ds),
             out / "rtl" / "ms_usb_desc_pkg.sv": desc_package(ds, hex_path)}
    for path, text in files.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.exists() or path.read_text() != text:
            path.write_text(text)
    return list(files)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True, help="output folder (e.g. build/gen)")
    args = ap.parse_args(argv)
    for p in generate(args.out):
        print(p)


if __name__ == "__main__":
    main()
