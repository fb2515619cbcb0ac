"""Node energy: charge per transmission, reception and idle listening; battery and lifetime.

Seed 000, sections I-II: the data rate of each sensor should be as low as control allows so the
nodes' batteries last; relays pay for the traffic they forward. DESIGN.md, section 5: battery
state and projected lifetime are published in ``net/stats``.

Charge model (per radio attempt on a hop, see :mod:`gateway.delay_models` for attempts)::

    T_frame = (frame_bytes + phy_bytes) * 8 / bitrate          air time of a data frame
    T_ack   = (ack_bytes + phy_bytes) * 8 / bitrate            air time of an acknowledgement
    sender,   every attempt:      q_tx  = I_tx T_frame + I_rx (T_listen + T_ack)
    receiver, every attempt:      q_rx  = I_rx T_frame
    receiver, successful attempt: q_ack = I_tx T_ack
    idle listening (duty-cycled): I_idle = d I_rx + (1 - d) I_sleep, all the time

``T_listen`` is the sender's clear-channel assessment plus the RX/TX turnaround before the
acknowledgement. A relay receives (``q_rx``, ``q_ack``) from the previous hop and sends (``q_tx``)
to the next, retries included. Charges in mAh (mA x s / 3600). Nodes of the kinds in
``mains_powered`` (default: the gateway) are counted but have no battery limit.

Defaults: an IEEE 802.15.4 mote (TelosB / Tmote Sky, CC2420 radio, 2.4 GHz)

* ``i_tx_mA = 19.5`` (MCU on, radio TX at 0 dBm), ``i_rx_mA = 21.8`` (MCU on, radio RX),
  ``i_sleep_mA = 0.0051`` (MCU standby, radio off): Moteiv, *Tmote Sky datasheet* (2006),
  "Operating conditions", typical values; the CC2420 alone draws 17.4 mA TX / 18.8 mA RX
  (Texas Instruments/Chipcon, *CC2420 datasheet*, rev. 1.4, table 3).
* ``bitrate_bps = 250_000``, ``phy_bytes = 6`` (4-byte preamble, SFD, length), ``ack_bytes = 5``
  (acknowledgement MPDU), turnaround 12 symbols = 192 us and CCA 8 symbols = 128 us, so
  ``listen_s = 320e-6``: IEEE Std 802.15.4-2006, sections 6.3, 6.4.1, 7.2.2.3.
* ``frame_bytes = 50``: a sensor sample with MAC header and a short application payload (ours).
* ``listen_duty_cycle = 0.01``: low-power listening at 1 % (ours; typical of LPL/BoX-MAC).
* ``battery_mAh = 2500``: two AA alkaline cells in series (the TelosB pack; Energizer E91
  datasheet, about 2500 mAh at 25 mA to 0.8 V per cell).

With these, per attempt: ``q_tx = 19.5 mA x 1.792 ms + 21.8 mA x 0.672 ms = 49.59 mA ms``
(13.78 nAh), ``q_rx = 21.8 mA x 1.792 ms = 39.07 mA ms`` (10.85 nAh), ``q_ack = 19.5 mA x
0.352 ms = 6.86 mA ms`` (1.91 nAh); ``I_idle = 0.223 mA``. Not modelled: the long preambles of
low-power listening, overhearing by neighbours, and control traffic (routing beacons, probes).

Time: scenario time units are converted to seconds with ``seconds_per_unit``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from pydantic import BaseModel, ConfigDict, Field

from core.time import to_units
from gateway.paths import Delivery, Route
from gateway.topology import NodeKind, Topology

__all__ = [
    "EnergyConfig",
    "NodeCharge",
    "NodeEnergy",
    "EnergyMeter",
    "traffic_per_second",
    "projected_lifetime",
]

SECONDS_PER_HOUR = 3600.0


class EnergyConfig(BaseModel):
    """Radio currents, frame sizes, battery capacity and the length of a time unit."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    i_tx_mA: float = Field(default=19.5, ge=0, description="current while transmitting")
    i_rx_mA: float = Field(default=21.8, ge=0, description="current while receiving/listening")
    i_sleep_mA: float = Field(default=0.0051, ge=0, description="current asleep")
    listen_duty_cycle: float = Field(
        default=0.01, ge=0, le=1, description="fraction of idle time the radio listens"
    )
    bitrate_bps: float = Field(default=250_000.0, gt=0)
    frame_bytes: int = Field(default=50, ge=1, description="data frame MPDU")
    ack_bytes: int = Field(default=5, ge=0, description="acknowledgement MPDU (0: no ACKs)")
    phy_bytes: int = Field(default=6, ge=0, description="PHY preamble, SFD and length")
    listen_s: float = Field(default=320e-6, ge=0, description="CCA + turnaround, per attempt")
    battery_mAh: float = Field(default=2500.0, gt=0, description="capacity of a full battery")
    batteries: dict[str, float] = Field(default={}, description="per-node capacity overrides, mAh")
    mains_powered: tuple[NodeKind, ...] = ("gateway",)
    seconds_per_unit: float = Field(default=1.0, gt=0, description="seconds per time unit")

    @property
    def t_frame_s(self) -> float:
        return (self.frame_bytes + self.phy_bytes) * 8.0 / self.bitrate_bps

    @property
    def t_ack_s(self) -> float:
        return (
            0.0
            if self.ack_bytes == 0
            else (self.ack_bytes + self.phy_bytes) * 8.0 / self.bitrate_bps
        )

    @property
    def q_tx_mAh(self) -> float:
        """Sender's charge per attempt: frame out, then listening for the acknowledgement."""
        return (
            self.i_tx_mA * self.t_frame_s + self.i_rx_mA * (self.listen_s + self.t_ack_s)
        ) / SECONDS_PER_HOUR

    @property
    def q_rx_mAh(self) -> float:
        """Receiver's charge per attempt (the frame is received, decoded or not)."""
        return self.i_rx_mA * self.t_frame_s / SECONDS_PER_HOUR

    @property
    def q_ack_mAh(self) -> float:
        """Receiver's charge per successful attempt (sending the acknowledgement)."""
        return self.i_tx_mA * self.t_ack_s / SECONDS_PER_HOUR

    @property
    def i_idle_mA(self) -> float:
        """Average idle-listening current of a duty-cycled radio."""
        d = self.listen_duty_cycle
        return d * self.i_rx_mA + (1.0 - d) * self.i_sleep_mA

    def capacity(self, node: str) -> float:
        """Battery capacity of ``node``, mAh."""
        return self.batteries.get(node, self.battery_mAh)


@dataclass
class NodeCharge:
    """Charge counted for one node, mAh, and its radio activity."""

    tx_mAh: float = 0.0
    rx_mAh: float = 0.0
    idle_mAh: float = 0.0
    tx_attempts: int = 0
    rx_attempts: int = 0
    acks: int = 0

    @property
    def total_mAh(self) -> float:
        return self.tx_mAh + self.rx_mAh + self.idle_mAh


@dataclass(frozen=True)
class NodeEnergy:
    """Analytic energy figures of one node at the current routes and sampling periods."""

    node: str
    tx_mA: float
    rx_mA: float
    idle_mA: float
    capacity_mAh: float
    remaining_mAh: float
    mains_powered: bool

    @property
    def current_mA(self) -> float:
        """Average current drawn."""
        return self.tx_mA + self.rx_mA + self.idle_mA

    @property
    def lifetime_s(self) -> float:
        """Seconds until the remaining charge is spent at :attr:`current_mA` (inf if mains)."""
        if self.mains_powered or self.current_mA == 0.0:
            return math.inf
        return self.remaining_mAh / self.current_mA * SECONDS_PER_HOUR

    @property
    def lifetime_days(self) -> float:
        return self.lifetime_s / 86_400.0


@dataclass
class EnergyMeter:
    """Counts the charge each node spends on the packets carried and on idle listening.

    Parameters
    ----------
    config : EnergyConfig
        Charges and capacities.
    topology : Topology
        Node kinds (mains-powered or not) and up/down states for idle listening.
    t0 : int
        Start of the idle-listening account, ticks.
    """

    config: EnergyConfig
    topology: Topology
    t0: int = 0
    charges: dict[str, NodeCharge] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._t = int(self.t0)

    def _of(self, node: str) -> NodeCharge:
        return self.charges.setdefault(node, NodeCharge())

    def record(self, route: Route, delivery: Delivery) -> None:
        """Charge the senders and receivers of every attempt of one packet on ``route``."""
        c = self.config
        for i, a in enumerate(delivery.attempts):
            hop = route.hops[i]
            ok = delivery.t_deliver is not None or i < len(delivery.attempts) - 1
            s, r = self._of(hop.src), self._of(hop.dst)
            s.tx_mAh += a * c.q_tx_mAh
            s.tx_attempts += a
            r.rx_mAh += a * c.q_rx_mAh + (c.q_ack_mAh if ok else 0.0)
            r.rx_attempts += a
            r.acks += int(ok)

    def advance(self, t: int) -> None:
        """Charge idle listening from the last time to ``t`` (ticks) to every node that is up."""
        if t < self._t:
            raise ValueError(f"advance: time went backwards ({self._t} -> {t})")
        seconds = to_units(t - self._t) * self.config.seconds_per_unit
        q = self.config.i_idle_mA * seconds / SECONDS_PER_HOUR
        for name, spec in self.topology.nodes.items():
            if spec.up:
                self._of(name).idle_mAh += q
        self._t = t

    def charge(self, node: str) -> NodeCharge:
        """Charge counted for ``node`` so far."""
        return self.charges.get(node, NodeCharge())

    def _mains(self, node: str) -> bool:
        spec = self.topology.nodes.get(node)
        return spec is not None and spec.kind in self.config.mains_powered

    def remaining_mAh(self, node: str) -> float:
        """Charge left in ``node``'s battery (capacity for mains-powered nodes)."""
        cap = self.config.capacity(node)
        if self._mains(node):
            return cap
        return max(cap - self.charge(node).total_mAh, 0.0)

    def battery_pct(self, node: str) -> float:
        """Battery state of ``node``, percent of its capacity."""
        return 100.0 * self.remaining_mAh(node) / self.config.capacity(node)

    def depleted(self) -> list[str]:
        """Battery-powered nodes whose battery is empty (candidates for a ``node_down`` event)."""
        return [
            n
            for n in sorted(self.topology.nodes)
            if not self._mains(n) and self.remaining_mAh(n) <= 0
        ]


def traffic_per_second(
    routes: Mapping[str, Route | None],
    periods: Mapping[str, float],
    seconds_per_unit: float = 1.0,
) -> dict[str, tuple[float, float, float]]:
    """Expected radio activity per second of every node carrying traffic.

    Parameters
    ----------
    routes : mapping of str to Route or None
        Route of each path (``None``: down, carries nothing).
    periods : mapping of str to float
        Packet period of each path in time units (a sensor's sampling period ``tau_s``);
        paths without a period carry nothing.
    seconds_per_unit : float
        Length of a time unit in seconds.

    Returns
    -------
    dict
        ``node -> (tx attempts/s, rx attempts/s, acks sent/s)``. A hop is attempted only by
        packets that survived the hops before it: ``reach_i * E[attempts_i]`` per packet.
    """
    out: dict[str, list[float]] = {}
    for name, route in routes.items():
        if route is None or name not in periods:
            continue
        if not periods[name] > 0:
            raise ValueError(f"periods.{name}: must be > 0, got {periods[name]}")
        rate = 1.0 / (periods[name] * seconds_per_unit)
        reach = 1.0
        for hop in route.hops:
            tries = rate * reach * hop.expected_attempts
            out.setdefault(hop.src, [0.0, 0.0, 0.0])[0] += tries
            rx = out.setdefault(hop.dst, [0.0, 0.0, 0.0])
            rx[1] += tries
            reach *= hop.success_probability
            rx[2] += rate * reach
    return {n: (v[0], v[1], v[2]) for n, v in sorted(out.items())}


def projected_lifetime(
    topology: Topology,
    routes: Mapping[str, Route | None],
    periods: Mapping[str, float],
    config: EnergyConfig,
    meter: EnergyMeter | None = None,
) -> dict[str, NodeEnergy]:
    """Average currents and projected lifetime of every node at the given sampling periods.

    Analytic: per-second attempt rates from :func:`traffic_per_second` times the per-attempt
    charges, plus idle listening for nodes that are up. The lifetime is counted from the charge
    ``meter`` says is left (a full battery without a meter).
    """
    rates = traffic_per_second(routes, periods, config.seconds_per_unit)
    out = {}
    for name, spec in sorted(topology.nodes.items()):
        tx, rx, acks = rates.get(name, (0.0, 0.0, 0.0))
        cap = config.capacity(name)
        out[name] = NodeEnergy(
            node=name,
            tx_mA=tx * config.q_tx_mAh * SECONDS_PER_HOUR,
            rx_mA=(rx * config.q_rx_mAh + acks * config.q_ack_mAh) * SECONDS_PER_HOUR,
            idle_mA=config.i_idle_mA if spec.up else 0.0,
            capacity_mAh=cap,
            remaining_mAh=cap if meter is None else meter.remaining_mAh(name),
            mains_powered=spec.kind in config.mains_powered,
        )
    return out
