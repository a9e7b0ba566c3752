"""The machine a timing was measured on, written beside every timing report (bench, scaling, the VEIL pipeline)."""

from __future__ import annotations

import os
import platform
from typing import Any


def machine() -> dict[str, Any]:
    """Python's version, the processor's architecture and the CPUs the system has."""
    return {"python": platform.python_version(), "processor": platform.machine(), "cpus": os.cpu_count() or 1}
