"""What a scorecard's numbers depend on besides the scenario, runs and seed: windwarden's code, numpy, scipy and
Python. A cluster's workers must match this process (``cluster.check_environments``); ``eval --out`` records it in
``execution.json``."""

from __future__ import annotations

import functools
import hashlib
import importlib
import importlib.metadata
import platform
from pathlib import Path

import numpy as np
import scipy

CODE_PACKAGES = ("wwcore", "plant_sim", "service", "windwarden")  # the code a scorecard's numbers come from


@functools.cache
def environment() -> dict[str, str]:
    """windwarden's version and code fingerprint, numpy, scipy and Python versions (once per process)."""
    return {
        "windwarden": importlib.metadata.version("windwarden"),
        "code": code_fingerprint(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "python": platform.python_version(),
    }


def code_fingerprint() -> str:
    """SHA-256 (first 16 hex digits) of the Python sources of the packages that compute a scorecard: each file's
    path and contents, in sorted order, so an edited file or a different release shows."""
    digest = hashlib.sha256()
    for package in CODE_PACKAGES:
        root = Path(importlib.import_module(package).__file__).parent
        for path in sorted(root.rglob("*.py")):
            digest.update(str(path.relative_to(root.parent)).encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()[:16]
