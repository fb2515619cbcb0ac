"""Runtime: the application layer (DESIGN section 2) — the scenario schema, the CLI, the
launcher, the engines (:mod:`runtime.direct`, and the bus nodes of :mod:`runtime.nodes` on the
kernel), the historian, records and reports, ``wncs inject`` and ``wncs analyze``.

It imports every layer below it and no zenoh: the bus is the kernel's (:mod:`kernel`).
"""
