"""The plant-wide scenario of coupled loops (issue 20, item 4): ``scenarios/tank_train_20.yaml``,
20 tanks in series (plants/tank_train.py) each with its level loop over a WSN, as
``wncs scale 20 --plant tank_train`` writes it; it starts at rest and every loop reaches each of
its set points, by the direct engine."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cli.main import main
from core.record import summarize
from runtime.direct import simulate
from runtime.scale import scale_scenario
from scenario import GatewayNodeConfig, load_scenario, parse_scenario
from tests.conftest import SCENARIOS

SHIPPED = SCENARIOS / "tank_train_20.yaml"


def test_the_shipped_scenario_is_what_wncs_scale_writes(tmp_path, capsys):
    out = tmp_path / "train.yaml"
    assert main(["scale", "20", "--plant", "tank_train", "--out", str(out)]) == 0
    assert "20 loops" in capsys.readouterr().out
    assert out.read_text(encoding="utf-8") == SHIPPED.read_text(encoding="utf-8")


def test_one_plant_twenty_coupled_loops_over_wsn_paths_at_rest():
    sc = load_scenario(SHIPPED)
    assert len(sc.loops) == 20 and list(sc.plants()) == ["train"]
    train = sc.nodes["train"]
    p = train.params
    assert (p["n"], p["b"], p["a_prime"], p["c"]) == (20, 2.0, 0.5, 0.5)  # seed 002 eq. (22)
    assert len({lp.controller for lp in sc.loops.values()}) == 20
    assert len(sc.gateways()) == 2
    for i, (name, lp) in enumerate(sorted(sc.loops.items())):
        assert (lp.plant, lp.sensor, lp.actuator) == ("train", f"h{i}", f"u{i}"), name
        assert sc.is_wireless(lp.network) and isinstance(sc.nodes[lp.network], GatewayNodeConfig)
        assert lp.setpoint == train.x0[f"h{i}"]  # starts at its set point
        law = sc.nodes[lp.controller].law
        assert law.type == "nlpi" and law.u_start == train.u0[f"u{i}"]  # from the held input
    # the held inputs are the coupled equilibrium: u_i = (a' sqrt(h_i) - c a' sqrt(h_{i-1})) / b
    h = [train.x0[f"h{i}"] for i in range(20)]
    for i in range(20):
        upstream = 0.5 * 0.5 * math.sqrt(h[i - 1]) if i else 0.0
        assert train.u0[f"u{i}"] == pytest.approx((0.5 * math.sqrt(h[i]) - upstream) / 2.0)
        assert train.u0[f"u{i}"] >= 0.0  # the pump can hold it
    model = train.build()
    x0 = np.array([train.x0[s] for s in model.state_names])
    u0 = np.array([train.u0[s] for s in model.input_names])
    assert np.max(np.abs(model.rhs(0.0, x0, u0))) < 1e-12
    for name in sc.loops:  # 20 mm up, then back
        mine = [c.value for c in sc.setpoints if c.loop == name]
        assert mine == [sc.loops[name].setpoint + 20.0, sc.loops[name].setpoint]
    assert len({c.t for c in sc.setpoints}) > 1  # staggered


def test_every_loop_reaches_each_set_point_by_the_end_of_its_hold():
    """Computed from the run's record: the true level at the end of every hold (before the
    loop's next change, or at the end of the run) is within the loop's settling band of the set
    point (a fraction of the step, 20 mm); before its first step the level is at rest."""
    sc = load_scenario(SHIPPED)
    rec = simulate(sc)
    summary = summarize(rec)
    end = sc.end_time
    for name, lp in sc.loops.items():
        t, y = rec.plants["train"].signal(lp.sensor)
        changes = [(0.0, lp.setpoint)] + [(c.t, c.value) for c in sc.setpoints if c.loop == name]
        for k, (t_from, r) in enumerate(changes):
            t_end = changes[k + 1][0] if k + 1 < len(changes) else end
            size = abs(r - changes[k - 1][1]) if k else abs(changes[1][1] - r)
            y_end = y[np.searchsorted(t, t_end, side="right") - 1]
            assert abs(y_end - r) <= lp.settling_band * size, (name, t_from, y_end, r)
            if k == 0:  # at rest until its first step (no bump from the start)
                assert np.max(np.abs(y[t < t_end] - r)) < 1e-6, name
        steps = summary["loops"][name]["steps"]
        assert len(steps) == 2 and all(s["settling_time"] is not None for s in steps), name
        assert all(s["settling_time"] < 25.0 for s in steps), name


def _only(steps_of: str | None, n: int = 4):
    """A coupled train of ``n`` in which only loop ``steps_of`` steps (None: none does)."""
    data = scale_scenario(n, plant="tank_train", end_time=30.0)
    data["setpoints"] = [s for s in data["setpoints"] if s["loop"] == steps_of]
    rec = simulate(parse_scenario(data, source="variant"))
    return {f"h{i}": rec.plants["train"].signal(f"h{i}")[1] for i in range(n)}


def test_a_step_disturbs_the_loops_downstream_and_none_upstream():
    still = _only(None)
    first = _only("level000")
    last = _only("level003")
    for i in range(1, 4):  # loop 0's step reaches every tank downstream, less and less
        assert np.max(np.abs(first[f"h{i}"] - still[f"h{i}"])) > 1e-5, i
    reach = [np.max(np.abs(first[f"h{i}"] - still[f"h{i}"])) for i in range(1, 4)]
    assert reach[0] > 0.1 and reach[0] > reach[1] > reach[2]  # 0.2 mm on the next tank
    for i in range(3):  # the last loop's step: upstream levels exactly as without it
        assert last[f"h{i}"].tolist() == still[f"h{i}"].tolist(), i
    assert np.max(np.abs(last["h3"] - still["h3"])) > 10.0
