"""What the simulations are compared with: closed forms (analytic.py: waves, spall, scab,
plates, one-degree-of-freedom estimates) and the static solutions of the same mesh
(homogenise.py)."""
