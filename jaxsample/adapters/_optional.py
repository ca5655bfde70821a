"""The adapters' libraries are an optional extra: a missing one is named, with the install line."""

from __future__ import annotations

import importlib.util

EXTRA = 'pip install "jaxsample[adapters]"'


def require(module: str, library: str) -> None:
    """Raise an `ImportError` naming `library` and the extra when `module` is not installed."""
    if importlib.util.find_spec(module) is None:
        raise ImportError(f"this jaxsample adapter needs {library}, which is not installed; "
                          f"it comes with the adapters extra: {EXTRA}", name=module)
