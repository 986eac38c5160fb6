"""Seeded surrounding traffic at three densities, with mixed drivers.

Drivers are the five vehicle types of the predictor's training data
(``scripts/sumo/highway.rou.xml``): four car drivers (calm, average, sporty, erratic) and
12 % trucks, all with SUMO's Krauss car-following model (imperfection ``sigma`` 0.3..0.8
redrawn every ``sigmaStep = 1 s``), individual desired speeds from ``speedFactor``
distributions, and the LC2013 lane-change model.  The closed loop therefore meets the kind
of drivers the predictor was trained on.

Traffic of an episode (seed ``S``, density ``k`` vehicles per km and lane):

* **Initial platoon** — every lane is filled over ``[0, fill_m]`` with vehicles whose
  spacing is ``gap_min + Exp(1000/k - gap_min)`` (a shifted exponential, mean ``1000/k`` m),
  drawn with ``numpy.random.default_rng(S)``; the types are drawn from the type mix with the
  same generator.  They depart at ``t = 0`` at their position with ``departSpeed="max"``
  (the largest safe speed SUMO can insert them with).
* **Inflow** — one Poisson flow per lane at the road's start at ``q = k·v_ref`` vehicles per
  second (``v_ref = 28 m/s``), ``period="exp(q)"``, randomised by SUMO's ``--seed S``.

===========  =================  =========================
density      vehicles/km/lane   character
===========  =================  =========================
``light``    8                  free flow, wide gaps
``medium``   16                 gaps of ~60 m, some interaction
``dense``    28                 gaps of ~35 m, the target lane is rarely free
``los-e``    35                 level of service E (near capacity), gaps of ~29 m
===========  =================  =========================

Missions (:mod:`iamp.simulation.missions`) change the road (a lane drop, an on-ramp without
traffic but the ego, a slow truck ahead of the ego) and the drivers' cooperation.  Each
vehicle departs on the edge that contains its position (``departPos`` relative to it) and on
that edge's local lane index; none is placed on the dropped lane downstream of its end.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from iamp.core.errors import ScenarioError

DENSITIES: dict[str, float] = {"light": 8.0, "medium": 16.0, "dense": 28.0, "los-e": 35.0}
V_REF = 28.0  # m/s, converts a density into an inflow

#: ``(id, probability, attributes)`` — the vTypes of ``scripts/sumo/highway.rou.xml``.
DRIVER_TYPES: tuple[tuple[str, float, str], ...] = (
    ("car_calm", 0.30, 'vClass="passenger" length="4.6" minGap="2.5" accel="2.2" decel="4.0" emergencyDecel="9.0" '
                       'sigma="0.3" sigmaStep="1.0" tau="1.4" speedFactor="normc(0.95,0.08,0.75,1.20)" '
                       'lcSpeedGain="0.7" lcKeepRight="1.0"'),
    ("car_average", 0.34, 'vClass="passenger" length="4.6" minGap="2.5" accel="2.6" decel="4.5" '
                          'emergencyDecel="9.0" sigma="0.5" sigmaStep="1.0" tau="1.1" '
                          'speedFactor="normc(1.00,0.10,0.75,1.30)" lcSpeedGain="1.0" lcKeepRight="1.0"'),
    ("car_sporty", 0.16, 'vClass="passenger" length="4.4" minGap="2.0" accel="3.2" decel="5.0" emergencyDecel="9.0" '
                         'sigma="0.6" sigmaStep="1.0" tau="0.9" speedFactor="normc(1.10,0.10,0.80,1.40)" '
                         'lcSpeedGain="2.0" lcAssertive="1.5" lcKeepRight="0.5"'),
    ("car_erratic", 0.08, 'vClass="passenger" length="4.8" minGap="2.5" accel="2.8" decel="4.5" '
                          'emergencyDecel="9.0" sigma="0.8" sigmaStep="1.0" tau="1.0" '
                          'speedFactor="normc(1.00,0.15,0.70,1.40)" lcSpeedGain="1.5" lcKeepRight="0.7"'),
    ("truck", 0.12, 'vClass="truck" length="12.0" minGap="3.0" accel="1.0" decel="3.5" emergencyDecel="7.0" '
                    'sigma="0.4" sigmaStep="1.0" tau="1.5" maxSpeed="25.0" speedFactor="normc(1.00,0.05,0.90,1.10)" '
                    'lcSpeedGain="0.3" lcKeepRight="1.0"'),
)

#: The ego's vType: SPEC §9's default body 4.8 x 1.8 m; iamp moves it during a manoeuvre,
#: SUMO's Krauss drives it in its lane otherwise (no own lane changes).
EGO_TYPE = ('<vType id="ego_type" vClass="passenger" length="4.8" width="1.8" minGap="2.5" accel="2.6" decel="4.5" '
            'emergencyDecel="9.0" sigma="0.0" tau="1.2" speedFactor="1.0" speedDev="0" color="1,0,0"/>')
#: The slow-leader mission's truck: 60 km/h, no imperfection, no lane changes (set by TraCI).
TRUCK_TYPE = ('<vType id="truck_lead_type" vClass="truck" length="12.0" width="2.5" minGap="3.0" accel="1.0" '
              'decel="3.5" emergencyDecel="7.0" sigma="0.0" tau="1.5" maxSpeed="{v:.2f}" speedFactor="1.0" '
              'speedDev="0"/>')


def _with(attrs: str, over: dict[str, float]) -> str:
    """``attrs`` with the keys of ``over`` replaced or added."""
    import re

    for key, value in over.items():
        pat = re.compile(rf'\b{key}="[^"]*"')
        attrs = pat.sub(f'{key}="{value:g}"', attrs) if pat.search(attrs) else attrs + f' {key}="{value:g}"'
    return attrs


def density_of(traffic: str) -> float:
    """Vehicles per km and lane of a named density."""
    try:
        return DENSITIES[traffic]
    except KeyError:
        raise ScenarioError(f"unknown traffic {traffic!r}; choose from {', '.join(DENSITIES)}", "--traffic") from None


def routes_xml(traffic: str, seed: int, *, lanes: int, edge: str, ego_pos: float, ego_lane: int,
               fill_m: float = 1500.0, inflow_end: float = 400.0, gap_min: float = 16.0,
               highway: Any = None, empty_lanes: tuple[int, ...] = (), cooperation: dict[str, float] | None = None,
               truck: tuple[float, float] | None = None, sublane: bool = False) -> str:
    """The route file of one episode (vTypes, the ego, the initial platoon, the inflow).

    The ego departs at ``t = 0`` at ``ego_pos`` (front bumper) in ``ego_lane``; initial
    vehicles closer than ``gap_min`` to it in its lane are left out.  ``highway``
    (:class:`~iamp.simulation.network.Highway`, default the plain road on ``edge``) gives the
    edges; ``empty_lanes`` get no traffic; ``cooperation`` overrides driver attributes;
    ``truck = (ahead_m, speed)`` puts the slow-leader truck ``truck_lead`` ahead of the ego;
    ``sublane`` gives the ego SUMO's SL2015 lane-change model.
    """
    k = density_of(traffic)
    rng = np.random.default_rng(seed)
    probs = np.array([p for _, p, _ in DRIVER_TYPES])
    probs = probs / probs.sum()
    lines = ['<routes>']
    for name, _, attrs in DRIVER_TYPES:
        lines.append(f'    <vType id="{name}" {_with(attrs, cooperation or {})}/>')
    names = " ".join(name for name, _, _ in DRIVER_TYPES)
    weights = " ".join(f"{p:g}" for _, p, _ in DRIVER_TYPES)
    lines.append(f'    <vTypeDistribution id="drivers" vTypes="{names}" probabilities="{weights}"/>')
    ego_type = EGO_TYPE.replace('color=', 'laneChangeModel="SL2015" color=') if sublane else EGO_TYPE
    lines.append(f'    {ego_type}')

    def place(pos: float, lane: int) -> tuple[str, float, int] | None:
        """(route, departPos, local lane) of a vehicle at global ``pos``/``lane``; None if no lane."""
        if highway is None:
            return "r0", pos, lane
        eid, x0, first = highway.edge_at(pos)
        if lane < first:
            return None
        return f"r_{eid}", pos - x0, lane

    if highway is None:
        lines.append(f'    <route id="r0" edges="{edge}"/>')
    else:
        for eid, x0, _, _ in highway.segments():
            lines.append(f'    <route id="r_{eid}" edges="{highway.route(x0)}"/>')
    mean_gap = 1000.0 / k
    vehicles: list[tuple[float, int, str]] = []
    truck_pos = None if truck is None else ego_pos + truck[0]
    for lane in range(lanes):
        pos = float(rng.uniform(0.0, mean_gap))
        while pos < fill_m:
            vtype = DRIVER_TYPES[int(rng.choice(len(DRIVER_TYPES), p=probs))][0]
            clear = not (lane == ego_lane and abs(pos - ego_pos) < gap_min)
            if truck_pos is not None and lane == ego_lane and abs(pos - truck_pos) < gap_min + 12.0:
                clear = False
            if clear and lane not in empty_lanes:
                vehicles.append((pos, lane, vtype))
            pos += gap_min + float(rng.exponential(max(mean_gap - gap_min, 1.0)))
    if truck is not None and truck_pos is not None:
        # before the ego: SUMO inserts the vehicles of one departure time in file order, and a truck
        # inserted after the ego was refused (the ego, departing at its maximum speed, could not
        # brake for it) and appeared seconds later, behind the ego
        lines.append('    ' + TRUCK_TYPE.format(v=truck[1]))
        r, p, ln = place(truck_pos, ego_lane) or ("r0", truck_pos, ego_lane)
        lines.append(f'    <vehicle id="truck_lead" type="truck_lead_type" route="{r}" depart="0" departLane="{ln}" '
                     f'departPos="{p:.2f}" departSpeed="max"/>')
    r, p, ln = place(ego_pos, ego_lane) or ("r0", ego_pos, ego_lane)
    lines.append(f'    <vehicle id="ego" type="ego_type" route="{r}" depart="0" departLane="{ln}" '
                 f'departPos="{p:.2f}" departSpeed="max"/>')
    n = 0
    for pos, lane, vtype in sorted(vehicles, key=lambda v: (-v[0], v[1])):
        where = place(pos, lane)
        if where is None:
            continue
        r, p, ln = where
        lines.append(f'    <vehicle id="v{n}" type="{vtype}" route="{r}" depart="0" departLane="{ln}" '
                     f'departPos="{p:.2f}" departSpeed="max"/>')
        n += 1
    rate = k * V_REF / 1000.0
    r0 = "r0" if highway is None else f"r_{highway.segments()[0][0]}"
    for lane in range(lanes):
        if lane in empty_lanes:
            continue
        lines.append(f'    <flow id="in{lane}" type="drivers" route="{r0}" begin="0" '
                     f'end="{inflow_end:.0f}" period="exp({rate:.4f})" departLane="{lane}" departSpeed="max"/>')
    lines.append('</routes>')
    return "\n".join(lines) + "\n"

