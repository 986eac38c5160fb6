"""Scenario TOML texts shared by the tests (one place for the history-scenario template)."""

HISTORY_SCENARIO = """
name = "{name}"
[ego]
tf = 5.0
x0 = 0.0
y0 = -2.0
vx0 = 20.0
xf = {xf}
yf = 3.75
vxf = 20.0

[[vehicles]]
name = "sv1"
corner = "front-lower"
y = 3.75
length = 4.8
width = 1.8
safety_x = 5.0
safety_y = 0.5
[vehicles.history]
t = [{t}]
x = [{x}]
{extra}"""


def history_scenario(t, x, *, name="hist", xf=73.0, extra=""):
    """A one-history-vehicle scenario; ``t``/``x`` are numbers or already formatted text."""
    fmt = lambda v, spec: v if isinstance(v, str) else ", ".join(format(float(a), spec) for a in v)  # noqa: E731
    return HISTORY_SCENARIO.format(name=name, xf=xf, t=fmt(t, "g"), x=fmt(x, ".9g"), extra=extra)
