"""The rooms of the inversion that :func:`hairinv.invert.invert` runs in turn.

- :mod:`.problem`: the target rest shape, the contacts' weights and the SOCQP's ``W`` and ``b`` (eq. 6),
  and the check of eq. (4) on a stored model;
- :mod:`.method`: the choice between the interior-point method and the sweeps, and the forces the
  sweeps start from;
- :mod:`.stability`: the stability analysis of an equilibrium, strand by strand and in groups;
- :mod:`.stabilize`: the stability check of an inversion and the stiffening of unstable strands;
- :mod:`.report`: what the user is told.
"""
