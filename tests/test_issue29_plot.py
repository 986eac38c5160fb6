"""Issue 29 item 3: the figures draw the ego with its own body, never a neighbour's.

A 16.5 m truck as vehicle 1 once made ``iamp plot`` draw the ego 16.5 m long (the figure read
a field the ego does not have and fell back to vehicle 1's size), so the picture showed a
collision the plan does not have.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from matplotlib.patches import Rectangle

import iamp
from iamp.comparison.figures.trajectory import draw_xy


def _scenario(truck_length: float, ego_length: float, ego_width: float) -> str:
    return f"""
[ego]
tf = 5.0
x0 = 0.0
y0 = -2.0
vx0 = 20.0
xf = 85.0
yf = 3.75
vxf = 20.0
length = {ego_length}
width = {ego_width}

[[vehicles]]
corner = "front-lower"
y = 3.75
length = {truck_length}
width = 2.6
safety_x = 5.0
safety_y = 0.5
x_poly = [-25.0, 18.0, 0.0, 0.0]
"""


def _ego_patches(ax: matplotlib.axes.Axes) -> list[Rectangle]:
    return [p for p in ax.patches if isinstance(p, Rectangle) and p.get_zorder() == 4]


@settings(max_examples=8, deadline=None)
@given(truck=st.floats(8.0, 20.0), ego_l=st.floats(3.5, 6.0), ego_w=st.floats(1.5, 2.2))
def test_the_ego_is_drawn_with_its_own_length_and_width(tmp_path_factory: pytest.TempPathFactory, truck: float,
                                                        ego_l: float, ego_w: float) -> None:
    path = tmp_path_factory.mktemp("s") / "truck.toml"
    path.write_text(_scenario(round(truck, 2), round(ego_l, 2), round(ego_w, 2)))
    prob = iamp.load_scenario(str(path))
    plan = iamp.plan(prob)
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    try:
        draw_xy(ax, plan, np.linspace(0.0, prob.tf, 4))
        ego = _ego_patches(ax)
        assert len(ego) == 4
        for p in ego:
            assert p.get_width() == pytest.approx(round(ego_l, 2))
            assert p.get_height() == pytest.approx(round(ego_w, 2))
    finally:
        plt.close(fig)
