"""Device URL schemes: a registry from a URL's scheme (``usb``, ``sim``, ``usbip``, ...) to the
code that opens it, so that :meth:`multisonar.Device.open` needs no knowledge of what lies
behind a scheme (as pyftdi's URL schemes: the driver resolves a URL, the fake device is never
imported by the driver).

Who registers what:

* the driver (:mod:`multisonar.device`) registers its own schemes, ``usb`` and ``libusb`` (the
  board on libusb);
* every other scheme is registered by the module that implements it, in a block at the end of
  that module (:mod:`multisonar.simdevice`: ``sim``, :mod:`multisonar.twin`: ``twin``,
  :mod:`multisonar.usb.usbip_client`: ``usbip``);
* a scheme that nobody has registered yet is looked up among the entry points of the group
  ``multisonar.schemes`` (``[project.entry-points."multisonar.schemes"]`` in
  ``host/pyproject.toml``, or in any other installed package); the entry point is loaded on
  first use, which imports the module and so registers the scheme. That is how
  ``import multisonar; multisonar.Device.open("sim://corridor")`` finds the simulated device
  without the driver importing it, and how a third-party package adds a scheme.

An entry point names either a module that calls :func:`register_scheme` when imported
(``sim = "multisonar.simdevice"``) or an opener itself (``mine = "pkg.mod:open_mine"``; its
docstring's first line is the help). A scheme is either an *opener*
(``opener(url: DeviceUrl, *, timeout_s) -> Connection``: finds the pyusb device itself, as
``usbip``) or a *model* (``model(url: DeviceUrl) -> Model``: builds a device-side
:class:`~multisonar.usb.function.UsbFunction`, which the registry opens through the in-process
pyusb backend and :func:`make_model` hands to servers such as the USB/IP server).
"""

from __future__ import annotations

import re
import threading
from dataclasses import dataclass, field
from importlib.metadata import EntryPoint, PackageNotFoundError, distribution, entry_points
from types import ModuleType
from typing import Any, Callable, Mapping
from urllib.parse import parse_qs, unquote, urlparse

from . import protocol as P
from .errors import DeviceNotFound

#: entry-point group of URL schemes (name = scheme, value = module or opener)
ENTRY_POINT_GROUP = "multisonar.schemes"

#: this package's own entry points, used only when it runs from a source tree without being
#: installed (no metadata, so no entry points); tests/test_layering.py checks that they equal
#: the ones of host/pyproject.toml
_SOURCE_TREE_SCHEMES = {"sim": "multisonar.simdevice", "twin": "multisonar.twin",
                        "usbip": "multisonar.usb.usbip_client"}

_NAME = re.compile(r"[a-z][a-z0-9+.-]*\Z")  # RFC 3986 scheme, lower case (urlparse lowers it)


class SchemeError(ValueError):
    """A URL scheme cannot be registered, loaded or used as asked."""


class UnknownScheme(SchemeError):
    """No scheme of that name is registered or declared by an entry point."""

    def __init__(self, scheme: str, known: list[str], url: str | None = None) -> None:
        self.scheme, self.known, self.url = scheme, list(known), url
        listing = ", ".join(f"{k}://" for k in self.known) or "none"
        if scheme:
            what = f"unknown device URL scheme {scheme!r}" + (f" in {url!r}" if url is not None else "")
        else:
            what = f"device URL {url!r} has no scheme (SCHEME://...)"
        super().__init__(f"{what}; known schemes: {listing} (multisonar.urls.schemes() describes them)")


@dataclass(frozen=True)
class DeviceUrl:
    """A parsed device URL, as openers and models receive it."""

    url: str  #: as given
    scheme: str  #: lower case
    netloc: str
    path: str
    query: Mapping[str, str] = field(default_factory=dict)  #: ``?k=v&...`` (the last of repeated keys)

    @property
    def target(self) -> str:
        """``netloc + path`` without surrounding slashes, %-decoded: the scene of ``sim://corridor``
        (``sim://%2Fdata%2Fhall.yaml`` for an absolute path)."""
        return unquote((self.netloc + self.path).strip("/"))

    @property
    def hostname(self) -> str | None:
        return urlparse(self.url).hostname

    @property
    def port(self) -> int | None:
        return urlparse(self.url).port


def parse_url(url: str) -> DeviceUrl:
    u = urlparse(url)
    return DeviceUrl(url, u.scheme.lower(), u.netloc, u.path, {k: v[-1] for k, v in parse_qs(u.query).items()})


@dataclass
class Connection:
    """What an opener returns: a pyusb device (``usb.core.Device``) ready for the driver."""

    device: Any
    cleanup: Callable[[], None] | None = None  #: called by ``Device.close()`` (and on a failed open)
    min_timeout_s: float = 0.0  #: the driver's timeouts are raised to this (slow models)


@dataclass
class Model:
    """What a model factory returns: a device-side UsbFunction and how to release it."""

    function: Any  #: a multisonar.usb.function.UsbFunction
    close: Callable[[], None] | None = None
    min_timeout_s: float = 0.0


Opener = Callable[..., Connection]  #: ``opener(url: DeviceUrl, *, timeout_s: float) -> Connection``
ModelFactory = Callable[[DeviceUrl], Model]


@dataclass(frozen=True)
class Scheme:
    name: str
    opener: Opener
    help: str = ""
    model: ModelFactory | None = None
    origin: str = ""  #: module.qualname of what was registered


_registry: dict[str, Scheme] = {}
_loaded: set[tuple[str, str]] = set()  # entry points (name, value) loaded
_lock = threading.Lock()  # held only while the registry changes, never while a plugin imports


def _origin(obj: Any) -> str:
    return f"{getattr(obj, '__module__', '?')}.{getattr(obj, '__qualname__', type(obj).__name__)}"


def _first_line(doc: str | None) -> str:
    return (doc or "").strip().split("\n", 1)[0].strip()


def register_scheme(name: str, opener: Opener | None = None, *, help: str = "",  # noqa: A002 - argparse's name
                    model: ModelFactory | None = None, replace: bool = False) -> Scheme:
    """Register ``name://``: an ``opener(url, *, timeout_s) -> Connection`` or a
    ``model(url) -> Model`` (then the opener is the in-process backend on the model).

    Registering a name again is an error unless ``replace`` or it is the same function
    (a module imported twice); :func:`unregister_scheme` removes one."""
    if not isinstance(name, str) or not _NAME.match(name):
        raise SchemeError(f"bad scheme name {name!r}: lower-case letters, digits, '+', '-', '.'; a letter first")
    if opener is None and model is None:
        raise TypeError(f"register_scheme({name!r}): give an opener or a model")
    what = opener if opener is not None else model
    scheme = Scheme(name, opener if opener is not None else _inprocess_opener(model), help, model, _origin(what))
    with _lock:
        old = _registry.get(name)
        if old is not None and not replace and old.origin != scheme.origin:
            raise SchemeError(f"scheme {name!r} is already registered (by {old.origin}); pass replace=True "
                              "or unregister_scheme() it first")
        _registry[name] = scheme
    return scheme


def unregister_scheme(name: str) -> Scheme | None:
    with _lock:
        return _registry.pop(name, None)


def _entry_points() -> list[EntryPoint]:
    eps = list(entry_points(group=ENTRY_POINT_GROUP))
    try:
        distribution("multisonar")
    except PackageNotFoundError:  # a source tree on sys.path: no metadata, so no entry points of ours
        eps += [EntryPoint(n, v, ENTRY_POINT_GROUP) for n, v in _SOURCE_TREE_SCHEMES.items()]
    seen: set[tuple[str, str]] = set()
    out = []
    for ep in eps:
        if (ep.name, ep.value) not in seen:
            seen.add((ep.name, ep.value))
            out.append(ep)
    return out


def _load(ep: EntryPoint) -> None:
    if (ep.name, ep.value) in _loaded:
        return
    try:
        obj = ep.load()
    except Exception as e:  # noqa: BLE001 - a broken plugin is reported, with its cause
        raise SchemeError(f"the {ep.name}:// scheme's entry point {ep.value!r} failed to load: {e!r}") from e
    _loaded.add((ep.name, ep.value))
    if ep.name in _registry:
        return
    if callable(obj) and not isinstance(obj, ModuleType):
        register_scheme(ep.name, obj, help=_first_line(getattr(obj, "__doc__", None)))
    else:
        raise SchemeError(f"the entry point {ep.name} = {ep.value!r} (group {ENTRY_POINT_GROUP}) did not register "
                          f"the {ep.name}:// scheme: its module must call multisonar.urls.register_scheme"
                          f"({ep.name!r}, ...), or the entry point must name the opener")


def scheme_names() -> list[str]:
    """The registered schemes and those declared by entry points, sorted; imports nothing."""
    return sorted(set(_registry) | {ep.name for ep in _entry_points()})


def schemes() -> dict[str, str]:
    """Every known scheme with its help, sorted by name (loads every entry point; one that fails
    to load is listed with the reason)."""
    out: dict[str, str] = {}
    for ep in _entry_points():
        if ep.name not in _registry:
            try:
                _load(ep)
            except SchemeError as e:
                out[ep.name] = f"(unavailable: {e})"
    out.update({k: s.help for k, s in _registry.items()})
    return dict(sorted(out.items()))


def lookup(name: str, *, url: str | None = None) -> Scheme:
    """The scheme ``name``, loading its entry point if it is not registered yet.

    Raises :class:`UnknownScheme` (naming it and listing the known ones) or
    :class:`SchemeError` (its entry point failed to load)."""
    name = (name or "").lower()
    s = _registry.get(name)
    if s is None and name:
        for ep in _entry_points():
            if ep.name == name:
                _load(ep)
        s = _registry.get(name)
    if s is None:
        raise UnknownScheme(name, scheme_names(), url)
    return s


def open_url(url: str, *, timeout_s: float = 2.0) -> Connection:
    """Open ``url`` with its scheme's opener (what :meth:`multisonar.Device.open` does first)."""
    u = parse_url(url)
    return lookup(u.scheme, url=url).opener(u, timeout_s=timeout_s)


def make_model(url: str) -> Model:
    """The device-side model of a model scheme (``sim://corridor``), e.g. to serve it over USB/IP."""
    u = parse_url(url)
    s = lookup(u.scheme, url=url)
    if s.model is None:
        models = [k for k in scheme_names() if k in _registry and _registry[k].model is not None]
        raise SchemeError(f"{url}: the {u.scheme}:// scheme opens a connection, not a device model that can be "
                          f"served (registered model schemes: {', '.join(f'{k}://' for k in models) or 'none'})")
    return s.model(u)


def _inprocess_opener(model: ModelFactory | None) -> Opener:
    """The opener of a model scheme: the model behind the in-process pyusb backend."""
    assert model is not None

    def open_inprocess(url: DeviceUrl, *, timeout_s: float = 2.0) -> Connection:
        import usb.core

        from .usb.inproc import InProcessBackend

        m = model(url)
        try:
            dev = usb.core.find(idVendor=P.USB_VID, idProduct=P.USB_PID, backend=InProcessBackend(m.function))
        except BaseException:
            if m.close is not None:
                m.close()
            raise
        if dev is None:
            if m.close is not None:
                m.close()
            raise DeviceNotFound(f"{url.url}: the model does not identify as {P.USB_VID:04x}:{P.USB_PID:04x}")
        return Connection(dev, cleanup=m.close, min_timeout_s=m.min_timeout_s)

    open_inprocess.__doc__ = _first_line(getattr(model, "__doc__", None))
    return open_inprocess


__all__ = ["ENTRY_POINT_GROUP", "Connection", "DeviceUrl", "Model", "Scheme", "SchemeError", "UnknownScheme",
           "lookup", "make_model", "open_url", "parse_url", "register_scheme", "scheme_names", "schemes",
           "unregister_scheme"]
