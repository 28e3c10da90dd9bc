"""The contact solver: frictional cone complementarity problems over many contacts.

What a caller builds (:mod:`.problem`): a :class:`ConeProblem` (the rows ``H`` of the contacts, the
diagonal operator ``D``, the regularisation ``gamma``, the right-hand side ``b``, the friction
coefficients and the strands' layout), a :class:`Law` (:data:`CONE`, the convex problem of the
inversion; :data:`COULOMB`, De Saxce's, of a time step) and a method's settings. Each method has one
entry point, ``solve(problem, law, settings, start)``:

- :func:`hairinv.solver.gauss_seidel.solve`: block Gauss-Seidel over the contacts with an exact local
  solve per contact (:mod:`.local`), Nesterov momentum for the convex law, deterministic on any number
  of threads; :class:`SweepSettings`;
- :func:`hairinv.solver.interior.solve`: a primal-dual interior point (the convex law only), one sparse
  Cholesky factorisation a step (:mod:`.blocked`, :mod:`.supernodal`); :class:`InteriorSettings`.

Every method reports a :class:`Status` (:mod:`.status`). :mod:`.blocks` solves the contacts of one
strand together (dense blocks, nonsmooth Newton); :mod:`.reference` wraps Clarabel for the tests and
benchmarks. The solver knows nothing of rods: the rows come from :mod:`hairinv.contacts.rows`.
"""

from .problem import CONE, COULOMB, ConeProblem, InteriorSettings, Law, SweepSettings
from .rows import ContactRows
from .status import Status

__all__ = ["CONE", "COULOMB", "ConeProblem", "ContactRows", "InteriorSettings", "Law", "Status", "SweepSettings"]
