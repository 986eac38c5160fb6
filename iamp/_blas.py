"""One BLAS kernel on every x86-64 machine, so that the same command gives the same numbers.

numpy's and scipy's wheels carry OpenBLAS built for many CPUs (``DYNAMIC_ARCH``): at load time it
picks the kernels of the CPU it runs on, and the kernels add in different orders.  A matrix product
then differs in the last bits from one machine to the next, and a closed-loop episode, whose
decisions compare such numbers with thresholds, can take another course.  On one machine,
``OPENBLAS_CORETYPE=K iamp simulate --planner free --seed 2 --json`` merged after 12.5 s with
``K=Haswell``, 12.7 s with ``K=SkylakeX`` and 34.9 s with ``K=Prescott``.

:func:`pin` asks OpenBLAS for the ``Haswell`` kernels (AVX2 and FMA, which x86-64 CPUs have had
since 2013; its generic kernels where the CPU lacks them) and Intel MKL for its conditional
numerical reproducibility (``MKL_CBWR=COMPATIBLE``), each with one thread. It only takes effect
before numpy is first imported (OpenBLAS reads the setting when it loads): ``iamp``'s command line
always does so; a program that imports numpy before iamp keeps its machine's kernels. A value the
user set is kept. Importing this module (``iamp`` does so first) calls it. Other processors (ARM)
and other BLAS libraries keep their kernels.
"""

from __future__ import annotations

import os
import platform
import sys

__all__ = ["KERNEL", "THREADS", "pin", "pinned_kernel"]

#: The OpenBLAS kernels iamp asks for on an x86-64 CPU with AVX2 and FMA.
KERNEL = "Haswell"
#: The kernels where the CPU lacks them (OpenBLAS's generic x86-64 kernels; it reports them as ``Katmai``).
FALLBACK = "Prescott"


def _cpu_flags() -> set[str]:
    """The CPU's feature flags as Linux lists them (empty where ``/proc/cpuinfo`` cannot be read)."""
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as f:
            for line in f:
                if line.startswith("flags"):
                    return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


def pinned_kernel() -> str | None:
    """The OpenBLAS kernel :func:`pin` asks for on this machine (``None``: not an x86-64 CPU)."""
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return None
    return KERNEL if {"avx2", "fma"} <= _cpu_flags() else FALLBACK


#: BLAS threads: one.  iamp's matrices are small, and OpenBLAS's second thread only spun: it doubled
#: the CPU time of an avoidance plan (13 ms of wall, 25 ms of CPU) at the same wall time, and a
#: campaign's worker processes already use the cores.
THREADS = "1"


def pin() -> None:
    """Set ``OPENBLAS_CORETYPE`` (and ``MKL_CBWR``) and one BLAS thread (``OPENBLAS_NUM_THREADS``,
    ``MKL_NUM_THREADS``) unless numpy is loaded or the user set them."""
    if "numpy" in sys.modules:
        return
    os.environ.setdefault("OPENBLAS_NUM_THREADS", THREADS)
    os.environ.setdefault("MKL_NUM_THREADS", THREADS)
    kernel = pinned_kernel()
    if kernel is not None:
        os.environ.setdefault("OPENBLAS_CORETYPE", kernel)
        os.environ.setdefault("MKL_CBWR", "COMPATIBLE")


pin()
