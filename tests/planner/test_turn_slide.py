"""planner.turn_slide: postures whose turns the skid-steer model does not price over the limit.

Where the overall CoM sits changes a pivot's slide on a side slope (0.09-0.39 m/rad for the
postures of one corner of validation route 26); the most stable posture is not the one that
turns best. The turning chords come from the planned poses; a grid of overall CoMs prices
every row (checked against the model per row); a search with the limit keeps the chosen
postures' turns under it where a stable posture can, and without one keeps them all.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_under_arm import _map, _settings

from mmstab.planner.ground.under_arm import GroundUnderArm
from mmstab.planner.searches.roadmap import solve_roadmap_sequence
from mmstab.planner.turning import (
    GRID,
    TURN_MIN,
    SlideLimit,
    TurnPricer,
    slide_exclusions,
    turn_chords,
)
from mmstab.stability.static import mu_max
from mmstab.terrain.generators import Grid, plane
from mmstab.terrain.heightmap_terrain import HeightmapTerrain
from mmstab.workspace import build_workspace
from mmstab.workspace.roadmap import build_roadmap

LIMIT = 0.07  # the tests' limit on an 8.6 deg plane [m] (the default is 0.04)


@pytest.fixture(scope="module")
def small(robot):
    return build_roadmap(robot, build_workspace(robot, (10, 8, 8, 8), progress=False))


def _pivot(heading0: float, turn: float) -> np.ndarray:
    """Two poses up to a pivot, three after it (headings [rad]), 0.4 m apart."""
    a = np.array([[-0.8, 0.0], [-0.4, 0.0], [0.0, 0.0]])
    d = np.array([np.cos(heading0 + turn), np.sin(heading0 + turn)])
    b = np.array([0.4, 0.8])[:, None] * d
    return np.r_[np.c_[a, np.full(3, heading0)], np.c_[b, np.full(2, heading0 + turn)]]


def test_the_chords_that_turn(robot):
    terrain = _map(robot, "tilted")
    poses = _pivot(0.3, 1.0)
    (chord,) = turn_chords(terrain, poses, closed=False)
    assert (chord.first, chord.last) == (2, 3) and chord.turn == pytest.approx(1.0)
    # the gravity at the chord's middle, at the headings across the turn
    mid = (poses[2, :2] + poses[3, :2]) / 2
    want = terrain.gravity_body(np.array([[*mid, 0.3], [*mid, 0.8], [*mid, 1.3]]))
    np.testing.assert_allclose(chord.gravity_body, want)
    straight = poses.copy()
    straight[:, 2] = 0.3
    assert turn_chords(terrain, straight, closed=False) == []
    # a loop closes with the chord back to the first pose (1 rad back: a turn too)
    loop = turn_chords(terrain, poses, closed=True)
    assert [c.first for c in loop] == [2, 4] and loop[1].turn == pytest.approx(-1.0)
    assert loop[1].poses(len(poses)) == [4, 0]
    # a pivot the planned poses fall inside: its chords turning the same way are one turn
    inside = np.insert(poses, 3, [0.0, 0.0, 0.7], axis=0)
    (split,) = turn_chords(terrain, inside, closed=False)
    assert (split.first, split.last) == (2, 4) and split.turn == pytest.approx(1.0)
    assert split.poses(len(inside)) == [2, 3, 4]
    # ... also across a loop's seam (the first chord and the last turn the same way)
    seam = turn_chords(terrain, np.roll(inside, -3, axis=0), closed=True)
    assert [(c.first, c.last, round(c.turn, 6)) for c in seam] == [(5, 7, 1.0), (2, 3, -1.0)]
    small_turn = poses.copy()
    small_turn[3:, 2] = 0.3 + TURN_MIN / 2
    assert turn_chords(terrain, small_turn, closed=False) == []


def test_the_grid_prices_rows_as_the_model_does(robot, small):
    terrain = _map(robot, "tilted")
    (chord,) = turn_chords(terrain, _pivot(0.3, 1.0), closed=False)
    pricer = TurnPricer(robot, terrain)
    rng = np.random.default_rng(7)
    rows = rng.choice(len(small.nodes_q), 60, replace=False)
    com = robot.overall_com(robot.arm_com(small.nodes_q[rows]))
    grid = pricer.grid_slide(chord, 1, com)
    exact = np.nan_to_num(pricer.per_radian(chord.gravity_body[1], com), nan=np.inf) * 1.0
    finite = np.isfinite(exact)
    assert finite.mean() > 0.9
    # trilinear over a GRID x GRID x 2 grid: within 12 % of the model's (measured 10 %, 3 cm
    # on 22-41 cm), 6 mm in the median
    error = np.abs(grid[finite] - exact[finite])
    assert np.all(error < 0.12 * exact[finite]) and np.median(error) < 0.008
    assert np.ptp(exact[finite]) > 0.03  # and the CoM matters by more than that
    # the chord's worst heading is the largest of its headings' prices
    slide, worst = pricer.slide(chord, com[:2])
    per = [
        np.nan_to_num(pricer.per_radian(g, com[:2]), nan=np.inf).max() for g in chord.gravity_body
    ]
    assert worst == int(np.argmax(per)) and slide == pytest.approx(max(per) * 1.0)
    assert GRID == 3


def _gentle(robot) -> HeightmapTerrain:
    """An 8.6 deg plane: a half-radian pivot slides from 4.7 cm as the CoM goes (median 6.5)."""
    return HeightmapTerrain(plane(Grid.of_size((6.0, 6.0), 0.04), 0.15, 0.7)).with_robot(robot)


def test_all_turns_at_once_price_as_each_alone(robot, small):
    terrain = _map(robot, "tilted")
    loop = turn_chords(terrain, _pivot(0.3, 1.0), closed=True)
    pricer = TurnPricer(robot, terrain)
    rng = np.random.default_rng(3)
    com = robot.overall_com(robot.arm_com(small.nodes_q[rng.choice(len(small.nodes_q), 40)]))
    together = pricer.slides(loop, [com[:2], com[2:5]])
    alone = [pricer.slide(loop[0], com[:2]), pricer.slide(loop[1], com[2:5])]
    for (a, ha), (b, hb) in zip(together, alone, strict=True):
        assert ha == hb and a == pytest.approx(b, rel=1e-6)
    grids = pricer.grid_slides(loop, [0, 2], com)
    for t, h, grid in zip(loop, [0, 2], grids, strict=True):
        np.testing.assert_allclose(grid, pricer.grid_slide(t, h, com), rtol=1e-6)


@pytest.mark.parametrize("spread", ["every axis", "one z"])
def test_the_c_grid_read_is_the_numpy_one(robot, small, spread, monkeypatch):
    """turning.c (the rows' overall CoMs, their extent, the trilinear read) against NumPy
    (Robot.overall_com, scipy's map_coordinates): to round-off, rows at the grid's corners
    and edges among them, two turns at once."""
    from mmstab.planner import turning

    terrain = _map(robot, "tilted")
    loop = turn_chords(terrain, _pivot(0.3, 1.0), closed=True)
    pricer = TurnPricer(robot, terrain)
    rng = np.random.default_rng(11)
    arm = robot.arm_com(small.nodes_q)
    if spread == "one z":  # every row at one height: the z axis has one node
        arm[:, 2] = 0.25
    rows = np.sort(rng.choice(len(arm), 500, replace=False))
    lo, hi = (np.argmin(arm[:, 0]), np.argmax(arm[:, 0])), (np.argmin(arm[:, 1]),)
    rows = np.union1d(rows, [*lo, *hi])  # the extent's own rows: the grid's edges
    assert turning._turn_kernels() is not None
    c = pricer.grid_slides_of_rows(loop, [0, 2], arm, rows)
    numpy = pricer.grid_slides(loop, [0, 2], robot.overall_com(arm[rows]))
    for a, b in zip(c, numpy, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15)
        assert np.ptp(b) > 0.01  # the rows' prices differ: the read is not a constant
    monkeypatch.setattr(turning, "_turn_kernels", lambda: None)  # no compiler: NumPy's
    for a, b in zip(pricer.grid_slides_of_rows(loop, [0, 2], arm, rows), numpy, strict=True):
        np.testing.assert_array_equal(a, b)


def _plan(robot, small, terrain, poses, limit):
    g = terrain.gravity_body(poses)
    under = GroundUnderArm(robot, terrain, poses)
    slide = (
        None if limit is None else SlideLimit(terrain, turn_chords(terrain, poses, False), limit)
    )
    s = _settings(0.05)
    return solve_roadmap_sequence(robot, g, small, s, mu_max(robot), False, poses, under=under,
                                  slide=slide)  # fmt: skip


def test_a_search_with_the_limit_turns_under_it_where_a_stable_posture_can(robot, small):
    # an 8.6 deg plane; a pivot of half a radian across the slope: the most stable
    # postures slide 11.9 cm there; a limit of 7 cm (some stable postures turn within it)
    terrain = _gentle(robot)
    poses = _pivot(0.3, 0.5)
    (chord,) = turn_chords(terrain, poses, closed=False)
    pricer = TurnPricer(robot, terrain)
    free = _plan(robot, small, terrain, poses, None)
    held = _plan(robot, small, terrain, poses, LIMIT)
    before = pricer.slide(chord, robot.overall_com(free.com[2:4]))[0]
    after = pricer.slide(chord, robot.overall_com(held.com[2:4]))[0]
    assert before > LIMIT  # the most stable postures slide in the pivot
    (record,) = held.turns
    assert (record["first"], record["last"]) == (2, 3)
    assert record["slide_m"] == pytest.approx(before)
    assert record["poses"] == [2, 3]
    assert after <= LIMIT * 1.12  # the grid's error allowed (12 %)
    assert after < before
    assert held.total <= free.total + 1e-9  # a limit only removes candidates
    # away from the turn the choice is the search's own
    assert np.all(held.mu > 0)


def test_no_stable_posture_under_the_limit_keeps_them_all(robot, small):
    terrain = _gentle(robot)
    poses = _pivot(0.3, 0.5)
    chords = turn_chords(terrain, poses, closed=False)
    free = _plan(robot, small, terrain, poses, None)
    g = terrain.gravity_body(poses)
    # a limit no posture turns within: nothing excluded, the record says so
    rows = np.arange(len(small.nodes_q))
    fits = [type("Fit", (), {"mu": staticmethod(lambda c: np.ones(len(c)))})() for _ in g]
    excluded, records = slide_exclusions(robot, terrain, chords, free.com, 1e-6,
                                         robot.arm_com(small.nodes_q), np.ones(len(rows), bool),
                                         fits)  # fmt: skip
    assert excluded == {} and records[0]["poses"] == []
    held = _plan(robot, small, terrain, poses, 1e-6)
    np.testing.assert_array_equal(held.nodes, free.nodes)


def test_the_limit_is_off_by_default_and_checked(tmp_path, capsys):
    import yaml
    from conftest import PROBLEMS, assert_bad_planner_key

    from mmstab.core.files import ConfigError
    from mmstab.core.problem import load_problem
    from mmstab.planner import PlannerSettings

    kerb = load_problem(PROBLEMS / "kerb.yaml")  # a route over a heightmap: every default
    assert PlannerSettings.from_section(kerb.section("planner")).turn_slide is None
    assert_bad_planner_key(tmp_path, capsys, "turn_slide", -0.04)
    assert_bad_planner_key(tmp_path, capsys, "turn_slide", 0.04)  # a circle: no route to price
    data = yaml.safe_load((PROBLEMS / "kerb.yaml").read_text())
    data["robot"] = str(PROBLEMS / "robots" / "cameleon.yaml")
    for method, ok in (("roadmap", True), ("cmaes", False)):  # only the roadmap's search
        data["planner"].update(turn_slide=0.04, method=method)
        path = tmp_path / f"kerb_{method}.yaml"
        path.write_text(yaml.safe_dump(data))
        if ok:
            settings = PlannerSettings.from_section(load_problem(path).section("planner"))
            assert settings.turn_slide == 0.04
        else:
            with pytest.raises(ConfigError, match="method: roadmap") as info:
                load_problem(path)
            assert info.value.field == "planner.turn_slide"


def test_the_limit_prices_with_the_problems_slide_model(robot, tmp_path):
    from conftest import write_problem

    from mmstab.app.settings import Settings
    from mmstab.core.problem import load_problem
    from mmstab.planner import PlannerSettings

    def physics(p, r):
        p.setdefault("physics", {}).update(shear_modulus=0.2, turn_ratio="auto")

    problem = load_problem(write_problem(tmp_path, physics))
    planner, phys = problem.section("planner"), problem.section("physics")
    settings = PlannerSettings.from_section(planner, phys)
    assert settings.slide_model == (0.2, "auto")
    assert Settings.from_problem(problem).planner.slide_model == (0.2, "auto")
    assert PlannerSettings.from_section(planner).slide_model == (0.0041, 1.0)  # the defaults
    # the pricer takes them: a much softer belt (a larger shear modulus) creeps more (on a
    # pivot the rigid slope part binds up to K = 0.05 m, and the ratio only scales the twist)
    terrain = _gentle(robot)
    (chord,) = turn_chords(terrain, _pivot(0.3, 0.5), closed=False)
    com = robot.overall_com(robot.arm_com(robot.stowed))[None]
    default = TurnPricer(robot, terrain).slide(chord, com)[0]
    assert TurnPricer(robot, terrain, (0.0041, 1.0)).slide(chord, com)[0] == default
    soft = TurnPricer(robot, terrain, settings.slide_model).slide(chord, com)[0]
    assert soft == pytest.approx(1.044 * default, rel=2e-3)


def test_plan_reports_the_turns_the_limit_constrained(tmp_path, capsys):
    """``mmstab plan``: summary.json's ``turn_slide`` and its text line name each turn priced
    over the limit, where it is, and the poses that chose again."""
    import copy
    import json
    import sys

    import yaml
    from conftest import ROOT

    from mmstab.cli import main

    sys.path.insert(0, str(ROOT / "tests" / "runs"))
    from test_random_routes import pair_problem

    path = pair_problem(1, tmp_path)  # a 16-pose random route with two turns on a slope
    data = copy.deepcopy(yaml.safe_load(path.read_text()))
    data.setdefault("planner", {})["turn_slide"] = 0.12
    path.write_text(yaml.safe_dump(data))
    main(["plan", str(path), "-o", str(tmp_path / "out"), "--allow-sliding", "--allow-unstable"])
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    turns = s["turn_slide"]["turns"]
    assert s["turn_slide"]["limit_m"] == 0.12 and len(turns) == 2
    for t in turns:
        assert t["slide_m"] > 0.12 and t["poses"] == list(range(t["first"], t["last"] + 1))
        assert (t["start_s"], t["end_s"]) == (s["s"][t["first"]], s["s"][t["last"]])
    line = [x for x in capsys.readouterr().out.splitlines() if "turn slide limit" in x]
    assert line == [
        "plan: turn slide limit 12 cm: "
        + "; ".join(
            f"s = {t['start_s']:.2f}-{t['end_s']:.2f} m ({t['turn_rad']:.2f} rad) priced "
            f"{100 * t['slide_m']:.1f} cm, poses {', '.join(map(str, t['poses']))} chose again"
            for t in turns
        )
    ]
    # off: the key says so and no line
    data["planner"]["turn_slide"] = None
    path.write_text(yaml.safe_dump(data))
    main(["plan", str(path), "-o", str(tmp_path / "off"), "--allow-sliding", "--allow-unstable"])
    off = json.loads((tmp_path / "off" / "summary.json").read_text())["turn_slide"]
    assert off == {"limit_m": None, "turns": []}
    assert "turn slide limit" not in capsys.readouterr().out
