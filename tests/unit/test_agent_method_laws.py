"""Every single-loop law the platform ships is judged by the agent's method or refused when the
scenario loads (issue 35, item 7): the tank of seed 002 with each law under an agent.

The fast and chance methods model the PI and seed 002's 2-DOF laws (:data:`agents.wncsca.laws.
MODELLED_LAWS`; ``tests/integration/test_wncsca_laws.py`` runs the tank's non-linear PI under
them); a loop of another law under them is refused by ``wncs validate`` with the loop, its law,
why it is not modelled and the method that applies (``paper``), never a traceback at run time.
The paper's method simulates any law, so it accepts all of them. Multi-loop laws (MRAC, QDC, the
PI-P cascade) are not judged by simulation at all (their loops are governed through their links'
update periods), so the agent's method does not apply to them.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from agents.wncsca.laws import MODELLED_LAWS, REFUSED
from controllers.registry import LAWS
from core.errors import ConfigError
from scenario import load_scenario
from tests.conftest import write_variant

TANK = Path(__file__).resolve().parents[2] / "scenarios" / "tank_sim.yaml"
SPEC = {"overshoot_pct": 4.3, "settling_time": 13.0}
SINGLE_LOOP_LAWS = {
    "pi": {"type": "pi", "Kp": 0.5, "Ki": 0.1, "u_min": 0.0, "feedforward": "none"},
    "nlpi": {"type": "nlpi", **SPEC},
    "pi2dof": {"type": "pi2dof", "h_design": 100.0, **SPEC},
    "stnlpi": {"type": "stnlpi", **SPEC},
}


def test_the_table_covers_every_single_loop_law():
    shipped = {n for n, k in LAWS.kinds.items() if not getattr(k.build, "multi_loop", False)}
    assert shipped == set(SINGLE_LOOP_LAWS)


def _variant(tmp_path: Path, law: dict, method: str) -> Path:
    def edit(data: dict) -> None:
        data["nodes"]["level_controller"]["law"] = law
        data["nodes"]["agent"] = {"kind": "agent", "method": method}

    return write_variant(tmp_path, TANK, f"tank_{law['type']}_{method}.yaml", edit)


@pytest.mark.parametrize("method", ["fast", "chance", "paper"])
@pytest.mark.parametrize("law", sorted(SINGLE_LOOP_LAWS))
def test_each_law_is_judged_or_refused_with_its_reason(tmp_path, law, method):
    path = _variant(tmp_path, SINGLE_LOOP_LAWS[law], method)
    config = LAWS[law].config
    if method == "paper" or issubclass(config, MODELLED_LAWS):
        load_scenario(path)  # judged: the scenario loads
        return
    with pytest.raises(ConfigError) as info:
        load_scenario(path)
    msg = str(info.value)
    assert str(path) in msg and "nodes.agent.method" in msg, msg
    assert "loop 'level'" in msg and f"{law!r}" in msg and "method 'paper'" in msg, msg
    assert REFUSED[law] in msg, msg


@pytest.mark.parametrize("method", ["fast", "chance"])
def test_a_test_that_empties_the_tank_is_refused_where_the_nonlinear_pi_has_no_tangent(
    tmp_path, method
):
    """The NL PI's linearising term ``K_l sqrt(h)`` has an infinite slope at 0: the jitter margin
    needs the law's tangent at the test's final set point, so a test ending at an empty tank is
    refused on load (naming the field) instead of failing in the agent's first decision."""

    def edit(data: dict) -> None:
        data["nodes"]["agent"] = {
            "kind": "agent",
            "method": method,
            "test": {"end_time": 100.0, "setpoints": [{"t": 0.0, "loop": "level", "value": 0.0}]},
        }

    path = write_variant(tmp_path, TANK, f"empty_{method}.yaml", edit)
    with pytest.raises(ConfigError) as info:
        load_scenario(path)
    msg = str(info.value)
    assert "nodes.agent.test.setpoints" in msg and "loop 'level' at 0" in msg, msg
    assert "infinite slope" in msg and "method 'paper'" in msg, msg
