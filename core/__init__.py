"""Core: integer virtual time, the error hierarchy, loop metrics, run records and the bus-free
half of every node (:mod:`core.behaviour`), with the clock's round logic (:mod:`core.rounds`).

It imports nothing of ours but :mod:`bus_schemas`, and no zenoh, msgpack or scipy: every layer
above may use it.
"""
