"""Seed 004's simple-feedback and PI-P cascade laws, one concept a module.

* :mod:`controllers.cascade.model` -- the paper twin: the PI simple-feedback, PI-P cascade and
  linear laws on the sampled process (Fig. 1, 2), as objects and as transfer functions;
* :mod:`controllers.cascade.tuning` -- variance-optimal tuning on the analytic model, and the
  settings shipped for the example processes;
* :mod:`controllers.cascade.law` -- what the bus runs: the PI-P cascade over two loops
  (``type: pip_cascade``), and the scenario variant that switches a loop to it.

The naming rule of the split packages: ``model.py`` is the paper-reproduction twin (what the
paper's figures are reproduced with), ``law.py`` (controllers) or ``plant.py`` (plants) what the
bus runs. Import from the concept's module.
"""
