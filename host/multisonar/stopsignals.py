"""Clean stops for the long-running commands (live, serve): SIGINT (Ctrl-C) and SIGTERM (a
service manager) call a stop function, which ends the command's loop at its next check, instead
of raising KeyboardInterrupt at an arbitrary point or killing the process. The handlers are
installed, not inherited: a process started as a background job of a non-interactive shell
inherits SIGINT ignored, and Python then raises no KeyboardInterrupt at all."""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Callable, Iterator

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def stop_on_signals(stop: Callable[[], None]) -> Iterator[None]:
    """Within the block, SIGINT and SIGTERM call ``stop`` (which must only set a flag or an
    event: it runs in the main thread between two bytecodes); the previous handlers come back
    after it. Call from the main thread."""
    previous = {sig: signal.signal(sig, lambda *_: stop()) for sig in STOP_SIGNALS}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
