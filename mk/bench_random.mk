# mk/bench_random.mk: the random-input geometry benchmark image (issue #26); included by the top
# Makefile (its `include $(sort $(wildcard mk/*.mk))`).
#   make build/fw/bench_fix_random.hex       firmware/app/bench_fix_random.c + the Q geometry
#                                            library: 100000 fixes on 1000 sensors, seed 1
#   make build/fw/bench_fix_random-CALLS-SENSORS-SEED[-cold].hex
#                                            other sizes / seeds; -cold: FENCE.I before every
#                                            timed call (VexRiscv only; cold instruction cache)
# scripts/bench_fw_random.py and tests/rtl/test_ms_soc_random.py build and run them. Memory as
# the other images (FW_LDFLAGS: 48 KiB image, 16 KiB data / bss / stack); the image holds
# ms_prepare and the fast path only (--gc-sections drops the general path ms_fix_fast never
# calls), ~28 KB, bss ~12 KB (mostly the histograms).
BENCH_RANDOM_SRC  := firmware/app/bench_fix_random.c
BENCH_RANDOM_DEPS := $(BENCH_RANDOM_SRC) $(GEOM_SRC) $(GEOM_HDR) $(wildcard firmware/app/*.h) \
                     $(STAMPS)/gen Makefile mk/bench_random.mk
# bench_random_cc DEFINES: compile and link $@
bench_random_cc = $(FW_CC) $(FW_CFLAGS) -ffunction-sections -fdata-sections -Ifirmware/geometry \
                  -DMS_GEOM_ARITH=MS_ARITH_Q $(1) $(BENCH_RANDOM_SRC) $(GEOM_SRC) -o $@ $(FW_LDFLAGS)
.PRECIOUS: $(BUILD)/fw/bench_fix_random-%.elf

$(BUILD)/fw/bench_fix_random.elf: $(BENCH_RANDOM_DEPS)
	@mkdir -p $(@D)
	$(call bench_random_cc,)

# stem CALLS-SENSORS-SEED[-cold]
$(BUILD)/fw/bench_fix_random-%.elf: $(BENCH_RANDOM_DEPS)
	@mkdir -p $(@D)
	$(call bench_random_cc,-DBENCH_CALLS=$(word 1,$(subst -, ,$*)) -DBENCH_SENSORS=$(word 2,$(subst -, ,$*)) \
	    -DBENCH_SEED=$(word 3,$(subst -, ,$*)) $(if $(filter cold,$(subst -, ,$*)),-DBENCH_FIX_COLD))
