"""Link quality of a TSCH network: per directed pair and channel, the PDR of one data frame.

The MAC simulator asks :meth:`LinkQuality.pdr` ``(a, b, channel, t)``, the probability that one
data frame sent by ``a`` on IEEE 802.15.4 2.4 GHz channel ``channel`` (11..26) at ``t`` seconds
since the start is received by ``b``. Two sources, and a layer on top of either:

* :class:`PositionLinks` (``link_model: pathloss``): from node positions, log-distance path loss
  with log-normal shadowing, RSSI mapped to PDR by ``oqpsk`` or ``pister_hack``;
* :class:`TraceLinks` (``link_model: trace``): from a k7 link trace (:mod:`gateway.tsch.k7`);
* :class:`WithInterference`: interference bursts degrading given channels for a time window.

:func:`table` gives the whole matrix at one time (for a scheduler, for display).

Path loss (log-distance with log-normal shadowing; T. S. Rappaport, *Wireless Communications:
Principles and Practice*, 2nd ed., 2002, sections 4.9.1 and 4.9.2)::

    RSSI_dBm = P_tx_dBm - PL(d0) - 10 n log10(d / d0) - X,     X ~ N(0, sigma_dB)

* ``PL(d0) = 20 log10(4 pi d0 / lambda) = 40.2 dB`` at ``d0 = 1 m``: free-space (Friis) loss at
  2.44 GHz, the band centre (``lambda = c / f = 0.1229 m``). One value for all channels: the
  free-space loss varies by 0.3 dB across 2405-2480 MHz, negligible beside the shadowing.
* ``n = 3.0``: the upper end of "obstructed in factories: 2 to 3" in Rappaport, Table 4.2
  (path loss exponents for different environments); an indoor industrial plant with machinery.
* ``sigma = 4 dB``: log-normal shadowing, a moderate indoor value (ours, not fitted to a
  measurement; set it from a site survey when one exists).
* ``X`` is drawn once per **undirected** link and per channel (independent per channel: a crude
  frequency-selective fading; RSSI is reciprocal, a -> b equals b -> a) and is then constant.
* ``d < d0`` is clamped to ``d0`` (the model holds for ``d >= d0``); two nodes at the **same
  position** are refused (:class:`core.errors.ConfigError` naming the nodes): almost surely a
  configuration error, and ``log10(0)`` has no meaning.
* receiver sensitivity ``-97 dBm``: Texas Instruments, *CC2538 datasheet* (SWRS096),
  "Receiver sensitivity -97 dBm"; below it PDR = 0 whatever the mapping.
* transmit power 0 dBm, noise floor ``-100 dBm`` (ours: thermal noise over the 2 MHz channel is
  ``-174 dBm/Hz + 63 dB = -111 dBm``, so this assumes a receiver noise figure of 11 dB).

Random draws: the caller passes a seeded ``numpy.random.Generator``; :class:`PositionLinks`
draws exactly once, ``rng.normal(0, sigma, size=(L, C))``, whose row ``i`` is the ``i``-th
undirected link in sorted order (each link as the sorted pair of its node names, the links
sorted lexicographically) and column ``j`` the ``j``-th channel in increasing order (link-major:
all channels of the first link, then of the second, ...). It draws even when ``sigma = 0`` so
the generator is left in the same state. The result does not depend on the order of the
positions mapping or of ``pairs``.

RSSI -> PDR, by ``pdr_model``:

* ``oqpsk``: the IEEE 802.15.4 2.4 GHz O-QPSK bit error rate, IEEE Std 802.15.4-2006 Annex
  E.4.1.8 (the same in 802.15.4-2011 and -2015)::

      BER  = (8/15) (1/16) sum_{k=2}^{16} (-1)^k C(16, k) exp(20 SINR (1/k - 1))
      PDR  = (1 - BER)^(8 L)

  ``SINR`` linear: received signal power ``10^(RSSI/10)`` mW over noise (+ interference)
  power; RSSI is taken as the signal power alone (the path-loss model gives no noise part).
  ``L`` is the PSDU length in bytes (``frame_bytes``, at most 127). The 6-byte PHY header
  (4 preamble bytes, SFD, PHR) is **not** counted: preamble and SFD are for acquisition, which the
  sensitivity cut-off stands for; the 1-byte PHR would add 8 bits to 1016 (< 1 % on the
  exponent). At ``SINR = 0`` the sum is 15 and ``BER = 1/2``; ``BER`` falls monotonically with
  ``SINR``.
* ``pister_hack``: the RSSI -> PDR table of the 6TiSCH simulator's "Pister hack" model,
  ``PisterHackModel.RSSI_PDR_TABLE`` in ``SimEngine/Connectivity.py`` of
  https://github.com/6tisch/simulator (read in the forks atiselsts/6tisch-simulator and
  FlorentCollin/6tisch-simulator, identical in every version seen; measured on the Dust
  Networks dataset, http://wsn.eecs.berkeley.edu/connectivity/?dataset=dust)::

      RSSI dBm  -97     -96     -95     -94     -93     -92     -91     -90     -89     -88
      PDR       0.0000  0.1494  0.2340  0.4071  0.6359  0.6866  0.7476  0.8603  0.8702  0.9324
      RSSI dBm  -87     -86     -85     -84     -83     -82     -81     -80     -79
      PDR       0.9427  0.9562  0.9611  0.9739  0.9745  0.9844  0.9854  0.9903  1.0000

  (-97 and -79 are "not from experiment"), linearly interpolated between the integer points,
  0 below -97 dBm and 1 above -79 dBm (``PisterHackModel.convert_rssi_to_pdr``; at exactly
  -79 dBm it looks up the missing -78 entry, where we return 1 as ``Connectivity._rssi_to_pdr``
  does).

Interference (:class:`InterferenceBurst`): during ``[t_start, t_end)`` (start included, end
excluded), on its channels, the PDR of every link (or only of links into its ``receivers``)
becomes ``min(pdr, prr)``: ``prr`` is the reception ratio the interference leaves, a cap, not a
factor. Overlapping bursts: the smallest cap. RSSI is unchanged (it is the wanted signal's).
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Iterable, Mapping, Sequence
from typing import Literal, Protocol, Self, runtime_checkable

import numpy as np
import numpy.typing as npt
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from core.errors import ConfigError
from gateway.tsch.k7 import CHANNELS_24GHZ, K7Trace, LinkSeries

__all__ = [
    "PISTER_RSSI_PDR_TABLE",
    "PathLossConfig",
    "ber_oqpsk",
    "rssi_to_pdr_oqpsk",
    "rssi_to_pdr_pister",
    "LinkQuality",
    "PositionLinks",
    "TraceLinks",
    "InterferenceBurst",
    "WithInterference",
    "table",
]

# 6TiSCH simulator, SimEngine/Connectivity.py, PisterHackModel.RSSI_PDR_TABLE (dBm -> PDR)
PISTER_RSSI_PDR_TABLE: Mapping[int, float] = {
    -97: 0.0000,  # not from experiment
    -96: 0.1494,
    -95: 0.2340,
    -94: 0.4071,
    -93: 0.6359,
    -92: 0.6866,
    -91: 0.7476,
    -90: 0.8603,
    -89: 0.8702,
    -88: 0.9324,
    -87: 0.9427,
    -86: 0.9562,
    -85: 0.9611,
    -84: 0.9739,
    -83: 0.9745,
    -82: 0.9844,
    -81: 0.9854,
    -80: 0.9903,
    -79: 1.0000,  # not from experiment
}
_PISTER_X = np.array(sorted(PISTER_RSSI_PDR_TABLE), dtype=float)
_PISTER_Y = np.array([PISTER_RSSI_PDR_TABLE[int(x)] for x in _PISTER_X], dtype=float)

# IEEE 802.15.4-2006 Annex E.4.1.8: k = 2..16, (-1)^k C(16, k) and the exponent factor 20 (1/k - 1)
_K = np.arange(2, 17)
_OQPSK_COEF = np.array([(-1.0) ** k * math.comb(16, int(k)) for k in _K])
_OQPSK_EXPO = 20.0 * (1.0 / _K - 1.0)
_OQPSK_SCALE = (8.0 / 15.0) * (1.0 / 16.0)


class PathLossConfig(BaseModel):
    """Log-distance path loss, shadowing, radio and RSSI -> PDR mapping (see the module)."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    tx_power_dbm: float = Field(default=0.0, description="transmit power, dBm")
    d0_m: float = Field(default=1.0, gt=0, description="reference distance d0, metres")
    pl_d0_db: float = Field(
        default=40.2,
        ge=0,
        description="path loss at d0, dB (free space at 2.44 GHz and 1 m: 40.2)",
    )
    path_loss_exponent: float = Field(
        default=3.0, gt=0, description="path loss exponent n (Rappaport Table 4.2, factory: 2-3)"
    )
    sigma_db: float = Field(
        default=4.0, ge=0, description="standard deviation of the log-normal shadowing, dB"
    )
    noise_floor_dbm: float = Field(default=-100.0, description="receiver noise floor, dBm")
    sensitivity_dbm: float = Field(
        default=-97.0, description="receiver sensitivity, dBm (TI CC2538: -97); PDR 0 below"
    )
    frame_bytes: int = Field(
        default=127,
        ge=1,
        le=127,
        description="PSDU length in bytes the BER applies to (PHY header not counted)",
    )
    pdr_model: Literal["oqpsk", "pister_hack"] = Field(
        default="oqpsk",
        description="RSSI -> PDR: IEEE 802.15.4 O-QPSK BER, or the 6TiSCH Pister-hack table",
    )


# ------------------------------------------------------------------------------ RSSI -> PDR


def ber_oqpsk(sinr: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Bit error rate of IEEE 802.15.4 2.4 GHz O-QPSK (802.15.4-2006 Annex E.4.1.8).

    Parameters
    ----------
    sinr : array_like
        Signal to noise-plus-interference ratio, **linear** (not dB), ``>= 0``.

    Returns
    -------
    numpy.ndarray
        BER, same shape as ``sinr``, in ``[0, 0.5]`` (0.5 at ``sinr = 0``).

    Raises
    ------
    ValueError
        A negative or NaN ``sinr``.
    """
    s = np.asarray(sinr, dtype=float)
    if np.any(~(s >= 0)):
        raise ValueError("ber_oqpsk: the SINR is linear and must be >= 0")
    terms = _OQPSK_COEF * np.exp(np.multiply.outer(s, _OQPSK_EXPO))
    ber = _OQPSK_SCALE * terms.sum(axis=-1)
    return np.asarray(np.clip(ber, 0.0, 0.5), dtype=np.float64)


def rssi_to_pdr_oqpsk(
    rssi_dbm: npt.ArrayLike,
    noise_floor_dbm: float,
    frame_bytes: int,
    interference_dbm: npt.ArrayLike | None = None,
) -> npt.NDArray[np.float64]:
    """PDR of a ``frame_bytes`` PSDU from its RSSI, by the O-QPSK BER (no sensitivity cut).

    Parameters
    ----------
    rssi_dbm : array_like
        Received signal power, dBm.
    noise_floor_dbm : float
        Noise power, dBm.
    frame_bytes : int
        PSDU bytes the BER applies to (``PDR = (1 - BER)^(8 frame_bytes)``).
    interference_dbm : array_like, optional
        Total interference power, dBm, added to the noise (broadcast with ``rssi_dbm``).

    Returns
    -------
    numpy.ndarray
        PDR in [0, 1], shape of ``rssi_dbm`` (broadcast with ``interference_dbm``).
    """
    if frame_bytes < 1:
        raise ValueError(f"frame_bytes must be >= 1, got {frame_bytes}")
    rssi = np.asarray(rssi_dbm, dtype=float)
    noise_mw = 10.0 ** (noise_floor_dbm / 10.0)
    if interference_dbm is not None:
        noise_mw = noise_mw + 10.0 ** (np.asarray(interference_dbm, dtype=float) / 10.0)
    sinr = 10.0 ** (rssi / 10.0) / noise_mw
    ber = ber_oqpsk(sinr)
    return np.asarray(np.exp(8.0 * frame_bytes * np.log1p(-ber)), dtype=np.float64)


def rssi_to_pdr_pister(rssi_dbm: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """PDR from RSSI by the 6TiSCH Pister-hack table (:data:`PISTER_RSSI_PDR_TABLE`).

    Parameters
    ----------
    rssi_dbm : array_like
        RSSI, dBm.

    Returns
    -------
    numpy.ndarray
        PDR: linear interpolation between the table's integer-dBm points, 0 below -97 dBm, 1
        above -79 dBm.
    """
    rssi = np.asarray(rssi_dbm, dtype=float)
    return np.asarray(np.interp(rssi, _PISTER_X, _PISTER_Y, left=0.0, right=1.0), np.float64)


# ------------------------------------------------------------------------------- the protocol


@runtime_checkable
class LinkQuality(Protocol):
    """What the MAC simulator asks of a link model."""

    def pdr(self, a: str, b: str, channel: int, t: float) -> float:
        """Probability that one data frame ``a -> b`` on ``channel`` at ``t`` s is received."""
        ...

    def rssi(self, a: str, b: str, channel: int, t: float) -> float | None:
        """RSSI at ``b`` of ``a``'s frames on ``channel`` at ``t`` s, dBm (``None``: no link)."""
        ...


def _check_channels(channels: Iterable[int]) -> tuple[int, ...]:
    out = tuple(sorted(set(channels)))
    if not out:
        raise ConfigError("no channels given (IEEE 802.15.4 2.4 GHz: 11..26)")
    for ch in out:
        if isinstance(ch, bool) or not isinstance(ch, int | np.integer) or ch not in CHANNELS_24GHZ:
            raise ConfigError(f"channel {ch!r} is not an IEEE 802.15.4 2.4 GHz channel (11..26)")
    return tuple(int(ch) for ch in out)


# ------------------------------------------------------------------------------ from positions


class PositionLinks:
    """Link quality from node positions: log-distance path loss and log-normal shadowing.

    Everything is computed once in the constructor; :meth:`pdr` and :meth:`rssi` are dictionary
    look-ups and do not depend on ``t``.

    Parameters
    ----------
    positions : mapping
        Node name -> ``(x, y)`` in metres.
    channels : sequence of int
        The channels in use (11..26).
    config : PathLossConfig
        Path loss, radio and PDR mapping.
    rng : numpy.random.Generator
        Draws the shadowing once (order: see the module docstring).
    pairs : iterable of (str, str), optional
        The directed pairs that may communicate; ``None``: every ordered pair of distinct
        nodes. Other pairs have PDR 0 and no RSSI.

    Raises
    ------
    ConfigError
        Unknown node in ``pairs``, a pair of a node with itself, two nodes of a pair at the
        same position, a non-finite position, a channel outside 11..26.
    """

    def __init__(
        self,
        positions: Mapping[str, tuple[float, float]],
        channels: Sequence[int],
        config: PathLossConfig,
        rng: np.random.Generator,
        pairs: Iterable[tuple[str, str]] | None = None,
    ) -> None:
        self.config = config
        self.channels = _check_channels(channels)
        self._channel_set = frozenset(self.channels)
        pos: dict[str, tuple[float, float]] = {}
        for name, xy in positions.items():
            x, y = (float(v) for v in xy)
            if not (math.isfinite(x) and math.isfinite(y)):
                raise ConfigError(f"node {name!r}: position {xy!r} is not finite")
            pos[name] = (x, y)
        self.nodes = tuple(sorted(pos))
        if pairs is None:
            directed = [(a, b) for a in self.nodes for b in self.nodes if a != b]
        else:
            directed = sorted(set(pairs))
            for a, b in directed:
                for n in (a, b):
                    if n not in pos:
                        raise ConfigError(f"pair ({a!r}, {b!r}): unknown node {n!r}")
                if a == b:
                    raise ConfigError(f"pair ({a!r}, {b!r}): a node does not link to itself")
        self.pairs: tuple[tuple[str, str], ...] = tuple(directed)
        links = sorted({(a, b) if a < b else (b, a) for a, b in directed})
        self.links: tuple[tuple[str, str], ...] = tuple(links)

        dist = np.array([math.dist(pos[a], pos[b]) for a, b in links], dtype=float)
        for (a, b), d in zip(links, dist, strict=True):
            if d == 0.0:
                raise ConfigError(f"nodes {a!r} and {b!r} are at the same position {pos[a]}")
        self.distance_m = dict(zip(links, dist.tolist(), strict=True))
        c = config
        mean = (
            c.tx_power_dbm
            - c.pl_d0_db
            - 10.0 * c.path_loss_exponent * np.log10(np.maximum(dist, c.d0_m) / c.d0_m)
        )
        shadow = rng.normal(0.0, c.sigma_db, size=(len(links), len(self.channels)))
        rssi = mean[:, None] - shadow
        if c.pdr_model == "oqpsk":
            pdr = rssi_to_pdr_oqpsk(rssi, c.noise_floor_dbm, c.frame_bytes)
        else:
            pdr = rssi_to_pdr_pister(rssi)
        pdr = np.where(rssi < c.sensitivity_dbm, 0.0, pdr)

        self.mean_rssi_dbm = dict(zip(links, mean.tolist(), strict=True))
        row = {link: i for i, link in enumerate(links)}
        self._pdr: dict[tuple[str, str, int], float] = {}
        self._rssi: dict[tuple[str, str, int], float] = {}
        for a, b in directed:
            i = row[(a, b) if a < b else (b, a)]
            for j, ch in enumerate(self.channels):
                self._pdr[a, b, ch] = float(pdr[i, j])
                self._rssi[a, b, ch] = float(rssi[i, j])

    def pdr(self, a: str, b: str, channel: int, t: float = 0.0) -> float:
        """PDR of ``a -> b`` on ``channel`` (0 for a pair not modelled; ``t`` is unused).

        Raises
        ------
        ValueError
            ``channel`` is not one of :attr:`channels`.
        """
        p = self._pdr.get((a, b, channel))
        if p is None:
            self._require_channel(channel)
            return 0.0
        return p

    def rssi(self, a: str, b: str, channel: int, t: float = 0.0) -> float | None:
        """RSSI of ``a -> b`` on ``channel``, dBm (``None`` for a pair not modelled)."""
        r = self._rssi.get((a, b, channel))
        if r is None:
            self._require_channel(channel)
        return r

    def _require_channel(self, channel: int) -> None:
        if channel not in self._channel_set:
            raise ValueError(f"channel {channel} is not in use (channels: {self.channels})")


# ----------------------------------------------------------------------------------- from a trace


class TraceLinks:
    """Link quality replayed from a k7 trace (:func:`gateway.tsch.k7.read_k7`).

    Parameters
    ----------
    trace : K7Trace
        The parsed trace; ``t`` is seconds since its first row.
    node_map : mapping, optional
        Trace node id -> scenario node name. When given, only the mapped ids are kept, and
        :meth:`pdr` / :meth:`rssi` take scenario names; otherwise they take trace ids.

    Raises
    ------
    ConfigError
        ``node_map`` names an id absent from the trace, or maps two ids to one name.
    """

    def __init__(self, trace: K7Trace, node_map: Mapping[str, str] | None = None) -> None:
        self.trace = trace
        series: dict[tuple[str, str, int], LinkSeries] = {}
        if node_map is None:
            series.update(trace.series)
        else:
            known = set(trace.nodes)
            for tid in sorted(node_map):
                if tid not in known:
                    raise ConfigError(
                        f"{trace.source}: node_map: trace node id {tid!r} is not in the trace"
                    )
            names = list(node_map.values())
            if len(set(names)) != len(names):
                dup = sorted({n for n in names if names.count(n) > 1})
                raise ConfigError(f"{trace.source}: node_map maps several ids to {dup}")
            for (src, dst, ch), s in trace.series.items():
                if src in node_map and dst in node_map:
                    series[node_map[src], node_map[dst], ch] = s
        self._series = series

    @property
    def duration_s(self) -> float:
        """Time of the trace's last row, seconds (the last values hold after it)."""
        return self.trace.duration_s

    def pdr(self, a: str, b: str, channel: int, t: float) -> float:
        """PDR of ``a -> b`` on ``channel`` at ``t`` s (0 if never measured)."""
        s = self._series.get((a, b, channel))
        if s is None:
            return 0.0
        i = bisect_right(s.times, t) - 1
        return s.pdr[i if i > 0 else 0]

    def rssi(self, a: str, b: str, channel: int, t: float) -> float | None:
        """Mean RSSI of ``a -> b`` on ``channel`` at ``t`` s, dBm (``None``: unknown)."""
        s = self._series.get((a, b, channel))
        if s is None:
            return None
        i = bisect_right(s.times, t) - 1
        return s.rssi[i if i > 0 else 0]


# -------------------------------------------------------------------------------- interference


class InterferenceBurst(BaseModel):
    """Interference on some channels during ``[t_start, t_end)``: PDR capped at ``prr``."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    t_start: float = Field(description="start, seconds since the start (included)")
    t_end: float = Field(description="end, seconds since the start (excluded)")
    channels: tuple[int, ...] = Field(min_length=1, description="channels hit (11..26)")
    prr: float = Field(ge=0, le=1, description="reception ratio left: PDR becomes min(pdr, prr)")
    receivers: frozenset[str] | None = Field(
        default=None, description="only links into these nodes; None: every link"
    )

    @field_validator("channels")
    @classmethod
    def _channels_in_band(cls, v: tuple[int, ...]) -> tuple[int, ...]:
        for ch in v:
            if ch not in CHANNELS_24GHZ:
                raise ValueError(f"channel {ch} outside 11..26")
        return tuple(sorted(set(v)))

    @model_validator(mode="after")
    def _ordered(self) -> Self:
        if not self.t_end > self.t_start:
            raise ValueError(f"t_end ({self.t_end}) must be after t_start ({self.t_start})")
        return self

    def active(self, channel: int, t: float) -> bool:
        """Whether the burst is on ``channel`` at ``t``."""
        return self.t_start <= t < self.t_end and channel in self.channels


class WithInterference:
    """Any :class:`LinkQuality` with interference bursts on top.

    Parameters
    ----------
    base : LinkQuality
        The link model below.
    bursts : iterable of InterferenceBurst
        Initial bursts; more with :meth:`add` at run time.
    """

    def __init__(self, base: LinkQuality, bursts: Iterable[InterferenceBurst] = ()) -> None:
        self.base = base
        self._bursts: list[InterferenceBurst] = []
        # channel -> [(t_start, t_end, prr, receivers)], kept as tuples for the hot path
        self._by_channel: dict[int, list[tuple[float, float, float, frozenset[str] | None]]] = {}
        for burst in bursts:
            self.add(burst)

    @property
    def bursts(self) -> tuple[InterferenceBurst, ...]:
        """The bursts, in the order added."""
        return tuple(self._bursts)

    def add(self, burst: InterferenceBurst) -> None:
        """Add a burst (it applies to every later query)."""
        self._bursts.append(burst)
        entry = (burst.t_start, burst.t_end, burst.prr, burst.receivers)
        for ch in burst.channels:
            self._by_channel.setdefault(ch, []).append(entry)

    def pdr(self, a: str, b: str, channel: int, t: float) -> float:
        """The base PDR, capped by every burst active on ``channel`` at ``t``."""
        p = self.base.pdr(a, b, channel, t)
        for t0, t1, prr, receivers in self._by_channel.get(channel, ()):
            if t0 <= t < t1 and prr < p and (receivers is None or b in receivers):
                p = prr
        return p

    def rssi(self, a: str, b: str, channel: int, t: float) -> float | None:
        """The base RSSI (interference does not change the wanted signal's strength)."""
        return self.base.rssi(a, b, channel, t)


# ------------------------------------------------------------------------------------- matrix


def table(
    lq: LinkQuality, nodes: Iterable[str], channels: Iterable[int], t: float
) -> dict[tuple[str, str], dict[int, float]]:
    """The PDR of every ordered pair of distinct ``nodes`` on every channel at ``t``.

    Parameters
    ----------
    lq : LinkQuality
        The link model.
    nodes : iterable of str
        Node names (sorted in the result).
    channels : iterable of int
        Channels (sorted in the result).
    t : float
        Seconds since the start.

    Returns
    -------
    dict
        ``(a, b) -> {channel: pdr}``.
    """
    names = sorted(set(nodes))
    chans = sorted(set(channels))
    return {
        (a, b): {ch: lq.pdr(a, b, ch, t) for ch in chans} for a in names for b in names if a != b
    }
