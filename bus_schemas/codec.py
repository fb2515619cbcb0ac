"""The msgpack codec: the only place msgpack is called.

``encode`` turns an :class:`~bus_schemas.envelope.Envelope` into bytes; ``decode_envelope``
checks the envelope of raw bytes; ``decode_body`` validates its body against a schema.
Every failure is a :class:`~bus_schemas.errors.SchemaError` saying what was wrong.
"""

from __future__ import annotations

import hashlib
from typing import Any, TypeVar

import msgpack
from pydantic import BaseModel, ValidationError

from bus_schemas.envelope import SCHEMA_VERSION, Envelope, RawEnvelope
from bus_schemas.errors import SchemaError

__all__ = [
    "ENCODING",
    "encode",
    "pack_body",
    "pack_mapping",
    "unpack_mapping",
    "decode_envelope",
    "decode_body",
    "validate_body",
    "problems",
    "decode",
    "digest",
]

ENCODING = "application/msgpack"

BodyT = TypeVar("BodyT", bound=BaseModel)


def pack_body(body: BaseModel) -> bytes:
    """The msgpack bytes of a body alone (the historian stores bodies without envelopes)."""
    return _packb(body.model_dump(mode="python"))


def pack_mapping(body: dict[str, Any]) -> bytes:
    """The msgpack bytes of an unvalidated body mapping (as the historian stores it)."""
    return _packb(body)


def unpack_mapping(raw: bytes) -> dict[str, Any]:
    """Inverse of :func:`pack_mapping`; ``SchemaError`` when ``raw`` is not msgpack."""
    try:
        obj = msgpack.unpackb(raw, raw=False)
    except (msgpack.exceptions.UnpackException, ValueError, TypeError) as err:
        raise SchemaError(f"body is not msgpack: {type(err).__name__}: {err}") from err
    if not isinstance(obj, dict):
        raise SchemaError(f"body must be a map, got {type(obj).__name__}")
    return obj


def _packb(obj: Any) -> bytes:
    return bytes(msgpack.packb(obj, use_bin_type=True))


def encode(*, run: str, src: str, seq: int, round: int, t: int, body: BaseModel) -> bytes:
    """Encode one message; the body must already be a validated model."""
    return _packb(
        {
            "v": SCHEMA_VERSION,
            "run": run,
            "src": src,
            "seq": seq,
            "round": round,
            "t": t,
            "body": body.model_dump(mode="python"),
        }
    )


def digest(payload: bytes) -> int:
    """A message's fingerprint: the first 8 bytes of the BLAKE2b hash of its bytes, as an int.

    A publisher announces the digests of a round's messages in its ``Done``, the clock passes
    them on in the next ``Tick``, and a subscriber takes exactly the messages announced
    (:mod:`kernel.node`): a forged message, even in a well-formed envelope from the key's
    owner, cannot stand in for a genuine one unless it is the same bytes. 0.5 us a message."""
    return int.from_bytes(hashlib.blake2b(payload, digest_size=8).digest(), "big")


def _first_error(err: ValidationError) -> str:
    e = err.errors()[0]
    loc = ".".join(str(p) for p in e["loc"]) or "<root>"
    more = f" (+{err.error_count() - 1} more)" if err.error_count() > 1 else ""
    return f"{loc}: {e['msg']}{more}"


def problems(err: ValidationError) -> tuple[str, ...]:
    """Every error of ``err`` as ``"<dotted field>: <what> (got <input>)"``, in the schema's
    field order: ``"paths.level.sensor.estimates.hops: Input should be greater than or equal to
    0 (got -0.1)"``, ``"paths: missing"``, ``"paths.level.sensor.estimates: key 'x': Input
    should be 'timestamps', 'ping' or 'hops'"``."""
    out = []
    for e in err.errors():
        loc = [str(p) for p in e["loc"]]
        key = loc[-2] if loc[-1:] == ["[key]"] else None
        where = ".".join(loc[:-2] if key is not None else loc) or "body"
        if e["type"] == "missing":
            out.append(f"{where}: missing")
            continue
        got = repr(e["input"])
        got = got if len(got) <= 40 else got[:37] + "..."
        what = f"key {key}: {e['msg']}" if key is not None else f"{e['msg']} (got {got})"
        out.append(f"{where}: {what}")
    return tuple(out)


def decode_envelope(raw: bytes) -> RawEnvelope:
    """Unpack and check an envelope; the body is left as a mapping."""
    try:
        obj = msgpack.unpackb(raw, raw=False, strict_map_key=True)
    except (msgpack.ExtraData, msgpack.FormatError, msgpack.StackError, ValueError) as err:
        raise SchemaError(f"not a msgpack message: {err}") from err
    except Exception as err:  # msgpack raises assorted errors on garbage; all mean the same
        raise SchemaError(f"not a msgpack message: {type(err).__name__}: {err}") from err
    if not isinstance(obj, dict):
        raise SchemaError(f"envelope must be a map, got {type(obj).__name__}")
    try:
        return RawEnvelope.model_validate(obj)
    except ValidationError as err:
        raise SchemaError(f"bad envelope: {_first_error(err)}") from err


def decode_body(env: RawEnvelope, body_type: type[BodyT]) -> BodyT:
    """Validate the body of a checked envelope against ``body_type``."""
    return validate_body(env.body, body_type)


def validate_body(body: Any, body_type: type[BodyT]) -> BodyT:
    """Validate a body mapping against ``body_type`` (what :func:`decode_body` does, for a body
    that did not come in an envelope: the direct engine's messages)."""
    try:
        return body_type.model_validate(body)
    except ValidationError as err:
        raise SchemaError(
            f"bad {body_type.__name__} body: {_first_error(err)}", problems(err)
        ) from err


def decode(raw: bytes, body_type: type[BodyT]) -> Envelope[BodyT]:
    """Decode and validate a whole message."""
    env = decode_envelope(raw)
    body = decode_body(env, body_type)
    envelope: Any = Envelope[body_type]  # type: ignore[valid-type]
    return envelope(**env.model_dump(exclude={"body"}), body=body)  # type: ignore[no-any-return]
