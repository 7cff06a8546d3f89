# All RTL of the project in compile order, one path per line; $GEN is build/gen,
# $PICORV32 / $VEXRISCV the verilog folders of the pinned pythondata-cpu-picorv32 / -vexriscv packages;
# $GEN/cpu/VexRiscv_icache16k.v is the pinned standard VexRiscv with a 16 KiB I-cache (scripts/gen_vex_icache.py).
# Lint, cocotb tests and (later) synthesis read this one list.
$GEN/rtl/ms_layout_pkg.sv
$GEN/sv/sonar_regs_pkg.sv
$GEN/sv/sonar_regs.sv
rtl/common/ms_ram_dp.sv
rtl/common/ms_reset_copy.sv
rtl/rx/ms_rx_conditioner.sv
rtl/ms_csr.sv
rtl/event/ms_event_fifo.sv
rtl/tx/ms_tx_channel.sv
rtl/tx/ms_tx_phaser.sv
$PICORV32/picorv32.v
$GEN/cpu/VexRiscv_icache16k.v
$GEN/sv/soc_regs_pkg.sv
$GEN/sv/soc_regs.sv
rtl/common/ms_ram_sp_bytes.sv
rtl/soc/ms_pico_bridge.sv
rtl/soc/ms_vex_bridge.sv
rtl/soc/ms_soc.sv
$GEN/rtl/ms_ucode_pkg.sv
rtl/core/ms_sched_engine.sv
rtl/core/ms_sched_div.sv
rtl/core/ms_sched_slot.sv
rtl/core/ms_sched_workq.sv
rtl/core/ms_sched_cfg.sv
rtl/core/ms_scheduler.sv
rtl/ms_sonar_core.sv
rtl/ms_system.sv
rtl/usb/ms_usb_pkg.sv
rtl/usb/ms_usb_rx.sv
rtl/usb/ms_usb_tx.sv
rtl/usb/ms_usb_tx_tl.sv
rtl/usb/ms_usb_pkt_rx.sv
rtl/usb/ms_usb_desc_rom.sv
rtl/usb/ms_usb_ep0.sv
rtl/usb/ms_usb_ep_out.sv
rtl/usb/ms_usb_ep_in.sv
rtl/usb/ms_usb_xact.sv
rtl/usb/ms_usb_device.sv
rtl/link/ms_link_pkg.sv
rtl/link/ms_link_cmd_rx.sv
rtl/link/ms_link_txq.sv
rtl/link/ms_link_packer.sv
rtl/link/ms_link.sv
rtl/link/ms_system_usb.sv
