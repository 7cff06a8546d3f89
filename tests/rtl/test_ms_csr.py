"""Register block (generated from SystemRDL) with its delay RAM, in simulation."""

import pytest

from cocotb_run import run_cocotb


@pytest.mark.sim
def test_ms_csr():
    run_cocotb("ms_csr", "tb_ms_csr", icarus_ok=False)


@pytest.mark.sim
def test_ms_csr_reduced():
    """The LFE5U-25F profile's register block: 4 VS entries implemented, 8 window slots."""
    run_cocotb("ms_csr", "tb_ms_csr", icarus_ok=False, variant="vs4-ws8", parameters={"NUM_VS": 4, "WSLOTS": 8},
               extra_env={"CSR_NUM_VS": "4", "CSR_WSLOTS": "8"},
               testcase=["caps_and_implemented_entries", "counters_status_and_errors", "vs_table_refilled_after_reset"])
