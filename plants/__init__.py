"""Plant models: parameters, ODE right-hand side, equilibrium, linearization; and the plant node.

`plants.registry` maps a scenario's ``model:`` name to its class.
"""
