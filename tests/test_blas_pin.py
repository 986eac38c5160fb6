"""iamp asks OpenBLAS for one kernel on every x86-64 machine (``iamp/_blas.py``): the same command gives
the same numbers whatever CPU it runs on, and a kernel the user chose is kept."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

from iamp import _blas

CORENAME = """
import ctypes, glob, os, sys
import iamp, numpy
libs = glob.glob(os.path.join(os.path.dirname(numpy.__file__), os.pardir, "numpy.libs", "*openblas*"))
for lib in libs:
    for name in ("scipy_openblas_get_corename64_", "openblas_get_corename64_", "openblas_get_corename"):
        f = getattr(ctypes.CDLL(lib), name, None)
        if f is not None:
            f.restype = ctypes.c_char_p
            print(f().decode()); sys.exit(0)
print("unknown")
"""


def _corename(**env: str) -> str:
    clean = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_CORETYPE", "MKL_CBWR")}
    out = subprocess.run([sys.executable, "-c", CORENAME], capture_output=True, text=True, env={**clean, **env},
                         timeout=120, check=True)
    return out.stdout.strip()


needs_x86 = pytest.mark.skipif(_blas.pinned_kernel() is None, reason="not an x86-64 CPU: iamp leaves BLAS alone")


@needs_x86
def test_importing_iamp_first_loads_the_pinned_kernel() -> None:
    name = _corename()
    if name == "unknown":
        pytest.skip("numpy's BLAS is not the bundled OpenBLAS")
    assert name.lower() == str(_blas.pinned_kernel()).lower()


@needs_x86
def test_a_kernel_the_user_chose_is_kept() -> None:
    name = _corename(OPENBLAS_CORETYPE="Sandybridge")
    if name == "unknown":
        pytest.skip("numpy's BLAS is not the bundled OpenBLAS")
    assert name.lower() == "sandybridge"


def test_the_kernel_follows_the_cpu_flags(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(platform, "machine", lambda: "x86_64")
    monkeypatch.setattr(_blas, "_cpu_flags", lambda: {"sse3", "avx", "avx2", "fma"})
    assert _blas.pinned_kernel() == "Haswell"
    monkeypatch.setattr(_blas, "_cpu_flags", lambda: {"sse3", "avx", "avx2"})  # no FMA
    assert _blas.pinned_kernel() == "Prescott"
    monkeypatch.setattr(platform, "machine", lambda: "aarch64")
    assert _blas.pinned_kernel() is None


def test_pin_changes_nothing_once_numpy_is_loaded(monkeypatch: pytest.MonkeyPatch) -> None:
    import numpy  # noqa: F401  (loaded: OpenBLAS has chosen its kernel already)

    monkeypatch.delenv("OPENBLAS_CORETYPE", raising=False)
    _blas.pin()
    assert "OPENBLAS_CORETYPE" not in os.environ


def test_one_blas_thread_unless_the_user_chose() -> None:
    code = "import os, iamp, numpy; print(os.environ.get('OPENBLAS_NUM_THREADS'))"
    clean = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    run = [sys.executable, "-c", code]
    assert subprocess.run(run, capture_output=True, text=True, env=clean, check=True).stdout.strip() == "1"
    chosen = subprocess.run(run, capture_output=True, text=True, env={**clean, "OPENBLAS_NUM_THREADS": "2"},
                            check=True).stdout.strip()
    assert chosen == "2"


def test_the_flags_are_read_from_cpuinfo_and_avx2_with_fma_is_enough(monkeypatch: pytest.MonkeyPatch,
                                                                      tmp_path: Path) -> None:
    fake = tmp_path / "cpuinfo"
    fake.write_text("processor\t: 0\nmodel name\t: x: y\nflags\t\t: fpu sse3 avx2 fma\nbugs\t\t: none\n",
                    encoding="ascii")
    real_open = open
    monkeypatch.setattr(_blas, "open", lambda path, *a, **k: real_open(fake, *a, **k), raising=False)
    assert _blas._cpu_flags() == {"fpu", "sse3", "avx2", "fma"}
    monkeypatch.setattr(platform, "machine", lambda: "x86_64")
    monkeypatch.setattr(_blas, "_cpu_flags", lambda: {"avx2", "fma"})  # exactly the two: enough
    assert _blas.pinned_kernel() == "Haswell"
