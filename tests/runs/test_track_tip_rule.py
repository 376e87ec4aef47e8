"""``mmstab track`` judges a tip as ``mmstab plan`` does: rocks that hold are no tip, a climb
that overturns the robot is one, and μ < 0 must last before the run calls it.

Ground we did not write: routes 4 and 30 of ``make validate-routes`` (seeded side slopes with
a ditch and a kerb across them). On route 30 the tracking run rests at states with μ < 0
where the robot rocks onto a support that holds it (MuJoCo holds the route); on route 4 the
plan's climb-out check finds a climb that overturns it (MuJoCo overturns there).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import validation_route_file

from mmstab.core.problem import load_problem
from mmstab.runs.tracking.simulation import TIP_HOLD, TipWatch, mu_with_arm


def validation_route(k: int, directory: Path):
    return load_problem(validation_route_file(k, directory))


class Scripted(TipWatch):
    """The hold rule on given tipping samples (``masks``: one per chunk)."""

    def __init__(self, masks: list[list[bool]], hold: int, samples: int) -> None:
        self.masks, self.hold, self.samples = iter(masks), hold, samples
        self.seen, self.start = 0, None

    def tipping(self, chunk):
        return np.array(next(self.masks), dtype=bool)


def calls(watch: Scripted, n: int) -> list[int | None]:
    return [watch(np.zeros((5, 9))) for _ in range(n)]


def test_a_tip_is_tipping_held_for_the_hold_and_reported_where_it_began() -> None:
    T, F = True, False
    # two samples tipping, then clear: a flicker; three on end: a tip at the first of them
    assert calls(Scripted([[F, T, T, F, F], [F, F, T, T, T]], 3, 10), 2) == [None, 2]
    # a stretch across chunks: it began in the chunk before (index < 0)
    assert calls(Scripted([[F, F, F, T, T], [T, F, F, F, F]], 3, 10), 2) == [None, -2]
    # broken by one clear sample: counted again from the next
    assert calls(Scripted([[T, T, F, T, T], [F, T, T, F, F]], 3, 10), 2) == [None, None]
    # still tipping at the run's last sample: a tip, however short
    assert calls(Scripted([[F, F, F, F, F], [F, F, F, T, T]], 3, 10), 2) == [None, 3]
    assert int(round(TIP_HOLD / 1e-3)) == 50  # 50 control periods at 1 ms


@pytest.fixture(scope="module")
def route30(tmp_path_factory):
    return validation_route(30, tmp_path_factory.mktemp("route30"))


def test_a_state_that_rocks_onto_a_holding_support_is_not_tipping(route30) -> None:
    # route 30's tracking run at 5.671 s: base (x, y, heading), wheels, arm (4 joints)
    state = np.array([
        1.1042876871056689e-02, -1.3000623819374948, 2.7277165573017634, 14.890039500150007,
        14.890039500149825, 2.0026936776031405, -0.094903096649923677, 0.25450034438047414,
        0.24280897183995545,
    ])  # fmt: skip
    assert mu_with_arm(route30, state[None])[0] < -100.0  # the loaded contacts do not hold it
    watch = TipWatch(route30, 1e-3, 100)
    rock = watch.rock
    assert rock.applies(route30.terrain) and rock.push > 0 and rock.threshold > 0
    assert not watch.tipping(state[None])[0]  # it rocks onto a support that holds it
    # the online loop asks the same check of its map (here the problem's ground)
    arm = route30.robot.arm_com(state[None, 5:])
    assert rock.holds(route30.terrain, state[None, :3], arm).tolist() == [True]
    watch.rock = SimpleNamespace(holds=lambda terrain, p, a: np.zeros(len(p), dtype=bool))
    assert watch.tipping(state[None])[0]  # without the rock check it tips
    # with a tool wrench the rock check (the weight alone) does not excuse it
    robot = dataclasses.replace(route30.robot, tool_wrench=np.zeros(6))
    pulled = SimpleNamespace(robot=robot, terrain=route30.terrain, route=route30.route)
    watch = TipWatch(pulled, 1e-3, 100)
    assert not watch.rock.applies(route30.terrain) and watch.tipping(state[None])[0]


def test_track_refuses_a_plan_whose_climb_overturns_the_robot(tmp_path) -> None:
    from mmstab.app import plan as make_plan
    from mmstab.outputs.tracking import track_verdict
    from mmstab.runs.verdict import plan_stability

    problem = validation_route(4, tmp_path)
    plan = make_plan(problem)
    verdict = plan_stability(problem, plan)
    assert verdict["climb_out"]["overturns"] and not verdict["stable"]
    assert not verdict["unstable_poses"]  # every planned pose holds: the climb alone tips
    assert track_verdict(problem, plan) == "tips"
