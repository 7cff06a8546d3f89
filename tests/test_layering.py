"""Layering of the host package (issue #29): no import cycles in host/multisonar (every import
counts, also those inside functions), the driver (multisonar.device) does not import the
simulated device, the twin or the USB/IP modules, and device URL schemes come from the
registry (multisonar.urls) and its entry points."""

from __future__ import annotations

import ast
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from multisonar import Device, urls

HOST = Path(__file__).resolve().parents[1] / "host"
PKG = HOST / "multisonar"
DRIVER = "multisonar.device"
NOT_FROM_DRIVER = ("multisonar.simdevice", "multisonar.twin", "multisonar.usb.usbip_")


def _modules() -> dict[str, Path]:
    mods = {}
    for p in sorted(PKG.rglob("*.py")):
        parts = list(p.relative_to(HOST).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        mods[".".join(parts)] = p
    return mods


def _imports(mods: dict[str, Path]) -> dict[str, dict[str, int]]:
    """module -> {imported package module: line of the first such import}. ``from X import y``
    imports X.y when that is a module, else X."""
    edges: dict[str, dict[str, int]] = {}
    for m, p in mods.items():
        pkg = m if p.name == "__init__.py" else m.rpartition(".")[0]
        out: dict[str, int] = {}

        def add(target: str, line: int) -> None:
            if target in mods and target != m:
                out.setdefault(target, line)

        for n in ast.walk(ast.parse(p.read_text(), str(p))):
            if isinstance(n, ast.Import):
                for a in n.names:
                    add(a.name, n.lineno)
            elif isinstance(n, ast.ImportFrom):
                if n.level:
                    base = pkg.split(".")[:len(pkg.split(".")) - (n.level - 1)]
                    mod = ".".join(base + ([n.module] if n.module else []))
                else:
                    mod = n.module or ""
                subs = [f"{mod}.{a.name}" for a in n.names if f"{mod}.{a.name}" in mods]
                for s in subs:
                    add(s, n.lineno)
                if not subs or any(f"{mod}.{a.name}" not in mods for a in n.names):
                    add(mod, n.lineno)
        edges[m] = out
    return edges


def _cycles(edges: dict[str, dict[str, int]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def _where(mods: dict[str, Path], edges: dict[str, dict[str, int]], a: str, b: str) -> str:
    return f"{mods[a].relative_to(HOST.parent)}:{edges[a][b]}: {a} -> {b}"


def test_scanner_sees_function_local_and_relative_imports():
    mods = _modules()
    edges = _imports(mods)
    assert "multisonar.urls" in edges["multisonar.device"]  # module level, relative
    assert "multisonar.usb.inproc" in edges["multisonar.urls"]  # inside a function
    assert "multisonar.usb.usbip_proto" in edges["multisonar.usb.usbip_client"]  # ``from .x import (...)``
    assert "multisonar.protocol" in edges["multisonar.usb.usbip_client"]  # ``from .. import protocol``
    assert "multisonar.device" in edges["multisonar"]


def test_no_import_cycles():
    mods = _modules()
    edges = _imports(mods)
    report = []
    for comp in _cycles(edges):
        report.append("cycle: " + ", ".join(comp))
        report += ["    " + _where(mods, edges, a, b) for a in comp for b in edges[a] if b in comp]
    assert not report, "import cycles in host/multisonar:\n" + "\n".join(report)


def test_driver_imports_no_device_model_nor_usbip():
    mods = _modules()
    edges = _imports(mods)
    direct = [_where(mods, edges, DRIVER, b) for b in edges[DRIVER] if b.startswith(NOT_FROM_DRIVER)]
    assert not direct, "the driver imports what should register itself:\n" + "\n".join(direct)
    # nor through another module: everything the driver pulls in, transitively
    seen, todo = {DRIVER}, [DRIVER]
    via: dict[str, str] = {}
    while todo:
        a = todo.pop()
        for b in edges[a]:
            if b not in seen:
                seen.add(b)
                via[b] = a
                todo.append(b)
    bad = sorted(m for m in seen if m.startswith(NOT_FROM_DRIVER))
    chains = []
    for m in bad:
        chain = [m]
        while chain[-1] != DRIVER:
            chain.append(via[chain[-1]])
        chains.append(" <- ".join(chain))
    assert not bad, "the driver reaches them through:\n" + "\n".join(chains)


def test_entry_points_match_the_source_tree_table():
    """pyproject's multisonar.schemes entry points are the ones the registry falls back to in an
    uninstalled source tree, and the installed metadata is current (re-install after editing)."""
    meta = tomllib.loads((HOST / "pyproject.toml").read_text())
    declared = meta["project"]["entry-points"][urls.ENTRY_POINT_GROUP]
    assert declared == urls._SOURCE_TREE_SCHEMES
    installed = {ep.name: ep.value for ep in urls._entry_points() if ep.value.startswith("multisonar.")}
    assert installed == declared, "stale metadata: pip install --no-deps --no-build-isolation -e host"


def test_unknown_scheme_names_it_and_lists_the_known_ones():
    with pytest.raises(urls.UnknownScheme) as ei:
        Device.open("bogus://somewhere")
    msg = str(ei.value)
    assert "'bogus'" in msg and "bogus://somewhere" in msg
    for name in ("usb", "libusb", "usbip", "sim", "twin"):
        assert f"{name}://" in msg
    assert isinstance(ei.value, ValueError) and ei.value.scheme == "bogus"
    with pytest.raises(urls.UnknownScheme, match="no scheme.*sim://"):
        Device.open("corridor")
    assert set(urls.schemes()) >= {"usb", "libusb", "usbip", "sim", "twin"}
    assert all(urls.schemes().values())  # every scheme has a help line


def test_third_party_scheme_and_model():
    from multisonar.simdevice import SimDevice

    built = []

    def model(url: urls.DeviceUrl) -> urls.Model:
        """x-mine://SCENE: a replaying simulated device"""
        sim = SimDevice(url.target, source="replay")
        built.append((url.target, dict(url.query)))
        return urls.Model(sim, close=sim.close)

    urls.register_scheme("x-mine", model=model, help=model.__doc__)
    try:
        with pytest.raises(urls.SchemeError, match="already registered"):
            urls.register_scheme("x-mine", lambda url, *, timeout_s: None)
        assert "x-mine" in urls.scheme_names()
        with Device.open("x-mine://corridor?k=v") as dev:
            assert dev.info().simulated
        assert built == [("corridor", {"k": "v"})]
        assert isinstance(urls.make_model("x-mine://corridor").function, SimDevice)
        with pytest.raises(urls.SchemeError, match="not a device model.*sim://"):
            urls.make_model("usb://")
    finally:
        urls.unregister_scheme("x-mine")
    with pytest.raises(urls.UnknownScheme):
        Device.open("x-mine://corridor")
    with pytest.raises(urls.SchemeError, match="bad scheme name"):
        urls.register_scheme("Bad_Name", model=model)


def test_sim_url_works_after_importing_only_the_package():
    """A fresh interpreter: ``from multisonar import Device`` and sim:// opens through the
    entry point, which imports the simulated device but not the twin nor USB/IP."""
    code = ("import sys\n"
            "from multisonar import Device\n"
            "assert 'multisonar.simdevice' not in sys.modules\n"
            "with Device.open('sim://corridor?source=replay') as dev:\n"
            "    assert dev.info().simulated\n"
            "print(sorted(m for m in sys.modules if m.startswith(('multisonar.twin', 'multisonar.usb.usbip'))))\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"
