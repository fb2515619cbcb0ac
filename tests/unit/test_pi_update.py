"""The agent's vectorised PI (:func:`controllers.pi.pi_update`) is the controller node's PI.

Each of the agent's trial simulators (batch, chance, fast predictor) executes the loops' PI laws
with :func:`~controllers.pi.pi_update` on arrays of realizations; a controller node runs
:class:`~controllers.pi.PI` one execution at a time. Here both run the same random executions
(uneven intervals, set-point steps, feedforward changes, both integration rules, limits hit from
both sides) and must agree to the last bit, outputs and integrals alike.
"""

from __future__ import annotations

import numpy as np
import pytest

from controllers.pi import PI, PIConfig, pi_update


@pytest.mark.parametrize("integration", ["forward", "backward"])
def test_pi_update_is_pi_step_to_the_bit(integration):
    rng = np.random.default_rng(34)
    items, steps = 64, 200
    cfg = PIConfig(Kp=1.7, Ki=2.3, u_min=-0.6, u_max=0.8, integration=integration)
    laws = [PI(cfg) for _ in range(items)]
    t = np.cumsum(rng.uniform(0.01, 0.4, (steps, items)), axis=0)
    y = rng.normal(0.0, 0.5, (steps, items))
    r = np.repeat(rng.choice([-0.5, 0.0, 0.7], (steps // 20, items)), 20, axis=0)
    u_bar = np.repeat(rng.uniform(-0.2, 0.2, (steps // 50, items)), 50, axis=0)

    integral = np.zeros(items)
    e_prev = np.zeros(items)
    low = high = 0
    for k in range(steps):
        expected = []
        for i, law in enumerate(laws):
            law.set_feedforward(float(u_bar[k, i]))
            expected.append(law.step(float(t[k, i]), float(y[k, i]), float(r[k, i])))
        e = r[k] - y[k]
        dt = t[k] - t[k - 1] if k else np.zeros(items)
        increment = cfg.Ki * (e_prev if integration == "forward" else e) * dt
        u, integral = pi_update(e, increment, integral, u_bar[k], cfg.Kp, cfg.u_min, cfg.u_max)
        e_prev = e
        assert u.tolist() == expected, f"execution {k}"
        assert integral.tolist() == [law.integral for law in laws], f"execution {k}"
        low += int(np.sum(u == cfg.u_min))
        high += int(np.sum(u == cfg.u_max))
    assert low > steps and high > steps  # the clamps were exercised, on both sides
