"""Identification of a plant model from its data (issue 35, item 3; seed 000 section II: the
ICAM's identification agent, LMId, "perturbs the plant with pseudo-random signals ... gathers data
and applies its model identification algorithm").

Numerical cores, no bus:

* :mod:`agents.identify.excitation`: generalized binary noise, the pseudo-random perturbation;
* :mod:`agents.identify.greybox`: a plant model's own physical parameters by non-linear least
  squares on its right-hand side, with their covariance;
* :mod:`agents.identify.arx`: a black-box ARX model for plants without a physical form.

Each estimate carries its covariance, so the agent's model can take the identified values with
their (smaller) uncertainty.
"""
