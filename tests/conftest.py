import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import settings as hypothesis_settings

import iamp._blas  # noqa: F401  (first: the BLAS kernel iamp pins, before anything loads numpy)

# Generated examples are drawn from a fixed seed (derandomize), so the suite gives the same verdict
# on every run and machine; IAMP_HYPOTHESIS=explore draws fresh examples each run (to look for new
# counterexamples, which then become @example cases).
hypothesis_settings.register_profile("iamp", derandomize=True)
hypothesis_settings.register_profile("explore", derandomize=False)
hypothesis_settings.load_profile(os.environ.get("IAMP_HYPOTHESIS", "iamp"))

IAMP = [sys.executable, "-m", "iamp"]


def run_cli(*args, cwd=None, timeout=600):
    """Run the CLI as a user would; returns CompletedProcess with text output."""
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    return subprocess.run(IAMP + [str(a) for a in args], capture_output=True, text=True, cwd=cwd,
                          timeout=timeout, env=env)


@pytest.fixture
def cli():
    return run_cli


# --- recorded data (issue 29 item 8) ------------------------------------------------------------

#: Environment variable naming the folder of the recorded data (default: ``<repo>/../shared/data``).
DATA_ENV = "IAMP_DATA"
REPO = Path(__file__).resolve().parents[1]


def data_root() -> Path:
    """The recorded-data folder: ``$IAMP_DATA`` if set (and not empty), else ``<repo>/../shared/data``."""
    env = os.environ.get(DATA_ENV, "").strip()
    return Path(env).expanduser() if env else REPO.parent / "shared" / "data"


def data_path(*parts: str) -> Path:
    """A file or folder of the recorded data (:func:`data_root` joined with ``parts``)."""
    return data_root().joinpath(*parts)


def needs_data(*parts: str) -> pytest.MarkDecorator:
    """Skip marker for tests that need ``data_path(*parts)``, with the reason (where it was looked for)."""
    p = data_path(*parts)
    return pytest.mark.skipif(not p.exists(), reason=f"recorded data absent: {p} (set {DATA_ENV} to the folder that "
                                                     f"holds {'/'.join(parts)})")


# --- the [commonroad] extra ------------------------------------------------------------------------

#: Whether the [commonroad] extra is installed (commonroad-io, the drivability checker, triangle).
HAVE_COMMONROAD = all(importlib.util.find_spec(m) is not None for m in ("commonroad", "commonroad_dc", "triangle"))
#: Skip marker for tests that need the [commonroad] extra.
needs_commonroad = pytest.mark.skipif(not HAVE_COMMONROAD, reason="the [commonroad] extra is not installed "
                                                                  "(pip install 'iamp[commonroad]')")


def needs_commonroad_data(*parts: str) -> pytest.MarkDecorator:
    """Skip marker for tests that need the [commonroad] extra and ``data_path(*parts)``, with the reason."""
    p = data_path(*parts)
    return pytest.mark.skipif(not HAVE_COMMONROAD or not p.is_dir(),
                              reason=("the [commonroad] extra is not installed (pip install 'iamp[commonroad]')"
                                      if not HAVE_COMMONROAD else f"the shared CommonRoad data is absent ({p})"))


def load_script(name: str):  # type: ignore[no-untyped-def]
    """The module ``scripts/<name>.py`` (the scripts are not a package), loaded afresh."""
    spec = importlib.util.spec_from_file_location(name, Path(__file__).resolve().parents[1] / "scripts" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
