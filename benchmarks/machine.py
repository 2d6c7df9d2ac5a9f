"""What every benchmark prints first: the machine its figures were taken on.

The benchmarks run as scripts (``python benchmarks/bench_*.py``), so this module is
imported from the script's own folder.
"""

from __future__ import annotations

import os
import platform


def machine() -> str:
    """Return the host name, CPU model, core count and load average (1, 5, 15 min)."""
    model = platform.processor() or platform.machine() or "unknown CPU"
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as info:
            for line in info:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    return f"{platform.node()}: {model}, nproc {os.cpu_count()}, load average {load}"
