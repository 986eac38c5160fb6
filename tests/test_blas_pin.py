"""iamp asks OpenBLAS for one kernel, and numpy for its AVX2 loops, on every x86-64 machine
(``iamp/_blas.py``): the same command gives the same numbers whatever CPU it runs on, and a kernel or
SIMD target the user chose is kept."""

from __future__ import annotations

import ast
import importlib
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
    assert _blas.cpu_model() == "x: y"  # the bench's record of the CPU (the text after the first colon)
    monkeypatch.setattr(platform, "machine", lambda: "x86_64")
    monkeypatch.setattr(_blas, "_cpu_flags", lambda: {"avx2", "fma"})  # exactly the two: enough
    assert _blas.pinned_kernel() == "Haswell"


NATIVE = """
import numpy, iamp
print(iamp._blas.loaded_kernel())
"""


def _stderr_and_kernel(code: str, **env: str) -> tuple[str, str]:
    clean = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_CORETYPE", "MKL_CBWR", "PYTHONWARNINGS")}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env={**clean, **env},
                         timeout=120, check=True)
    return out.stderr, out.stdout.strip()


@needs_x86
def test_numpy_imported_first_with_other_kernels_warns_once_and_names_the_fix() -> None:
    """A program that imports numpy before iamp keeps the CPU's own kernels (OpenBLAS chose them
    when it loaded): ``import iamp`` warns exactly when they are not the pinned ones, naming both
    and the two ways out; iamp imported first, or a kernel the user chose, warns nothing."""
    err, native = _stderr_and_kernel(NATIVE)
    if native == "None":
        pytest.skip("numpy's BLAS is not the bundled OpenBLAS")
    wanted = str(_blas.pinned_kernel())
    if native.lower() == wanted.lower():
        assert "BlasKernelWarning" not in err
    else:
        assert err.count("BlasKernelWarning") == 1
        assert f"runs the {native} kernels, not {wanted}" in err and f"OPENBLAS_CORETYPE={wanted}" in err
    err, first = _stderr_and_kernel("import iamp, numpy\nprint(iamp._blas.loaded_kernel())")
    assert first.lower() == wanted.lower() and "BlasKernelWarning" not in err
    err, chosen = _stderr_and_kernel(NATIVE, OPENBLAS_CORETYPE="Sandybridge")
    assert chosen.lower() == "sandybridge" and "BlasKernelWarning" not in err


def test_no_numpy_no_kernel_and_no_warning(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without numpy loaded there is nothing to read; a kernel that differs warns with the class
    a caller can filter (``warnings.simplefilter("ignore", iamp._blas.BlasKernelWarning)``)."""
    monkeypatch.delitem(sys.modules, "numpy", raising=False)
    assert _blas.loaded_kernel() is None
    monkeypatch.setattr(_blas, "loaded_kernel", lambda: "SkylakeX")
    monkeypatch.setattr(_blas, "pinned_kernel", lambda: "Haswell")
    monkeypatch.delenv("OPENBLAS_CORETYPE", raising=False)
    monkeypatch.setattr(_blas, "NUMPY_FIRST", False)
    assert _blas.warn_if_unpinned() is None  # numpy loaded after iamp: the kernels are the pinned ones
    monkeypatch.setattr(_blas, "NUMPY_FIRST", True)
    with pytest.warns(_blas.BlasKernelWarning, match="SkylakeX kernels, not Haswell"):
        assert _blas.warn_if_unpinned() is not None
    monkeypatch.setattr(_blas, "loaded_kernel", lambda: "haswell")
    assert _blas.warn_if_unpinned() is None


def _first_import_line(tree: ast.Module, wanted: tuple[str, ...]) -> int | None:
    for node in tree.body:
        names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                 else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
        if any(n == w or n.startswith(w + ".") for n in names for w in wanted):
            return node.lineno
    return None


def test_every_script_imports_iamp_before_numpy() -> None:
    """The scripts whose numbers the docs quote pin the BLAS kernels as the command line does: at
    module level, ``iamp`` is imported before numpy, scipy or matplotlib (which load OpenBLAS)."""
    late = []
    for path in sorted((Path(__file__).resolve().parents[1] / "scripts").glob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        heavy = _first_import_line(tree, ("numpy", "scipy", "matplotlib"))
        first = _first_import_line(tree, ("iamp",))
        if heavy is not None and (first is None or first > heavy):
            late.append(path.name)
    assert late == []


def test_numpy_s_avx512_targets_are_switched_off_on_a_cpu_that_has_them(monkeypatch: pytest.MonkeyPatch) -> None:
    """``pin`` gives ``NPY_DISABLE_CPU_FEATURES`` numpy 2.4's AVX-512 targets on an x86-64 CPU with
    AVX-512 (where numpy's float64 power, exp, log, sin and cos would run other implementations than on
    an AVX2 CPU); nothing without AVX-512, on another processor, or with another numpy (whose targets
    may have other names); a value the user set is kept; nothing once numpy is loaded."""
    monkeypatch.setattr(platform, "machine", lambda: "x86_64")
    monkeypatch.setattr(_blas, "_cpu_flags", lambda: {"avx2", "fma", "avx512f"})
    monkeypatch.setattr(_blas, "_numpy_version", lambda: (2, 4))
    assert _blas.numpy_disabled() == "X86_V4 AVX512_ICL AVX512_SPR"
    for other in ((2, 3), (2, 5), (3, 0), None):  # target names not known here: left alone
        monkeypatch.setattr(_blas, "_numpy_version", lambda v=other: v)
        assert _blas.numpy_disabled() is None
    monkeypatch.setattr(_blas, "_numpy_version", lambda: (2, 4))
    monkeypatch.setattr(_blas, "_cpu_flags", lambda: {"avx2", "fma"})
    assert _blas.numpy_disabled() is None
    monkeypatch.setattr(_blas, "_cpu_flags", lambda: {"avx2", "fma", "avx512f"})
    monkeypatch.setattr(platform, "machine", lambda: "aarch64")
    assert _blas.numpy_disabled() is None
    # pin() with numpy not loaded: set where unset, kept where the user chose
    monkeypatch.setattr(platform, "machine", lambda: "x86_64")
    importlib.import_module("numpy")  # loaded whatever ran before (``import iamp`` alone does not load it)

    numpy = sys.modules.pop("numpy")
    try:
        monkeypatch.delenv("NPY_DISABLE_CPU_FEATURES", raising=False)
        _blas.pin()
        assert os.environ["NPY_DISABLE_CPU_FEATURES"] == _blas.NUMPY_DISABLED
        monkeypatch.setenv("NPY_DISABLE_CPU_FEATURES", "AVX512_SPR")
        _blas.pin()
        assert os.environ["NPY_DISABLE_CPU_FEATURES"] == "AVX512_SPR"
    finally:
        sys.modules["numpy"] = numpy
    monkeypatch.delenv("NPY_DISABLE_CPU_FEATURES", raising=False)
    _blas.pin()  # numpy loaded: its targets are chosen already
    assert "NPY_DISABLE_CPU_FEATURES" not in os.environ


def test_the_switched_off_targets_are_every_numpy_target_above_avx2() -> None:
    """With numpy 2.4 installed, the names are exactly its x86-64 dispatch targets above ``X86_V3``
    (AVX2 and FMA): none is left on, and numpy knows each (it complains at import about a name it
    does not dispatch, which the subprocess's empty standard error would show)."""
    import numpy as np

    if _blas.pinned_kernel() is None or tuple(int(x) for x in np.__version__.split(".")[:2]) != (2, 4):
        pytest.skip("numpy 2.4 on x86-64 only")
    from numpy._core._multiarray_umath import __cpu_dispatch__

    assert set(__cpu_dispatch__) - {"X86_V3"} == set(_blas.NUMPY_DISABLED.split())
    code = "import iamp, numpy; print(iamp._blas.numpy_avx512())"
    clean = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True,
                         env={**clean, "NPY_DISABLE_CPU_FEATURES": _blas.NUMPY_DISABLED})
    assert out.stderr == "" and out.stdout.strip() == "[]"


def test_numpy_s_avx512_loops_are_read_from_its_runtime_features() -> None:
    """``numpy_avx512`` (what ``iamp bench`` records) lists numpy's dispatch targets ``X86_V4`` and
    ``AVX512*`` that its runtime ``__cpu_features__`` reports on, not the CPU's AVX-512 features
    (which stay on when the targets are switched off); in a process where iamp switched them off it is
    empty, and where the user switched nothing off it lists every such target the CPU runs."""
    from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__

    assert _blas.numpy_avx512() == sorted(k for k in __cpu_dispatch__ if __cpu_features__.get(k)
                                          and (k == "X86_V4" or k.startswith("AVX512")))
    code = "import iamp, numpy; print(' '.join(iamp._blas.numpy_avx512()) or '-')"
    clean = {k: v for k, v in os.environ.items() if k != "NPY_DISABLE_CPU_FEATURES"}
    pinned = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                            check=True, env=clean).stdout.strip()
    native = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                            check=True, env={**clean, "NPY_DISABLE_CPU_FEATURES": ""}).stdout.strip()
    if _blas.numpy_disabled() is not None:  # a CPU with AVX-512 and numpy 2.4: iamp switches them off
        assert pinned == "-" and "X86_V4" in native.split()
    elif "avx512f" not in _blas._cpu_flags():
        assert pinned == native == "-"


def _piqp_folder() -> Path | None:
    """piqp's package folder, found on ``sys.path`` (not through ``sys.modules``: once imported, piqp's
    ``__init__`` copies its bindings' namespace into its own, ``__spec__`` included, so
    ``importlib.util.find_spec("piqp")`` then answers with the bindings' spec, which has no folder)."""
    from importlib.machinery import PathFinder

    spec = PathFinder.find_spec("piqp")
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(next(iter(spec.submodule_search_locations)))


@needs_x86
def test_piqp_loads_its_avx2_build_where_the_cpu_has_avx512() -> None:
    """In a fresh process ``import iamp`` then ``import piqp`` loads piqp's AVX2 bindings on a CPU with
    AVX-512 and AVX2 (one build only, never two), and the package still works (a QP solved); importing
    piqp first keeps piqp's own choice, which ``piqp_build`` reports."""
    folder = _piqp_folder()
    if folder is None or not list(folder.glob("piqp_python_avx2.*")):
        pytest.skip("piqp with an AVX2 build is not installed")
    code = ("import sys\nFIRST\nimport iamp, piqp, numpy as np, scipy.sparse as sp\n"
            "s = piqp.SparseSolver(); s.setup(sp.csc_matrix(np.eye(2)), np.array([1.0, -2.0]))\n"
            "s.solve(); print(iamp._blas.piqp_build(), s.result.x[0], s.result.x[1],"
            " sorted(k for k in sys.modules if k.startswith('piqp.piqp_python')))")
    out = subprocess.run([sys.executable, "-c", code.replace("FIRST", "")], capture_output=True, text=True,
                         timeout=120, check=True).stdout.split()
    flags = _blas._cpu_flags()
    if "avx512f" in flags and {"avx2", "fma"} <= flags:
        assert out[0] == "piqp_python_avx2"
    assert out[3:] == [f"['piqp.{out[0]}']"]  # exactly one build loaded
    assert float(out[1]) == pytest.approx(-1.0, abs=1e-8) and float(out[2]) == pytest.approx(2.0, abs=1e-8)
    first = subprocess.run([sys.executable, "-c", code.replace("FIRST", "import piqp")], capture_output=True,
                           text=True, timeout=120, check=True).stdout.split()
    if "avx512f" in flags:
        assert first[0] == "piqp_python_avx512"  # piqp's own choice, kept


def test_pin_piqp_changes_nothing_where_it_must_not(monkeypatch: pytest.MonkeyPatch) -> None:
    """``pin_piqp`` installs its import hook only on an x86-64 CPU with AVX-512, AVX2 and FMA and
    before piqp is loaded, once; the hook answers only for ``piqp.instruction_set`` in a folder that
    has piqp's AVX2 build, and its loader switches ``avx512f`` off after the module's own code ran."""
    import types

    monkeypatch.setattr(sys, "meta_path", [f for f in sys.meta_path if not isinstance(f, _blas._PiqpAvx2)])
    saved = {k: v for k, v in sys.modules.items() if k == "piqp" or k.startswith("piqp.")}
    try:
        for k in saved:
            del sys.modules[k]
        monkeypatch.setattr(platform, "machine", lambda: "x86_64")
        for flags in ({"avx2", "fma"}, {"avx512f"}, {"avx512f", "avx2"}):
            monkeypatch.setattr(_blas, "_cpu_flags", lambda f=flags: f)
            assert _blas.pin_piqp() is False
        monkeypatch.setattr(_blas, "_cpu_flags", lambda: {"avx2", "fma", "avx512f"})
        monkeypatch.setattr(platform, "machine", lambda: "aarch64")
        assert _blas.pin_piqp() is False
        monkeypatch.setattr(platform, "machine", lambda: "x86_64")
        sys.modules["piqp"] = types.ModuleType("piqp")
        assert _blas.pin_piqp() is False
        del sys.modules["piqp"]
        assert not any(isinstance(f, _blas._PiqpAvx2) for f in sys.meta_path)
        assert _blas.pin_piqp() is True and _blas.pin_piqp() is True
        assert sum(isinstance(f, _blas._PiqpAvx2) for f in sys.meta_path) == 1
    finally:
        for k in [k for k in sys.modules if k == "piqp" or k.startswith("piqp.")]:
            del sys.modules[k]
        sys.modules.update(saved)
    hook = _blas._PiqpAvx2()
    assert hook.find_spec("piqp.other", ["/nowhere"]) is None and hook.find_spec("piqp.instruction_set") is None

    class Loader:
        def create_module(self, spec: object) -> None:
            return None

        def exec_module(self, module: types.ModuleType) -> None:
            module.avx512f = True  # type: ignore[attr-defined]
            module.avx2 = True  # type: ignore[attr-defined]

    module = types.ModuleType("piqp.instruction_set")
    _blas._FlagOff(Loader()).exec_module(module)
    assert module.avx512f is False and module.avx2 is True  # type: ignore[attr-defined]
    folder = _piqp_folder()
    if folder is not None:
        spec = hook.find_spec("piqp.instruction_set", [str(folder)])
        has_avx2 = bool(list(folder.glob("piqp_python_avx2.*")))
        assert spec is not None and isinstance(spec.loader, _blas._FlagOff) == has_avx2


def test_the_piqp_hook_answers_only_for_piqp_s_instruction_set_beside_an_avx2_build(tmp_path: Path) -> None:
    """The import hook returns no spec for another name (even one its folder holds), the ordinary
    spec where the folder has no ``piqp_python_avx2`` build, and a spec whose loader switches
    ``avx512f`` off (after the module's own code set it) where it has one: checked on two folders
    made here, each with an ``instruction_set`` module in Python."""
    import importlib.util

    hook = _blas._PiqpAvx2()
    for name, build in (("plain", None), ("avx2", "piqp_python_avx2.cpython-311-x86_64-linux-gnu.so"),
                        ("baseline", "piqp_python.cpython-311-x86_64-linux-gnu.so")):
        folder = tmp_path / name
        folder.mkdir()
        (folder / "instruction_set.py").write_text("avx512f = True\navx2 = True\n")
        (folder / "other.py").write_text("x = 1\n")
        if build:
            (folder / build).write_bytes(b"")
        assert hook.find_spec("piqp.other", [str(folder)]) is None
        assert hook.find_spec("piqp.instruction_set", []) is None
        spec = hook.find_spec("piqp.instruction_set", [str(folder)])
        assert spec is not None and spec.origin == str(folder / "instruction_set.py")
        module = importlib.util.module_from_spec(spec)
        assert spec.loader is not None
        spec.loader.exec_module(module)
        assert isinstance(spec.loader, _blas._FlagOff) == (name == "avx2")
        assert module.avx512f is (name != "avx2") and module.avx2 is True
