"""The package version, in a module of its own so that any module can read it without
importing the package's ``__init__`` (which imports the driver): ``multisonar.__version__``
re-exports it."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version as _version

try:
    __version__ = _version("multisonar")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+src"
