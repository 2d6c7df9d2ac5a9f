"""What every benchmark prints first: the machine its figures were taken on.

The benchmarks run as scripts (``python benchmarks/bench_*.py``), so this module is
imported from the script's own folder.
"""

from __future__ import annotations

import os
import platform

#: CPU flags (``/proc/cpuinfo``) that change how fast numpy, BLAS and FFTW run, by name.
VECTOR_FLAGS = (("avx512f", "AVX-512"), ("avx2", "AVX2"), ("fma", "FMA"))


def _cpuinfo() -> tuple[str, set[str]]:
    """Return the CPU model and its flags from ``/proc/cpuinfo`` (empty when unreadable)."""
    model, flags = "", set()
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as info:
            for line in info:
                if line.startswith("model name") and not model:
                    model = line.split(":", 1)[1].strip()
                elif line.startswith("flags") and not flags:
                    flags = set(line.split(":", 1)[1].split())
                if model and flags:
                    break
    except OSError:
        pass
    return model, flags


def vector_extensions() -> str:
    """Return the CPU's vector extensions that matter here, e.g. ``"AVX2, FMA, no AVX-512"``."""
    _, flags = _cpuinfo()
    if not flags:
        return "vector extensions unknown"
    have = [name for flag, name in VECTOR_FLAGS if flag in flags]
    if "avx512f" not in flags:
        have.append("no AVX-512")
    return ", ".join(have)


def machine() -> str:
    """Return the host name, CPU model, vector extensions, core count and load average."""
    model = _cpuinfo()[0] or platform.processor() or platform.machine() or "unknown CPU"
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    return (
        f"{platform.node()}: {model} ({vector_extensions()}), nproc {os.cpu_count()}, "
        f"load average {load}"
    )
