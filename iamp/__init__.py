"""iamp — interaction-aware optimal lane-change planning.

PMP with interior-point collision constraints, a QP/MPC baseline, and an MTD Markov-chain
predictor.  The public API is listed in ``__all__`` (SPEC §12).
"""

from iamp._version import __version__

__all__ = ["__version__"]
