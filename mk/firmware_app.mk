# mk/firmware_app.mk: the sonar firmware image (issue #5); included by the top Makefile.
#   make build/fw/sonar_app.hex   firmware/app/sonar/*.c + the Q geometry library, with the
#                                 compiled-in schedule build/fw/sonar_app_cfg.h
# The schedule header comes from multisonar.tools.fw_schedule (SONAR_APP_CFG: a configuration
# named there; default 'scene', the whole-system test's table, tests/rtl/test_system_scene.py).
# Memory: the board's 60 KiB (ms_ulx3s RAM_WORDS 15360: 30 DP16KD, the 25F has 56): 40 KiB
# image at 0, then 3.5 KiB of stack (growing down from 0xAE00) and 16.5 KiB of data + bss from
# 0xAE00 (firmware/app/sonar/sonar_app.ld). In the simulated SoC's 64 KiB the top 4 KiB stay
# unused. The link fails when the image or data + bss outgrows its room (~40 KB image, ~16.3 KB
# data + bss with 32 pulse groups; the deepest call path takes ~1 KB of stack, firmware/README.md). The stack sits below the data
# so that the gp window (4 KiB from the data) starts 3.5 KiB above the image's end: GNU ld 2.40
# relaxes against the unrelaxed layout, and with the data right after the image, an unrelaxed
# image over 40 KiB (~1.1 KiB above the relaxed one) broke the link ("relocation truncated to
# fit: R_RISCV_GPREL_I" against __data_source).
SONAR_APP_LDFLAGS := -T firmware/app/sonar/sonar_app.ld -Wl,--defsym=__flash=0x0 \
                     -Wl,--defsym=__flash_size=0xA000 -Wl,--defsym=__ram=0xAE00 \
                     -Wl,--defsym=__ram_size=0x4200 -Wl,--gc-sections -Wl,--sort-section=name

SONAR_APP_CFG ?= scene
SONAR_APP_SRC := $(sort $(wildcard firmware/app/sonar/*.c))
SONAR_APP_HDR := $(wildcard firmware/app/sonar/*.h firmware/app/*.h)

$(BUILD)/fw/sonar_app_cfg.h: host/multisonar/tools/fw_schedule.py host/multisonar/schedule.py \
                             host/multisonar/regmap.py $(LAYOUT_FILE) $(STAMPS)/gen $(STAMPS)/venv mk/firmware_app.mk
	@mkdir -p $(@D)
	$(VPY) -m multisonar.tools.fw_schedule --header $@ --config $(SONAR_APP_CFG)

$(BUILD)/fw/sonar_app.elf: $(SONAR_APP_SRC) $(GEOM_SRC) $(GEOM_HDR) \
                           $(BUILD)/fw/sonar_app_cfg.h $(SONAR_APP_HDR) $(STAMPS)/gen Makefile \
                           mk/firmware_app.mk firmware/app/sonar/sonar_app.ld
	@mkdir -p $(@D)
	$(FW_CC) $(FW_CFLAGS) -ffunction-sections -fdata-sections -Ifirmware/geometry -Ifirmware/app -I$(BUILD)/fw \
	    -DMS_GEOM_ARITH=MS_ARITH_Q $(SONAR_APP_SRC) $(GEOM_SRC) -o $@ $(SONAR_APP_LDFLAGS) -Wl,--print-memory-usage
	riscv64-unknown-elf-size $@
