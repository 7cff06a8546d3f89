"""The SoC RAM (rtl/common/ms_ram_sp_bytes.sv) with a size that is not a power of two: banks
preloaded from bin2memh's per-bank images, byte writes, and the addresses past the end."""

import random

import pytest

from cocotb_run import ROOT, run_cocotb
from multisonar.tools import bin2memh

WORDS = 15360  # the board's RAM: 8192 + 4096 + 2048 + 1024 words, columns of 2, 4, 8, 16 bits
IMAGE_WORDS = 11600  # like the firmware: the image ends inside the second bank, the others get the filler


def test_bin2memh_banks_follow_the_set_bits():
    assert bin2memh.banks(15360) == [(0, 8192), (8192, 4096), (12288, 2048), (14336, 1024)]
    assert bin2memh.banks(16384) == [(0, 16384)]
    assert [bin2memh.column_bits(n) for _, n in bin2memh.banks(15360)] == [2, 4, 8, 16]
    image = bytes(range(256)) * 8  # 512 words
    parts = bin2memh.convert_banks(image, 1792)  # banks of 1024, 512, 256 words: 16, 32, 32 bits
    assert [len(p) for p in parts] == [2, 1, 1]
    assert [len(c.split()) for c in parts[0]] == [512, 512] and parts[1] == parts[2] == ["00000000\n"]
    assert parts[0][0].split()[1] == "0504" and parts[0][1].split()[1] == "0706"  # word 0x07060504


@pytest.mark.sim
def test_ms_ram_sp_bytes_banked():
    out = ROOT / "build" / "sim" / "ms_ram_sp_bytes-image"
    out.mkdir(parents=True, exist_ok=True)
    rng = random.Random(8)
    binary = bytes(rng.getrandbits(8) for _ in range(4 * IMAGE_WORDS))
    (out / "image.bin").write_bytes(binary)
    bin2memh.main([str(out / "image.bin"), str(out / "image.hex"), "--words", str(WORDS)])
    run_cocotb("ms_ram_sp_bytes", "tb_ms_ram_sp_bytes", sources=[ROOT / "rtl/common/ms_ram_sp_bytes.sv"],
               parameters={"WORDS": WORDS, "AW": 14, "INIT_FILE": f'"{out / "image.hex"}"'},
               extra_env={"MS_RAM_IMAGE": str(out / "image.bin")})
