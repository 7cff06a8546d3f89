"""Turn a firmware binary into a $readmemh image of 32-bit little-endian words.

    python -m multisonar.tools.bin2memh firmware.bin firmware.hex --words 8192
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


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("binary", type=Path)
    ap.add_argument("hex", type=Path)
    ap.add_argument("--words", type=int, default=8192, help="RAM size in 32-bit words")
    a = ap.parse_args(argv)
    a.hex.write_text(convert(a.binary.read_bytes(), a.words))


if __name__ == "__main__":
    main()
