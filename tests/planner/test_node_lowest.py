"""The nodes' least arm height over the tilts (mmstab.planner.grounded.node_lowest).

The route search knows from it, before measuring, which nodes are too low above the ground
at a pose and which surely clear it. Checked: on a plane it is the measure itself; on
seeded bumps, slopes and kerbs every node it calls too low (or surely clear) the measure
finds too low (clear), and plans with it are those measured node by node; it is kept beside
the roadmap's cache file and read back equal.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_under_arm import GROUND, _map, _poses, _settings

from mmstab.planner import candidates
from mmstab.planner.candidates import NodeClearance
from mmstab.planner.ground.under_arm import SLACK, GroundUnderArm
from mmstab.planner.grounded import node_lowest
from mmstab.planner.searches.roadmap import solve_roadmap_sequence
from mmstab.stability.static import mu_max
from mmstab.workspace import build_workspace
from mmstab.workspace.kept import SOURCE_ATTR
from mmstab.workspace.roadmap import build_roadmap

#: 12 degrees [rad]: the attitude margin of the rocking variant of the validation.
ROCK = 0.21


@pytest.fixture(scope="module")
def small(robot):
    return build_roadmap(robot, build_workspace(robot, (10, 8, 8, 8), progress=False))


@pytest.mark.parametrize("margin", [0.0, 0.0524, ROCK])
def test_on_a_plane_the_nodes_lowest_is_the_measure(robot, small, margin):
    under = GroundUnderArm(robot, _map(robot, "flat"), _poses(1), margin=margin)
    lowest = node_lowest(small, under)
    assert lowest.shape == (len(small.nodes_q),)
    np.testing.assert_array_equal(lowest, under.heights(0, small.nodes_q))
    if margin == 0.0:  # the pieces' lowest point is the collision shapes' (node_ground)
        np.testing.assert_allclose(lowest, small.node_ground, atol=1e-12)
    else:  # a tilt only brings the arm down
        assert np.all(lowest <= small.node_ground + 1e-12)
        assert np.mean(lowest < small.node_ground - 0.01) > 0.5


@pytest.mark.parametrize(("kind", "seed"), [("bumps", 1), ("slope-bumps", 2), ("kerb", 0)])
@pytest.mark.parametrize("margin", [0.0524, ROCK])
def test_what_it_decides_the_measure_finds(robot, small, kind, seed, margin):
    rng = np.random.default_rng(seed)
    terrain = _map(robot, kind, seed)
    poses = np.column_stack([rng.uniform(-1.5, 1.5, 3), rng.uniform(-1.5, 1.5, 3),
                             rng.uniform(-np.pi, np.pi, 3)])  # fmt: skip
    under = GroundUnderArm(robot, terrain, poses, margin=margin)
    reach = np.flatnonzero(small.node_ground >= GROUND)
    clear = NodeClearance(small, reach, GROUND, under)
    lowest = clear._lowest[0]
    q = small.nodes_q[reach]
    sure_low = sure_clear = 0
    for k in range(len(poses)):
        measured = under.clear(k, q, GROUND)
        low = lowest / under.poses[k].cos_tilt < GROUND - SLACK
        sure = under.surely_clear(k, lowest, GROUND)
        assert not (low & measured).any() and (sure <= measured).all()
        clear._start(k)  # the rows it knows at once: those too low
        np.testing.assert_array_equal(clear._low[k], low)
        np.testing.assert_array_equal(clear._known[k], low)
        sure_low, sure_clear = sure_low + int(low.sum()), sure_clear + int(sure.sum())
    assert sure_low > 0
    # beside the kerb the ground in reach rises 15 cm: arms held higher surely clear it (the
    # bumps rise more under the whole reach: none surely does, every one is measured)
    assert (sure_clear > 0) == (kind == "kerb")


def _measured_node_by_node(monkeypatch: pytest.MonkeyPatch) -> None:
    """NodeClearance as before node_lowest: nothing known before measuring, the old bound."""

    def start(self, k):
        if k not in self._known and self.under is not None and self.ground is not None:
            self._known[k] = np.zeros(len(self.reach), dtype=bool)
            self._low[k] = np.zeros(len(self.reach), dtype=bool)

    def surely(self, k, lowest, ground):
        return np.zeros(len(lowest), dtype=bool)  # every row measured

    monkeypatch.setattr(candidates.NodeClearance, "_start", start)
    monkeypatch.setattr(GroundUnderArm, "surely_clear", surely)


@pytest.mark.parametrize(("kind", "seed"), [("slope-bumps", 0), ("kerb", 0), ("bumps", 3)])
@pytest.mark.parametrize("margin", [0.0524, ROCK])
def test_plans_are_those_measured_node_by_node(robot, small, kind, seed, margin, monkeypatch):
    terrain = _map(robot, kind, seed)
    poses = _poses(6)
    g = terrain.gravity_body(poses)
    s = _settings(GROUND)

    def plan():
        under = GroundUnderArm(robot, terrain, poses, margin=margin)
        return solve_roadmap_sequence(robot, g, small, s, mu_max(robot), False, poses, under=under)

    fast = plan()
    _measured_node_by_node(monkeypatch)
    slow = plan()
    np.testing.assert_array_equal(fast.nodes, slow.nodes)
    np.testing.assert_array_equal(fast.mu, slow.mu)
    for a, b in zip(fast.moves, slow.moves, strict=True):
        np.testing.assert_array_equal(a, b)


def test_kept_beside_the_roadmap_file_and_read_back_equal(robot, small, tmp_path):
    source = tmp_path / "roadmap-test.npz"
    source.write_bytes(b"stand-in")  # the kept arrays are stamped with its mtime only
    under = GroundUnderArm(robot, _map(robot, "flat"), _poses(1), margin=ROCK)
    object.__setattr__(small, SOURCE_ATTR, source)
    try:
        object.__setattr__(small, "_node_lowest", None)
        first = node_lowest(small, under)
        folders = list((tmp_path / "roadmap-test").glob("lowest-*"))
        assert len(folders) == 1 and (folders[0] / "lowest.npy").is_file()
        object.__setattr__(small, "_node_lowest", None)  # a new process: read from the file
        np.testing.assert_array_equal(node_lowest(small, under), first)
        other = GroundUnderArm(robot, _map(robot, "flat"), _poses(1), margin=0.0524)
        node_lowest(small, other)  # another margin: another folder
        assert len(list((tmp_path / "roadmap-test").glob("lowest-*"))) == 2
    finally:
        object.__setattr__(small, SOURCE_ATTR, None)
        object.__setattr__(small, "_node_lowest", None)
