"""Robots as users describe them, and the messages a user trips on.

A 5-joint arm with a zero-length (spherical-wrist style) link planned from a three-key
problem; per-joint settings from the robot's joint count, every mismatch in one message;
``collision.allow`` and the pairs that touch at every posture; links whose shape is off
their DH segment; misspelt keys named with the closest valid one; angles in degrees; what
``mmstab rest`` checks, prints and echoes.
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import PROBLEMS, ROBOT_YAML, write_problem

from mmstab.cli import main
from mmstab.core.defaults import DEFAULT_SECTIONS, joint_defaults
from mmstab.core.files import ConfigError
from mmstab.core.notes import held_notes
from mmstab.core.problem import load_problem, problem_from_dict
from mmstab.core.sizes import WS_FULL_GRID_MAX
from mmstab.model.collision import CollisionChecker
from mmstab.model.robot import LINK_EXTENT_TOL, link_extent_warnings, load_robot, robot_from_dict
from mmstab.model.touching import TOUCHING_SAMPLES, touching_pairs, with_touching_allowed

ROUTE = {"waypoints": [[0.0, 0.0], [1.5, 0.0]], "speed": 0.3, "turn_radius": 0.0}
#: A coarse grid for the 5-joint arm's plan (its default is 14 x 17 x 15 x 15 x 8).
GRID_5 = [8, 8, 8, 8, 4]


def _refused(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    """Run ``argv``: exit status 2 and one line on stderr, returned."""
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mmstab: error: "), err
    return err[0]


def cameleon() -> dict:
    return yaml.safe_load(ROBOT_YAML.read_text())


def five_joint_robot() -> dict:
    """cameleon.yaml with a zero-length wrist-roll link between the forearm and the wrist.

    The link's frame is the forearm's (a = d = alpha = 0); its shape a sphere at the joint.
    The forearm capsule (r 0.035) ends at the joint and the wrist capsule (r 0.03) starts
    0.25 - 0.20 = 0.05 m from it, whatever the angle: 0.05 < 0.035 + 0.03, they always touch.
    """
    robot = cameleon()
    roll = copy.deepcopy(robot["arm"]["links"][3])
    roll.update(
        name="wrist_roll",
        dh={"a": 0.0, "alpha": 0.0, "d": 0.0, "theta_offset": 0.0},
        mass=0.3,
        com=[0.0, 0.0, 0.0],
        geometry={"type": "capsule", "radius": 0.03, "p0": [0.0, 0.0, 0.0], "p1": [0.0, 0.0, 0.0]},
    )
    robot["arm"]["links"].insert(3, roll)
    robot["arm"]["stowed"] = [0.0, 0.1, 2.9, 0.0, 0.0]
    return robot


def write(tmp_path: Path, problem: dict, robot: dict, name: str = "p.yaml") -> Path:
    (tmp_path / "robots").mkdir(exist_ok=True)
    (tmp_path / "robots" / "r.yaml").write_text(yaml.safe_dump(robot))
    path = tmp_path / name
    path.write_text(yaml.safe_dump({"robot": "robots/r.yaml", **problem}))
    return path


# ------------------------------------------------------------ a 5-joint arm, three keys
def test_a_5_joint_arm_with_a_zero_length_wrist_plans_from_a_three_key_problem(tmp_path, capsys):
    """Before: 'controller.w_b' (a key the file does not have), then, with the four keys
    sized by hand, 'no collision-free posture on the workspace grid'.

    The three keys take the 5-joint defaults (checked on the loaded problem); the plan runs
    on a coarse grid given as a fourth key, so that the test does not build the default
    grid's V and roadmap (13 s on a fresh clone) for this arm alone."""
    three = write(tmp_path, {"terrain": {"slope": 0.1}, "path": ROUTE}, five_joint_robot())
    loaded = load_problem(three)
    assert loaded.section("workspace")["grid"] == [14, 17, 15, 15, 8]
    assert len(loaded.section("controller")["w_b"]) == 7
    four = {"terrain": {"slope": 0.1}, "path": ROUTE, "workspace": {"grid": GRID_5}}
    path = write(tmp_path, four, five_joint_robot(), "p4.yaml")
    robot = load_robot(tmp_path / "robots" / "r.yaml")
    # the forearm and the wrist touch at every posture: every grid posture "collided"
    raw = CollisionChecker(robot)
    q = np.random.default_rng(1).uniform(robot.joint_lower, robot.joint_upper, (300, 5))
    assert np.asarray(raw.collides(q)).all()
    assert touching_pairs(robot) == (("forearm", "wrist"),)
    assert main(["plan", str(path), "-o", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    note = f"forearm-wrist touch at every one of {TOUCHING_SAMPLES + 1} sampled postures"
    assert note in err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    postures = np.array([p["posture"] for p in summary["poses"]])
    assert postures.shape == (4, 5)  # 1.5 m every 0.5 m
    assert all(p["collision_free"] for p in summary["poses"])
    checker = CollisionChecker(with_touching_allowed(robot)[0])
    assert checker.allowed == ("forearm-wrist",)
    assert not np.asarray(checker.collides(postures)).any()
    # ... and every planned posture is free of every pair but the one skipped
    for qk in postures:
        assert raw.colliding_pairs(qk) == ["forearm-wrist"]
    assert min(p["mu_planned"] for p in summary["poses"]) > 0
    saved = yaml.safe_load((tmp_path / "out" / "problem.yaml").read_text())
    assert saved["workspace"]["grid"] == GRID_5 and len(saved["controller"]["w_b"]) == 7


def test_every_per_joint_mismatch_is_named_in_one_message(tmp_path, capsys):
    """Before: one field per run (controller.w_b, then posture_gain, ...)."""
    ramp = yaml.safe_load((PROBLEMS / "ramp.yaml").read_text())
    path = write(tmp_path, {k: v for k, v in ramp.items() if k != "robot"}, five_joint_robot())
    line = _refused(capsys, ["plan", path])
    assert line == (
        f"mmstab: error: {path}: controller.w_b: has 6 entries, needs 7 for the robot's "
        "5-joint arm; controller.posture_gain: has 4 entries, needs 5; "
        "controller.posture_weight: has 4 entries, needs 5; workspace.grid: has 4 entries, "
        "needs 5 (left out, a per-joint key takes its default for the robot's joints)"
    )


def test_per_joint_defaults_follow_the_joint_count():
    four = joint_defaults(4)
    for section, keys in four.items():
        for key, value in keys.items():
            assert DEFAULT_SECTIONS[section][key] == value  # the 4-DoF default problem's
    for n in range(1, 9):
        d = joint_defaults(n)
        assert len(d["controller"]["w_b"]) == n + 2
        assert len(d["controller"]["posture_gain"]) == len(d["workspace"]["grid"]) == n
        full = math.prod(d["workspace"]["grid"])
        assert full <= WS_FULL_GRID_MAX  # a whole grid (the roadmap needs one)
        if n >= 4:
            assert 0.7 * 435000 < full <= 435000, full
    # 13 extra samples scaled by (435000 / (435000 * 13)) ** (1 / 5) = 0.599: 24 -> 14, 13 -> 8
    assert joint_defaults(5)["workspace"]["grid"] == [14, 17, 15, 15, 8]


def test_per_joint_keys_the_file_gives_are_kept(tmp_path):
    problem = {"terrain": {"slope": 0.1}, "path": ROUTE}
    problem["controller"] = {"posture_gain": [4.0] * 5}
    problem["workspace"] = {"grid": [6, 6, 6, 6, 6]}
    path = write(tmp_path, problem, five_joint_robot())
    p = problem_from_dict(yaml.safe_load(path.read_text()), path)
    assert p.data["controller"]["posture_gain"] == [4.0] * 5
    assert p.data["controller"]["posture_weight"] == [1e-3] * 5
    assert p.data["workspace"]["grid"] == [6] * 5


# -------------------------------------------------------------------- collision.allow
def test_collision_allow_names_an_unknown_body_with_the_closest_one():
    robot = cameleon()
    robot["collision"] = {"allow": [["forearm", "body"], ["upper_arm", "wirst"]]}
    with pytest.raises(ConfigError) as info:
        robot_from_dict(robot, "r.yaml")
    assert info.value.field == "collision.allow[1][1]"
    assert info.value.message == "unknown body 'wirst'; did you mean 'wrist'?"
    robot["collision"] = {"allow": [["wrist", "wrist"]]}
    with pytest.raises(ConfigError, match="a pair of two different bodies"):
        robot_from_dict(robot, "r.yaml")
    robot["collision"] = {"alow": []}
    with pytest.raises(ConfigError, match="did you mean 'allow'"):
        robot_from_dict(robot, "r.yaml")


def test_an_allowed_pair_is_not_checked():
    plain = load_robot(ROBOT_YAML)
    checker = CollisionChecker(plain)
    q = np.random.default_rng(4).uniform(plain.joint_lower, plain.joint_upper, (400, 4))
    only = [qk for qk in q if checker.colliding_pairs(qk) == ["wrist-body"]]
    assert len(only) >= 3  # postures where the wrist touches the body and nothing else does
    data = cameleon()
    data["collision"] = {"allow": [["body", "wrist"]]}
    allowed = CollisionChecker(robot_from_dict(data, "r.yaml"))
    assert "wrist-body" in allowed.allowed
    assert "wrist-body" not in [pr.name for pr in allowed.pairs]
    assert not np.asarray(allowed.collides(np.array(only))).any()
    assert np.asarray(checker.collides(np.array(only))).all()


def test_no_shipped_robot_has_a_touching_pair_or_an_off_segment_link():
    for path in sorted((PROBLEMS / "robots").glob("*.yaml")):
        robot = load_robot(path)
        assert touching_pairs(robot) == (), path
        assert link_extent_warnings(robot) == [], path


@pytest.mark.parametrize(
    ("stowed", "message"),
    [
        # the upper arm lowered 0.8 rad from the mount 0.12 m ahead: through the body's top
        ([0.0, -0.8, 0.0, 0.0], "the stowed arm touches the robot (upper_arm-body); stow it "
         "clear, or allow the pair under collision.allow"),
        # held forward, the forearm hanging: clear of the base, 0.45 m into the ground
        ([0.0, 0.0, -1.57, 0.0], "the stowed arm reaches 0.450 m below the ground (the "
         "tracks' plane z_B = 0); raise it"),
    ],
)  # fmt: skip
def test_a_stowed_arm_in_the_base_or_the_ground_is_refused(tmp_path, capsys, stowed, message):
    """Before: ``mmstab plan`` on a route stopped with 'roadmap: the posture [...] rad reaches
    no node' (no file, no field, no cause); ``mmstab.load_robot`` took the robot."""
    import mmstab

    data = cameleon()
    data["arm"]["stowed"] = stowed
    path = write(tmp_path, {"terrain": {"slope": 0.1}, "path": ROUTE}, data)
    robot_file = tmp_path / "robots" / "r.yaml"
    line = _refused(capsys, ["plan", path, "-o", tmp_path / "out"])
    assert line == f"mmstab: error: {robot_file}: arm.stowed: {message}"
    assert not (tmp_path / "out").exists()
    with pytest.raises(ConfigError, match="arm.stowed: the stowed arm"):
        mmstab.load_robot(robot_file)
    # the same posture is a plan's to reach, not the file's: checked the way the planner does
    robot = with_touching_allowed(load_robot(ROBOT_YAML))[0]
    hits = CollisionChecker(robot).colliding_pairs(np.array(stowed))
    assert (hits == ["upper_arm-body"]) == ("touches" in message)


def test_a_link_shape_left_behind_by_a_changed_dh_length_is_warned(tmp_path, capsys):
    """Before: silent. The forearm's capsule starts 0.44 m behind its joint; at a = 0.30 m
    it sticks out 0.14 m behind the elbow (its CoM, 0.23 m back and 2 cm up, stays 0.02 m
    off: within the 5 cm)."""
    data = cameleon()
    data["arm"]["links"][2]["dh"]["a"] = 0.30
    robot = robot_from_dict(data, "r.yaml")
    (line,) = link_extent_warnings(robot)
    assert line.startswith("arm.links[2] (forearm): geometry.p0 0.140 m off its DH segment")
    assert f"more than {LINK_EXTENT_TOL} m" in line
    data["arm"]["links"][2]["dh"]["a"] = 0.46  # 2 cm: within the tolerance
    assert link_extent_warnings(robot_from_dict(data, "r.yaml")) == []
    path = write_problem(tmp_path, lambda p, r: r["arm"]["links"][2]["dh"].update(a=0.30))
    assert main(["rest", str(path), "--pose", "0", "0", "0"]) == 0
    warned = [w for w in capsys.readouterr().err.splitlines() if "warning" in w]
    assert len(warned) == 1 and "arm.links[2] (forearm)" in warned[0]
    # refused after the load (an --arm angle beyond the forearm's 2.9 rad): one line still
    (tmp_path / "again").mkdir()
    path = write_problem(tmp_path / "again", lambda p, r: r["arm"]["links"][2]["dh"].update(a=0.3))
    line = _refused(capsys, ["rest", path, "--pose", "0", "0", "0", "--arm", "0", "0", "3", "0"])
    assert "--arm: joint 2 = 3.0 rad is outside its limits" in line


# ----------------------------------------------------------------------- misspelt keys
def _route_problem(tmp_path: Path, edit) -> Path:
    def ed(p, r):
        p["path"] = copy.deepcopy(ROUTE)
        edit(p, r)

    return write_problem(tmp_path, ed)


MISSPELT = [
    # (edit, field, closest) -- before: "path.center: missing required key" for the first
    (
        lambda p, r: p["path"].update(waypionts=p["path"].pop("waypoints")),
        "path.waypionts",
        "waypoints",
    ),
    (lambda p, r: p["terrain"].update(slop=p["terrain"].pop("slope")), "terrain.slop", "slope"),
    (lambda p, r: p["terrain"].update(generat={}), "terrain.generat", "generate"),
    (lambda p, r: p.update(controler={}), "controler", "controller"),
    (lambda p, r: p["planner"].update(w_stabilty=0.9), "planner.w_stabilty", "w_stability"),
    (lambda p, r: p["path"].update(sped=0.3), "path.sped", "speed"),
]


@pytest.mark.parametrize("edit,field,closest", MISSPELT, ids=[m[1] for m in MISSPELT])
def test_a_misspelt_key_is_named_with_the_closest_valid_key(tmp_path, capsys, edit, field, closest):
    path = _route_problem(tmp_path, edit)
    line = _refused(capsys, ["rest", path, "--pose", "0", "0", "0"])
    assert line == f"mmstab: error: {path}: {field}: unknown key; did you mean '{closest}'?"


@pytest.mark.parametrize(
    "key,what",
    [
        ("turn_radius", "the corners' arc radius [m]; 0 pivots on the spot"),
        ("speed", "the reference speed on straight lines [m/s]"),
    ],
)
def test_a_missing_route_key_says_what_it_is_and_its_unit(tmp_path, capsys, key, what):
    path = _route_problem(tmp_path, lambda p, r: p["path"].pop(key))
    line = _refused(capsys, ["plan", path, "-o", str(tmp_path / "out")])
    assert line == f"mmstab: error: {path}: path.{key}: missing required key: {what}"
    assert not (tmp_path / "out").exists()


def test_a_problem_handed_where_a_robot_file_is_asked_for_is_named(tmp_path, capsys):
    """Before: 'path: unknown key' (the problem read as a robot file)."""
    path = write_problem(tmp_path, lambda p, r: None)
    robot = yaml.safe_load(Path(path).read_text())["robot"]
    line = _refused(capsys, ["urdf", str(path), "-o", str(tmp_path / "r.urdf")])
    assert line == (
        f"mmstab: error: {path}: robot: a problem file, not a robot file: its robot is {robot!r}"
    )
    assert not (tmp_path / "r.urdf").exists()
    load_robot(Path(path).parent / robot)  # the file it names is one


def test_a_misspelt_robot_key_is_named_with_the_closest_valid_key(tmp_path, capsys):
    path = write_problem(tmp_path, lambda p, r: r["arm"].update(stowd=r["arm"].pop("stowed")))
    line = _refused(capsys, ["rest", path, "--pose", "0", "0", "0"])
    robot = tmp_path / "robots" / "cameleon.yaml"
    assert line == f"mmstab: error: {robot}: arm.stowd: unknown key; did you mean 'stowed'?"


# ------------------------------------------------------------------------------ degrees
DEGREES = [
    (lambda p, r: p["terrain"].update(slope=15), "problem.yaml: terrain.slope: 15", 0.2618),
    (
        lambda p, r: p.update(path={**p["path"], "start_angle": -90}),
        "problem.yaml: path.start_angle: -90",
        -1.571,
    ),
    (
        lambda p, r: r["arm"].update(stowed=[0, 10, 166, 0]),
        "cameleon.yaml: arm.stowed[1]: 10",
        0.1745,
    ),
    (
        lambda p, r: r["base"]["flippers"].update(angle=30),
        "cameleon.yaml: base.flippers.angle: 30",
        0.5236,
    ),
]


@pytest.mark.parametrize("edit,where,rad", DEGREES, ids=[d[1].split(": ")[1] for d in DEGREES])
def test_an_angle_in_degrees_is_refused_naming_the_unit(tmp_path, capsys, edit, where, rad):
    """Before: 'greater than the maximum of 1.2' (slope), or run (start_angle, stowed)."""
    path = write_problem(tmp_path, edit)
    line = _refused(capsys, ["rest", path, "--pose", "0", "0", "0"])
    value = where.rsplit(": ", 1)[1]
    assert line.endswith(
        f"{where} looks like degrees; the unit is radians ({value} deg = {rad:.4g} rad)"
    )


def test_a_bound_on_an_angle_names_its_unit(tmp_path, capsys):
    path = write_problem(tmp_path, lambda p, r: p["terrain"].update(slope=1.5))
    line = _refused(capsys, ["rest", path, "--pose", "0", "0", "0"])
    assert line.endswith("terrain.slope: 1.5 is greater than the maximum of 1.2 [rad]")


@pytest.mark.parametrize(
    "options,message",
    [
        (["--pose", "-2", "-1", "90"], "--pose YAW: 90 looks like degrees; the unit is radians"),
        (["--pose", "0", "0", "0", "--flipper", "30"], "--flipper: 30 looks like degrees"),
        (["--pose", "0", "0", "0", "--arm", "0", "10", "0", "0"], "--arm: joint 1: 10 looks"),
    ],
)
def test_rest_refuses_options_in_degrees(capsys, options, message):
    """Before: --pose -2 -1 90 ran at a yaw of 90 rad."""
    line = _refused(capsys, ["rest", PROBLEMS / "kerb.yaml", *options])
    assert message in line


# --------------------------------------------------------------------------------- rest
def _off_the_map(tmp_path: Path) -> Path:
    data = yaml.safe_load((PROBLEMS / "kerb.yaml").read_text())
    data["robot"] = str(ROBOT_YAML)
    data["path"]["waypoints"] = [[-2.0, 0.0], [9.0, 0.0]]  # the map ends at x = 3 m
    path = tmp_path / "off.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_rest_and_terrain_export_do_not_check_the_route(tmp_path, capsys):
    """Before: 'path.waypoints[0]: the route from here leaves known ground' for rest too."""
    path = _off_the_map(tmp_path)
    line = _refused(capsys, ["plan", path])
    assert f"{path}: path.waypoints[0]: the route from here leaves known ground" in line
    assert main(["rest", str(path), "--pose", "-2", "-1", "0.3", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["pose"] == {"x_m": -2.0, "y_m": -1.0, "yaw_rad": 0.3}
    out = tmp_path / "ground.npz"
    assert main(["terrain", "export", str(path), "-o", str(out)]) == 0  # nor terrain export
    assert out.is_file()


def test_rest_labels_contacts_and_polygon_vertices_truthfully(capsys):
    """Before: 'N contacts; support polygon' over a polygon of other points than the N."""
    argv = ["rest", str(PROBLEMS / "kerb.yaml"), "--pose", "0.45", "0", "0.3"]
    assert main(argv) == 0
    text = capsys.readouterr().out.splitlines()
    assert main([*argv, "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    (head,) = [t for t in text if "touching contact points" in t]
    n, m = len(d["contacts"]), len(d["support_polygon"])
    assert head.startswith(f"rest: {n} touching contact points; support polygon of {m} vertices")
    start = text.index(head) + 1
    rows = [t for t in text[start : start + m + 1] if t.strip().startswith("[")]
    assert len(rows) == m  # the printed polygon has the stated number of vertices


def test_rest_json_echoes_its_inputs_with_units(capsys):
    robot = load_robot(ROBOT_YAML)
    argv = ["rest", str(PROBLEMS / "kerb.yaml"), "--pose", "-2", "-1", "0.3", "--json"]
    assert main(argv) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["pose"] == {"x_m": -2.0, "y_m": -1.0, "yaw_rad": 0.3}
    assert d["arm"] == "stowed" and d["arm_q_rad"] == robot.stowed.tolist()
    assert d["flipper_angle_rad"] == robot.base.flippers.angle
    assert d["units"]["mu"] == "N rad" and d["units"]["roll"] == "rad"
    assert set(d["units"]) <= set(d)
    q = [1.0, 0.5, -0.3, 0.2]
    assert main([*argv, "--arm", *map(str, q), "--flipper", "0.1"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert (d["arm"], d["arm_q_rad"], d["flipper_angle_rad"]) == ("given", q, 0.1)


def test_a_payload_beyond_the_wrist_is_no_link_off_its_segment():
    """The payload folds into the wrist's CoM ((1.5 * -0.11 + 3 * 0.3) / 4.5 = 0.163 m ahead of
    the wrist frame): the warning is about the file's links, not the loaded wrist."""
    data = yaml.safe_load((PROBLEMS / "ramp.yaml").read_text())
    data["payload"] = {"mass": 3.0, "com": [0.3, 0.0, 0.0]}
    with held_notes() as notes:
        problem = problem_from_dict(data, PROBLEMS / "payload.yaml")
    assert notes == []
    assert problem.robot.links[-1].com[0] == pytest.approx((1.5 * -0.11 + 3 * 0.3) / 4.5)
    assert len(link_extent_warnings(problem.robot)) == 1  # the loaded wrist would be warned
