"""Schemas and codec: every body round-trips; bad input is refused with a SchemaError."""

from __future__ import annotations

import hashlib
import math

import msgpack
import pytest
import zenoh

from bus_schemas import (
    Decision,
    Done,
    Estimate,
    InjectRequest,
    ModeRequest,
    Move,
    NetApplied,
    PlantState,
    Rates,
    Sample,
    SamplingPeriod,
    Setpoint,
    Stop,
    Tick,
    Timing,
    Working,
    codec,
    keys,
)
from core.errors import SchemaError

BODIES = [
    Sample(value=0.7, t_sampled=1_800_000),
    Move(value=1.25, t_computed=5),
    Estimate(values=(1.5, -0.02), t_sent=38_806),
    Setpoint(value=56.0),
    PlantState(t=(0, 10_000), values={"H": (0.7, 0.71), "T": (52.0, 52.1)}),
    Tick(
        round=3, t=100, expected={"loop/level/meas": 1}, digests={"loop/level/meas": (2**64 - 1,)}
    ),
    Done(
        round=3,
        node="reactor",
        published={"plant/reactor/state": 1},
        digests={"plant/reactor/state": (7,)},
        next_time=None,
    ),
    Stop(ok=False, reason="node 'x' left", round=9, t=10, dropped_invalid={"a/b": 2}),
    Working(round=3, node="wncsca", busy_s=2.5),
]


@pytest.mark.parametrize("body", BODIES, ids=lambda b: type(b).__name__)
def test_round_trip(body):
    raw = codec.encode(run="r1", src="reactor", seq=4, round=7, t=123, body=body)
    env = codec.decode(raw, type(body))
    assert env.body == body
    assert (env.v, env.run, env.src, env.seq, env.round, env.t) == (1, "r1", "reactor", 4, 7, 123)


def _raw(**over):
    env = {
        "v": 1,
        "run": "r1",
        "src": "a",
        "seq": 0,
        "round": 0,
        "t": 0,
        "body": {"value": 1.0, "t_sampled": 0},
    }
    env.update(over)
    return msgpack.packb(env)


@pytest.mark.parametrize(
    "raw, fragment",
    [
        (b"\xc1\xff garbage", "msgpack"),
        (msgpack.packb([1, 2, 3]), "must be a map"),
        (_raw(v=2), "bad envelope: v"),
        (_raw(t=1.5), "bad envelope: t"),  # float time is refused
        (_raw(seq=-1), "bad envelope: seq"),
        (_raw(extra=1), "bad envelope: extra"),
        (_raw(body={"value": "high", "t_sampled": 0}), "body: value"),
        (_raw(body={"value": math.nan, "t_sampled": 0}), "body: value"),
        (_raw(body={"value": 1.0}), "body: t_sampled"),
        (_raw(body={"value": 1.0, "t_sampled": 0, "unit": "m"}), "body: unit"),
        (_raw(body={"value": 1.0, "t_sampled": 0.5}), "body: t_sampled"),
    ],
)
def test_rejects_bad_input(raw, fragment):
    with pytest.raises(SchemaError, match=fragment.replace("(", r"\(")):
        codec.decode(raw, Sample)


def test_plant_state_columns_must_match_times():
    raw = codec.encode(
        run="r", src="p", seq=0, round=0, t=0, body=PlantState(t=(0,), values={"H": (1.0,)})
    )
    env = msgpack.unpackb(raw)
    env["body"]["values"]["H"] = [1.0, 2.0]
    with pytest.raises(SchemaError, match="values.H: 2 values for 1 times"):
        codec.decode(msgpack.packb(env), PlantState)


def test_a_digest_is_the_first_8_bytes_of_blake2b_of_the_message():
    raw = codec.encode(run="r", src="p", seq=0, round=0, t=0, body=Setpoint(value=1.0))
    assert codec.digest(raw) == int(hashlib.blake2b(raw, digest_size=8).hexdigest(), 16)
    assert codec.digest(raw[:-1] + bytes([raw[-1] ^ 1])) != codec.digest(raw)


@pytest.mark.parametrize(
    ("body", "fragment"),
    [
        ({"published": {"a/b": 2}, "digests": {"a/b": [1]}}, "digests announce"),
        ({"published": {"a/b": 1}, "digests": {}}, "digests announce"),
        ({"published": {}, "digests": {"a/b": [1]}}, "digests announce"),
        ({"published": {"a/b": 1}, "digests": {"a/b": [-1]}}, "digests.a/b.0"),
        ({"published": {"a/b": 1}, "digests": {"a/b": [2**64]}}, "digests.a/b.0"),
        ({"published": {"a/b": 1}, "digests": {"a/b": ["1"]}}, "digests.a/b.0"),
    ],
)
def test_a_done_must_announce_a_digest_for_each_message_it_counts(body, fragment):
    with pytest.raises(SchemaError, match=fragment):
        codec.validate_body({"round": 1, "node": "n", **body}, Done)


def test_a_tick_with_digests_must_announce_them_for_its_counts():
    with pytest.raises(SchemaError, match="digests announce"):
        codec.validate_body(
            {"round": 1, "t": 0, "expected": {"a/b": 2}, "digests": {"a/b": [1]}}, Tick
        )


@pytest.mark.parametrize(
    "body, fragment",
    [
        ({"round": -1, "node": "a", "busy_s": 1.0}, "round"),
        ({"round": 1.0, "node": "a", "busy_s": 1.0}, "round"),  # rounds are integers
        ({"round": 1, "node": "a", "busy_s": -0.5}, "busy_s"),
        ({"round": 1, "node": "a", "busy_s": math.inf}, "busy_s"),
        ({"round": 1, "node": "a"}, "busy_s"),
    ],
)
def test_a_progress_heartbeat_is_refused_when_malformed(body, fragment):
    with pytest.raises(SchemaError, match=fragment):
        codec.validate_body(body, Working)


def test_schema_error_is_a_value_error():
    with pytest.raises(ValueError):
        codec.decode(b"", Sample)


BUILT = [
    keys.tick(),
    keys.done("n1"),
    keys.done_all(),
    keys.working("n1"),
    keys.working_all(),
    keys.stop(),
    keys.alive("n1"),
    keys.alive_all(),
    keys.sensor("reactor", "H"),
    keys.actuator("reactor", "F_out"),
    keys.plant_state("reactor"),
    keys.meas("level"),
    keys.move("level"),
    keys.link_tx("x1"),
    keys.link_rx("x1"),
    keys.setpoint("level"),
    keys.setpoint_all(),
]


@pytest.mark.parametrize("rel", BUILT)
def test_keys_are_valid_key_expressions(rel):
    full = keys.full("r1a2", rel)
    assert str(zenoh.KeyExpr(full)) == full
    assert keys.relative("r1a2", full) == rel


@pytest.mark.parametrize("bad", ["", "a/b", "a*", "$x", "a b", "-a"])
def test_bad_names_refused(bad):
    with pytest.raises(ValueError, match="key chunk"):
        keys.sensor("reactor", bad)


# -- the coordination agent's and operations' bodies (round trip and refusals) -------------------
AGENT_BODIES = [
    Decision(
        subject="proposal",
        network="network",
        proposal=1,
        verdict="reject",
        reasons=("level: control-path delay 0.3 >= its bound 0.252",),
        delays={"level": 0.3},
        bounds={"level": 0.252},
        offending=("level",),
        paths=("level.sensor",),
    ),
    Rates(
        mode="steady_state",
        periods={"level": 1_000_000},
        closed={"level": False},
        control_periods={"level": 275_000},
        proposal=0,
        method="paper",
        overshoot_pct={"level": 24.6},
    ),
    SamplingPeriod(period=275_000),
    ModeRequest(mode="steady_state"),
    Timing(proposal=0, decision_s=0.6),
    Setpoint(value=0.72, t_apply=16_000_000),
    NetApplied(event="rates", source="agent", paths={}, proposal=0, periods={"level": 275_000}),
    InjectRequest(mode="steady_state"),
    InjectRequest(setpoint={"loop": "level", "value": 0.72}),
    InjectRequest(event={"type": "node_down", "node": "r1"}),
]


@pytest.mark.parametrize("body", AGENT_BODIES, ids=lambda b: type(b).__name__)
def test_agent_bodies_round_trip(body):
    raw = codec.encode(run="r1", src="wncsca", seq=0, round=1, t=2, body=body)
    assert codec.decode(raw, type(body)).body == body


def _body(body_type, body) -> bytes:
    env = {"v": 1, "run": "r1", "src": "a", "seq": 0, "round": 0, "t": 0, "body": body}
    return msgpack.packb(env)


@pytest.mark.parametrize(
    "body_type, body, fragment",
    [
        (SamplingPeriod, {"period": 0}, "period"),
        (SamplingPeriod, {"period": 0.5}, "period"),  # ticks, never float time
        (
            Rates,
            {
                "mode": "x",
                "periods": {"level": -1},
                "closed": {},
                "control_periods": {},
                "proposal": None,
            },
            "must be > 0 ticks",
        ),
        (Decision, {"subject": "proposal", "verdict": "maybe", "reasons": []}, "verdict"),
        (Decision, {"subject": "weather", "verdict": "accept", "reasons": []}, "subject"),
        (InjectRequest, {}, "exactly one of event, mode, setpoint"),
        (InjectRequest, {"mode": "steady_state", "setpoint": {"loop": "level"}}, "exactly one"),
        (Timing, {"proposal": 0, "decision_s": -1.0}, "decision_s"),
        (Setpoint, {"value": 1.0, "t_apply": -5}, "t_apply"),
        (Estimate, {"values": [], "t_sent": 0}, "values"),
        (Estimate, {"values": ["hot"], "t_sent": 0}, "values"),
        (Estimate, {"values": [float("nan")], "t_sent": 0}, "finite"),
        (Estimate, {"values": [1.0], "t_sent": -1}, "t_sent"),
        (
            Rates,
            {
                "mode": "x",
                "periods": {},
                "closed": {},
                "control_periods": {},
                "proposal": None,
                "link_periods": {"x1": 0},
            },
            "link_periods.x1: must be > 0 ticks",
        ),
    ],
)
def test_agent_bodies_reject_bad_input(body_type, body, fragment):
    with pytest.raises(SchemaError, match=fragment):
        codec.decode(_body(body_type, body), body_type)


@pytest.mark.parametrize(
    "rel",
    [
        keys.sampling("reactor", "H"),
        keys.loop_setpoint("level"),
        keys.ops_mode(),
        keys.wncsca_decision(),
        keys.wncsca_rates(),
        keys.wncsca_timing(),
        keys.net_proposal(),
        keys.net_applied(),
    ],
)
def test_agent_keys_are_valid_key_expressions(rel):
    full = keys.full("r1a2", rel)
    assert str(zenoh.KeyExpr(full)) == full
