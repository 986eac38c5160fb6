"""``iamp reproduce``: the reproduction report (experiments, tables, LaTeX document)."""

from __future__ import annotations

from .reproduction import ReproduceConfig, reproduce

__all__ = ["ReproduceConfig", "reproduce"]
