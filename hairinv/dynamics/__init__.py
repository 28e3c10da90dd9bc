"""Dynamics: the inverted groom simulated under gravity, frictional contact and a moving body (``hairinv simulate``).

- :mod:`.inertia`: the super-helix's mass matrix and velocity-product forces, strand by strand;
- :mod:`.rods`: what a run does not change (:class:`~.rods.RodModel`), what each step changes
  (:class:`~.rods.RodState`) and the strands' step matrices kept between steps (:class:`~.rods.StepMatrices`);
- :mod:`.tracking`: :class:`~.tracking.ContactTracker`, contact detection and the contacts remembered from
  step to step;
- :mod:`.simulate`: :class:`~.simulate.Simulation`, the driver: one linearly implicit step under the body's
  motion, frictional contact, and halved steps where an element turns too far;
- :mod:`.contact`: a step's contact problem in factored form (``W = Z^T Z``) and its solve under
  Coulomb's law with De Saxce's change of variable (:func:`~.contact.solve_coulomb`, through
  :mod:`hairinv.solver`);
- :mod:`.scene`: the scene files (a body's keyframed motion, trims);
- :mod:`.run`: a scene run on a model file, its frames and report;
- :mod:`.verify`: the still check of ``hairinv verify``.

docs/dynamics.md gives the equations and the choices measured.
"""
