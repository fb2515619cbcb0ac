"""Link traces in the k7 format: per directed link and channel, PDR and RSSI over time.

The k7 format is the connectivity-trace format of the 6TiSCH simulator (``ConnectivityMatrixK7``
in ``SimEngine/Connectivity.py`` of https://github.com/6tisch/simulator) and of the ``k7``
Python package (https://github.com/keomabrun/k7, ``README.md`` "k7 format"; openwsn-berkeley /
Mercator testbed datasets). A file is text, optionally gzip-compressed (``.gz``)::

    {"location": "grenoble", "start_date": "...", "channels": [11, 12, ...], ...}   line 1
    datetime,src,dst,channel,mean_rssi,pdr,tx_count                                  line 2
    2018-01-11 16:33:07,18,19,11,-53.2,1.0,100                                       line 3...

* line 1: a JSON object, the trace's metadata (location, start/stop dates, node count,
  channels, ...). It is kept as :attr:`K7Trace.header`; only ``channels`` is used (see below).
* line 2: the CSV column names. Required: ``datetime``, ``src``, ``dst``, ``mean_rssi``, ``pdr``
  and one channel column, ``channel`` or ``channels``; others (``tx_count``,
  ``transaction_id``) are ignored.
* then one row per measurement of one directed link, in non-decreasing time.

Column formats, as the sources above write and read them:

* ``datetime``: ISO 8601 (``2018-01-11 16:33:07`` in the k7 README and older 6TiSCH traces,
  ``2018-01-11T16:33:07.000000`` in newer ones); parsed with :meth:`datetime.fromisoformat`
  (aware times are converted to UTC).
* ``src``, ``dst``: node ids, kept as strings (``"18"``; Mercator MAC-like ids ``"d9-a5-68"``).
  The k7 README allows an empty src or dst (a measurement over all neighbours): such rows do not
  describe one link and are skipped (their line numbers are in :attr:`K7Trace.skipped_lines`).
* channel: ``channel`` holds one IEEE 802.15.4 channel (``11``), or is empty; ``channels``
  (older 6TiSCH ``ConnectivityK7`` / k7 0.0.5) a list ``[11;12]``. Either column accepts both
  forms. An empty cell means "all channels": 6TiSCH's ``_set_connectivity`` applies such a row
  to every channel; we expand it to the header's ``channels`` list (an error if the header has
  none). Channels must lie in 11..26 (the 2.4 GHz O-QPSK band).
* ``mean_rssi``: dBm; empty or ``None`` (the 6TiSCH converter writes ``None`` when nothing was
  received) gives an unknown RSSI (``None``).
* ``pdr``: a number in [0, 1].

Time: seconds since the trace's **first data row** (not the header's ``start_date``). Each
(src, dst, channel) series is piecewise constant: a row's values hold from its time until the
next row of the same series; after the last row the last values hold. Before a series' first
row its first values hold (backfilled to t = 0): the 6TiSCH simulator backdates the rows of the
trace's first sweep to ASN 0 (until a link repeats); we backdate every series' first row, so a
link measured first late in a long sweep is not taken as absent before. Several rows of a series
at the same time: the later line wins. A (src, dst, channel) never measured has PDR 0 and no
RSSI, as 6TiSCH's ``LINK_NONE``.

Malformed input raises :class:`core.errors.ConfigError` (a ``ValueError``) whose message is
``<file>:<line>: <what is wrong>`` with a 1-based line number.
"""

from __future__ import annotations

import gzip
import json
import math
import os
from bisect import bisect_right
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from types import MappingProxyType
from typing import Any

from core.errors import ConfigError

__all__ = [
    "CHANNELS_24GHZ",
    "REQUIRED_COLUMNS",
    "LinkSeries",
    "K7Trace",
    "read_k7",
    "parse_k7",
]

CHANNELS_24GHZ = tuple(range(11, 27))  # IEEE 802.15.4 2.4 GHz O-QPSK channels
REQUIRED_COLUMNS = ("datetime", "src", "dst", "mean_rssi", "pdr")  # plus channel or channels
_CHANNEL_COLUMNS = ("channel", "channels")
_NO_RSSI = ("", "none", "nan")


@dataclass(frozen=True)
class LinkSeries:
    """The measurements of one (src, dst, channel), piecewise constant in time.

    Attributes
    ----------
    times : tuple of float
        Row times, seconds since the trace's first row, strictly increasing.
    pdr : tuple of float
        PDR from each time on, in [0, 1].
    rssi : tuple of float or None
        Mean RSSI from each time on, dBm; ``None``: unknown.
    """

    times: tuple[float, ...]
    pdr: tuple[float, ...]
    rssi: tuple[float | None, ...]

    def index(self, t: float) -> int:
        """Index of the row in force at ``t`` (the first row before it, see the module)."""
        i = bisect_right(self.times, t) - 1
        return i if i > 0 else 0

    def pdr_at(self, t: float) -> float:
        """PDR at ``t`` seconds."""
        return self.pdr[self.index(t)]

    def rssi_at(self, t: float) -> float | None:
        """Mean RSSI at ``t`` seconds, dBm (``None``: unknown)."""
        return self.rssi[self.index(t)]


@dataclass(frozen=True)
class K7Trace:
    """A parsed k7 file.

    Attributes
    ----------
    source : str
        The file it was read from (for messages).
    header : mapping
        The JSON header (line 1), as read.
    start : datetime
        Time of the first data row (t = 0).
    duration_s : float
        Time of the last data row, seconds.
    series : mapping
        ``(src, dst, channel) -> LinkSeries``.
    skipped_lines : tuple of int
        Rows skipped because src or dst was empty (1-based line numbers).
    """

    source: str
    header: Mapping[str, Any]
    start: datetime
    duration_s: float
    series: Mapping[tuple[str, str, int], LinkSeries]
    skipped_lines: tuple[int, ...] = ()

    @property
    def nodes(self) -> tuple[str, ...]:
        """Every node id appearing as src or dst, sorted."""
        return tuple(sorted({k[0] for k in self.series} | {k[1] for k in self.series}))

    @property
    def channels(self) -> tuple[int, ...]:
        """Every channel with at least one row, sorted."""
        return tuple(sorted({k[2] for k in self.series}))

    def pdr(self, src: str, dst: str, channel: int, t: float) -> float:
        """PDR of ``src -> dst`` on ``channel`` at ``t`` seconds (0 if never measured)."""
        s = self.series.get((src, dst, channel))
        return 0.0 if s is None else s.pdr_at(t)

    def rssi(self, src: str, dst: str, channel: int, t: float) -> float | None:
        """Mean RSSI of ``src -> dst`` on ``channel`` at ``t`` seconds, dBm (``None``: unknown)."""
        s = self.series.get((src, dst, channel))
        return None if s is None else s.rssi_at(t)


def read_k7(path: str | os.PathLike[str]) -> K7Trace:
    """Read a k7 file (gzip-compressed if its name ends in ``.gz``).

    Parameters
    ----------
    path : str or path-like
        The file.

    Returns
    -------
    K7Trace

    Raises
    ------
    ConfigError
        Malformed content, with the file and the 1-based line (see the module docstring).
    OSError
        The file cannot be read.
    """
    name = os.fspath(path)
    if name.endswith(".gz"):
        with gzip.open(name, "rt", encoding="utf-8") as fh:
            return parse_k7(fh, source=name)
    with open(name, encoding="utf-8") as fh:
        return parse_k7(fh, source=name)


def parse_k7(lines: Iterable[str], source: str = "<k7>") -> K7Trace:
    """Parse the lines of a k7 file.

    Parameters
    ----------
    lines : iterable of str
        The file's lines (trailing newlines allowed), e.g. an open text file.
    source : str
        Name of the file, for messages.

    Returns
    -------
    K7Trace

    Raises
    ------
    ConfigError
        Empty file, bad JSON header, missing column, wrong number of fields, bad datetime, time
        going backwards, unknown channel format or channel, non-numeric or out-of-range pdr,
        non-numeric mean_rssi; the message names ``source`` and the 1-based line.
    """
    it = iter(lines)
    header, header_channels = _json_header(next(it, None), source)
    columns = _csv_header(next(it, None), source)
    rows = _Rows(columns, header_channels, source)
    for lineno, line in enumerate(it, start=3):
        rows.read(lineno, line)
    if rows.start is None:
        raise _fail(source, 3, "no data rows after the CSV header")
    series = {
        key: LinkSeries(tuple(times), tuple(pdrs), tuple(rssis))
        for key, (times, pdrs, rssis) in sorted(rows.raw.items())
    }
    return K7Trace(
        source=source,
        header=MappingProxyType(header),
        start=rows.start,
        duration_s=rows.last_t,
        series=MappingProxyType(series),
        skipped_lines=tuple(rows.skipped),
    )


def _fail(source: str, lineno: int, what: str) -> ConfigError:
    return ConfigError(f"{source}:{lineno}: {what}")


def _json_header(first: str | None, source: str) -> tuple[dict[str, Any], tuple[int, ...]]:
    """Line 1: the JSON header, and the channels it lists."""
    if first is None or not first.strip():
        raise _fail(source, 1, "empty file (expected a JSON header line)")
    try:
        header = json.loads(first)
    except json.JSONDecodeError as exc:
        raise _fail(source, 1, f"bad JSON header: {exc.msg}") from None
    if not isinstance(header, dict):
        raise _fail(source, 1, f"bad JSON header: expected an object, got {type(header).__name__}")
    try:
        header_channels = _header_channels(header.get("channels"))
    except _RowError as exc:
        raise _fail(source, 1, f"bad JSON header: {exc}") from None
    return header, header_channels


@dataclass(frozen=True)
class _Columns:
    """Line 2: where each column a row needs is, and how many fields a row has."""

    line: str  # the CSV header, for messages
    i_dt: int
    i_src: int
    i_dst: int
    i_ch: int
    i_rssi: int
    i_pdr: int
    n_fields: int


def _csv_header(second: str | None, source: str) -> _Columns:
    """Line 2: the CSV column names."""
    if second is None or not second.strip():
        raise _fail(
            source, 2, "missing CSV header line (datetime,src,dst,channel,mean_rssi,pdr,...)"
        )
    columns = [c.strip() for c in second.rstrip("\r\n").split(",")]
    for col in REQUIRED_COLUMNS:
        if col not in columns:
            raise _fail(source, 2, f"missing column {col!r} (columns: {','.join(columns)})")
    chan_cols = [c for c in _CHANNEL_COLUMNS if c in columns]
    if not chan_cols:
        raise _fail(
            source, 2, f"missing column 'channel' or 'channels' (columns: {','.join(columns)})"
        )
    if len(chan_cols) > 1:
        raise _fail(source, 2, "both 'channel' and 'channels' columns: keep one")
    return _Columns(
        line=second.strip(),
        i_dt=columns.index("datetime"),
        i_src=columns.index("src"),
        i_dst=columns.index("dst"),
        i_ch=columns.index(chan_cols[0]),
        i_rssi=columns.index("mean_rssi"),
        i_pdr=columns.index("pdr"),
        n_fields=len(columns),
    )


_Series = tuple[list[float], list[float], list[float | None]]  # times (s), pdrs, rssis


class _Rows:
    """The data rows read so far: each (src, dst, channel) series, the skipped lines, the first
    row's time and the last row's, seconds after the first."""

    def __init__(self, columns: _Columns, header_channels: tuple[int, ...], source: str) -> None:
        self.columns = columns
        self.header_channels = header_channels
        self.source = source
        self.raw: dict[tuple[str, str, int], _Series] = {}
        self.skipped: list[int] = []
        self.start: datetime | None = None
        self.last: datetime | None = None
        self.last_t = 0.0

    def read(self, lineno: int, line: str) -> None:
        """Add data row ``line`` (line ``lineno``; a blank line is nothing)."""
        c, source = self.columns, self.source
        text = line.rstrip("\r\n")
        if not text.strip():
            return
        fields = [f.strip() for f in text.split(",")]
        if len(fields) != c.n_fields:
            raise _fail(
                source, lineno, f"expected {c.n_fields} fields ({c.line}), got {len(fields)}"
            )
        try:
            when = _datetime(fields[c.i_dt])
            channels = _channels(fields[c.i_ch], self.header_channels)
            pdr = _pdr(fields[c.i_pdr])
            rssi = _rssi(fields[c.i_rssi])
        except _RowError as exc:
            raise _fail(source, lineno, str(exc)) from None
        if self.last is not None and when < self.last:
            raise _fail(
                source, lineno, f"time goes backwards: {fields[c.i_dt]} is before the row above"
            )
        if self.start is None:
            self.start = when
        self.last = when
        self.last_t = (when - self.start).total_seconds()
        src, dst = fields[c.i_src], fields[c.i_dst]
        if not src or not dst:
            self.skipped.append(lineno)
            return
        for ch in channels:
            times, pdrs, rssis = self.raw.setdefault((src, dst, ch), ([], [], []))
            if times and times[-1] == self.last_t:  # same time: the later line wins
                pdrs[-1], rssis[-1] = pdr, rssi
            else:
                times.append(self.last_t)
                pdrs.append(pdr)
                rssis.append(rssi)


# ----------------------------------------------------------------------------------- helpers


class _RowError(ValueError):
    """What is wrong with one field; the caller adds the file and line."""


def _header_channels(value: Any) -> tuple[int, ...]:
    if value is None:
        return ()
    if not isinstance(value, list) or not all(
        isinstance(c, int) and not isinstance(c, bool) for c in value
    ):
        raise _RowError(f"'channels' must be a list of integers, got {value!r}")
    for c in value:
        if c not in CHANNELS_24GHZ:
            raise _RowError(f"channel {c} outside 11..26")
    return tuple(sorted(set(value)))


def _datetime(text: str) -> datetime:
    try:
        when = datetime.fromisoformat(text)
    except ValueError:
        raise _RowError(
            f"bad datetime {text!r} (expected ISO 8601, e.g. 2018-01-11 16:33:07)"
        ) from None
    if when.tzinfo is not None:
        when = when.astimezone(UTC).replace(tzinfo=None)
    return when


def _channels(text: str, header_channels: tuple[int, ...]) -> tuple[int, ...]:
    if text == "":
        if not header_channels:
            raise _RowError("empty channel (all channels) but the JSON header lists no 'channels'")
        return header_channels
    if text.startswith("[") and text.endswith("]"):
        parts = [p.strip() for p in text[1:-1].split(";")]
    else:
        parts = [text]
    if not all(p.isdigit() for p in parts):
        raise _RowError(f"unknown channel format {text!r} (expected 11, [11;12] or empty)")
    out = tuple(int(p) for p in parts)
    for c in out:
        if c not in CHANNELS_24GHZ:
            raise _RowError(f"channel {c} outside 11..26")
    return out


def _pdr(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise _RowError(f"non-numeric pdr {text!r}") from None
    if not (0.0 <= value <= 1.0):  # also refuses nan
        raise _RowError(f"pdr {text} outside [0, 1]")
    return value


def _rssi(text: str) -> float | None:
    if text.lower() in _NO_RSSI:
        return None
    try:
        value = float(text)
    except ValueError:
        raise _RowError(f"non-numeric mean_rssi {text!r}") from None
    if not math.isfinite(value):
        raise _RowError(f"non-finite mean_rssi {text!r}")
    return value
