"""hairinv: inverse dynamic hair modeling with frictional contact.

Turns a static hairstyle (3D curves) and the body it rests on into a
super-helix hair model whose rest state under gravity and Coulomb friction is
exactly the input (Derouet-Jourdan et al. 2013).
"""

__version__ = "0.1.0"
