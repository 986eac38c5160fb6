"""Issue 30 items 1 and 5, issue 29 items 11, 13 and 16 (simulate/campaign): the monitor judges with
RSS on oriented bodies, explains SUMO's disagreements, counts the followers' emergency brakes;
``iamp simulate`` exits 5 on a failed mission and refuses options ``--commonroad`` ignores; every
option has a help text."""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from iamp.simulation.metrics import StepLog, separation
from iamp.simulation.monitor import EMERGENCY_DECEL, monitor, responsibility

# -- oriented bodies -------------------------------------------------------------------------------


def _rect(cx, cy, L, W, psi):  # type: ignore[no-untyped-def]
    c, s = math.cos(psi), math.sin(psi)
    return [(cx + a * L / 2 * c - b * W / 2 * s, cy + a * L / 2 * s + b * W / 2 * c)
            for a, b in ((1, 1), (-1, 1), (-1, -1), (1, -1))]  # counter-clockwise


def _clip_area(subject, clip):  # type: ignore[no-untyped-def]
    """Area of the intersection of two convex counter-clockwise polygons (Sutherland-Hodgman),
    an implementation independent of the separating-axis test."""
    def inside(p, a, b):  # type: ignore[no-untyped-def]
        return (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) >= 0

    def cut(p, q, a, b):  # type: ignore[no-untyped-def]
        x1, y1, x2, y2 = *p, *q
        x3, y3, x4, y4 = *a, *b
        den = (x1 - x2) * (y3 - y4) - (y1 - y2) * (x3 - x4)
        t = ((x1 - x3) * (y3 - y4) - (y1 - y3) * (x3 - x4)) / den
        return (x1 + t * (x2 - x1), y1 + t * (y2 - y1))

    out = list(subject)
    for i in range(len(clip)):
        a, b = clip[i], clip[(i + 1) % len(clip)]
        pts, out = out, []
        for j in range(len(pts)):
            p, q = pts[j], pts[(j + 1) % len(pts)]
            if inside(q, a, b):
                if not inside(p, a, b):
                    out.append(cut(p, q, a, b))
                out.append(q)
            elif inside(p, a, b):
                out.append(cut(p, q, a, b))
        if not out:
            return 0.0
    return 0.5 * abs(sum(out[i][0] * out[(i + 1) % len(out)][1] - out[(i + 1) % len(out)][0] * out[i][1]
                         for i in range(len(out))))


@settings(max_examples=300, deadline=None)
@given(dx=st.floats(-8, 8), dy=st.floats(-5, 5), L=st.floats(3.5, 16.0), W=st.floats(1.5, 2.6),
       psi_e=st.floats(-math.pi, math.pi), psi=st.floats(-math.pi, math.pi))
def test_separating_axis_test_agrees_with_the_intersection_area(dx, dy, L, W, psi_e, psi):
    area = _clip_area(_rect(0, 0, 4.8, 1.8, psi_e), _rect(dx, dy, L, W, psi))
    sep = float(separation(np.zeros(2), 4.8, 1.8, psi_e, np.array([[dx, dy]]), np.array([L]), np.array([W]),
                           np.array([psi]))[0])
    assume(abs(sep) > 1e-6 and (area > 1e-6 or area == 0.0))
    assert (sep < 0) == (area > 0)


def _log(steps, ego, others, dt=0.1):  # type: ignore[no-untyped-def]
    """``ego(k) -> (x, vx, y, vy)``, ``others(k) -> {id: (x, y, v, a, lane, L, W, psi)}``."""
    log = StepLog()
    for k in range(steps):
        x, vx, y, vy = ego(k)
        log.t.append(k * dt)
        log.ego.append((x, vx, y, vy, 0.0, 0.0))
        log.mode.append("active")
        log.plan_time.append(math.nan)
        nb = others(k)
        log.ids.append(tuple(nb))
        log.nb.append(np.array([nb[v] for v in nb], dtype=float).reshape(-1, 8))
    return log


def _lane(y: float) -> int:
    return 0 if y < 1.6 else 1


def test_a_turned_ego_touching_a_neighbour_is_a_contact_the_axis_aligned_boxes_miss():
    """Issue 30: a 45 deg heading at crawl speed, a real overlap axis-aligned boxes miss."""
    v = 0.8 / math.sqrt(2)
    log = _log(3, lambda k: (0.0, v, 0.0, v), lambda k: {"a": (0.0, 2.5, 0.0, 0.0, 1, 4.8, 1.8, 0.0)})
    area = _clip_area(_rect(0, 0, 4.8, 1.8, math.pi / 4), _rect(0, 2.5, 4.8, 1.8, 0.0))
    assert area > 0  # the bodies do overlap
    m = monitor(log, 0.1, (4.8, 1.8), _lane, 1, 30.0, None, [])
    assert m["contacts"] == 1 and m["axis_aligned_contacts"] == 0
    assert m["monitor_only_contacts"] == 1 and m["contact_disagreements"] == 1
    assert "lane" in m["monitor_only"][0]["reason"]


def test_a_sumo_report_with_the_bodies_apart_is_listed_with_its_reason():
    log = _log(5, lambda k: (0.0, 0.0, 0.0, 0.0), lambda k: {"b": (0.0, 2.2, 0.0, 0.0, 0, 4.8, 1.8, 0.0)})
    m = monitor(log, 0.1, (4.8, 1.8), _lane, 1, 30.0, None, [(0.2, "b", "collision")])
    assert m["contacts"] == 0 and m["sumo_contacts"] == 1 and m["sumo_only_contacts"] == 1
    only = m["sumo_only"][0]
    assert only["separation_m"] == pytest.approx(0.4) and "lane-based" in only["reason"]
    # SUMO agreeing with the bodies (within one step) is no disagreement
    log2 = _log(5, lambda k: (0.0, 0.0, 0.0, 0.0), lambda k: {"b": (4.0, 0.0, 0.0, 0.0, 0, 4.8, 1.8, 0.0)})
    m2 = monitor(log2, 0.1, (4.8, 1.8), _lane, 1, 30.0, None, [(0.2, "b", "collision")])
    assert m2["contacts"] == 1 and m2["contact_disagreements"] == 0 and m2["contact_list"][0]["sumo_reported"]


# -- blame of contacts -----------------------------------------------------------------------------

def test_a_cut_in_that_touches_the_follower_is_a_contact_at_fault():
    """The ego moves sideways at 1 m/s into the lane of a follower 3 m behind at its speed."""
    dt = 0.1

    def ego(k):  # type: ignore[no-untyped-def]
        t = k * dt
        return (100 + 20 * t, 20.0, max(3.2 - max(t - 0.5, 0.0), 0.0), -1.0 if 0.5 <= t < 3.7 else 0.0)

    log = _log(40, ego, lambda k: {"f": (100 - 4.8 + 1.0 + 20 * k * dt, 0.0, 20.0, 0.0, 0, 4.8, 1.8, 0.0)})
    m = monitor(log, dt, (4.8, 1.8), _lane, 0, 30.0, None, [])
    assert m["contacts"] == 1 and m["contacts_at_fault"] == 1 and m["contacts_not_at_fault"] == 0
    c = m["contact_list"][0]
    assert c["response"] == "lateral" and c["threshold_t"] is not None and not c["other_at_fault"]
    assert m["rss_dangerous_s"] > 0 and m["rss_dangerous_by_response_s"]["lateral"] == m["rss_dangerous_s"]
    assert m["rss"]["response_time_s"] == 0.5 and "source" in m["rss"]


def test_a_follower_running_into_the_ego_is_a_contact_not_at_fault():
    dt = 0.1
    # 170 m behind at +15 m/s: RSS-safe at first (d_lon(30, 15) = 158 m), touches after 11.3 s
    log = _log(130, lambda k: (200 + 15 * k * dt, 15.0, 0.0, 0.0),
               lambda k: {"f": (200 - 4.8 - 170 + 30 * k * dt, 0.0, 30.0, 0.0, 0, 4.8, 1.8, 0.0)})
    m = monitor(log, dt, (4.8, 1.8), _lane, 1, 30.0, None, [])
    assert m["contacts"] == 1 and m["contacts_at_fault"] == 0 and m["contacts_not_at_fault"] == 1
    assert m["contact_list"][0]["other_at_fault"] and m["rss_dangerous_s"] == 0.0


# -- the followers' emergency brakes -----------------------------------------------------------------

def _brake_log(a_of, between=False):  # type: ignore[no-untyped-def]
    def others(k):  # type: ignore[no-untyped-def]
        nb = {"f": (70.0 + 20 * k * 0.1, 0.0, 20.0, a_of(k), 0, 4.8, 1.8, 0.0),
              "ahead": (160.0 + 20 * k * 0.1, 0.0, 20.0, -9.0, 0, 4.8, 1.8, 0.0)}
        if between:
            nb["m"] = (85.0 + 20 * k * 0.1, 0.0, 20.0, 0.0, 0, 4.8, 1.8, 0.0)
        return nb
    return _log(20, lambda k: (100 + 20 * k * 0.1, 20.0, 0.0, 0.0), others)


def test_emergency_brakes_count_runs_behind_the_ego_only():
    a = lambda k: -EMERGENCY_DECEL - 1 if k in (3, 4, 5, 10) else -1.0  # noqa: E731
    m = responsibility(_brake_log(a), 0.1, (4.8, 1.8), [], _lane)
    # two runs of vehicle f (steps 3-5 and 10); the car ahead of the ego brakes for itself
    assert m["follower_emergency_brakes"] == 2
    assert [e["t"] for e in m["follower_emergency_brake_list"]] == pytest.approx([0.3, 1.0])
    assert m["follower_emergency_brake_list"][0]["decel"] == pytest.approx(EMERGENCY_DECEL + 1)
    # braking just below the threshold, or with a vehicle in between, is not the ego's
    assert responsibility(_brake_log(lambda k: -EMERGENCY_DECEL + 0.1), 0.1, (4.8, 1.8), [], _lane)[
        "follower_emergency_brakes"] == 0
    assert responsibility(_brake_log(a, between=True), 0.1, (4.8, 1.8), [], _lane)["follower_emergency_brakes"] == 0


# -- iamp simulate: exit status, --commonroad options, help texts ---------------------------------------

def test_simulate_exits_5_on_a_failed_mission_and_0_on_success(monkeypatch, capsys):
    from iamp.cli import main as cli_main
    from iamp.cli.types import EXIT_BAD_INPUT, EXIT_MISSION_FAILED, EXIT_SOLVER
    from iamp.simulation import episode
    from iamp.simulation.episode import EpisodeResult

    assert EXIT_MISSION_FAILED not in (0, 1, EXIT_BAD_INPUT, EXIT_SOLVER, 4)
    for success, code in ((False, EXIT_MISSION_FAILED), (True, 0)):
        monkeypatch.setattr(episode, "run_episode",
                            lambda spec, s=success: EpisodeResult(spec, {"success": s, "planner": spec.planner},
                                                                  StepLog()))
        assert cli_main.main(["simulate", "--planner", "free", "--json"]) == code
        assert json.loads(capsys.readouterr().out)["success"] is success


@pytest.mark.parametrize("option", [["--planner", "qp"], ["--mission", "onramp"], ["--traffic", "dense"],
                                    ["--cooperation", "low"], ["--duration", "30"], ["--period", "0.2"],
                                    ["--sublane"], ["--deadline"], ["--ego-in-forecast"], ["--figure", "e.png"]])
def test_simulate_commonroad_refuses_an_option_it_would_ignore(option, tmp_path, capsys):
    from iamp.cli.main import main

    code = main(["simulate", "--commonroad", str(tmp_path), *option])
    err = capsys.readouterr().err
    assert code == 2 and option[0] in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err


@pytest.mark.parametrize("option", [["--road-planner", "pmp"], ["--recording", "r.xml"], ["--routes", "as-shipped"]])
def test_commonroad_options_are_refused_without_commonroad(option, capsys):
    from iamp.cli.main import main

    assert main(["simulate", *option]) == 2
    assert option[0] in capsys.readouterr().err


@pytest.mark.parametrize(("option", "repair"), [([], True), (["--routes", "repaired"], True),
                                               (["--routes", "as-shipped"], False)])
def test_simulate_commonroad_routes_flag_reaches_the_loop(option, repair, tmp_path, monkeypatch):
    """``--routes`` chooses whether SUMO gets the scene's routes repaired (the default) or as shipped."""
    pytest.importorskip("commonroad")
    import iamp.commonroad
    import iamp.commonroad.interactive as interactive
    from iamp.cli.main import main

    seen: dict[str, object] = {}

    def fake(folder, planner, **kw):  # type: ignore[no-untyped-def]
        seen.update(kw)
        return {"success": True}, None

    monkeypatch.setattr(interactive, "simulate_with_log", fake)
    monkeypatch.setattr(iamp.commonroad, "require", lambda *a, **k: None)
    main(["simulate", "--commonroad", str(tmp_path), "--json", *option])
    assert seen.get("repair_routes") is repair


def _options(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()):  # type: ignore[no-untyped-def]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _options(sub, (*path, name))
        elif not isinstance(action, argparse._HelpAction) and action.help != argparse.SUPPRESS:
            yield " ".join(path), "/".join(action.option_strings) or action.dest, action.help


def test_every_option_of_every_subcommand_has_a_help_text_that_names_no_issue():
    from iamp.cli.main import build_parser

    rows = list(_options(build_parser()))
    assert any(cmd == "simulate" for cmd, _, _ in rows) and any(cmd == "campaign" for cmd, _, _ in rows)
    missing = {(cmd, opt) for cmd, opt, h in rows if not (h and str(h).strip())}
    assert not missing, sorted(missing)
    assert not [(cmd, opt) for cmd, opt, h in rows if h and "issue" in str(h).lower()]


# -- campaign: columns, old folders -------------------------------------------------------------------

def test_campaign_rows_carry_the_rss_columns_and_tables_show_them():
    from iamp.simulation.campaign import COLUMNS, flatten, latex_table, paired_table
    from iamp.simulation.stats import campaign_report

    for col in ("contacts_at_fault", "contacts_not_at_fault", "rss_dangerous_s", "rss_dangerous_lateral_s",
                "follower_emergency_brakes", "sumo_only_contacts", "contact_disagreements"):
        assert col in COLUMNS
    base = {"mission": "merge", "traffic": "dense", "ego_ax_range": [0, 0], "rms_accel": [0, 0], "rms_jerk": [0, 0],
            "plan_time_s": {"p50": None, "p95": None, "max": None},
            "wall_s": {"total": 1, "sumo": 0, "prediction": 0, "planning": 0}}
    rows = []
    for seed in (1, 2):
        for planner, fault in (("pmp", seed == 1), ("free", False)):
            row = flatten({**base, "planner": planner, "seed": seed, "success": True, "contacts": int(fault),
                           "contacts_at_fault": int(fault), "follower_emergency_brakes": 0, "rss_dangerous_s": 1.5,
                           "rss_dangerous_by_response_s": {"lateral": 1.0, "longitudinal": 0.5, "both": 0.0}})
            rows.append({k: ("" if v is None else str(v)) for k, v in row.items()})
    assert rows[0]["rss_dangerous_lateral_s"] == "1.0"
    rep = campaign_report(rows, ["pmp", "free"])
    cell = rep["cells"][0]
    assert cell["contact_at_fault_episodes"] == 1 and cell["rss_dangerous_s_median"] == 1.5
    assert "at fault" in latex_table(rep["cells"]) and "1/2 [" in latex_table(rep["cells"])
    for text in (latex_table(rep["cells"]), paired_table(rep["paired"])):  # every row has the spec's columns
        lines = text.splitlines()
        spec = lines[0][len("\\begin{tabular}{"):-1]
        assert all(line.count("&") + 1 == len(spec) for line in lines if "&" in line)
    assert rep["paired"][0]["contact_at_fault"]["b"] == 1 and "at fault" in paired_table(rep["paired"])
    # rows of a campaign made before SPEC §17: not measured, shown as --
    old = [{k: v for k, v in r.items() if k not in ("contacts_at_fault", "follower_emergency_brakes",
                                                     "rss_dangerous_s")} for r in rows]
    rep_old = campaign_report(old, ["pmp", "free"])
    assert rep_old["cells"][0]["contact_at_fault_episodes"] is None and rep_old["paired"][0]["contact_at_fault"] is None
    assert "--" in latex_table(rep_old["cells"]) and "--" in paired_table(rep_old["paired"])


def test_resuming_a_campaign_of_an_older_episode_format_refuses_naming_it(tmp_path):
    from iamp.simulation.campaign import EPISODE_FORMAT, ManifestMismatch, check_manifest, manifest_of

    episode = {"duration_s": 60.0, "period_s": 0.1, "deadline_s": None, "warmup_s": 5.0, "settle_s": 8.0,
               "cooperation": "default", "sublane": False, "ego_in_forecast": False}
    wanted = manifest_of(["merge"], ["pmp"], ["dense"], 3, episode)
    assert wanted["episode_format"] == EPISODE_FORMAT and wanted["rss"]["brake_max"] == 8.0
    old = {k: v for k, v in wanted.items() if k != "rss"}
    old["episode_format"] = "15.1"
    (tmp_path / "manifest.json").write_text(json.dumps(old))
    (tmp_path / "episodes.csv").write_text("mission,planner,traffic,seed\nmerge,pmp,dense,1\n")
    with pytest.raises(ManifestMismatch, match=rf"episode format '15.1', now '{EPISODE_FORMAT}'.*rss.*--force"):
        check_manifest(tmp_path, wanted, force=False)
    assert check_manifest(tmp_path, wanted, force=True) == wanted and not (tmp_path / "episodes.csv").exists()
