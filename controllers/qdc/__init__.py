"""Quasi-decentralized networked control of seed 001 (Sun & El-Farra), one concept a module.

* :mod:`controllers.qdc.design` -- the plant's units (eq. (1)) and the gains ``K_i``, ``K_ij``,
  ``L_i`` of section V (eq. (2)-(3));
* :mod:`controllers.qdc.network` -- the controller structures: the units' local control systems
  of eq. (4), stacked, and the centralized one of Fig. 2(c);
* :mod:`controllers.qdc.model` -- the paper twin: the closed loop and its linear and non-linear
  simulations;
* :mod:`controllers.qdc.law` -- what the bus runs: one unit's local control system
  (``type: qdc``).

The naming rule of the split packages: ``model.py`` is the paper-reproduction twin (what the
paper's figures are reproduced with), ``law.py`` (controllers) or ``plant.py`` (plants) what the
bus runs. Import from the concept's module.
"""
