"""The roadmap horizon's choices against a map's ground under the arm (online).

The measure itself is :mod:`mmstab.planner.ground.map_ground`'s (one pose's ground on one
map); here the roadmap's node test takes it (:func:`clearance_on`) and a re-choice drops
the candidates and moves too low on the map (:func:`forbid_low`).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from mmstab.model.robot import FloatArray
from mmstab.planner.candidates import NodeClearance
from mmstab.planner.ground.map_ground import MapGround
from mmstab.planner.ground.under_arm import KeptPieces


def clearance_on(
    base: NodeClearance, ground: MapGround, ks: list[int], kept: KeptPieces
) -> NodeClearance:
    """``base``'s test with the ground under the arm at poses ``ks`` (its pose i: ks[i]).

    The reachable nodes' eligibility and their pieces in B (``kept``) are computed once for
    the run; each pose's measures are its state's (learnt here, kept while it stands).
    """
    st = [ground.state(k) for k in ks]
    known = {i: x.known for i, x in enumerate(st)}
    low = {i: x.low for i, x in enumerate(st)}
    clear = dataclasses.replace(base, under=ground.under(ks), excluded={}, _low=low, _known=known)
    clear.__dict__.update(above=base.above, _eligible=base.eligible(), _pieces=kept)
    return clear


def forbid_low(
    base: NodeClearance,
    ground: MapGround,
    kept: KeptPieces,
    chain: list[int],
    cand: NDArray[np.intp],
    value: FloatArray,
    allowed: list[NDArray[np.bool_]],
    behind: bool,
) -> None:
    """Drop a re-choice's candidates too low on this map; forbid moves with an end too low.

    A pose's kept candidates were measured on the map that scored it: measured again here
    (free where its state stands). As offline
    (:func:`mmstab.planner.searches.roadmap._forbid_low_ends`):
    the arm moves while the base drives between two poses, so each end must clear both
    poses' ground; with ``behind``, ``chain[0]``'s candidates must also clear the ground of
    the pose before it (its node fixed).

    Args:
        base: the reachable nodes' test.
        ground: this map's ground under the arm.
        kept: the nodes' pieces in B.
        chain: the consecutive poses chosen again.
        cand: their candidates' reach rows (n, M).
        value: their values (n, M), -inf where dropped (changed here).
        allowed: per consecutive pair, the allowed moves (M, M) (changed here).
        behind: pose ``chain[0] - 1`` has a node.
    """
    mapped = [k for k in [chain[0] - 1, *chain] if k in ground.M_T_B]
    if not mapped:
        return
    clear = clearance_on(base, ground, mapped, kept)
    at = {k: i for i, k in enumerate(mapped)}
    rows: list[list[NDArray[np.intp]]] = [[] for _ in mapped]  # measured in one batch
    for i, k in enumerate(chain):
        for j in (k - 1, k, k + 1):
            if j in at:
                rows[at[j]].append(cand[i, np.isfinite(value[i])])
    clear.measure([np.concatenate([np.zeros(0, dtype=np.intp), *r]) for r in rows])
    for i, k in enumerate(chain):
        if k in at:
            f = np.flatnonzero(np.isfinite(value[i]))
            value[i, f[~clear.at(at[k], cand[i, f])]] = -np.inf
    if behind and chain[0] - 1 in at:
        f = np.flatnonzero(np.isfinite(value[0]))
        value[0, f[~clear.at(at[chain[0] - 1], cand[0, f])]] = -np.inf
    for i, (ka, kb) in enumerate(zip(chain[:-1], chain[1:], strict=True)):
        if ka in at and kb in at:
            fa, fb = np.isfinite(value[i]), np.isfinite(value[i + 1])
            allowed[i][fa] &= clear.at(at[kb], cand[i, fa])[:, None]
            allowed[i][:, fb] &= clear.at(at[ka], cand[i + 1, fb])[None, :]
