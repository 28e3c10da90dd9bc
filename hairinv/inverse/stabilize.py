"""The stability check of an inversion, and the stiffening that makes unstable strands hold.

A strand whose equilibrium is unstable (:mod:`hairinv.inverse.stability`) gets its stiffness multiplied
by ``solver.stiffen_margin`` times the critical factor ``1 - lambda``. Unstable under its contact forces
held fixed (``solver.stable_under = forces``, the default): the forces are kept, they hold the input at
any stiffness, and the rest shape is taken again with the factor, so one round makes every strand
stable. Unstable on its supports (``supports``): the problem is solved again with the factor, from the
last forces, until every strand is stable or :data:`STABILIZE_ROUNDS` rounds are done.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..config import SolverSettings
from ..model import UNSTABLE_MARGIN, Material, stiffness
from .method import Solved
from .problem import InverseProblem
from .stability import group_margins, stability_margins

__all__ = ["STABILIZE", "STABILIZE_ROUNDS", "STABLE_UNDER", "Stability", "check_and_stiffen"]

STABILIZE = ("stiffen", "off")
#: what the stability check holds: the contact forces fixed (every motion), or the loaded contact points
STABLE_UNDER = ("forces", "supports")
#: inversions with stiffened strands tried before the remaining unstable strands are reported: a
#: strand's factor makes it stable on the supports it had; the new forces may load other contacts
STABILIZE_ROUNDS = 8


@dataclass
class Stability:
    """What the stability check of an inversion found (its defaults: not checked)."""

    margin: np.ndarray | None = None
    """(S,) each strand's margin on the motions checked (``solver.stable_under``), lowered to its group's
    where strands leaning on each other are unstable together; None: not checked"""
    unstable: int = 0
    unstable_gravity_only: int = 0
    """strands the gravity-only inversion with the material's own stiffness leaves unstable"""
    gravity_only_factor: float = 1.0
    """the one stiffness factor the gravity-only inversion would need for every strand to be stable"""
    unstable_held: int = 0
    """strands unstable even with every declared contact point held"""
    unstable_groups: int = 0
    unchecked_together: int = 0
    """strands in groups too large for the joint check"""
    rounds: int = 0
    """inversions solved again with stiffened strands"""
    sweeps: int = 0
    """the sweeps of those inversions"""


class _Margins:
    """The margins stabilisation works on, and the others, at a stiffness; a call with ``changed`` (the
    strands whose stiffness alone changed since the last call, with the same forces) checks only those."""

    def __init__(self, problem: InverseProblem, material: Material, by_forces: bool):
        self.problem, self.material, self.by_forces = problem, material, by_forces
        self.last = None

    def __call__(self, stiff: np.ndarray, carrying: np.ndarray, force: np.ndarray, changed=None) -> tuple:
        """(the margin stabilisation works on, free, always, groups, their margins, strands unchecked)"""
        p = self.problem
        checked = stability_margins(p.helices, self.material, stiff, p.rows, p.contacts, carrying, force,
                                    strands=changed, previous=self.last if changed is not None else None,
                                    supported=not self.by_forces)
        self.last = checked
        supported, free, always, fixed = checked
        if self.by_forces:  # stable on every motion is stable together too: no joint check of the groups
            groups, group_lam, too_large = [], np.zeros(0), 0
        else:
            groups, group_lam, too_large = group_margins(p.helices, self.material, stiff, p.rows, p.contacts,
                                                         carrying, force)
        return (fixed if self.by_forces else supported), free, always, groups, group_lam, too_large


def check_and_stiffen(problem: InverseProblem, material: Material, settings: SolverSettings, solved: Solved,
                      stiff: np.ndarray, factor: np.ndarray | None,
                      again: Callable[[np.ndarray, np.ndarray], Solved]) -> tuple[Stability, Solved, np.ndarray]:
    """Check the stability of the inversion ``solved`` at the stiffness ``stiff`` (3E,) and, with the
    per-strand stiffness factors ``factor`` (S,) that gave it (None: stabilisation off), stiffen the
    unstable strands, raising ``factor`` in place.

    ``again(stiff, r)`` solves the problem at the stiffness ``stiff`` from the forces ``r`` (``supports``).
    Returns what the check found, the last solve, and the stiffness (3E,) the strands were inverted with."""
    helices = problem.helices
    S = helices.n_strands
    by_forces = settings.stable_under == "forces"
    margins = _Margins(problem, material, by_forces)
    found = Stability()
    margin, free, always, groups, group_lam, too_large = margins(stiff, solved.carrying, solved.result.r)
    base = np.ones(S) if factor is None else factor
    # the gravity-only inversion with the material's own stiffness: stable where base (1 - free) <= 1
    needed_free = base * np.maximum(1.0 - free, 0.0)
    found.unstable_gravity_only = int(np.count_nonzero(needed_free > 1.0 - UNSTABLE_MARGIN)) if factor is not None \
        else int(np.count_nonzero(free < UNSTABLE_MARGIN))
    found.gravity_only_factor = float(needed_free.max()) if S else 1.0
    found.unstable_held = int(np.count_nonzero(always < UNSTABLE_MARGIN))
    if factor is not None:
        for _ in range(STABILIZE_ROUNDS):
            weak = margin < UNSTABLE_MARGIN
            weak_groups = [(g, lam) for g, lam in zip(groups, group_lam) if lam < UNSTABLE_MARGIN]
            if not weak.any() and not weak_groups:
                break
            before = factor.copy()
            factor[weak] *= (1.0 - margin[weak]) * settings.stiffen_margin
            # the groups that fall over together are stiffened uniformly, so that the closed form holds
            # for the group as for one strand (from the factors the check saw)
            for g, lam in weak_groups:
                factor[g] = np.maximum(factor[g], before[g] * (1.0 - lam) * settings.stiffen_margin)
            stiff = stiffness(helices, material, factor)
            if by_forces:
                # the margin depends on the stiffness and the forces alone, and these forces hold the
                # input exactly at any stiffness (the rest shape follows it): one round makes every
                # strand stable. Solving again would move forces onto other strands and stiffen those in
                # turn (a draped groom: 26 strands, factors up to 41, 8 times the sweeps, against 16 up
                # to 4.3 this way)
                changed = np.flatnonzero(factor != before)
                margin, _, always, groups, group_lam, too_large = margins(stiff, solved.carrying,
                                                                          solved.result.r, changed)
                continue
            solved = again(stiff, solved.result.r)
            found.sweeps += solved.result.sweeps
            found.rounds += 1
            margin, _, always, groups, group_lam, too_large = margins(stiff, solved.carrying, solved.result.r)
    weak_together = np.zeros(S, dtype=bool)
    for g, lam in zip(groups, group_lam):
        if lam < UNSTABLE_MARGIN:
            weak_together[g] = True
    found.unstable_groups = int(np.count_nonzero(group_lam < UNSTABLE_MARGIN))
    found.unstable = int(np.count_nonzero((margin < UNSTABLE_MARGIN) | weak_together))
    for g, lam in zip(groups, group_lam):  # a strand of a group unstable together is unstable
        margin[g] = np.minimum(margin[g], lam)
    found.margin = margin
    found.unchecked_together = too_large
    return found, solved, stiff
