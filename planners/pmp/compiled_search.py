"""Removed (issue 32): the numba copy of the ``m >= 2`` contact-time search.

The search has one implementation, :func:`iamp.planners.pmp.search.global_search`; the copy
(scalar numba kernels, about 1,200 lines) agreed with it only to about ``1e-9`` and ran only
when numba happened to be loaded in the process, so a plan could change with an unrelated
import.  This module stays for callers that asked for the copy: :func:`load` says it is not
there, and they take the one search.
"""

from __future__ import annotations


def available() -> bool:
    """``False``: the compiled copy of the search no longer exists."""
    return False


def ready() -> bool:
    """``False``: nothing to load."""
    return False


def load() -> bool:
    """``False``: the caller plans with :func:`iamp.planners.pmp.search.global_search`."""
    return False
