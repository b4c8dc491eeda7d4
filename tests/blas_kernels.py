"""Print the OpenBLAS kernels other than this machine's own that its CPU can run.

``make test`` runs the solver tests once more under each of them
(``OPENBLAS_CORETYPE``), so that a result that depends on how one BLAS kernel rounds
shows up on any machine. A kernel is listed only if the CPU has the
instructions it needs (SkylakeX: AVX-512; Haswell: AVX2 and FMA; Sandybridge: AVX):
forcing one the CPU lacks would crash with an illegal instruction. The machine's own
kernel is read from OpenBLAS itself (threadpoolctl), so a CPU that OpenBLAS maps to
another family's kernels (Zen to Haswell, say) is handled as OpenBLAS handles it.

Usage: ``python tests/blas_kernels.py`` -> e.g. ``SkylakeX Sandybridge``.
"""
from __future__ import annotations

import platform
import sys
from pathlib import Path

#: Kernel -> the CPU flags (/proc/cpuinfo) it needs.
KERNELS = {"SkylakeX": ("avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"),
           "Haswell": ("avx2", "fma"),
           "Sandybridge": ("avx",)}


def cpu_flags(cpuinfo: str) -> set[str]:
    """The flags of the first processor in ``/proc/cpuinfo`` text."""
    for line in cpuinfo.splitlines():
        if line.startswith("flags"):
            return set(line.split(":", 1)[1].split())
    return set()


def own_kernels() -> set[str]:
    """The kernels OpenBLAS chose in this process (numpy's and scipy's copies)."""
    import numpy  # noqa: F401 -- loads numpy's OpenBLAS
    import scipy.linalg  # noqa: F401 -- loads scipy's
    from threadpoolctl import threadpool_info

    return {str(i.get("architecture")) for i in threadpool_info()
            if i.get("internal_api") == "openblas"}


def other_kernels(flags: set[str], own: set[str]) -> list[str]:
    """The kernels of :data:`KERNELS` the CPU can run, less the ones in use."""
    own_lower = {k.lower() for k in own}
    return [k for k, needs in KERNELS.items()
            if set(needs) <= flags and k.lower() not in own_lower]


def main() -> int:
    if platform.machine() not in ("x86_64", "AMD64"):
        return 0                          # the x86 kernels only; elsewhere nothing to add
    try:
        flags = cpu_flags(Path("/proc/cpuinfo").read_text())
    except OSError:
        return 0
    print(" ".join(other_kernels(flags, own_kernels())))
    return 0


if __name__ == "__main__":
    sys.exit(main())
