"""Schemas and codec: every body round-trips; bad input is refused with a SchemaError."""

from __future__ import annotations

import math

import msgpack
import pytest
import zenoh

from bus_schemas import Done, Move, PlantState, Sample, Setpoint, Stop, Tick, codec, keys
from runtime.errors import SchemaError

BODIES = [
    Sample(value=0.7, t_sampled=1_800_000),
    Move(value=1.25, t_computed=5),
    Setpoint(value=56.0),
    PlantState(t=(0, 10_000), values={"H": (0.7, 0.71), "T": (52.0, 52.1)}),
    Tick(round=3, t=100, expected={"loop/level/meas": 1}),
    Done(round=3, node="reactor", published={"plant/reactor/state": 1}, next_time=None),
    Stop(ok=False, reason="node 'x' left", round=9, t=10, dropped_invalid={"a/b": 2}),
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


def test_schema_error_is_a_value_error():
    with pytest.raises(ValueError):
        codec.decode(b"", Sample)


BUILT = [
    keys.tick(),
    keys.done("n1"),
    keys.done_all(),
    keys.stop(),
    keys.alive("n1"),
    keys.alive_all(),
    keys.sensor("reactor", "H"),
    keys.actuator("reactor", "F_out"),
    keys.plant_state("reactor"),
    keys.meas("level"),
    keys.move("level"),
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
