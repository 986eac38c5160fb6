"""
Predict a vehicle from its history
==================================

Predict a surrounding vehicle's future from 3 s of observed positions (the shipped MTD model).

Run: ``python examples/predict.py``
"""

from __future__ import annotations

import numpy as np

import iamp


def main() -> iamp.Prediction:
    t = np.linspace(-3.0, 0.0, 31)  # observed every 0.1 s up to now (t = 0)
    x = -15.0 + 18.0 * t  # a vehicle at a constant 18 m/s, 15 m behind the ego's start
    prediction = iamp.Predictor.default().predict(iamp.History(t, x), tf=5.0)
    c = prediction.x_poly
    print("x(t) = " + " + ".join(f"{ck:.4g} t^{k}" for k, ck in enumerate(c)))
    print("x(5 s) predicted:", np.polynomial.polynomial.polyval(5.0, c), "(constant speed: 75.0)")
    return prediction


if __name__ == "__main__":
    main()
