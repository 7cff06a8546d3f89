"""Register block (generated from SystemRDL) with its delay RAM, in simulation."""

import pytest

from cocotb_run import run_cocotb


@pytest.mark.sim
def test_ms_csr():
    run_cocotb("ms_csr", "tb_ms_csr", icarus_ok=False)

