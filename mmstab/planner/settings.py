"""The ``planner`` section of a problem: settings of Eq. 6 and of the search.

Keys added after the first release (``method``, ``seeding``, ``coarse_*``,
``sigma0_unit``, ``restarts``, ``turret_window``, ``sequence_candidates``) may be omitted
from a problem file; their defaults
(``mmstab.core.defaults.SECTION_DEFAULTS``) are the first release's behaviour, so an older file
plans exactly (bit for bit) as before. ``problems/ramp.yaml`` sets the reliable search
(``docs/planner.md``).
"""

from __future__ import annotations

from typing import Any, NamedTuple

from mmstab.core.defaults import SECTION_DEFAULTS

#: ``physics``' defaults of the skid-steer model ``planner.turn_slide`` prices with: the belts'
#: shear modulus [m] and the drive ratio (:attr:`PlannerSettings.slide_model`).
DEFAULT_SLIDE_MODEL: tuple[float, float | str] = (
    float(SECTION_DEFAULTS["physics"]["shear_modulus"]),
    SECTION_DEFAULTS["physics"]["turn_ratio"],
)


class PlannerSettings(NamedTuple):
    """The ``planner`` section of a problem (see ``problems/ramp.yaml``).

    Attributes:
        w_stability: omega_1 of Eq. 6 (>= 0).
        w_motion: omega_2 of Eq. 6 (>= 0); w_stability + w_motion = 1.
        poses: number of base poses along the circle.
        starts: link0 angles of the starts (other joints zero) [rad]; used when
            ``seeding`` is ``"starts"``.
        sigma0: initial CMA step size, in metres or in V's diameters (``sigma0_unit``).
        popsize: CMA population size (of the first run of each start).
        max_iterations: CMA iteration budget per run.
        tol_fitness: stop when the fitness changes less than this over recent iterations.
        tol_x: stop when the search distribution is narrower than this [m].
        max_resample: re-ask rounds per generation for samples outside V; those still
            outside are then ranked below the feasible ones (see ``ask_generation``).
        seed: seed of the planner's own random generator.
        method: ``"cmaes"`` (CMA-ES in V), ``"exhaustive"`` (Eq. 6 over every valid
            grid CoM inside V, the reference) or ``"sequence"`` (the whole path at once
            over V's postures, ``mmstab.planner.searches.sequence``; per pose as exhaustive).
        seeding: ``"starts"`` (the FK CoMs of ``starts``) or ``"coarse"`` (the best
            samples of a coarse evaluation of Eq. 6 over V's samples).
        coarse_samples: how many of V's samples the coarse evaluation scores (evenly
            strided).
        coarse_basins: how many distinct optima of the coarse pass are refined.
        coarse_neighbours: each is refined to the best of its this many nearest samples
            of V (0: not refined).
        coarse_seeds: how many refined optima (best first) start a CMA-ES run.
        sigma0_unit: ``"m"`` (sigma0 in metres) or ``"diameter"`` (sigma0 times V's
            diameter).
        restarts: IPOP restarts per start: each reruns CMA-ES from the same start with the
            population doubled; the best run is kept.
        turret_window: largest change of link0 (the turret) between consecutive planned
            poses [rad]; None: unbounded (``mmstab.planner.turret``).
        sequence_candidates: samples per pose among which ``method: sequence`` chooses
            (``mmstab.planner.searches.sequence``).
        motion_cost: ``method: roadmap``'s motion term between consecutive postures (the
            other methods use Eq. 6's): ``joints`` (the default: the squared lattice
            distance, the L1 joint distance [rad], over the reachable postures' L1 extent
            squared; the roadmap distance where a monotone lattice path is free, a lower
            bound elsewhere) or ``com`` (Eq. 6's: the squared CoM distance over the
            diameter squared).
        ground_clearance: ``method: roadmap`` and ``method: sequence``: least height of
            the arm's lowest point above the support plane z_B = 0 that a chosen posture
            and the moves between them keep [m]; None: not checked (``cmaes`` and
            ``exhaustive`` do not check it). A file that names none: 0.02, on a path
            (route or circle) over a heightmap 0.05
            (:data:`mmstab.core.defaults.HEIGHTMAP_ROUTE_PLANNER`).
        attitude_margin: ``method: roadmap`` on a path over terrain: the arm keeps
            ``ground_clearance`` through the body's tilts (pitch, roll) of up to this
            [rad] about its origin, at the planned poses and the moves' ends
            (:func:`mmstab.model.plane_clearance.tilted_height`); None: off (a file that names
            none: off, on a path over a heightmap 0.21: 12 deg).
        flipper_angles: flipper angles searched per pose over the robot's flipper limits
            (``mmstab.planner.levers``); 0 (the default): the flippers stay at the file's angle.
        turn_slide: ``method: roadmap`` on a route: the slide [m] the skid-steer model may
            price a turn at with the chosen postures; where a turn between two planned
            poses slides more, both poses keep only postures whose turn does not, and the
            path is searched again (:mod:`mmstab.planner.turning`); None: off (the
            default; ``make validate-routes-rocking`` sets 0.04, under
            ``physics.slip_distance``'s 0.05 that judges the plan).
        slide_model: the skid-steer model's constants ``turn_slide`` prices with, the
            problem's ``physics.shear_modulus`` [m] and ``physics.turn_ratio`` (a number or
            ``auto``), as its slide verdict does (:meth:`from_section`'s ``physics``).
        climb: ``method: roadmap`` on a route: at a pose whose front wheels run into a step
            before the next pose, and at that next pose, only postures whose overall CoM
            lets the tracks climb it (``mmstab.planner.climbing``); where no stable posture
            does, the pose keeps them all and the plan reports the stall.
    """

    w_stability: float
    w_motion: float
    poses: int
    starts: tuple[float, ...]
    sigma0: float
    popsize: int
    max_iterations: int
    tol_fitness: float
    tol_x: float
    max_resample: int
    seed: int
    method: str
    seeding: str
    coarse_samples: int
    coarse_basins: int
    coarse_neighbours: int
    coarse_seeds: int
    sigma0_unit: str
    restarts: int
    turret_window: float | None = None
    sequence_candidates: int = 256
    flipper_angles: int = 0
    motion_cost: str = "joints"
    ground_clearance: float | None = 0.02
    attitude_margin: float | None = None
    turn_slide: float | None = None
    climb: bool = True
    slide_model: tuple[float, float | str] = DEFAULT_SLIDE_MODEL

    @classmethod
    def from_section(
        cls, cfg: dict[str, Any], physics: dict[str, Any] | None = None
    ) -> PlannerSettings:
        """Build from a validated ``planner`` section (omitted new keys: their defaults).

        ``physics``: the problem's ``physics`` section, for :attr:`slide_model` (None: its
        defaults).
        """
        cfg = {**SECTION_DEFAULTS["planner"], **cfg}
        phys = {**SECTION_DEFAULTS["physics"], **(physics or {})}
        ratio = phys["turn_ratio"]
        return cls(
            slide_model=(
                float(phys["shear_modulus"]),
                ratio if isinstance(ratio, str) else float(ratio),
            ),
            w_stability=float(cfg["w_stability"]),
            w_motion=float(cfg["w_motion"]),
            poses=int(cfg["poses"]),
            starts=tuple(float(s) for s in cfg["starts"]),
            sigma0=float(cfg["sigma0"]),
            popsize=int(cfg["popsize"]),
            max_iterations=int(cfg["max_iterations"]),
            tol_fitness=float(cfg["tol_fitness"]),
            tol_x=float(cfg["tol_x"]),
            max_resample=int(cfg["max_resample"]),
            seed=int(cfg["seed"]),
            method=str(cfg["method"]),
            seeding=str(cfg["seeding"]),
            coarse_samples=int(cfg["coarse_samples"]),
            coarse_basins=int(cfg["coarse_basins"]),
            coarse_neighbours=int(cfg["coarse_neighbours"]),
            coarse_seeds=int(cfg["coarse_seeds"]),
            sigma0_unit=str(cfg["sigma0_unit"]),
            restarts=int(cfg["restarts"]),
            turret_window=None if cfg["turret_window"] is None else float(cfg["turret_window"]),
            sequence_candidates=int(cfg["sequence_candidates"]),
            flipper_angles=int(cfg.get("flipper_angles", 0)),
            motion_cost=str(cfg["motion_cost"]),
            ground_clearance=None
            if cfg["ground_clearance"] is None
            else float(cfg["ground_clearance"]),
            attitude_margin=None
            if cfg["attitude_margin"] is None
            else float(cfg["attitude_margin"]),
            turn_slide=None if cfg.get("turn_slide") is None else float(cfg["turn_slide"]),
            climb=bool(cfg["climb"]),
        )

    def sigma0_metres(self, diameter: float) -> float:
        """The initial CMA step size [m] for a workspace of ``diameter`` [m]."""
        return self.sigma0 * diameter if self.sigma0_unit == "diameter" else self.sigma0
