"""The agent's timeline puts the predicted and the measured overshoot of a step side by side and
warns when the limit was broken (issue 35, item 6): a user's step predicted 24.9 % and measured
35.3 % must not pass in silence."""

from __future__ import annotations

from agents.wncsca.timeline import format_timeline
from core.record import wncsca_summary


def _summary(measured: float) -> dict:
    judged = (
        "step level 0.7 -> 0.75: P(overshoot <= 25 %) = 0.96 (95 % CI 0.80-1.00), predicted "
        "overshoot 24.9 % at the control periods (level 0.175, temperature 0.075)"
    )
    return {
        "time_unit": "pu",
        "loops": {
            "level": {"steps": [{"t": 1.8, "from": 0.7, "to": 0.75, "overshoot_pct": measured}]}
        },
        "wncsca": {
            "decisions": [
                {
                    "t": 1.8,
                    "order": 1,
                    "subject": "setpoint",
                    "verdict": "accept",
                    "reasons": ["level -> 0.75 at t=1.8", judged],
                }
            ]
        },
    }


def test_a_step_past_the_limit_is_flagged_beside_its_prediction():
    line = format_timeline(_summary(35.3)).splitlines()[-1]
    assert "level set point 0.7 -> 0.75: measured overshoot 35.3 % (predicted 24.9 %)" in line
    assert line.endswith("WARNING: past the 25 % limit")


def test_a_step_within_the_limit_is_not_flagged():
    line = format_timeline(_summary(21.0)).splitlines()[-1]
    assert "measured overshoot 21.0 % (predicted 24.9 %)" in line and "WARNING" not in line


def test_each_judgement_of_a_proposal_has_its_own_wall_time_and_a_keep_none():
    raw = {
        "decisions": [
            {"t": 0, "subject": "proposal", "proposal": 0, "verdict": "reject", "reasons": []},
            {"t": 0, "subject": "proposal", "proposal": 0, "verdict": "keep", "reasons": []},
            {"t": 5, "subject": "proposal", "proposal": 0, "verdict": "accept", "reasons": []},
            {"t": 5, "subject": "mode", "proposal": None, "verdict": "accept", "reasons": []},
        ],
        "timing": [{"proposal": 0, "decision_s": 4.0}, {"proposal": 0, "decision_s": 2.5}],
    }
    got = [d.get("decision_time_s") for d in wncsca_summary(raw)["decisions"]]
    assert got == [4.0, None, 2.5, None]
