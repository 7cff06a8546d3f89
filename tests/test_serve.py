"""`multisonar serve`: any registered model URL served over USB/IP, reached by the unchanged driver."""

from __future__ import annotations

import signal
import subprocess
import sys

import pytest

from multisonar import Device


def _serve(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "multisonar", "serve", "--port", "0", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.parametrize("args", [("--url", "sim://corridor?seed=3&queue=64"), ("--scene", "wall_1m")])
def test_serve_a_model_url_and_read_it_over_usbip(args):
    proc = _serve(*args)
    try:
        line = proc.stdout.readline()  # "serving sim://... at usbip://127.0.0.1:PORT; Ctrl-C stops"
        assert line.startswith("serving sim://"), (line, proc.stderr.read() if proc.poll() is not None else "")
        url = line.split(" at ", 1)[1].split(";", 1)[0].strip()
        with Device.open(url, timeout_s=10) as dev:
            info = dev.info()
            assert info.simulated and info.channels == 24
    finally:
        proc.terminate()
        proc.wait(timeout=10)


@pytest.mark.parametrize("sig,sigint_ignored", [(signal.SIGINT, True), (signal.SIGTERM, False)],
                         ids=["sigint-started-in-background", "sigterm"])
def test_serve_stops_cleanly_on_sigint_and_sigterm(sig, sigint_ignored):
    """Ctrl-C and a service manager's SIGTERM close the server and its model and exit 0, also when
    the process was started with SIGINT ignored (a script's background job)."""
    proc = subprocess.Popen([sys.executable, "-m", "multisonar", "serve", "--port", "0", "--scene", "wall_1m"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=(lambda: signal.signal(signal.SIGINT, signal.SIG_IGN)) if sigint_ignored
                            else None)
    try:
        assert proc.stdout.readline().startswith("serving sim://")
        proc.send_signal(sig)
        assert proc.wait(timeout=10) == 0, proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


@pytest.mark.parametrize("url, message", [
    ("usb://", "opens a connection, not a device model"),
    ("nosuch://x", "nosuch"),
    ("sim://no_such_scene", "no_such_scene"),
])
def test_serve_refuses_what_it_cannot_serve_in_one_line(url, message):
    out = subprocess.run([sys.executable, "-m", "multisonar", "serve", "--port", "0", "--url", url],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 1 and message in out.stderr and "Traceback" not in out.stderr, out.stderr
