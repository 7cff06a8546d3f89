# mk/twin.mk: the full-system twin (issue #7); included by the top Makefile.
#   make twin        build/twin/fast/libmstwin.so (profile-guided, below): ms_system_usb (VexRiscv + firmware/app/sonar,
#                    sonar core, host link, USB device on its transaction-level port) verilated
#                    with the C++ harness sim/twin/ms_twin.cpp, loaded by multisonar.twin (ctypes)
#   make twin-fst    the same with FST tracing compiled in (build/twin/fst/), for --fst
#   make twin-prof   the same with debug line tables (build/twin/prof/), for the per-block cost
#                    profile of scripts/bench_twin_profile.py --callgrind
# The RTL is read from rtl/sources.f (the list lint, the cocotb tests and synthesis read).
# Firmware: firmware/app/sonar built as build/fw/sonar_app.hex is, but with the demo's
# table compiled in (multisonar.tools.fw_schedule --config demo: the power-on default and the
# phased groups whose virtual source the firmware knows) -> build/twin/fw/sonar_app.hex.
TWIN_DIR     := $(BUILD)/twin
TWIN_HEX     := $(TWIN_DIR)/fw/sonar_app.hex

$(TWIN_DIR)/fw/sonar_app_cfg.h: host/multisonar/tools/fw_schedule.py host/multisonar/demo.py host/multisonar/schedule.py \
                                host/multisonar/regmap.py $(LAYOUT_FILE) $(STAMPS)/gen $(STAMPS)/venv mk/twin.mk
	@mkdir -p $(@D)
	$(VPY) -m multisonar.tools.fw_schedule --header $@ --config demo

$(TWIN_DIR)/fw/sonar_app.elf: $(SONAR_APP_SRC) $(GEOM_SRC) $(GEOM_HDR) \
                              $(TWIN_DIR)/fw/sonar_app_cfg.h $(SONAR_APP_HDR) $(STAMPS)/gen Makefile mk/twin.mk \
                              mk/firmware_app.mk firmware/app/sonar/sonar_app.ld
	@mkdir -p $(@D)
	$(FW_CC) $(FW_CFLAGS) -ffunction-sections -fdata-sections -Ifirmware/geometry -Ifirmware/app -I$(TWIN_DIR)/fw \
	    -DMS_GEOM_ARITH=MS_ARITH_Q $(SONAR_APP_SRC) $(GEOM_SRC) -o $@ $(SONAR_APP_LDFLAGS)

$(TWIN_DIR)/fw/sonar_app.hex: $(TWIN_DIR)/fw/sonar_app.elf
	riscv64-unknown-elf-objcopy -O binary $< $(@:.hex=.bin)
	$(VPY) -m multisonar.tools.bin2memh $(@:.hex=.bin) $@ --words $(FW_WORDS)
# the image is read by $readmemh when the simulation starts (INIT_FILE is its path): a firmware
# change rebuilds the image, not the verilated model
TWIN_DEPS    := sim/twin/ms_twin_top.sv sim/twin/ms_twin.cpp sim/twin/ms_twin.vlt rtl/sources.f $(wildcard rtl/*.sv rtl/*/*.sv) \
                $(STAMPS)/gen mk/twin.mk
# --public-ignore: VexRiscv.v marks signals `verilator public`, which puts the logic reading them
# into the input region evaluated at every eval() (sim/twin/ms_twin.vlt names what the harness reads)
TWIN_VFLAGS  := --cc --exe --build -j 2 -O3 --x-assign fast --x-initial fast -Wno-fatal -Wno-lint -Wno-style --public-ignore \
                +define+MS_TWIN_CPU_GATE +define+MS_TWIN_TX_GATE +define+MS_TWIN_RX_GATE +define+MS_TWIN_USB_GATE \
                +define+MS_TWIN_SONAR_GATE \
                --quiet --timescale 1ns/1ps --top-module ms_twin_top -GINIT_FILE='"$(abspath $(TWIN_HEX))"' \
                -CFLAGS "-fPIC -O2 -std=c++17" -LDFLAGS "-shared" -o libmstwin.so

.PHONY: twin twin-fst twin-prof
twin: $(TWIN_HEX) $(TWIN_DIR)/fast/libmstwin.so
twin-fst: $(TWIN_HEX) $(TWIN_DIR)/fst/libmstwin.so
twin-prof: $(TWIN_HEX) $(TWIN_DIR)/prof/libmstwin.so

# Profile-guided: the harness is built instrumented (build/twin/pgo), runs the demo's workload
# for 0.05 sonar-s (multisonar.twin.pgo), and the fast build compiles from that profile: 1.3x
# the clocks per second of a plain -O2 build (docs/twin.md).
TWIN_PGO     := $(abspath $(TWIN_DIR)/pgo)
# The compiler of those two builds: clang where Debian's clang-14 with its profile runtime is
# installed (the set-up installs it; its profile-guided build runs the demo's session ~6 %
# faster than g++'s, docs/twin.md), else g++ (whose profile's file names are taken relative to
# each build's folder). TWIN_CLANG= (empty) forces g++. Recursive variables, expanded in the
# recipes: after the set-up has installed the packages, also in make's first run.
TWIN_CLANG   ?= $(shell command -v clang++-14 >/dev/null && command -v llvm-profdata-14 >/dev/null && \
                  [ -f "$$(clang++-14 --print-runtime-dir)/libclang_rt.profile-x86_64.a" ] && echo clang++-14)
TWIN_CXX      = $(if $(TWIN_CLANG),--compiler clang -MAKEFLAGS CXX=$(TWIN_CLANG) \
                  -MAKEFLAGS LINK=$(TWIN_CLANG) -CFLAGS -Wno-unknown-warning-option)
TWIN_PGO_GEN  = -CFLAGS -fprofile-generate=$(TWIN_PGO)/data -LDFLAGS -fprofile-generate=$(TWIN_PGO)/data \
                $(if $(TWIN_CLANG),,-CFLAGS -fprofile-prefix-path=$(TWIN_PGO))
TWIN_PGO_MERGE = $(if $(TWIN_CLANG),llvm-profdata-14 merge -o $(TWIN_PGO)/twin.profdata \
                  $(TWIN_PGO)/data/*.profraw,true)
TWIN_PGO_USE  = $(if $(TWIN_CLANG),-CFLAGS -fprofile-use=$(TWIN_PGO)/twin.profdata \
                  -CFLAGS -Wno-profile-instr-unprofiled -CFLAGS -Wno-profile-instr-out-of-date,\
                  -CFLAGS -fprofile-use=$(TWIN_PGO)/data -CFLAGS -fprofile-prefix-path=$(abspath $(@D)) \
                  -CFLAGS -fprofile-partial-training -CFLAGS -Wno-missing-profile)

$(TWIN_DIR)/pgo/libmstwin.so: $(TWIN_DEPS)
	@mkdir -p $(@D)
	@echo "twin: verilating ms_system_usb + sim/twin/ms_twin.cpp, instrumented for the profile -> $@"
	@rm -f $(TWIN_DIR)/pgo/*.o  # (objects of the other compiler, if it changed)
	verilator $(TWIN_VFLAGS) $(TWIN_CXX) $(TWIN_PGO_GEN) --Mdir $(TWIN_DIR)/pgo sim/twin/ms_twin.vlt \
	    $(RTL_SOURCES) sim/twin/ms_twin_top.sv sim/twin/ms_twin.cpp
	@touch $@

$(TWIN_DIR)/pgo/profile.stamp: $(TWIN_DIR)/pgo/libmstwin.so $(TWIN_HEX)
	@rm -rf $(TWIN_PGO)/data
	$(VPY) -m multisonar.twin.pgo $<
	$(TWIN_PGO_MERGE)
	@touch $@

$(TWIN_DIR)/fast/libmstwin.so: $(TWIN_DEPS) $(TWIN_DIR)/pgo/profile.stamp
	@mkdir -p $(@D)
	@echo "twin: verilating ms_system_usb + sim/twin/ms_twin.cpp with the profile -> $@"
	@rm -f $(TWIN_DIR)/fast/*.o  # every object from the new profile
	verilator $(TWIN_VFLAGS) $(TWIN_CXX) $(TWIN_PGO_USE) --Mdir $(TWIN_DIR)/fast sim/twin/ms_twin.vlt \
	    $(RTL_SOURCES) sim/twin/ms_twin_top.sv sim/twin/ms_twin.cpp
	@touch $@  # verilator leaves an up-to-date library untouched: make would re-run it every time

$(TWIN_DIR)/fst/libmstwin.so: $(TWIN_DEPS)
	@mkdir -p $(@D)
	@echo "twin: verilating with FST tracing -> $@"
	@# C++ at -O1: a traced run's time is the tracing's (-O2 was no faster on 300k clocks) and
	@# the compile takes two thirds of the CPU time (28 s instead of 42)
	verilator $(TWIN_VFLAGS) -CFLAGS -O1 --trace-fst --trace-structs --Mdir $(TWIN_DIR)/fst sim/twin/ms_twin.vlt \
	    $(RTL_SOURCES) sim/twin/ms_twin_top.sv sim/twin/ms_twin.cpp
	@touch $@

$(TWIN_DIR)/prof/libmstwin.so: $(TWIN_DEPS)
	@mkdir -p $(@D)
	@echo "twin: verilating with debug line tables (the cost profile) -> $@"
	verilator $(TWIN_VFLAGS) -CFLAGS -g --Mdir $(TWIN_DIR)/prof sim/twin/ms_twin.vlt $(RTL_SOURCES) \
	    sim/twin/ms_twin_top.sv sim/twin/ms_twin.cpp
	@touch $@
