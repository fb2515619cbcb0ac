"""Kernel: zenoh sessions (:mod:`kernel.bus`), the bus node that runs a behaviour round by round
(:mod:`kernel.node`) and the clock that drives the rounds (:mod:`kernel.clock`).

The only package that imports zenoh. It imports nothing of ours but :mod:`bus_schemas` and
:mod:`core`: what a node does is its behaviour's business, what a run is the scenario's.
"""
