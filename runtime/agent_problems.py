"""Negotiation problems of N loops for the coordination agent (issue 20, item 5).

:func:`jcstr_loops` builds a plant of ``n`` loops from the JCSTR of the worked example
(``scenarios/jcstr_wncs.yaml``, seed 000 III.C): ``ceil(n / 2)`` reactors, each with its level
and temperature loops (the last one with its level loop only when ``n`` is odd: its jacket
inflow is then held at its initial value), every reactor a variant with its own base area
(``A_B`` and the diameter of that circular base: the level's time constant) and feed temperature,
so that the loops' answers differ. Each loop is on a wired path of its own constant delay (the
worked example's 0.17 pu for the levels and 0.10 pu for the temperatures, varied a little per
reactor), each reactor has the worked example's level and temperature steps (1.8 and 2.4 pu),
and the agent has the scenario's configuration (phase ``worst`` over 4 phases, eps_OS as given).

The reactors are independent: the negotiation is N loops' worth of searches, in a model whose
every non-linear simulation runs all the reactors.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from scenario import Scenario, load_scenario

__all__ = ["WORKED_SCENARIO", "jcstr_loops"]

WORKED_SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "jcstr_wncs.yaml"

_AREAS = (1.0, 1.2, 0.85, 1.1, 0.95)  # base area of each reactor, pu^2 (cycled)
_FEED = (46.4, 45.0, 47.5, 46.0, 47.0)  # feed temperature, C (cycled)
_LEVEL_DELAY = (0.17, 0.15, 0.19, 0.16, 0.18)  # control-path delays, pu (cycled)
_TEMPERATURE_DELAY = (0.10, 0.09, 0.11, 0.08, 0.12)
_TANK = (10.0, 0.5)  # b, a': a slow free-outlet tank, pu (seed 002's model, level in pu)
_TANK_LAW = {"type": "pi", "Kp": 0.19142, "Ki": 0.036631, "u_min": 0.0, "u_max": 1.0}


def jcstr_loops(n: int, **agent: Any) -> tuple[Scenario, dict[str, float]]:
    """A scenario of ``n`` JCSTR loops (module docstring) and each loop's control-path delay.

    ``agent`` overrides fields of the agent's configuration (e.g. ``os_tolerance=0.2``).

    Raises
    ------
    ValueError
        If ``n < 1``.
    """
    if n < 1:
        raise ValueError(f"n: at least one loop, got {n}")
    base = load_scenario(WORKED_SCENARIO).model_dump()
    reactor = base["nodes"]["reactor"]
    law = {
        "level": base["nodes"]["level_controller"]["law"],
        "temperature": base["nodes"]["temperature_controller"]["law"],
    }
    sensors = {"level": ("H", "F_out", 0.70), "temperature": ("T", "F_jin", 52.0)}
    steps = {"level": (1.8, 0.75), "temperature": (2.4, 56.0)}
    agent_cfg = {
        k: v
        for k, v in base["nodes"]["wncsca"].items()
        if k not in ("test", "order", "modes", "alarm")
    }
    nodes: dict[str, Any] = {"network": {"kind": "network"}, "operator": {"kind": "operator"}}
    loops: dict[str, Any] = {}
    setpoints = []
    delays: dict[str, float] = {}
    for r in range(n // 2):
        kinds = ["level", "temperature"]
        area = _AREAS[r % len(_AREAS)]
        plant = f"reactor{r}"
        nodes[plant] = {
            **reactor,
            "params": {
                **reactor["params"],
                "A_B": area,
                "D": math.sqrt(4 * area / math.pi),
                "T_in": _FEED[r % len(_FEED)],
            },
        }
        for kind in kinds:
            name = f"{kind}{r}"
            sensor, actuator, r0 = sensors[kind]
            nodes[f"{name}_controller"] = {"kind": "controller", "loop": name, "law": law[kind]}
            loops[name] = {
                "plant": plant,
                "sensor": sensor,
                "actuator": actuator,
                "controller": f"{name}_controller",
                "network": "network",
                "tau_s": 0.1,
                "setpoint": r0,
            }
            t, value = steps[kind]
            setpoints.append({"t": t, "loop": name, "value": value})
            table = _LEVEL_DELAY if kind == "level" else _TEMPERATURE_DELAY
            delays[name] = table[r % len(table)]
    if n % 2:
        name = f"tank{n // 2}"
        b, a_prime = _TANK
        nodes[name] = {
            "kind": "plant",
            "model": "tank",
            "params": {"b": b, "a_prime": a_prime, "u_min": 0.0},
            "x0": {"h": 0.66},
            "u0": {"u": a_prime * math.sqrt(0.70) / b, "q_d": 0.0},
            "monitor_period": reactor["monitor_period"],
        }
        nodes[f"{name}_controller"] = {"kind": "controller", "loop": name, "law": _TANK_LAW}
        loops[name] = {
            "plant": name,
            "sensor": "h",
            "actuator": "u",
            "controller": f"{name}_controller",
            "network": "network",
            "tau_s": 0.1,
            "setpoint": 0.70,
        }
        setpoints.append({"t": 1.8, "loop": name, "value": 0.75})
        delays[name] = _LEVEL_DELAY[0]
    nodes["wncsca"] = {**agent_cfg, **agent}
    scenario = Scenario.model_validate(
        {
            "name": f"jcstr_{n}_loops",
            "time_unit": base["time_unit"],
            "end_time": 8.0,
            "seed": 0,
            "nodes": nodes,
            "loops": loops,
            "setpoints": setpoints,
        }
    )
    return scenario, delays
