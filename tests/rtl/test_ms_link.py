"""Host link (rtl/link/): command buffer, packet queues, packer. Details: tb_ms_link.py."""

import pytest

from cocotb_run import GEN, ROOT, run_cocotb

LINK_RTL = [GEN / "rtl/ms_protocol_pkg.sv", ROOT / "rtl/common/ms_ram_dp.sv"] + [ROOT / "rtl/link" / f for f in (
    "ms_link_pkg.sv", "ms_link_cmd_rx.sv", "ms_link_txq.sv", "ms_link_packer.sv", "ms_link.sv")]


@pytest.mark.sim
def test_ms_link():
    run_cocotb("ms_link", "tb_ms_link", sources=LINK_RTL)
