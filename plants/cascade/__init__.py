"""Seed 004's primary/secondary (cascade) process, one concept a module.

* :mod:`plants.cascade.transfer` -- rational transfer functions in ``q^-1``
  (:class:`~plants.cascade.transfer.TF`);
* :mod:`plants.cascade.model` -- the paper twin: the chain of sampled stages (Fig. 1), its delays,
  open and closed loops (eq. (1), (2));
* :mod:`plants.cascade.variance` -- analytic variances, the minimum-variance bounds (eq. (7),
  (8)) and the variance components (eq. (11)-(15));
* :mod:`plants.cascade.routine` -- routine operation simulated sample by sample with any law;
* :mod:`plants.cascade.examples` -- the example processes (ours, after the paper's Examples 1-3);
* :mod:`plants.cascade.plant` -- what the bus runs: the process in continuous time
  (``model: cascade_ct``), with its exact sampled model and step response.

The naming rule of the split packages: ``model.py`` is the paper-reproduction twin (what the
paper's figures are reproduced with), ``plant.py`` (plants) or ``law.py`` (controllers) what the
bus runs. Import from the concept's module.
"""
