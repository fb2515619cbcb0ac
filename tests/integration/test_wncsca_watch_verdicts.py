"""What the agent does when its model watch flags the model (issue 35, item 4), without an
``identify:`` to fit it again: it widens the uncertainty it states (standard deviations times
``widen``, capped at 30 %; an interval's half-widths about the believed value times ``widen``)
and the CUSUM starts again, or, with nothing stated, says the guarantee rests on a model that
does not fit. The window is a run of the jitter scenario whose reactor's U is 25 % below the
model's (``tests/integration/test_wncsca_watch.py``), handed to the agent's core as its watch
would have kept it."""

from __future__ import annotations

import pytest

from core.time import to_ticks
from runtime.direct import simulate
from scenario import load_scenario, views
from tests.conftest import write_variant
from tests.integration.test_wncsca_watch import JITTER, U, _window

pytestmark = pytest.mark.slow


def _coordinator(tmp_path, uncertainty: dict, widen: float = 2.0):
    def edit(data: dict) -> None:
        data["nodes"]["reactor"]["noise"] = {"H": 0.002, "T": 0.05}  # the sensors, as known
        data["nodes"]["wncsca"]["watch"] = {"widen": widen}
        if uncertainty:
            data["nodes"]["wncsca"]["model"] = {"reactor": {"uncertainty": uncertainty}}

    path = write_variant(tmp_path, JITTER, "watched.yaml", edit)
    co = views.coordinator(load_scenario(path), simulate=simulate)
    co.watching = _window(0, 0.75 * U)
    return co


def test_a_flagged_model_without_identify_has_its_stated_uncertainty_widened(tmp_path):
    co = _coordinator(
        tmp_path, {"U": {"rel_sd": 0.01}, "T_jin": {"interval": [297.9, 298.2]}}, widen=20.0
    )
    got = co.watched(to_ticks(9.8))
    assert got.decision is not None and got.decision.verdict == "reject"
    assert "the model no longer fits its plant" in got.decision.reasons[0]
    assert got.score is not None and got.score.z > 5.5
    plant = co.model.trials.spec.plants["reactor"]
    assert plant.uncertainty["U"].rel_sd == pytest.approx(0.2)
    assert plant.uncertainty["T_jin"].interval == pytest.approx((296.0, 302.0))  # about 298
    assert (
        "uncertainty widened x20: reactor.T_jin in [296, 302], reactor.U +-20 % (1 sd)"
    ) in got.decision.reasons[1]
    assert co.watch is not None and co.watch.cusum == 0.0  # a flag starts the sum again
    co.watching = _window(0, 0.75 * U)  # flagged again: 0.2 x 20, capped at 0.3
    co.watch.cusum = 100.0
    again = co.watched(to_ticks(9.8))
    assert again.decision is not None and again.decision.verdict == "reject"
    assert co.model.trials.spec.plants["reactor"].uncertainty["U"].rel_sd == pytest.approx(0.3)
    assert co.watch is not None and co.watching is None
    assert got.negotiations == []  # no configuration accepted yet: nothing to judge again


def test_a_flagged_model_with_nothing_stated_says_the_guarantee_rests_on_it(tmp_path):
    co = _coordinator(tmp_path, {})
    before = co.model.trials.spec.fingerprint
    got = co.watched(to_ticks(9.8))
    assert got.decision is not None and got.decision.verdict == "reject"
    assert "no uncertainty stated to widen and no identify: configured" in got.decision.reasons[1]
    assert co.model.trials.spec.fingerprint == before


def test_a_model_that_fits_is_said_to_fit_and_the_sum_stays_low(tmp_path):
    co = _coordinator(tmp_path, {})
    co.watching = _window(0, U)
    got = co.watched(to_ticks(9.8))
    assert got.decision is not None and got.decision.verdict == "accept"
    assert got.decision.reasons[0].endswith("model fits")
    assert co.watch is not None and co.watch.cusum < 5.0
