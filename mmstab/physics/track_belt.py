"""The belts of the tracks in MuJoCo: one spin per side (``ModelSettings.track_belt``).

A track's road wheels all turn with its belt. Modelled as independent hinges, each wheel's
spin is held only by its own velocity servo, a force the contact solver does not see (the
servo's damping is integrated implicitly after the solve); with the friction load along
the track the rigid row of wheels then hops (``docs/physics.md``, "Every disagreement,
why"). Joint equalities tie every wheel of a side to its first one, so the contact solver
sees the belt: one rolling degree of freedom per side carrying all its wheels' contacts.
"""

from __future__ import annotations

from collections.abc import Sequence


def belt_equalities(n_wheels: int, solref: Sequence[float]) -> list[str]:
    """MJCF ``<joint>`` equalities wheel_<side>_k = wheel_<side>_00 for k = 1 .. n - 1.

    Args:
        n_wheels: wheels per side (named ``wheel_<side>_NN`` by the robot model) [-].
        solref: the equalities' (time constant [s], damping ratio [-]).
    """
    ref = " ".join(f"{float(v):.17g}" for v in solref)
    return [
        f'<joint joint1="wheel_{side}_{k:02d}" joint2="wheel_{side}_00" '
        f'polycoef="0 1 0 0 0" solref="{ref}"/>'
        for side in ("left", "right")
        for k in range(1, n_wheels)
    ]
