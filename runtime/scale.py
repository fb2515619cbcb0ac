"""Scale scenarios: N control loops over wireless sensor paths (issue 20, item 4).

:func:`scale_scenario` writes the mapping of a scenario with ``n`` loops, each its own
controller, every sensor path over a WSN; ``wncs scale N --out FILE`` writes it as a scenario
file (validated first, like any file :func:`scenario.load.load_scenario` reads). With
``tank`` and ``jcstr`` the loops are independent (each tank, each reactor's pair, its own
plant); with ``tank_train`` they are the coupled loops of one plant.

Three plants:

``tank`` (default)
    ``n`` tanks of seed 002's simulation study (eq. (22): ``dh/dt = b u - a' sqrt(h)``, b = 2.0,
    a' = 0.5, h in mm, t in s), each with its non-linear 2-DOF PI (4.3 % overshoot, 13 s
    settling, eq. (13)-(14)) sampled every ``tau_s = 0.5`` s. Tank ``i`` starts at rest at
    ``60 + 10 (i mod 5)`` mm (its equilibrium input ``u = a' sqrt(h) / b``), steps up 20 mm at
    ``t1 = 5 + 0.25 (i mod 20)`` s and back at ``t1 + 25`` s; the run lasts 60 s.
``jcstr``
    ``n / 2`` jacketed CSTRs of seed 000 with the benchmark's parameters, gains and set points
    (``scenarios/jcstr_benchmark.yaml``: level 0.70 -> 0.75 pu, temperature 52 -> 56 C), each
    reactor's two steps shifted by ``0.02 (k mod 10)`` pu so that the reactors do not move in
    lock-step; 6 pu.
``tank_train``
    One plant (``plants/tank_train.py``): ``n`` of those tanks in series, a share ``c = 0.5``
    of tank ``i-1``'s outflow running into tank ``i`` (``dh_i/dt = b u_i + c a' sqrt(h_{i-1}) -
    a' sqrt(h_i)``), so every loop's move disturbs every loop downstream: the plant-wide
    scenario of coupled loops (``scenarios/tank_train_20.yaml`` is ``wncs scale 20 --plant
    tank_train``). Each tank has the same non-linear PI, which rejects the inflow from upstream
    as a disturbance (its integral); the closed loop is lower block-triangular, hence stable
    when each loop is. Levels, steps and run as ``tank``; the train starts at rest at the
    equilibrium of its coupled model (``u_i = (a' sqrt(h_i) - c a' sqrt(h_{i-1})) / b``, 0.69 to
    1.94 for these levels), and each law starts from the input its pump holds (``u_start``: the
    law's own rest, ``a' sqrt(h_i) / b``, would add the upstream inflow and kick every level
    but the first by some 2 mm). Every step of a tank reaches the tanks downstream, damped by
    each loop's integral on the way (alone, a 20 mm step moves the next tank by 0.2 mm at its
    peak, the one after by 0.003 mm); the pumps saturate at 0 for a while on the way down.

The WSN: loops are grouped ``per_gateway`` at a time (the areas of a plant, each with its own
gateway node); in an area every sensor is two hops from the gateway, through one of its relays
(one relay per five sensors), each link of packet reception ratio 0.98 with up to 3 retries and
per-attempt delay ``base + Exp(mean)``. The actuator paths are wired. The delays are short
against the sampling periods (tank: 0.02 + Exp(0.01) s per attempt, about 0.06 s a path
against 0.5 s; JCSTR: 0.003 + Exp(0.002) pu, about 0.01 pu against 0.1 pu), so every loop is
stable and each step is a step response spoiled only a little by its network.

Coupled or not, the loops exchange messages only with their own controller: the time a run
takes grows with the number of messages, i.e. in proportion to ``n`` if a round costs the same
whatever the number of nodes (``bench/scale.py``).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import yaml

from plants.tank_train import TankTrain, TankTrainParams
from scenario import Scenario, parse_scenario

__all__ = ["PLANTS", "scale_scenario", "scale_yaml", "write_scale"]

PLANTS = ("tank", "jcstr", "tank_train")

# seed 002 eq. (22), the simulation study's tank (h in mm, t in s)
_TANK = {"b": 2.0, "a_prime": 0.5, "u_min": 0.0}
_TANK_TAU_S = 0.5
_TANK_END = 60.0
_TRAIN_C = 0.5  # share of a tank's outflow that feeds the next tank of the train

# seed 000 section III.C, scenarios/jcstr_benchmark.yaml (our calibration)
_JCSTR = {
    "A_B": 1.0,
    "D": 1.1283791670955126,
    "U": 0.1713,
    "rho": 1.0,
    "C_p": 1.0,
    "V_j": 0.126,
    "F_in": 9.69,
    "T_in": 46.4,
    "T_jin": 298.0,
}
_JCSTR_LAWS = {
    "level": {"type": "pi", "Kp": -4.376, "Ki": -2.530, "u_min": 0.0, "u_max": 19.0},
    "temperature": {"type": "pi", "Kp": 0.05929, "Ki": 0.2366, "u_min": 0.0, "u_max": 5.0},
}
_HOP = {
    "tank": {"type": "exponential", "base": 0.02, "mean": 0.01},
    "jcstr": {"type": "exponential", "base": 0.003, "mean": 0.002},
}
_HOP["tank_train"] = _HOP["tank"]
_SENSORS_PER_RELAY = 5


def _area(names: list[str], hop: dict[str, Any]) -> dict[str, Any]:
    """A gateway node whose topology puts each of ``names`` (sensor nodes) two hops from the
    gateway, through one relay per :data:`_SENSORS_PER_RELAY` sensors."""
    nodes: dict[str, Any] = {"gw": {"kind": "gateway"}}
    links: list[dict[str, Any]] = []
    for j in range(math.ceil(len(names) / _SENSORS_PER_RELAY)):
        relay = f"r{j}"
        nodes[relay] = {"kind": "relay"}
        links.append({"a": relay, "b": "gw", "prr": 0.98})
    for i, sensor in enumerate(names):
        nodes[sensor] = {"kind": "sensor"}
        links.append({"a": sensor, "b": f"r{i // _SENSORS_PER_RELAY}", "prr": 0.98})
    return {
        "kind": "gateway",
        "topology": {
            "nodes": nodes,
            "retry_limit": 3,
            "metric": "hops",
            "delay": dict(hop),
            "links": links,
        },
    }


def _tank_level(i: int) -> float:
    """Tank ``i``'s initial level (mm)."""
    return 60.0 + 10.0 * (i % 5)


def _level_loop(
    i: int,
    plant: str,
    signals: tuple[str, str],
    net: str,
    sensor_node: str,
    start: dict[str, float],
) -> tuple[dict, dict, list]:
    """Level loop ``i`` of a tank (``signals``: its level and pump on ``plant``): its
    controller (``start``: more of its law's configuration), its loop and its steps (20 mm up at
    ``5 + 0.25 (i mod 20)`` s, back 25 s later)."""
    h0 = _tank_level(i)
    t1 = 5.0 + 0.25 * (i % 20)
    law = {"type": "nlpi", "overshoot_pct": 4.3, "settling_time": 13.0, **start}
    nodes = {f"ctrl{i:03d}": {"kind": "controller", "loop": f"level{i:03d}", "law": law}}
    loops = {
        f"level{i:03d}": {
            "plant": plant,
            "sensor": signals[0],
            "actuator": signals[1],
            "controller": f"ctrl{i:03d}",
            "network": net,
            "sensor_node": sensor_node,
            "tau_s": _TANK_TAU_S,
            "setpoint": h0,
            "settling_band": 0.01,
        }
    }
    steps = [
        {"t": t1, "loop": f"level{i:03d}", "value": h0 + 20.0},
        {"t": t1 + 25.0, "loop": f"level{i:03d}", "value": h0},
    ]
    return nodes, loops, steps


def _tank_unit(i: int, net: str, sensor_node: str) -> tuple[dict, dict, list]:
    """Tank ``i``: its nodes, its loop and its set-point steps."""
    h0 = _tank_level(i)
    u0 = _TANK["a_prime"] * math.sqrt(h0) / _TANK["b"]
    nodes, loops, steps = _level_loop(i, f"tank{i:03d}", ("h", "u"), net, sensor_node, {})
    plant = {
        f"tank{i:03d}": {
            "kind": "plant",
            "model": "tank",
            "params": dict(_TANK),
            "x0": {"h": h0},
            "u0": {"u": u0, "q_d": 0.0},
            "monitor_period": 0.25,
            "max_step": 0.05,
        }
    }
    return {**plant, **nodes}, loops, steps


def _train_plant(n: int) -> dict[str, Any]:
    """The train of ``n`` tanks at rest at the levels of :func:`_tank_level`: its plant node,
    its inputs the closed-form equilibrium of ``plants/tank_train.py``."""
    params = {"n": n, **_TANK, "c": _TRAIN_C}
    model = TankTrain(TankTrainParams.model_validate(params))
    levels = {name: _tank_level(i) for i, name in enumerate(model.output_names)}
    _, u_bar = model.equilibrium(levels)  # the closed form; refuses a pump below u_min
    return {
        "kind": "plant",
        "model": "tank_train",
        "params": params,
        "x0": levels,
        "u0": dict(zip(model.input_names, u_bar.tolist(), strict=True)),
        "monitor_period": 0.25,
        "max_step": 0.05,
    }


def _train_unit(
    i: int, train: dict[str, Any], net: str, sensor_node: str
) -> tuple[dict, dict, list]:
    """Tank ``i`` of the train (its plant node ``train``): its controller, starting from the
    input the plant holds, its loop and its steps."""
    start = {"u_start": train["u0"][f"u{i}"]}
    return _level_loop(i, "train", (f"h{i}", f"u{i}"), net, sensor_node, start)


def _jcstr_unit(k: int, net: str, sensor_nodes: tuple[str, str]) -> tuple[dict, dict, list]:
    """Reactor ``k``: its nodes, its level and temperature loops and their steps."""
    plant = f"reactor{k:03d}"
    nodes: dict[str, Any] = {
        plant: {
            "kind": "plant",
            "model": "jcstr",
            "params": dict(_JCSTR),
            "x0": {"H": 0.66, "T": 50.0, "T_j": 143.0},
            "u0": {"F_out": 9.69, "F_jin": 0.3501},
            "input_range": {"F_out": [0.0, math.inf], "F_jin": [0.0, math.inf]},  # valves
            "monitor_period": 0.05,
        }
    }
    loops: dict[str, Any] = {}
    steps: list[dict[str, Any]] = []
    shift = 0.02 * (k % 10)
    plan = (  # loop, sensor, actuator, initial and stepped set point, step time
        ("level", "H", "F_out", 0.70, 0.75, 1.8),
        ("temperature", "T", "F_jin", 52.0, 56.0, 2.4),
    )
    for (loop, sensor, actuator, sp0, sp1, t), node in zip(plan, sensor_nodes, strict=True):
        name = f"{loop}{k:03d}"
        nodes[f"{loop}_ctrl{k:03d}"] = {
            "kind": "controller",
            "loop": name,
            "law": {**_JCSTR_LAWS[loop], "integration": "backward"},
        }
        loops[name] = {
            "plant": plant,
            "sensor": sensor,
            "actuator": actuator,
            "controller": f"{loop}_ctrl{k:03d}",
            "network": net,
            "sensor_node": node,
            "tau_s": 0.1,
            "setpoint": sp0,
        }
        steps.append({"t": round(t + shift, 6), "loop": name, "value": sp1})
    return nodes, loops, steps


def scale_scenario(
    n: int,
    *,
    plant: str = "tank",
    per_gateway: int = 10,
    end_time: float | None = None,
    seed: int = 0,
) -> dict[str, Any]:
    """The mapping of a scenario with ``n`` loops (see the module docstring).

    Parameters
    ----------
    n : int
        Number of loops, >= 1 (``jcstr``: even, two loops per reactor).
    plant : {"tank", "jcstr", "tank_train"}
        The plant of every loop (``tank_train``: one plant for all the loops).
    per_gateway : int
        Loops per WSN area (gateway node), >= 1.
    end_time : float, optional
        End of the run; default 60 s (tank) or 6 pu (JCSTR). Steps after it are left out.
    seed : int
        The scenario's seed (the gateways' delay draws).

    Raises
    ------
    ValueError
        For an unknown plant, ``n < 1``, an odd ``n`` with ``jcstr`` or ``per_gateway < 1``.
    """
    if plant not in PLANTS:
        raise ValueError(f"plant: one of {PLANTS}, got {plant!r}")
    if n < 1:
        raise ValueError(f"n: at least one loop, got {n}")
    if per_gateway < 1:
        raise ValueError(f"per_gateway: at least one loop per gateway, got {per_gateway}")
    if plant == "jcstr" and n % 2:
        raise ValueError(f"n: a JCSTR has two loops; give an even number of loops, got {n}")
    per_unit = 2 if plant == "jcstr" else 1  # loops per unit (a reactor has two)
    units = n // per_unit
    per_area = max(per_gateway // per_unit, 1)  # units per gateway
    nodes: dict[str, Any] = {"train": _train_plant(n)} if plant == "tank_train" else {}
    loops: dict[str, Any] = {}
    setpoints: list[dict[str, Any]] = []
    for first in range(0, units, per_area):
        area = range(first, min(first + per_area, units))
        net = f"wsn{first // per_area:02d}"
        sensors = [f"s{i:03d}" for i in range(len(area) * per_unit)]
        nodes[net] = _area(sensors, _HOP[plant])
        for j, unit in enumerate(area):
            if plant == "tank":
                u_nodes, u_loops, steps = _tank_unit(unit, net, sensors[j])
            elif plant == "tank_train":
                u_nodes, u_loops, steps = _train_unit(unit, nodes["train"], net, sensors[j])
            else:
                pair = (sensors[2 * j], sensors[2 * j + 1])
                u_nodes, u_loops, steps = _jcstr_unit(unit, net, pair)
            nodes.update(u_nodes)
            loops.update(u_loops)
            setpoints += steps
    tanks = plant != "jcstr"
    end = end_time if end_time is not None else (_TANK_END if tanks else 6.0)
    nodes["operator"] = {"kind": "operator"}
    return {
        "name": f"scale_{plant}_{n}",
        "time_unit": "s" if tanks else "pu",
        "end_time": end,
        "seed": seed,
        "nodes": nodes,
        "loops": loops,
        "setpoints": sorted(
            (s for s in setpoints if s["t"] <= end), key=lambda s: (s["t"], s["loop"])
        ),
    }


def scale_yaml(n: int, **options: Any) -> str:
    """The scenario file's text: a comment saying how it was made, then the mapping."""
    data = scale_scenario(n, **options)
    given = " ".join(f"--{k.replace('_', '-')} {v}" for k, v in options.items() if v is not None)
    kind = "coupled" if options.get("plant") == "tank_train" else "independent"
    head = (
        f"# {n} {kind} loops over wireless sensor paths, written by "
        f"`wncs scale {n}{' ' + given if given else ''}` (runtime/scale.py says what they are).\n"
    )
    return head + yaml.safe_dump(data, sort_keys=False, width=100)


def write_scale(n: int, path: str | Path, **options: Any) -> Scenario:
    """Write the scenario of :func:`scale_scenario` to ``path`` and return it, validated."""
    text = scale_yaml(n, **options)
    scenario = parse_scenario(yaml.safe_load(text), source=str(path))
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text(text, encoding="utf-8")
    return scenario
