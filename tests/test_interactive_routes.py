"""The interactive scenes' SUMO routes with an edge repeated right after itself (issue 33).

The converter of the interactive US-101 scenes writes a route such as ``edges="92 92 29"`` where
two of a vehicle's lanelets lie on one SUMO edge; 42 of the 58 shared scenes hold at least one.
SUMO refuses such a route (no connection from an edge to itself), and with
``--ignore-route-errors`` it drives the vehicle to the end of the repeated edge and stops it there
for the rest of the run (``time-to-teleport`` -1).  In USA_US101-24_1 vehicle 31 stands at the end
of edge 92 from 8 s on, 10 m past the goal, and the cars behind it stop in a row across four lanes:
the goal (s 233.5-235.6 m, 13.5-19.5 m/s, 11.9-12.9 s) lay beyond that row, and the loop missed
it with SUMO seeds 1 and 2.  :func:`iamp.commonroad.interactive.repaired_routes` collapses the
repeated edge, so those vehicles drive on as the recorded ones did.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
from conftest import data_path

HAVE_EXTRA = all(importlib.util.find_spec(m) is not None for m in ("commonroad", "commonroad_dc", "triangle"))
HAVE_SUMO = importlib.util.find_spec("libsumo") is not None or importlib.util.find_spec("traci") is not None
INTERACTIVE = data_path("commonroad", "interactive-US101")
SCENE = INTERACTIVE / "USA_US101-24_1_I-1-1"
needs_scene = pytest.mark.skipif(not HAVE_EXTRA or not HAVE_SUMO or not SCENE.is_dir(),
                                 reason="needs the [commonroad] and [sim] extras, SUMO and the shared "
                                        f"interactive scenarios ({INTERACTIVE})")

ROUTES = """<routes>
    <vehicle id="a" depart="0"><route edges="92 92 29"/></vehicle>
    <vehicle id="b" depart="0"><route edges="91 92 92 92 92 29"/></vehicle>
    <vehicle id="c" depart="0"><route edges="92 29 92"/></vehicle>
    <route id="r" edges="29 29"/>
</routes>
"""


def _cfg(tmp: Path, vehicles: str) -> Path:
    (tmp / "in").mkdir()
    (tmp / "in" / "s.vehicles.rou.xml").write_text(vehicles)
    (tmp / "in" / "s.pedestrians.rou.xml").write_text("<routes>\n</routes>\n")
    cfg = tmp / "in" / "s.sumo.cfg"
    cfg.write_text('<configuration><input><net-file value="s.net.xml"/>'
                   '<route-files value="s.vehicles.rou.xml,s.pedestrians.rou.xml"/></input></configuration>')
    return cfg


def test_a_repeated_edge_is_collapsed_and_nothing_else_changes(tmp_path: Path) -> None:
    """Each run of one edge becomes that edge once; an edge met again later (``92 29 92``) is kept;
    routes are counted per changed ``edges`` attribute; the file without such a route is handed
    back as it is (the configuration's own path), the changed one written to the output folder."""
    import xml.etree.ElementTree as ET

    from iamp.commonroad.interactive import repaired_routes

    cfg = _cfg(tmp_path, ROUTES)
    (tmp_path / "out").mkdir()
    files, changed = repaired_routes(cfg, tmp_path / "out")
    assert changed == 3
    assert files[0] == tmp_path / "out" / "s.vehicles.rou.xml"
    assert files[1] == cfg.parent / "s.pedestrians.rou.xml"
    edges = [el.get("edges") for el in ET.parse(files[0]).getroot().iter() if el.get("edges")]
    assert edges == ["92 29", "91 92 29", "92 29 92", "29"]
    # every original route is its repaired one with each repeated edge restored
    original = [el.get("edges") for el in ET.fromstring(ROUTES).iter() if el.get("edges")]
    for o, r in zip(original, edges, strict=True):
        e = o.split()
        assert r.split() == [a for i, a in enumerate(e) if i == 0 or a != e[i - 1]]
        assert set(r.split()) == set(e)
    (tmp_path / "x").mkdir()
    clean = _cfg(tmp_path / "x", "<routes>\n</routes>\n")
    assert repaired_routes(clean, tmp_path / "out") == ([clean.parent / "s.vehicles.rou.xml",
                                                         clean.parent / "s.pedestrians.rou.xml"], 0)


@needs_scene
def test_sumo_stops_a_vehicle_with_a_repeated_edge_at_the_edge_end_and_not_after_the_repair(tmp_path: Path) -> None:
    """SUMO alone (no ego), seed 1: vehicle 31 of USA_US101-24_1 (route ``92 92 29``) stands at the
    end of edge 92 (within 0.5 m of the edge's length) from 8 s to 13 s; with the repaired routes it
    drives on (never below 10 m/s) onto edge 29, the last of its route, and leaves the network before
    8 s."""
    from iamp.commonroad.interactive import _files, _sumo, repaired_routes

    traci, sumolib = _sumo()
    _, cfg = _files(SCENE)

    def run(extra: list[str]) -> list[tuple[float, str, float, float]]:
        traci.start([sumolib.checkBinary("sumo"), "-c", str(cfg), "--ignore-route-errors", "true",
                     "--no-warnings", "true", "--no-step-log", "true", "--seed", "1", "--step-length", "0.1",
                     *extra])
        seen = []
        try:
            for k in range(130):
                traci.simulationStep()
                if "31" in traci.vehicle.getIDList():
                    seen.append(((k + 1) * 0.1, traci.vehicle.getRoadID("31"),
                                 traci.vehicle.getLanePosition("31"), traci.vehicle.getSpeed("31")))
        finally:
            traci.close()
        return seen

    length = float(next(e for e in sumolib.net.readNet(str(SCENE / f"{SCENE.name}.net.xml")).getEdges()
                        if e.getID() == "92").getLength())
    before = run([])
    late = [x for x in before if x[0] >= 8.0 - 1e-9]
    assert late and all(road == "92" and length - pos < 0.5 and v == 0.0 for _, road, pos, v in late)
    files, changed = repaired_routes(cfg, tmp_path)
    assert changed == 8
    after = run(["--route-files", ",".join(str(f.resolve()) for f in files)])
    assert any(road == "29" for _, road, _, _ in after)  # on to its last edge
    assert max(t for t, *_ in after) < 8.0  # and off the network before it stood there
    assert min(v for _, _, _, v in after) > 10.0


@pytest.mark.slow
@needs_scene
@pytest.mark.parametrize("seed", [1, 2])
def test_24_1_reaches_its_goal_once_the_refused_routes_are_repaired(seed: int) -> None:
    """The closed loop (defaults: routes repaired) reaches 24_1's goal inside its window without
    contact (body overlap, SUMO's report or RSS blame) and within the vehicle's limits, the goal
    test passing at the executed state; with SUMO's refused routes it missed the goal (the row of
    cars stopping behind the standing vehicles).  About 30 s each."""
    from iamp.commonroad.interactive import simulate

    r = simulate(SCENE, seed=seed)
    assert r["sumo_routes_repaired"] == 8
    assert r["goal_reached"] and r["status"] == "goal reached", r["decisions"]
    lo, hi = r["goal_window_s"]
    assert lo - 1e-9 <= r["time_to_goal_s"] <= hi + 1e-9
    assert r["collisions"] == 0 and r["contacts_at_fault"] == 0 and r["contacts_not_at_fault"] == 0
    assert r["sumo_collisions"] == 0 and r["limit_violations"] == 0 and r["ego_peak_accel"] <= r["a_max"]


@needs_scene
@pytest.mark.parametrize("repair", [True, False])
def test_a_route_file_that_is_not_xml_is_a_scenario_error_naming_it(tmp_path: Path, repair: bool) -> None:
    """A scene folder whose route file is broken: one :class:`~iamp.core.errors.ScenarioError`
    naming the file (the CLI's exit 2), whether iamp reads the routes (``repair``) or SUMO does."""
    import shutil

    from iamp.commonroad.interactive import simulate
    from iamp.core.errors import ScenarioError

    scene = tmp_path / SCENE.name
    shutil.copytree(SCENE, scene)
    broken = next(scene.glob("*.pedestrians.rou.xml"))
    broken.write_text("<routes><vehicle", encoding="utf-8")
    with pytest.raises(ScenarioError, match="pedestrians.rou.xml"):
        simulate(scene, repair_routes=repair)
