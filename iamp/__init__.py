"""iamp — interaction-aware optimal lane-change planning (PMP with interior-point
collision constraints, a QP/MPC baseline, and an MTD Markov-chain predictor)."""

__version__ = "0.1.0"
