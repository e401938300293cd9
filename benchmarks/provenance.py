"""Where and when a benchmark measured: the `measured` block every benchmarks/results/*.json carries, so that
BENCHMARKS.md (generated from the results by benchmarks/report.py) states it beside the numbers."""

from __future__ import annotations

import os
import platform
import time
from importlib import metadata
from pathlib import Path

PACKAGES = ("fmpy", "casadi", "numpy", "distributed", "pyarrow", "pythonfmu")


def _cpu() -> str:
    try:
        names = [line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                 if line.startswith("model name")]
    except OSError:
        names = []
    return f"{os.cpu_count()} × {names[0] if names else platform.processor() or platform.machine()}"


def _memory() -> str:
    try:
        kib = int(next(line.split()[1] for line in Path("/proc/meminfo").read_text().splitlines()
                       if line.startswith("MemTotal")))
        return f"{kib / 2**20:.0f} GiB"
    except (OSError, StopIteration, ValueError):
        return "unknown memory"


def _version(package: str) -> str | None:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return None


def stamp(conditions: str = "") -> dict:
    """The `measured` block: UTC time, machine, versions, the load average when the measurement ended (the machine
    may be shared: absolute times then scatter, ratios measured side by side in one process hold better)."""
    return {"utc": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "machine": f"{_cpu()}, {_memory()}, {platform.system()} {platform.release()}",
            "python": platform.python_version(),
            "versions": {name: _version(name) for name in PACKAGES if _version(name)},
            "load_average_1min": round(os.getloadavg()[0], 1),
            "conditions": conditions}
