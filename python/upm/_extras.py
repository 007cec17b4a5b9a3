"""Optional dependencies: a missing one raises `MissingExtraError` naming the extra to install."""

from __future__ import annotations

import importlib
from types import ModuleType

from ._errors import MissingExtraError

__all__ = ["need"]


def need(module: str, extra: str, what: str, package: str | None = None) -> ModuleType:
    """Import ``module``; if it is not installed, `MissingExtraError` saying that ``what`` needs
    it and how to install it (``pip install 'upm[extra]'``)."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingExtraError(
            f"{what} needs {package or module.split('.')[0]}, which is not installed: "
            f"pip install 'upm[{extra}]'"
        ) from None  # the message says it all; the chained ModuleNotFoundError only confuses
