"""mmstab's verdicts on a grid of ramp cases around the edge: tips, holds or slides.

A configuration is (heading, payload, arm, friction, track speed) on a planar ramp. Its
arm is ``stowed`` (``robot.stowed``), ``planned`` (at each slope, the posture of the
workspace V that maximises the force-angle measure there: the planner's stability optimum,
``w_motion`` 0) or a fixed named posture. mmstab predicts, per configuration,

- the tip slope: where the force-angle measure mu (``robot_force_angle``) crosses 0,
- the slip slope: ``atan(friction)`` (on a plane the support's tilt is the slope),

and the critical slope is the lower (the limit that binds, :func:`binding_limit`). The
grid's cases sit at slopes offset from it, so they straddle the edge. mmstab's verdict at
a slope: ``slides`` when the slope passes ``atan(friction)`` and slip binds first, ``tips``
when mu < 0, else ``holds`` (:func:`predicted_verdict`).
"""

from __future__ import annotations

import functools
import itertools
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import brentq

from mmstab.model.payload import Payload, attach_payload
from mmstab.model.plane_clearance import arm_ground_clearance
from mmstab.model.robot import FloatArray, Robot
from mmstab.physics.verdict_sim import (
    SimSettings,
    SimVerdict,
    Thresholds,
    planar_ground,
    sim_verdict,
)
from mmstab.planner.searches.exhaustive import best_mu
from mmstab.stability.slip import binding_limit
from mmstab.stability.static import robot_force_angle

#: Slopes searched for the tip slope [rad] (0 to 89 deg).
SLOPE_RANGE = (0.0, np.radians(89.0))


class Config(NamedTuple):
    """One configuration of the grid (every slope offset of it is a case).

    Attributes:
        heading: base heading on the ramp [rad] (0: across, left side uphill; pi/2: uphill).
        payload: payload mass at the wrist [kg] (0: none).
        arm: ``stowed``, ``planned`` or the name of a fixed posture.
        friction: Coulomb coefficient of tracks on ground [-].
        speed: track speed [m/s] (0: braked; > 0: driven straight ahead).
    """

    heading: float
    payload: float
    arm: str
    friction: float
    speed: float


class Prediction(NamedTuple):
    """mmstab's limits for a configuration.

    Attributes:
        tip_slope: slope where mu crosses 0 [rad] (``SLOPE_RANGE[1]`` if it never does).
        slip_slope: ``atan(friction)`` [rad].
        binds: ``tip`` or ``slip``, whichever comes first as the slope grows.
        critical: the binding limit's slope [rad].
    """

    tip_slope: float
    slip_slope: float
    binds: str
    critical: float


class Case(NamedTuple):
    """One case: a configuration at a slope, with mmstab's verdict and the arm's posture.

    Attributes:
        row: the case's row in the grid.
        config: the configuration.
        offset: slope minus the predicted critical slope [rad].
        angle: the ramp's slope [rad].
        posture: arm joint angles held [rad] (4,).
        mu: mmstab's force-angle measure there [N rad].
        verdict: mmstab's verdict (:func:`predicted_verdict`).
    """

    row: int
    config: Config
    offset: float
    angle: float
    posture: FloatArray
    mu: float
    verdict: str


class ArmPostures:
    """The arm's posture per configuration and slope, and mmstab's mu with it.

    Args:
        robot: the robot without payload.
        payload_com: the payload's CoM in the wrist frame (3,) [m].
        candidates: the postures ``planned`` chooses from (N, 4) [rad] (V's valid ones);
            those whose arm comes closer than ``clearance`` to the ground are dropped.
        fixed: named fixed postures [rad] (``stowed`` is the robot's own).
        clearance: least height of the arm above the support plane [m]
            (:func:`arm_ground_clearance`).
    """

    def __init__(
        self,
        robot: Robot,
        payload_com: ArrayLike,
        candidates: ArrayLike,
        fixed: dict[str, ArrayLike],
        clearance: float = 0.02,
    ):
        self.robot = robot
        self.payload_com = np.asarray(payload_com, dtype=float)
        q = np.atleast_2d(np.asarray(candidates, dtype=float))
        self.candidates = q[arm_ground_clearance(robot, q) >= clearance]
        self.fixed = {"stowed": robot.stowed, **fixed}

    @functools.lru_cache(maxsize=16)  # noqa: B019 - a few payloads per run
    def loaded(self, payload: float) -> Robot:
        """The robot with ``payload`` [kg] folded into its last link."""
        if payload <= 0:
            return self.robot
        return attach_payload(self.robot, Payload(float(payload), self.payload_com))

    @functools.lru_cache(maxsize=16)  # noqa: B019
    def candidate_coms(self, payload: float) -> FloatArray:
        """Arm CoMs of the candidates with ``payload`` [kg] (N, 3) [m]."""
        return np.asarray(self.loaded(payload).arm_com(self.candidates))

    def at(self, config: Config, slope: float) -> tuple[FloatArray, float]:
        """(posture (4,) [rad], mu [N rad]) of a configuration at a slope [rad]."""
        robot = self.loaded(config.payload)
        gravity = planar_ground(slope, config.friction).gravity_body(
            np.array([[0.0, 0.0, config.heading]])
        )[0]
        if config.arm == "planned":
            mu, k = best_mu(robot, gravity, self.candidate_coms(config.payload))
            return self.candidates[k].copy(), mu
        q = np.asarray(self.fixed[config.arm], dtype=float)
        return q, float(robot_force_angle(robot, gravity, robot.arm_com(q)).mu)


def predict(postures: ArmPostures, config: Config) -> Prediction:
    """Tip and slip slopes for a configuration and which binds."""

    def mu(slope: float) -> float:
        return postures.at(config, slope)[1]

    lo, hi = SLOPE_RANGE
    tip = hi if mu(hi) > 0 else float(brentq(mu, lo, hi, xtol=1e-8))
    slip = float(np.arctan(config.friction))
    binds = binding_limit(tip, slip)
    return Prediction(tip, slip, binds, tip if binds == "tip" else slip)


def predicted_verdict(slope: float, mu: float, prediction: Prediction) -> str:
    """``slides`` past ``atan(friction)`` when slip binds; ``tips`` when mu < 0; ``holds``."""
    if slope > prediction.slip_slope and prediction.binds == "slip":
        return "slides"
    return "tips" if mu < 0 else "holds"


def configs(
    headings: ArrayLike,
    payloads: ArrayLike,
    arms: list[str],
    frictions: ArrayLike,
    speeds: ArrayLike,
) -> list[Config]:
    """Every combination of the axes, in that order."""
    return [
        Config(float(h), float(p), str(a), float(f), float(s))
        for h, p, a, f, s in itertools.product(
            np.ravel(headings), np.ravel(payloads), arms, np.ravel(frictions), np.ravel(speeds)
        )
    ]


def build_cases(
    postures: ArmPostures, grid: list[Config], offsets: ArrayLike
) -> tuple[list[Prediction], list[Case]]:
    """The prediction per configuration and the cases at ``offsets`` [rad] from it.

    Slopes outside (0, ``SLOPE_RANGE[1]``) are left out.
    """
    predictions: list[Prediction] = []
    cases: list[Case] = []
    for config in grid:
        prediction = predict(postures, config)
        predictions.append(prediction)
        for offset in np.ravel(offsets):
            slope = prediction.critical + float(offset)
            if not 0.0 < slope < SLOPE_RANGE[1]:
                continue
            q, mu = postures.at(config, slope)
            verdict = predicted_verdict(slope, mu, prediction)
            cases.append(Case(len(cases), config, float(offset), slope, q, mu, verdict))
    return predictions, cases


class Bisection(NamedTuple):
    """MuJoCo's tip slope of a configuration, bisected.

    Attributes:
        predicted: mmstab's tip slope [rad].
        simulated: the middle of the last bracket [rad] (nan when no bracket was found).
        lo: highest slope that did not tip [rad].
        hi: lowest slope that tipped [rad].
        runs: simulations used.
    """

    predicted: float
    simulated: float
    lo: float
    hi: float
    runs: int


def case_sim(
    postures: ArmPostures,
    settings: SimSettings,
    thresholds: Thresholds,
    config: Config,
    slope: float,
) -> SimVerdict:
    """MuJoCo's verdict on a configuration at a slope [rad], the arm as mmstab holds it."""
    q, _ = postures.at(config, slope)
    payload = Payload(config.payload, postures.payload_com) if config.payload > 0 else None
    return sim_verdict(
        postures.robot,
        payload,
        q,
        slope,
        config.heading,
        config.friction,
        config.speed,
        settings,
        thresholds,
    )


def bisect_tip(
    postures: ArmPostures,
    settings: SimSettings,
    thresholds: Thresholds,
    config: Config,
    predicted: float,
    bracket: float,
    iterations: int,
) -> Bisection:
    """The slope where MuJoCo's verdict turns to ``tips``, by bisection.

    Starts from ``predicted +- bracket`` [rad]; widens by ``bracket`` (up to 3 times) on a
    side that does not straddle; then halves ``iterations`` times.
    """
    known: dict[float, bool] = {}

    def tips(slope: float) -> bool:
        if slope not in known:
            verdict = case_sim(postures, settings, thresholds, config, slope).verdict
            known[slope] = verdict == "tips"
        return known[slope]

    lo, hi = predicted - bracket, predicted + bracket
    for _ in range(3):
        if lo <= 0 or not tips(lo):
            break
        lo, hi = lo - bracket, lo
    else:
        return Bisection(predicted, float("nan"), lo, hi, len(known))
    for _ in range(3):
        if hi >= SLOPE_RANGE[1] or tips(hi):
            break
        lo, hi = hi, hi + bracket
    else:
        return Bisection(predicted, float("nan"), lo, hi, len(known))
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if tips(mid) else (mid, hi)
    return Bisection(predicted, 0.5 * (lo + hi), lo, hi, len(known))
