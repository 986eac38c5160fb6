"""Sphinx configuration of iamp's documentation site (``sphinx-build -W docs docs/_build/html``).

Offline by design: no intersphinx, equations rendered to SVG at build time (``imgmath`` with
LaTeX and dvisvgm, which ``.ci/run`` installs with the report's LaTeX), so the built site opens
from ``python -m http.server`` on a machine without internet.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
os.environ.setdefault("MPLBACKEND", "Agg")

import iamp  # noqa: E402

project = "iamp"
author = "the iamp developers"
copyright = "2026, the iamp developers"
release = iamp.__version__
version = ".".join(release.split(".")[:2])

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.imgmath",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store", "auto_examples/*.ipynb", "auto_examples/*.py",
                    "auto_examples/*.zip", "auto_examples/*.json", "auto_examples/*.md5", "sg_execution_times.rst"]

# Markdown pages (the contract, the concept pages) keep their "SPEC §N" prose; headings get anchors
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
suppress_warnings = ["myst.xref_missing", "myst.header"]

# the API reference: autosummary pages generated from the docstrings of iamp.__all__, every public
# method in full (docs/_templates/autosummary/class.rst)
templates_path = ["_templates"]
autosummary_generate = True
autodoc_typehints = "none"
autodoc_member_order = "bysource"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()  # tests/test_docstrings.py enforces the sections

# equations: SVG at build time, no CDN at view time
imgmath_image_format = "svg"
imgmath_font_size = 14
imgmath_use_preview = True
# docstrings write some symbols as Unicode (SPEC's notation): map them to LaTeX for pdfTeX
_UNICODE_MATH = {"Δ": r"\Delta", "δ": r"\delta", "Φ": r"\Phi", "φ": r"\phi", "τ": r"\tau", "ρ": r"\rho",
                 "μ": r"\mu", "λ": r"\lambda", "Ω": r"\Omega", "α": r"\alpha", "β": r"\beta", "σ": r"\sigma",
                 "ν": r"\nu", "θ": r"\theta", "ψ": r"\psi", "±": r"\pm", "≤": r"\le", "≥": r"\ge",
                 "×": r"\times", "·": r"\cdot", "−": "-", "∈": r"\in", "∞": r"\infty", "→": r"\to",
                 "ᵀ": r"^{\top}", "²": "^{2}", "³": "^{3}", "≈": r"\approx", "∂": r"\partial", "√": r"\sqrt",
                 "∑": r"\sum", "⁻": "^{-}", "⁺": "^{+}"}
imgmath_latex_preamble = "\\usepackage{newunicodechar}\n" + "\n".join(
    f"\\newunicodechar{{{ch}}}{{\\ensuremath{{{tex}}}}}" for ch, tex in _UNICODE_MATH.items())

sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": "auto_examples",
    "filename_pattern": r".*\.py$",  # run every example, not only plot_*.py
    "ignore_pattern": r"(__init__|_common)\.py$",
    "download_all_examples": False,
    "remove_config_comments": True,
    "abort_on_example_error": True,
    "plot_gallery": "True",
    "within_subsection_order": "FileNameSortKey",
    "image_scrapers": ("matplotlib",),
    "matplotlib_animations": False,
}

html_theme = "pydata_sphinx_theme"
html_title = f"iamp {release}"
html_static_path = ["_static"]
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
html_show_sourcelink = False
html_last_updated_fmt = None


# --- the animations of docs/animations.md, made by the shipped commands at build time --------------------
ANIM = Path(__file__).resolve().parent / "_static" / "anim"


def _make_animations(app: object) -> None:
    """Write the three GIFs of ``animations.md`` with ``iamp plot`` (never committed: made here)."""
    import shutil
    import subprocess
    import tempfile

    ANIM.mkdir(parents=True, exist_ok=True)
    iamp_cmd = [sys.executable, "-m", "iamp"]

    def run(*args: str) -> None:
        subprocess.run([*iamp_cmd, *args], check=True, capture_output=True, text=True, encoding="utf-8", cwd=ROOT)

    run("plot", "two-vehicle", "--planner", "qp", "--constraint", "avoid", "--animate", "--fps", "8",
        "--out", str(ANIM / "plan.gif"), "--force")
    work = Path(tempfile.mkdtemp(prefix="iamp-docs-"))  # the log and the solution: not part of the site
    log = work / "episode.csv"
    episode = subprocess.run([*iamp_cmd, "simulate", "--mission", "merge", "--traffic", "medium", "--seed", "2",
                              "--planner", "pmp-active", "--log", str(log), "--force", "--json"],
                             capture_output=True, text=True, encoding="utf-8", cwd=ROOT)
    if episode.returncode not in (0, 5):  # 5: the mission failed, the log is still an episode
        raise RuntimeError(f"iamp simulate failed: {episode.stderr.strip()}")
    run("plot", "--episode", str(log), "--out", str(ANIM / "episode.gif"), "--speed", "3", "--fps", "6",
        "--force")
    data = Path(os.environ.get("IAMP_DATA", ROOT.parent / "shared" / "data")) / "commonroad" / "US101"
    scenario = data / "USA_US101-11_1_T-1.xml"
    if not scenario.is_file():  # a site built without the recorded data says so in the picture's place
        from PIL import Image, ImageDraw

        note = Image.new("RGB", (800, 120), "white")
        ImageDraw.Draw(note).text((20, 45), f"Built without the recorded data ({scenario.name} not found): "
                                            "set IAMP_DATA and rebuild.", fill="black")
        note.save(ANIM / "commonroad.gif")
        shutil.rmtree(work, ignore_errors=True)
        return
    solution = work / "solution.xml"
    run("commonroad", "plan", str(scenario), "--out", str(solution), "--force")
    run("plot", "--commonroad", str(scenario), "--solution", str(solution), "--out", str(ANIM / "commonroad.gif"),
        "--fps", "5", "--force")
    shutil.rmtree(work, ignore_errors=True)


def setup(app: object) -> None:
    app.connect("builder-inited", _make_animations)  # type: ignore[attr-defined]
