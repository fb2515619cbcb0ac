"""WSN topology: nodes, links, shortest-path routes, reconfiguration events and alternatives.

Seed 000, sections I-II: the control loops' sensor and actuator traffic crosses a multi-hop
wireless sensor network whose configuration changes at run time; the delay a loop sees depends
on the configuration, above all on its number of hops. DESIGN.md, section 5: routes are shortest
paths (``scipy.sparse.csgraph``) by hop count or by expected transmissions; reconfiguration events
make the gateway recompute routes and propose the new configuration to the coordination agent,
and on rejection its next alternative, until none is left.

Model
-----
* Nodes have a kind (``sensor``, ``actuator``, ``relay``, ``gateway``), an optional position and
  an up/down state. Links are undirected (one PRR and one delay model for both directions) and
  carry a packet reception ratio ``prr`` in (0, 1], an optional per-link delay model and retry
  limit (else the network's defaults) and a TDMA slot index.
* Every node that is up forwards packets (a mesh, as in WirelessHART); a node that is down
  carries nothing and its paths are down.
* Paths are named (``src``, ``dst``) pairs, e.g. a loop's sensor -> gateway and
  gateway -> actuator. Each has a route, or none (the path is *down*).
* Route metrics (per-link weight, route cost = sum over its links)::

      hops         1 + 1e-6 / prr     (hop count; equal hop counts broken by ETX)
      etx          1 / prr            (expected transmissions without a retry limit)
      etx_limited  (1 - (1-prr)^(r+1)) / prr   (expected attempts with the retry limit r)
      delay        mean per-hop delay for delivered packets, retries included

  ``delay`` is used to rank alternatives; any of them can route.
* TDMA slots: a link without an explicit ``slot`` gets one when it is created: the smallest
  index not used by a link sharing one of its nodes (greedy edge colouring in link order). A hop
  uses ``slot mod frame_slots`` of its TDMA model.

Events (:data:`TopologyEvent`, discriminated on ``type``): ``node_down``, ``node_up``,
``link_degraded`` (new PRR), ``delay_model_changed`` (one link's model, or the network default for
all links), ``relay_added`` (with its links), ``node_moved`` (new position, its links replaced)
and ``interference`` (channels capped at a reception ratio: it changes no route here; a TSCH
network, :mod:`gateway.tsch.network`, applies it to its channels).
After each event the routes are recomputed (:meth:`Topology.apply`).

Alternatives (:class:`Alternatives`): the first proposal is the routes by the configured metric.
After a rejection naming some paths, each of them moves to the route of least expected
transmissions per delivered packet (energy) among its ``k`` shortest routes by mean delay (Yen's
algorithm) whose mean delay is strictly lower than its current one: fewer or faster hops,
usually at higher energy.
When none of the rejected paths can improve, there is no alternative left.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, model_validator
from scipy.sparse.csgraph import csgraph_from_dense, dijkstra

from gateway.delay_models import ConstantDelay, DelayModel, TDMADelay, expected_attempts
from gateway.paths import Hop, Route

__all__ = [
    "NodeKind",
    "Metric",
    "NodeSpec",
    "LinkSpec",
    "PathSpec",
    "TopologyConfig",
    "NodeDown",
    "NodeUp",
    "LinkDegraded",
    "DelayModelChanged",
    "RelayAdded",
    "NodeMoved",
    "Interference",
    "TopologyEvent",
    "Reconfiguration",
    "parse_event",
    "Topology",
    "Alternatives",
]

_FROZEN = ConfigDict(frozen=True, extra="forbid")

NodeKind = Literal["sensor", "actuator", "relay", "gateway"]
Metric = Literal["hops", "etx", "etx_limited", "delay"]

HOP_TIE_BREAK = 1e-6
"""Weight of ETX in the hop-count metric (breaks ties between routes of equal hop count)."""


class NodeSpec(BaseModel):
    """A node of the WSN."""

    model_config = _FROZEN

    kind: NodeKind
    position: tuple[float, float] | None = Field(default=None, description="(x, y), metres")
    up: bool = True


class LinkSpec(BaseModel):
    """An undirected radio link between nodes ``a`` and ``b``."""

    model_config = _FROZEN

    a: str
    b: str
    prr: float = Field(gt=0, le=1, description="packet reception ratio of one attempt")
    delay: DelayModel | None = Field(default=None, description="per-hop model; default: network")
    retry_limit: int | None = Field(default=None, ge=0, description="default: network's")
    slot: int | None = Field(default=None, ge=0, description="TDMA slot index; default: assigned")

    @property
    def key(self) -> tuple[str, str]:
        return _key(self.a, self.b)


class PathSpec(BaseModel):
    """A named path: packets from ``src`` to ``dst``."""

    model_config = _FROZEN

    src: str
    dst: str


def _key(a: str, b: str) -> tuple[str, str]:
    return (a, b) if a <= b else (b, a)


def _check_links(
    links: Iterable[LinkSpec],
    nodes: Mapping[str, NodeSpec],
    default_delay: DelayModel,
    where: str,
    existing: Iterable[tuple[str, str]] = (),
) -> None:
    seen = set(existing)
    for i, link in enumerate(links):
        at = f"{where}[{i}]"
        for end in ("a", "b"):
            name = getattr(link, end)
            if name not in nodes:
                raise ValueError(f"{at}.{end}: unknown node {name!r} (nodes: {sorted(nodes)})")
        if link.a == link.b:
            raise ValueError(f"{at}: a link joins two different nodes, got {link.a!r} twice")
        if link.key in seen:
            raise ValueError(f"{at}: duplicate link {link.a!r}-{link.b!r}")
        seen.add(link.key)
        model = link.delay if link.delay is not None else default_delay
        if isinstance(model, TDMADelay) and link.slot is not None:
            if link.slot >= model.frame_slots:
                raise ValueError(
                    f"{at}.slot: must be < frame_slots ({model.frame_slots}), got {link.slot}"
                )


class TopologyConfig(BaseModel):
    """A WSN configuration: nodes, links, per-hop defaults, routing metric and named paths."""

    model_config = _FROZEN

    nodes: dict[str, NodeSpec]
    links: list[LinkSpec] = []
    delay: DelayModel = Field(
        default=ConstantDelay(delay=0.01), description="per-hop delay model of links without one"
    )
    retry_limit: int = Field(default=3, ge=0, description="retries per hop (r + 1 attempts)")
    metric: Literal["hops", "etx", "etx_limited"] = "hops"
    paths: dict[str, PathSpec] = {}

    @model_validator(mode="after")
    def _check(self) -> TopologyConfig:
        if not any(n.kind == "gateway" for n in self.nodes.values()):
            raise ValueError("nodes: at least one node of kind 'gateway' is needed")
        _check_links(self.links, self.nodes, self.delay, "links")
        for name, p in self.paths.items():
            for end in ("src", "dst"):
                node = getattr(p, end)
                if node not in self.nodes:
                    raise ValueError(f"paths.{name}.{end}: unknown node {node!r}")
            if p.src == p.dst:
                raise ValueError(f"paths.{name}: src and dst are the same node {p.src!r}")
        return self


# ----------------------------------------------------------------------------- events


class NodeDown(BaseModel):
    """A node fails or is switched off: its links carry nothing."""

    model_config = _FROZEN
    type: Literal["node_down"] = "node_down"
    node: str


class NodeUp(BaseModel):
    """A node comes back with its links."""

    model_config = _FROZEN
    type: Literal["node_up"] = "node_up"
    node: str


class LinkDegraded(BaseModel):
    """A link's packet reception ratio changes (degraded, or recovered)."""

    model_config = _FROZEN
    type: Literal["link_degraded"] = "link_degraded"
    a: str
    b: str
    prr: float = Field(gt=0, le=1)


class DelayModelChanged(BaseModel):
    """A new per-hop delay model: for one link, or (``link`` omitted) for the whole network.

    The network-wide form replaces the default and drops every per-link model.
    """

    model_config = _FROZEN
    type: Literal["delay_model_changed"] = "delay_model_changed"
    delay: DelayModel
    link: tuple[str, str] | None = None


class RelayAdded(BaseModel):
    """A new relay with its links (each must have the relay as one end)."""

    model_config = _FROZEN
    type: Literal["relay_added"] = "relay_added"
    node: str
    position: tuple[float, float] | None = None
    links: list[LinkSpec]


class NodeMoved(BaseModel):
    """A node moves: new position, and its links are replaced by ``links``."""

    model_config = _FROZEN
    type: Literal["node_moved"] = "node_moved"
    node: str
    position: tuple[float, float] | None = None
    links: list[LinkSpec]


class Interference(BaseModel):
    """Interference on some channels (a TSCH network only, ``mac: tsch``): their reception
    ratio is capped at ``prr`` for ``duration`` time units (``None``: to the end of the run),
    on every link or only on links into ``receivers``. Routes do not change."""

    model_config = _FROZEN
    type: Literal["interference"] = "interference"
    channels: tuple[int, ...] = Field(min_length=1, description="IEEE 802.15.4 channels hit")
    prr: float = Field(ge=0, le=1, description="reception ratio left on those channels")
    duration: float | None = Field(default=None, gt=0, description="time units; None: to the end")
    receivers: tuple[str, ...] | None = Field(default=None, description="None: every link")

    @model_validator(mode="after")
    def _band(self) -> Interference:
        for i, ch in enumerate(self.channels):
            if not 11 <= ch <= 26:
                raise ValueError(f"channels[{i}]: {ch} is not an IEEE 802.15.4 channel (11..26)")
        return self


TopologyEvent = Annotated[
    NodeDown | NodeUp | LinkDegraded | DelayModelChanged | RelayAdded | NodeMoved | Interference,
    Field(discriminator="type"),
]
"""A reconfiguration event, chosen by its ``type`` field."""


_EVENT = TypeAdapter(TopologyEvent)


def parse_event(data: Mapping[str, Any]) -> TopologyEvent:
    """Validate a plain mapping (e.g. an ``events/...`` message body) into an event."""
    return _EVENT.validate_python(data)


@dataclass(frozen=True)
class Reconfiguration:
    """Routes after an event: all of them, those that changed, and the paths that are down."""

    routes: dict[str, Route | None]
    changed: tuple[str, ...]
    down: tuple[str, ...]


# ----------------------------------------------------------------------------- topology


class Topology:
    """The WSN as it is now: mutable by events, routes recomputed after each change.

    Parameters
    ----------
    config : TopologyConfig
        Initial configuration (validated).
    """

    def __init__(self, config: TopologyConfig) -> None:
        self._nodes: dict[str, NodeSpec] = dict(config.nodes)
        self._links: dict[tuple[str, str], LinkSpec] = {}
        self._slots: dict[tuple[str, str], int] = {}  # assigned to links without a slot
        self._delay: DelayModel = config.delay
        self._retry_limit = config.retry_limit
        self._metric: Literal["hops", "etx", "etx_limited"] = config.metric
        self._paths: dict[str, PathSpec] = dict(config.paths)
        self.version = 0
        for link in config.links:
            self._add_link(link)
        self._routes: dict[str, Route | None] | None = None

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Topology:
        """Build from a plain mapping (e.g. a YAML section), validating it."""
        return cls(TopologyConfig.model_validate(data))

    # --------------------------------------------------------------- state

    @property
    def config(self) -> TopologyConfig:
        """The current configuration (with up/down states; assigned slots stay implicit)."""
        return TopologyConfig(
            nodes=dict(self._nodes),
            links=list(self._links.values()),
            delay=self._delay,
            retry_limit=self._retry_limit,
            metric=self._metric,
            paths=dict(self._paths),
        )

    @property
    def metric(self) -> Literal["hops", "etx", "etx_limited"]:
        """Routing metric of :meth:`routes` (setting it recomputes the routes)."""
        return self._metric

    @metric.setter
    def metric(self, value: Literal["hops", "etx", "etx_limited"]) -> None:
        if value not in ("hops", "etx", "etx_limited"):
            raise ValueError(f"metric: must be hops, etx or etx_limited, got {value!r}")
        self._metric = value
        self._routes = None

    @property
    def nodes(self) -> dict[str, NodeSpec]:
        return dict(self._nodes)

    @property
    def links(self) -> list[LinkSpec]:
        return list(self._links.values())

    @property
    def paths(self) -> dict[str, PathSpec]:
        return dict(self._paths)

    def is_up(self, node: str) -> bool:
        return self._node(node, "node").up

    def link(self, a: str, b: str) -> LinkSpec:
        """The link between ``a`` and ``b``; ``ValueError`` if there is none."""
        try:
            return self._links[_key(a, b)]
        except KeyError:
            raise ValueError(f"link: no link between {a!r} and {b!r}") from None

    def hop(self, src: str, dst: str) -> Hop:
        """The effective parameters of the link ``src -> dst`` (defaults applied)."""
        link = self.link(src, dst)
        model = link.delay if link.delay is not None else self._delay
        slot = link.slot if link.slot is not None else self._slots[link.key]
        if isinstance(model, TDMADelay):
            slot %= model.frame_slots
        r = link.retry_limit if link.retry_limit is not None else self._retry_limit
        return Hop(src, dst, link.prr, model, r, slot)

    def add_path(self, name: str, src: str, dst: str) -> None:
        """Register (or replace) a named path; its route is computed with the others."""
        self._node(src, f"paths.{name}.src")
        self._node(dst, f"paths.{name}.dst")
        if src == dst:
            raise ValueError(f"paths.{name}: src and dst are the same node {src!r}")
        self._paths[name] = PathSpec(src=src, dst=dst)
        self._routes = None

    # --------------------------------------------------------------- routing

    def _weight(self, hop: Hop, metric: Metric) -> float:
        if metric == "hops":
            return 1.0 + HOP_TIE_BREAK / hop.prr
        if metric == "etx":
            return 1.0 / hop.prr
        if metric == "etx_limited":
            return expected_attempts(hop.prr, hop.retry_limit)
        if metric == "delay":
            return hop.mean_delay
        raise ValueError(f"metric: unknown {metric!r}")

    def _matrix(self, metric: Metric) -> tuple[list[str], np.ndarray]:
        names = sorted(self._nodes)
        index = {n: i for i, n in enumerate(names)}
        w = np.full((len(names), len(names)), np.inf)
        for (a, b), _link in self._links.items():
            if self._nodes[a].up and self._nodes[b].up:
                w[index[a], index[b]] = self._weight(self.hop(a, b), metric)
                w[index[b], index[a]] = self._weight(self.hop(b, a), metric)
        return names, w

    def _route_from(self, names: list[str], nodes: list[int]) -> Route:
        return Route(tuple(self.hop(names[i], names[j]) for i, j in itertools.pairwise(nodes)))

    @staticmethod
    def _dijkstra(w: np.ndarray, s: int, d: int) -> tuple[float, list[int]] | None:
        graph = csgraph_from_dense(w, null_value=np.inf)
        dist, pred = dijkstra(graph, directed=True, indices=s, return_predecessors=True)
        if not np.isfinite(dist[d]):
            return None
        nodes = [d]
        while nodes[-1] != s:
            nodes.append(int(pred[nodes[-1]]))
        return float(dist[d]), nodes[::-1]

    def route(self, src: str, dst: str, metric: Metric | None = None) -> Route | None:
        """Shortest route from ``src`` to ``dst`` over nodes that are up, or ``None``."""
        self._node(src, "src")
        self._node(dst, "dst")
        if src == dst:
            raise ValueError(f"dst: same node as src ({src!r})")
        if not (self._nodes[src].up and self._nodes[dst].up):
            return None
        names, w = self._matrix(metric or self.metric)
        found = self._dijkstra(w, names.index(src), names.index(dst))
        return None if found is None else self._route_from(names, found[1])

    def k_shortest(self, src: str, dst: str, k: int, metric: Metric = "delay") -> list[Route]:
        """Up to ``k`` loop-free routes from ``src`` to ``dst`` in order of cost (Yen, 1971)."""
        if k < 1:
            raise ValueError(f"k: must be >= 1, got {k}")
        self._node(src, "src")
        self._node(dst, "dst")
        if not (self._nodes[src].up and self._nodes[dst].up) or src == dst:
            return []
        names, w = self._matrix(metric)
        s, d = names.index(src), names.index(dst)
        first = self._dijkstra(w, s, d)
        if first is None:
            return []
        found: list[tuple[float, list[int]]] = [first]
        candidates: list[tuple[float, list[int]]] = []

        def cost(p: list[int]) -> float:
            return float(sum(w[i, j] for i, j in itertools.pairwise(p)))

        while len(found) < k:
            last = found[-1][1]
            for i in range(len(last) - 1):
                root = last[: i + 1]
                wi = w.copy()
                for _, p in found:
                    if p[: i + 1] == root:
                        wi[p[i], p[i + 1]] = np.inf
                for n in root[:-1]:
                    wi[n, :] = np.inf
                    wi[:, n] = np.inf
                spur = self._dijkstra(wi, root[-1], d)
                if spur is None:
                    continue
                path = root[:-1] + spur[1]
                if all(path != p for _, p in found) and all(path != p for _, p in candidates):
                    candidates.append((cost(path), path))
            if not candidates:
                break
            candidates.sort(key=lambda c: (c[0], len(c[1]), [names[n] for n in c[1]]))
            found.append(candidates.pop(0))
        return [self._route_from(names, p) for _, p in found]

    def routes(self) -> dict[str, Route | None]:
        """Route of every named path by the configured metric (``None``: the path is down)."""
        if self._routes is None:
            self._routes = {
                name: self.route(p.src, p.dst) for name, p in sorted(self._paths.items())
            }
        return dict(self._routes)

    def alternatives(self, k: int = 8) -> Alternatives:
        """Proposals for the current state: first the routes, then alternatives on rejection."""
        return Alternatives(self, k)

    # --------------------------------------------------------------- events

    def apply(self, event: TopologyEvent | Mapping[str, Any]) -> Reconfiguration:
        """Apply a reconfiguration event (a model or a mapping) and recompute the routes.

        Raises
        ------
        ValueError
            If the event names an unknown node or link, or its links are invalid; the topology
            is then unchanged.
        """
        if isinstance(event, Mapping):
            event = parse_event(event)
        before = self.routes()
        if isinstance(event, NodeDown | NodeUp):
            spec = self._node(event.node, "node")
            self._nodes[event.node] = spec.model_copy(update={"up": isinstance(event, NodeUp)})
        elif isinstance(event, LinkDegraded):
            link = self.link(event.a, event.b)
            self._links[link.key] = link.model_copy(update={"prr": event.prr})
        elif isinstance(event, DelayModelChanged):
            self._change_delay(event)
        elif isinstance(event, RelayAdded):
            if event.node in self._nodes:
                raise ValueError(f"node: {event.node!r} exists already")
            nodes = dict(self._nodes)
            nodes[event.node] = NodeSpec(kind="relay", position=event.position)
            self._check_own_links(event.node, event.links, nodes, self._links)
            self._nodes = nodes
            for link in event.links:
                self._add_link(link)
        elif isinstance(event, Interference):
            for node in event.receivers or ():
                self._node(node, "receivers")
        elif isinstance(event, NodeMoved):
            spec = self._node(event.node, "node")
            others = {k: v for k, v in self._links.items() if event.node not in k}
            self._check_own_links(event.node, event.links, self._nodes, others)
            self._nodes[event.node] = spec.model_copy(update={"position": event.position})
            self._links = others
            self._slots = {k: v for k, v in self._slots.items() if k in others}
            for link in event.links:
                self._add_link(link)
        else:  # pragma: no cover - the union is closed
            raise TypeError(f"unknown event {event!r}")
        self.version += 1
        self._routes = None
        after = self.routes()
        changed = tuple(n for n in after if after[n] != before.get(n))
        down = tuple(n for n, r in after.items() if r is None)
        return Reconfiguration(after, changed, down)

    def _change_delay(self, event: DelayModelChanged) -> None:
        if event.link is None:
            links = [ln.model_copy(update={"delay": None}) for ln in self._links.values()]
            _check_links(links, self._nodes, event.delay, "links")
            self._delay = event.delay
            self._links = {ln.key: ln for ln in links}
        else:
            link = self.link(*event.link)
            new = link.model_copy(update={"delay": event.delay})
            _check_links([new], self._nodes, self._delay, f"link({link.a}, {link.b})")
            self._links[link.key] = new

    def _check_own_links(
        self,
        node: str,
        links: list[LinkSpec],
        nodes: Mapping[str, NodeSpec],
        existing: Mapping[tuple[str, str], LinkSpec],
    ) -> None:
        _check_links(links, nodes, self._delay, "links", existing)
        for i, link in enumerate(links):
            if node not in (link.a, link.b):
                raise ValueError(f"links[{i}]: must have {node!r} as one end")

    def _slot(self, key: tuple[str, str]) -> int:
        link = self._links[key]
        return link.slot if link.slot is not None else self._slots[key]

    def _add_link(self, link: LinkSpec) -> None:
        if link.slot is None:
            used = {self._slot(k) for k in self._links if link.a in k or link.b in k}
            self._slots[link.key] = next(s for s in range(len(used) + 1) if s not in used)
        self._links[link.key] = link

    def _node(self, name: str, field: str) -> NodeSpec:
        try:
            return self._nodes[name]
        except KeyError:
            raise ValueError(f"{field}: unknown node {name!r}") from None


class Alternatives:
    """Successive configurations a gateway proposes until one is accepted or none is left.

    Parameters
    ----------
    topology : Topology
        The network as it is now (the candidates are computed once, at construction).
    k : int
        Candidate routes per path: the ``k`` shortest by mean delay (plus the default route).
    """

    def __init__(self, topology: Topology, k: int = 8) -> None:
        self.current: dict[str, Route | None] = topology.routes()
        self.count = 1
        self.exhausted = False
        self.stuck: tuple[str, ...] = ()
        self._candidates: dict[str, list[Route]] = {}
        for name, p in topology.paths.items():
            cands = topology.k_shortest(p.src, p.dst, k, "delay")
            default = self.current[name]
            if default is not None and default not in cands:
                cands.append(default)
            self._candidates[name] = cands

    def next(self, rejected: Iterable[str] | None = None) -> dict[str, Route | None] | None:
        """The next configuration after the current one was rejected because of ``rejected``.

        Parameters
        ----------
        rejected : iterable of str, optional
            Paths whose delay was too large (default: every path).

        Returns
        -------
        dict or None
            Routes of every path (the others unchanged); ``None`` when no rejected path can get
            a lower mean delay: no alternative is left. Rejected paths that could not improve
            while others did are listed in :attr:`stuck`.
        """
        names = sorted(self.current) if rejected is None else sorted(set(rejected))
        for n in names:
            if n not in self.current:
                raise ValueError(f"rejected: unknown path {n!r}")
        new = dict(self.current)
        stuck = []
        for n in names:
            cur = self.current[n]
            if cur is None:
                stuck.append(n)
                continue
            limit = cur.mean_delay * (1.0 - 1e-12)
            better = [c for c in self._candidates[n] if c.mean_delay < limit]
            if not better:
                stuck.append(n)
                continue
            new[n] = min(
                better,
                key=lambda c: (c.transmissions_per_delivery, c.mean_delay, c.n_hops, c.nodes),
            )
        self.stuck = tuple(stuck)
        if len(stuck) == len(names):
            self.exhausted = True
            return None
        self.current = new
        self.count += 1
        return dict(new)
