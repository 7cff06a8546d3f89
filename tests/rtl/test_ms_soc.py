"""The soft-core SoC runs firmware built by make; watchdog recovery. Both CPUs of ms_soc
(rtl/soc/ms_soc.sv): PicoRV32 and VexRiscv_Full (its own top ms_soc_vex_tb, so each CPU keeps
its Verilator build)."""

import pytest

from cocotb_run import ROOT, run_cocotb
from test_ms_soc_geometry import CPUS, firmware_hex

TOPS = {"picorv32": "ms_soc_tb", "vexriscv": "ms_soc_vex_tb"}


@pytest.mark.sim
@pytest.mark.parametrize("cpu", CPUS)
def test_ms_soc_firmware_selftest(cpu):
    hexfile = firmware_hex("soc_selftest", cpu)
    top = TOPS[cpu]
    tb_sources = [ROOT / "tests/rtl/ms_soc_tb.sv"]
    if top != "ms_soc_tb":
        tb_sources.append(ROOT / f"tests/rtl/{top}.sv")
    run_cocotb(top, "tb_ms_soc", sources=None, extra_sources=tb_sources,
               parameters={"INIT_FILE": f'"{hexfile}"'}, icarus_ok=False)
