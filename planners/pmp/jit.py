"""The kernels' one compile path, :mod:`iamp.core.jit` (in the core since the core's root finder,
:mod:`iamp.core.polyroots_kernel`, compiles through it too); the planners import it by this name."""

from __future__ import annotations

from iamp.core.jit import available, compilable, compiled_as, inlined, twin

__all__ = ["available", "compilable", "compiled_as", "inlined", "twin"]
