"""Turn a firmware binary into a $readmemh image of 32-bit little-endian words.

    python -m multisonar.tools.bin2memh firmware.bin firmware.hex --words 8192

When --words is not a power of two, rtl/common/ms_ram_sp_bytes.sv builds the RAM from one
bank per set bit of the size (largest first), each bank from columns as wide as one block
RAM of its depth holds (column_bits), and preloads column c of bank k from
``firmware.hex.k.c``; those files are written too (a bank the image does not reach gets one
zero word per column).
"""

from __future__ import annotations

import argparse
from pathlib import Path


def convert(binary: bytes, words: int) -> str:
    if len(binary) > 4 * words:
        raise ValueError(f"firmware image is {len(binary)} bytes; the RAM holds {4 * words}")
    binary = binary + b"\0" * (-len(binary) % 4)
    out = [f"{int.from_bytes(binary[i:i + 4], 'little'):08x}" for i in range(0, len(binary), 4)]
    return "\n".join(out) + "\n"


def banks(words: int) -> list[tuple[int, int]]:
    """(first word, words) of each bank of ms_ram_sp_bytes for a RAM of `words` words."""
    out, base = [], 0
    for b in reversed(range(words.bit_length())):
        if words >> b & 1:
            out.append((base, 1 << b))
            base += 1 << b
    return out


def column_bits(bank_words: int) -> int:
    """Bits per column of a bank: ms_ram_sp_bytes's W, one ECP5 DP16KD in the mode of that
    depth (8192 x 2, 4096 x 4, 2048 x 9, 1024 x 18, 512 x 36)."""
    return min(32, 16384 // bank_words)


def convert_banks(binary: bytes, words: int) -> list[list[str]]:
    """$readmemh images per bank (see banks()) and per column (column_bits()), low bits first."""
    image = [int(w, 16) for w in convert(binary, words).split()]
    out = []
    for base, n in banks(words):
        w = column_bits(n)
        part = image[base:base + n] or [0]
        digits = (w + 3) // 4
        out.append(["\n".join(f"{(v >> (c * w)) & ((1 << w) - 1):0{digits}x}" for v in part) + "\n"
                    for c in range(32 // w)])
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("binary", type=Path)
    ap.add_argument("hex", type=Path)
    ap.add_argument("--words", type=int, default=8192, help="RAM size in 32-bit words")
    a = ap.parse_args(argv)
    binary = a.binary.read_bytes()
    a.hex.write_text(convert(binary, a.words))
    if a.words & (a.words - 1):
        for k, columns in enumerate(convert_banks(binary, a.words)):
            for c, text in enumerate(columns):
                a.hex.with_name(f"{a.hex.name}.{k}.{c}").write_text(text)


if __name__ == "__main__":
    main()
