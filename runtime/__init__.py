"""Runtime: virtual time, the node base class, the clock, launcher, historian and CLI.

Only this package imports zenoh, and only in the modules that talk to the bus
(`bus`, `node`, `clock`, `historian`, `launcher`); the package itself imports nothing heavy,
so numerical cores may use `core.time` and `core.errors` freely.
"""
