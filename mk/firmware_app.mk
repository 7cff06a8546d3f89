# mk/firmware_app.mk: the sonar firmware image (issue #5); included by the top Makefile.
#   make build/fw/sonar_app.hex   firmware/app/sonar/*.c + the Q geometry library, with the
#                                 compiled-in schedule build/fw/sonar_app_cfg.h
# The schedule header comes from multisonar.tools.fw_schedule (SONAR_APP_CFG: a configuration
# named there; default 'scene', the whole-system test's table, tests/rtl/test_system_scene.py).
# Memory: the board's 60 KiB (ms_ulx3s RAM_WORDS 15360: 30 DP16KD, the 25F has 56): 40 KiB
# image at 0, 20 KiB data/bss/stack at 0xA000 (the stack from 0xF000 down). In the simulated
# SoC's 64 KiB the top 4 KiB stay unused. The link fails when either part outgrows its room
# (34 KB image, ~14 KB data + bss with 32 pulse groups, ~2.5 KB stack as of issue #26).
SONAR_APP_LDFLAGS := -Wl,--defsym=__flash=0x0 -Wl,--defsym=__flash_size=0xA000 \
                     -Wl,--defsym=__ram=0xA000 -Wl,--defsym=__ram_size=0x5000 -Wl,--gc-sections \
                     -Wl,--sort-section=name

SONAR_APP_CFG ?= scene
SONAR_APP_SRC := $(sort $(wildcard firmware/app/sonar/*.c))
SONAR_APP_HDR := $(wildcard firmware/app/sonar/*.h firmware/app/*.h)

$(BUILD)/fw/sonar_app_cfg.h: host/multisonar/tools/fw_schedule.py host/multisonar/schedule.py \
                             host/multisonar/regmap.py $(LAYOUT_FILE) $(STAMPS)/gen $(STAMPS)/venv mk/firmware_app.mk
	@mkdir -p $(@D)
	$(VPY) -m multisonar.tools.fw_schedule --header $@ --config $(SONAR_APP_CFG)

$(BUILD)/fw/sonar_app.elf: $(SONAR_APP_SRC) $(GEOM_SRC) $(GEOM_HDR) \
                           $(BUILD)/fw/sonar_app_cfg.h $(SONAR_APP_HDR) $(STAMPS)/gen Makefile \
                           mk/firmware_app.mk
	@mkdir -p $(@D)
	$(FW_CC) $(FW_CFLAGS) -ffunction-sections -fdata-sections -Ifirmware/geometry -Ifirmware/app -I$(BUILD)/fw \
	    -DMS_GEOM_ARITH=MS_ARITH_Q $(SONAR_APP_SRC) $(GEOM_SRC) -o $@ $(SONAR_APP_LDFLAGS) -Wl,--print-memory-usage
	riscv64-unknown-elf-size $@
