"""One shape for every "kind of thing a scenario names": node kinds, plant models, control laws,
per-hop delay models.

A :class:`Kind` is a name, the pydantic model of its configuration and how to build the object
from that configuration. A :class:`Registry` holds the kinds of one sort; generic code asks it,
never compares a name itself::

    LAWS = Registry("law", tag="type", kinds=[Kind("pi", PIConfig, PI), ...])
    LawConfig = LAWS.union()           # the scenario's discriminated union, from the registry
    law = LAWS.build(config)           # the kind named by config.type, built

Adding a kind is its own module plus one :class:`Kind` entry in its registry; nothing else
changes (``tests/unit/test_registry.py`` adds a law that way). The scenario's unions are made
when its module is imported, so a kind must be registered before that.
"""

from __future__ import annotations

import dataclasses
import typing
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from pydantic import BaseModel, Field

__all__ = ["Kind", "Registry"]

T = TypeVar("T")


@dataclass(frozen=True)
class Kind(Generic[T]):
    """One kind: its ``name`` in scenarios, its configuration model, and ``build``, which makes
    the object (``None``: the configuration is the object, as for delay models)."""

    name: str
    config: type[BaseModel]
    build: Callable[..., T] | None = None
    doc: str = ""

    def with_build(self, build: Callable[..., T]) -> Kind[T]:
        """This kind built another way (a test's stand-in for a node's behaviour)."""
        return dataclasses.replace(self, build=build)


class Registry(Generic[T]):
    """The kinds of one sort by name (see the module docstring).

    ``tag`` is the field of every configuration that names its kind (``kind``, ``type``); it
    must be declared ``Literal[<name>]`` on each configuration, and is checked to be. A registry
    without a tag (plant models: the node says ``model:`` beside ``params:``) has no union.
    """

    def __init__(self, what: str, *, tag: str | None, kinds: Iterable[Kind[T]] = ()) -> None:
        self.what = what
        self.tag = tag
        self.kinds: dict[str, Kind[T]] = {}  # public for tests that stand a kind in
        for kind in kinds:
            self.register(kind)

    def register(self, kind: Kind[T]) -> Kind[T]:
        """Add ``kind``; refuses a name already taken or a configuration whose tag does not name
        it."""
        if kind.name in self.kinds:
            raise ValueError(f"{self.what} {kind.name!r} is registered twice")
        if self.tag is not None:
            declared = _tag_values(kind.config, self.tag)
            if declared != (kind.name,):
                raise ValueError(
                    f"{self.what} {kind.name!r}: {kind.config.__name__}.{self.tag} must be "
                    f"Literal[{kind.name!r}], found {declared}"
                )
        self.kinds[kind.name] = kind
        return kind

    def __getitem__(self, name: str) -> Kind[T]:
        try:
            return self.kinds[name]
        except KeyError:
            raise KeyError(f"unknown {self.what} {name!r} (known: {sorted(self.kinds)})") from None

    def __contains__(self, name: object) -> bool:
        return name in self.kinds

    def __iter__(self) -> Iterator[str]:
        return iter(self.kinds)

    def __len__(self) -> int:
        return len(self.kinds)

    def of(self, config: BaseModel) -> Kind[T]:
        """The kind ``config`` configures (by its tag field)."""
        if self.tag is None:
            raise TypeError(f"{self.what} configurations carry no tag; look the kind up by name")
        return self[getattr(config, self.tag)]

    def build(self, config: BaseModel, *args: Any, **kwargs: Any) -> T:
        """The object of the kind ``config`` names, built from it (and ``args``, ``kwargs``)."""
        kind = self.of(config)
        if kind.build is None:
            return typing.cast(T, config)
        return kind.build(config, *args, **kwargs)

    def union(self) -> Any:
        """The discriminated union of every kind's configuration, for a pydantic field."""
        if self.tag is None:
            raise TypeError(f"{self.what} configurations carry no tag to discriminate by")
        configs = tuple(k.config for k in self.kinds.values())
        if len(configs) == 1:
            return configs[0]
        return typing.Annotated[typing.Union[configs], Field(discriminator=self.tag)]  # noqa: UP007


def _tag_values(config: type[BaseModel], tag: str) -> tuple[Any, ...]:
    field = config.model_fields.get(tag)
    if field is None:
        return ()
    if typing.get_origin(field.annotation) is typing.Literal:
        return typing.get_args(field.annotation)
    return ()
