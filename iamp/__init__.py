"""iamp — interaction-aware optimal lane-change planning (PMP with interior-point
collision constraints, a QP/MPC baseline, and an MTD Markov-chain predictor)."""

import os as _os

__version__ = "0.1.0"

# The source tree keeps planners/, prediction/ and compare/ beside this folder; an install
# maps them to iamp.planners, iamp.prediction and iamp.compare.  When iamp is imported
# straight from a checkout (e.g. `python -m pytest` from the repository root, where the
# checkout shadows the installed copy), make them reachable under the same names.
_here = _os.path.dirname(_os.path.abspath(__file__))
_root = _os.path.dirname(_here)
if not _os.path.isdir(_os.path.join(_here, "planners")) and _os.path.isfile(
        _os.path.join(_root, "planners", "__init__.py")):
    __path__.append(_root)  # noqa: F821 - the package's own __path__
