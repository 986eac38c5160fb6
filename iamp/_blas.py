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
always does so; a program that imports numpy before iamp keeps its machine's kernels, and
``import iamp`` then warns (:class:`BlasKernelWarning`, :func:`warn_if_unpinned`) where the kernels
numpy loaded are not the pinned ones (a closed-loop episode may then differ from the command
line's). A value the user set is kept. Importing this module (``iamp`` does so first) calls
:func:`pin` and :func:`pin_piqp`. Other processors (ARM) and other BLAS libraries keep their kernels.

numpy's own loops dispatch by CPU too: on a CPU with AVX-512 (numpy's ``X86_V4`` group and beyond)
its float64 ``power``, ``exp``, ``log``, ``sin``, ``cos`` and others run other implementations (SVML's,
its own AVX-512 ones) than on an AVX2 CPU, which differ in the last bits (``np.power(xs, 3)`` is in the
PMP's value function, ``planners/pmp/fixed.py``).  :func:`pin` therefore also switches those targets
off (``NPY_DISABLE_CPU_FEATURES``, numpy 2.4's names, :data:`NUMPY_DISABLED`) on a CPU that has
them, so that numpy runs its AVX2 (``X86_V3``) loops there as everywhere; a value the user set is
kept.  Only numpy 2.4's target names are known here (another numpy is left alone: a name it does not
dispatch makes it print a complaint at import), and a program that imports numpy before iamp keeps
its loops (:func:`numpy_avx512` says which run; ``iamp bench`` records it).

PIQP ships three builds of its bindings (``piqp_python_avx512``, ``piqp_python_avx2`` and a baseline
one) and its package picks the first the CPU supports, as told by its ``piqp.instruction_set``
module. Its AVX-512 build reports the backend check's KKT residuals of an avoidance plan differently
in the last bits (measured on an AMD EPYC with AVX-512: the plans themselves, statuses, costs,
crossing times, states and inputs, were the same on 60 plans).  Importing this module therefore
installs an import hook (:func:`pin_piqp`) that switches the ``avx512f`` flag of piqp's own
``instruction_set`` module off when piqp loads it, so that PIQP loads its AVX2 build there as on
every AVX2 machine; iamp's import loads nothing of piqp, and only one build is ever loaded.  A
program that imports piqp before iamp keeps its build (:func:`piqp_build` says which is loaded;
``iamp bench`` records it).
"""

from __future__ import annotations

import ctypes
import glob
import os
import platform
import sys
import warnings
from typing import Any

__all__ = ["KERNEL", "NUMPY_DISABLED", "THREADS", "BlasKernelWarning", "cpu_model", "loaded_kernel", "numpy_avx512",
           "numpy_disabled", "pin", "pin_piqp", "pinned_kernel", "piqp_build", "warn_if_unpinned"]

#: The OpenBLAS kernels iamp asks for on an x86-64 CPU with AVX2 and FMA.
KERNEL = "Haswell"
#: The kernels where the CPU lacks them (OpenBLAS's generic x86-64 kernels; it reports them as ``Katmai``).
FALLBACK = "Prescott"


def _cpuinfo(field: str) -> str | None:
    """The text after the colon of ``/proc/cpuinfo``'s first line starting with ``field`` (None where
    the file cannot be read or has no such line)."""
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as f:
            for line in f:
                if line.startswith(field):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return None


def _cpu_flags() -> set[str]:
    """The CPU's feature flags as Linux lists them (empty where ``/proc/cpuinfo`` cannot be read)."""
    return set((_cpuinfo("flags") or "").split())


def cpu_model() -> str | None:
    """The CPU's model name from ``/proc/cpuinfo`` (None where it is not there)."""
    return _cpuinfo("model name")


def pinned_kernel() -> str | None:
    """The OpenBLAS kernel :func:`pin` asks for on this machine (``None``: not an x86-64 CPU)."""
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return None
    return KERNEL if {"avx2", "fma"} <= _cpu_flags() else FALLBACK


#: BLAS threads: one.  iamp's matrices are small, and OpenBLAS's second thread only spun: it doubled
#: the CPU time of an avoidance plan (13 ms of wall, 25 ms of CPU) at the same wall time, and a
#: campaign's worker processes already use the cores.
THREADS = "1"


#: numpy's SIMD targets above AVX2 and FMA (``X86_V3``) that :func:`pin` switches off, in numpy 2.4's
#: names (its ``__cpu_dispatch__`` on x86-64: ``X86_V3 X86_V4 AVX512_ICL AVX512_SPR``).
NUMPY_DISABLED = "X86_V4 AVX512_ICL AVX512_SPR"


def _numpy_version() -> tuple[int, int] | None:
    """numpy's installed ``(major, minor)`` from its metadata, without importing it (None: unknown)."""
    try:
        from importlib.metadata import version

        major, minor = version("numpy").split(".")[:2]
        return int(major), int("".join(c for c in minor if c.isdigit()) or 0)
    except Exception:  # not installed, or a version string of another form
        return None


def numpy_disabled() -> str | None:
    """The value :func:`pin` gives ``NPY_DISABLE_CPU_FEATURES`` on this machine: :data:`NUMPY_DISABLED`
    on an x86-64 CPU with AVX-512 (``avx512f``) and numpy 2.4, else None (nothing to switch off, or
    a numpy whose target names are not known here: a name it does not dispatch makes it print a
    complaint at import)."""
    if pinned_kernel() is None or "avx512f" not in _cpu_flags():
        return None
    return NUMPY_DISABLED if _numpy_version() == (2, 4) else None


def pin() -> None:
    """Set ``OPENBLAS_CORETYPE`` (and ``MKL_CBWR``), one BLAS thread (``OPENBLAS_NUM_THREADS``,
    ``MKL_NUM_THREADS``) and numpy's SIMD targets (``NPY_DISABLE_CPU_FEATURES``, :func:`numpy_disabled`)
    unless numpy is loaded or the user set them."""
    if "numpy" in sys.modules:
        return
    os.environ.setdefault("OPENBLAS_NUM_THREADS", THREADS)
    os.environ.setdefault("MKL_NUM_THREADS", THREADS)
    kernel = pinned_kernel()
    if kernel is not None:
        os.environ.setdefault("OPENBLAS_CORETYPE", kernel)
        os.environ.setdefault("MKL_CBWR", "COMPATIBLE")
    simd = numpy_disabled()
    if simd is not None:
        os.environ.setdefault("NPY_DISABLE_CPU_FEATURES", simd)


#: PIQP's bindings, by the module its package loads (``piqp/__init__.py``, version 0.7).
PIQP_BUILDS = ("piqp_python_avx512", "piqp_python_avx2", "piqp_python")


class _PiqpAvx2:
    """The import hook of :func:`pin_piqp`: finds ``piqp.instruction_set`` as the other finders do and
    switches its ``avx512f`` flag off once loaded, where piqp's folder has its AVX2 build."""

    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> Any:
        if fullname != "piqp.instruction_set" or not path:
            return None
        from importlib.machinery import PathFinder

        spec = PathFinder.find_spec(fullname, path, target)
        if spec is None or spec.loader is None or not any(
                glob.glob(os.path.join(folder, PIQP_BUILDS[1] + ".*")) for folder in path):
            return spec
        spec.loader = _FlagOff(spec.loader)  # type: ignore[assignment]
        return spec


class _FlagOff:
    """A loader that runs ``loader`` and then switches the module's ``avx512f`` flag off (where it has one)."""

    def __init__(self, loader: Any) -> None:
        self.loader = loader

    def create_module(self, spec: Any) -> Any:
        return self.loader.create_module(spec)

    def exec_module(self, module: Any) -> None:
        self.loader.exec_module(module)
        if isinstance(getattr(module, "avx512f", None), bool):
            module.avx512f = False


def pin_piqp() -> bool:
    """Make piqp load its AVX2 build on an x86-64 CPU with AVX-512 (module docstring).

    Installs an import hook (first in ``sys.meta_path``) that, when piqp's package imports its own
    ``instruction_set`` extension module, loads it from piqp's folder as Python would and then
    switches its ``avx512f`` flag off, so that the package's choice falls on ``piqp_python_avx2``.
    Nothing of piqp is imported here.  Nothing happens where piqp is already imported, where the CPU
    lacks AVX-512 or AVX2 and FMA, or on another processor; the hook leaves the module alone where
    piqp's folder has no AVX2 build or the module no ``avx512f`` flag (another layout of piqp).

    Returns
    -------
    bool
        Whether the hook is installed (now or before).
    """
    if any(isinstance(f, _PiqpAvx2) for f in sys.meta_path):
        return True
    if "piqp" in sys.modules or "piqp.instruction_set" in sys.modules:
        return False
    if pinned_kernel() != KERNEL or "avx512f" not in _cpu_flags():
        return False
    sys.meta_path.insert(0, _PiqpAvx2())
    return True


def piqp_build() -> str | None:
    """The build of piqp's bindings loaded in this process (one of :data:`PIQP_BUILDS`; None where
    piqp is not loaded)."""
    for name in PIQP_BUILDS:
        if "piqp." + name in sys.modules:
            return name
    return None


def numpy_avx512() -> list[str]:
    """numpy's AVX-512 dispatch targets (``X86_V4``, ``AVX512*``) that run in this process: those
    among the targets its loops were built for (``__cpu_dispatch__``) that its runtime
    ``__cpu_features__`` reports on (empty where numpy is not loaded or does not say).  The CPU's
    own AVX-512 features stay on in ``__cpu_features__`` when ``NPY_DISABLE_CPU_FEATURES`` switches
    the targets off, so they are not what is reported."""
    numpy = sys.modules.get("numpy")
    if numpy is None:
        return []
    import importlib

    for name in ("numpy._core._multiarray_umath", "numpy.core._multiarray_umath"):  # numpy >= 2, numpy 1
        try:
            module = importlib.import_module(name)
            features, dispatch = module.__cpu_features__, module.__cpu_dispatch__
            break
        except (ImportError, AttributeError):
            continue
    else:
        return []
    return sorted(k for k in dispatch if features.get(k) and (k == "X86_V4" or k.startswith("AVX512")))


#: The corename functions of the OpenBLAS builds numpy's wheels bundle (scipy-openblas, 64-bit
#: interface) and of a plain OpenBLAS.
_CORENAME_FUNCTIONS = ("scipy_openblas_get_corename64_", "openblas_get_corename64_", "openblas_get_corename")


class BlasKernelWarning(RuntimeWarning):
    """numpy was imported before iamp with other BLAS kernels than the ones iamp pins: numbers may
    differ in their last bits from the command line's, and a closed-loop episode may take another
    course (module docstring)."""


def loaded_kernel() -> str | None:
    """The kernels (corename) of the OpenBLAS that numpy's wheel bundles, as loaded in this process;
    ``None`` where numpy is not loaded, or its BLAS is not a bundled OpenBLAS (a system BLAS, MKL)."""
    numpy = sys.modules.get("numpy")
    path = getattr(numpy, "__file__", None)
    if not path:
        return None
    for lib in sorted(glob.glob(os.path.join(os.path.dirname(path), os.pardir, "numpy.libs", "*openblas*"))):
        try:
            handle = ctypes.CDLL(lib)
        except OSError:
            continue
        for name in _CORENAME_FUNCTIONS:
            f = getattr(handle, name, None)
            if f is not None:
                f.restype = ctypes.c_char_p
                out = f()
                return out.decode("ascii", "replace").strip() if out else None
    return None


def warn_if_unpinned() -> str | None:
    """Warn (:class:`BlasKernelWarning`) when numpy's OpenBLAS runs other kernels than
    :func:`pinned_kernel` and the user did not choose them (``OPENBLAS_CORETYPE`` unset): numpy was
    imported before iamp (:data:`NUMPY_FIRST`).  Returns the warning's text, or None.  (numpy's
    AVX-512 loops, where numpy was imported first, are not warned about: :func:`numpy_avx512` says
    whether they run, and ``iamp bench`` records it.)"""
    wanted = pinned_kernel()
    if not NUMPY_FIRST or wanted is None or os.environ.get("OPENBLAS_CORETYPE"):
        return None
    loaded = loaded_kernel()
    if loaded is None or loaded.lower() == wanted.lower():
        return None
    text = (f"numpy was imported before iamp and its OpenBLAS runs the {loaded} kernels, not {wanted}: results "
            f"may differ in their last bits from the command line's, and a closed-loop episode may take another "
            f"course; import iamp before numpy, or set OPENBLAS_CORETYPE={wanted} before starting Python")
    warnings.warn(text, BlasKernelWarning, stacklevel=3)
    return text


#: Whether numpy was loaded before this module (then :func:`pin` could not choose its kernels).
NUMPY_FIRST = "numpy" in sys.modules
pin()
pin_piqp()
