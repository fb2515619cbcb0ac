"""Link quality of the TSCH network (gateway/tsch/link_quality.py) and the k7 parser (k7.py).

Numbers are checked against closed forms and independent computations: the O-QPSK BER sum in
plain Python with ``math.comb``, path-loss RSSI by hand, the shadowing's sample statistics, the
6TiSCH Pister table at its points and midpoints, a hand-written k7 file at chosen times.
"""

from __future__ import annotations

import gzip
import math
from datetime import datetime
from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

from core.errors import ConfigError
from gateway.tsch.k7 import K7Trace, parse_k7, read_k7
from gateway.tsch.link_quality import (
    PISTER_RSSI_PDR_TABLE,
    InterferenceBurst,
    LinkQuality,
    PathLossConfig,
    PositionLinks,
    TraceLinks,
    WithInterference,
    ber_oqpsk,
    rssi_to_pdr_oqpsk,
    rssi_to_pdr_pister,
    table,
)

DATA = Path(__file__).resolve().parents[1] / "data" / "k7"
SMALL = DATA / "small.k7"
ALL_CHANNELS = list(range(11, 27))


def ber_by_hand(sinr: float) -> float:
    """IEEE 802.15.4-2006 E.4.1.8, term by term."""
    total = 0.0
    for k in range(2, 17):
        total += (-1) ** k * math.comb(16, k) * math.exp(20.0 * sinr * (1.0 / k - 1.0))
    return (8.0 / 15.0) * (1.0 / 16.0) * total


def pdr_by_hand(rssi_dbm: float, noise_dbm: float, frame_bytes: int) -> float:
    sinr = 10.0 ** ((rssi_dbm - noise_dbm) / 10.0)
    return (1.0 - ber_by_hand(sinr)) ** (8 * frame_bytes)


# ---------------------------------------------------------------------------------- O-QPSK


@pytest.mark.parametrize("sinr", [0.02, 0.1, 0.25, 0.5, 1.0, 2.0, 4.0])
def test_ber_matches_the_standard_sum_term_by_term(sinr: float) -> None:
    assert float(ber_oqpsk(sinr)) == pytest.approx(ber_by_hand(sinr), rel=1e-9, abs=1e-300)


def test_ber_is_one_half_at_zero_sinr_and_falls_monotonically() -> None:
    # sum_{k=2}^{16} (-1)^k C(16,k) = 0 - (1 - 16) = 15, so BER(0) = 8/15 * 15/16 = 1/2
    assert sum((-1) ** k * math.comb(16, k) for k in range(2, 17)) == 15
    assert float(ber_oqpsk(0.0)) == pytest.approx(0.5, abs=1e-12)
    s = np.logspace(-4, 2, 3000)
    b = ber_oqpsk(s)
    assert np.all(np.diff(b) <= 0.0)
    assert b[0] > 0.49 and b[-1] == 0.0
    assert np.all((b >= 0.0) & (b <= 0.5))


def test_ber_refuses_negative_sinr() -> None:
    with pytest.raises(ValueError, match="linear"):
        ber_oqpsk([1.0, -0.1])


def test_pdr_oqpsk_against_hand_values() -> None:
    for rssi in (-102.0, -101.0, -100.0, -99.0, -98.0):
        assert float(rssi_to_pdr_oqpsk(rssi, -100.0, 127)) == pytest.approx(
            pdr_by_hand(rssi, -100.0, 127), rel=1e-9, abs=1e-300
        )
    # shorter frame: higher PDR at the same SINR, and PDR = (1 - BER)^(8 L) exactly
    b = float(ber_oqpsk(10 ** (-0.1)))  # SINR -1 dB
    assert float(rssi_to_pdr_oqpsk(-101.0, -100.0, 20)) == pytest.approx((1 - b) ** 160)
    assert rssi_to_pdr_oqpsk(-101.0, -100.0, 20) > rssi_to_pdr_oqpsk(-101.0, -100.0, 127)


def test_pdr_oqpsk_limits_and_shape() -> None:
    assert float(rssi_to_pdr_oqpsk(-70.0, -100.0, 127)) > 1 - 1e-12
    assert float(rssi_to_pdr_oqpsk(-110.0, -100.0, 127)) < 1e-12
    r = np.array([[-110.0, -101.0], [-99.0, -60.0]])
    p = rssi_to_pdr_oqpsk(r, -100.0, 127)
    assert p.shape == (2, 2)
    assert np.all(np.diff(p.ravel()) > 0)


def test_pdr_oqpsk_interference_adds_to_noise() -> None:
    # two -100 dBm powers add to 10 log10(2e-10) dBm
    both = 10 * math.log10(2e-10)
    got = float(rssi_to_pdr_oqpsk(-97.0, -100.0, 127, interference_dbm=-100.0))
    assert got == pytest.approx(pdr_by_hand(-97.0, both, 127), rel=1e-9)
    assert got < float(rssi_to_pdr_oqpsk(-97.0, -100.0, 127))


# ---------------------------------------------------------------------------------- Pister


def test_pister_table_is_the_6tisch_one() -> None:
    assert sorted(PISTER_RSSI_PDR_TABLE) == list(range(-97, -78))
    assert PISTER_RSSI_PDR_TABLE[-96] == 0.1494
    assert PISTER_RSSI_PDR_TABLE[-93] == 0.6359
    assert PISTER_RSSI_PDR_TABLE[-80] == 0.9903
    assert PISTER_RSSI_PDR_TABLE[-97] == 0.0 and PISTER_RSSI_PDR_TABLE[-79] == 1.0


def test_pister_interpolation_at_points_midpoints_and_outside() -> None:
    points = sorted(PISTER_RSSI_PDR_TABLE)
    got = rssi_to_pdr_pister(points)
    assert got.tolist() == [PISTER_RSSI_PDR_TABLE[r] for r in points]
    for lo in points[:-1]:
        mid = float(rssi_to_pdr_pister(lo + 0.5))
        want = 0.5 * (PISTER_RSSI_PDR_TABLE[lo] + PISTER_RSSI_PDR_TABLE[lo + 1])
        assert mid == pytest.approx(want, abs=1e-12)
    # a quarter of the way from -97 (0.0) to -96 (0.1494)
    assert float(rssi_to_pdr_pister(-96.75)) == pytest.approx(0.25 * 0.1494, abs=1e-12)
    assert rssi_to_pdr_pister([-120.0, -97.01, -78.99, -40.0]).tolist() == [0.0, 0.0, 1.0, 1.0]


# ---------------------------------------------------------------------------------- path loss


def test_default_pl_d0_is_free_space_at_2_44_ghz() -> None:
    lam = 299_792_458.0 / 2.44e9
    assert PathLossConfig().pl_d0_db == pytest.approx(20 * math.log10(4 * math.pi / lam), abs=0.01)


def test_config_refuses_bad_fields() -> None:
    with pytest.raises(ValidationError):
        PathLossConfig(frame_bytes=128)
    with pytest.raises(ValidationError):
        PathLossConfig(sigma_db=-1.0)
    with pytest.raises(ValidationError):
        PathLossConfig(pdr_model="friis")
    with pytest.raises(ValidationError):
        PathLossConfig(tx_power_dbm=float("nan"))
    with pytest.raises(ValidationError):
        PathLossConfig(colour="red")  # type: ignore[call-arg]


def test_rssi_by_hand_with_no_shadowing() -> None:
    cfg = PathLossConfig(sigma_db=0.0)
    pos = {"a": (0.0, 0.0), "b": (6.0, 8.0), "c": (0.3, 0.4), "d": (100.0, 0.0)}
    lq = PositionLinks(pos, [11, 15], cfg, np.random.default_rng(1))
    # d = 10 m: 0 - 40.2 - 30 log10(10) = -70.2 dBm
    assert lq.rssi("a", "b", 11) == pytest.approx(-70.2, abs=1e-12)
    assert lq.rssi("b", "a", 15) == pytest.approx(-70.2, abs=1e-12)
    assert lq.pdr("a", "b", 11, 0.0) == pytest.approx(pdr_by_hand(-70.2, -100.0, 127), rel=1e-12)
    # d = 0.5 m < d0: clamped to d0, -40.2 dBm
    assert lq.rssi("a", "c", 11) == pytest.approx(-40.2, abs=1e-12)
    # d = 100 m: -40.2 - 60 = -100.2 dBm, below the -97 dBm sensitivity: PDR 0
    assert lq.rssi("a", "d", 11) == pytest.approx(-100.2, abs=1e-12)
    assert lq.pdr("a", "d", 11, 0.0) == 0.0
    # d = |b - d| = sqrt(94^2 + 8^2)
    d = math.hypot(94.0, 8.0)
    assert lq.rssi("d", "b", 15) == pytest.approx(-40.2 - 30 * math.log10(d), abs=1e-12)
    assert lq.distance_m["b", "d"] == pytest.approx(d)


def test_tx_power_exponent_and_sensitivity_are_used() -> None:
    cfg = PathLossConfig(
        sigma_db=0.0,
        tx_power_dbm=5.0,
        pl_d0_db=30.0,
        d0_m=2.0,
        path_loss_exponent=2.0,
        sensitivity_dbm=-60.0,
    )
    pos = {"a": (0.0, 0.0), "b": (20.0, 0.0), "c": (0.0, 200.0)}
    lq = PositionLinks(pos, [20], cfg, np.random.default_rng(0))
    assert lq.rssi("a", "b", 20) == pytest.approx(5 - 30 - 20 * math.log10(10), abs=1e-12)
    assert lq.pdr("a", "b", 20, 0.0) > 0.999  # -45 dBm
    assert lq.rssi("a", "c", 20) == pytest.approx(5 - 30 - 20 * math.log10(100), abs=1e-12)
    assert lq.pdr("a", "c", 20, 0.0) == 0.0  # -65 dBm < -60 dBm sensitivity


def test_pister_model_through_positions() -> None:
    cfg = PathLossConfig(sigma_db=0.0, pdr_model="pister_hack")
    d = 10 ** ((93.5 - 40.2) / 30.0)  # RSSI = -93.5 dBm
    lq = PositionLinks({"a": (0.0, 0.0), "b": (d, 0.0)}, [26], cfg, np.random.default_rng(0))
    assert lq.rssi("a", "b", 26) == pytest.approx(-93.5, abs=1e-9)
    assert lq.pdr("a", "b", 26, 3.0) == pytest.approx(0.5 * (0.4071 + 0.6359), abs=1e-9)


def test_same_position_is_refused_naming_the_nodes() -> None:
    pos = {"s1": (1.0, 2.0), "gw": (1.0, 2.0), "r": (5.0, 5.0)}
    with pytest.raises(ConfigError, match=r"'gw' and 's1'.*same position"):
        PositionLinks(pos, [11], PathLossConfig(), np.random.default_rng(0))
    # not refused when that pair is not asked for
    lq = PositionLinks(
        pos, [11], PathLossConfig(), np.random.default_rng(0), pairs=[("s1", "r"), ("r", "gw")]
    )
    assert lq.pdr("s1", "gw", 11, 0.0) == 0.0


def test_pairs_restrict_the_links_and_channels_are_checked() -> None:
    pos = {"a": (0.0, 0.0), "b": (5.0, 0.0), "c": (0.0, 5.0)}
    cfg = PathLossConfig(sigma_db=0.0)
    lq = PositionLinks(pos, [12, 11], cfg, np.random.default_rng(0), pairs=[("a", "b")])
    assert lq.channels == (11, 12)
    assert lq.pairs == (("a", "b"),)
    assert lq.pdr("a", "b", 11, 0.0) > 0.99
    assert lq.pdr("b", "a", 11, 0.0) == 0.0 and lq.rssi("b", "a", 11) is None
    assert lq.pdr("a", "c", 12, 0.0) == 0.0
    with pytest.raises(ValueError, match="channel 13 is not in use"):
        lq.pdr("a", "b", 13, 0.0)
    with pytest.raises(ValueError, match="channel 13 is not in use"):
        lq.rssi("b", "a", 13, 0.0)
    with pytest.raises(ConfigError, match="unknown node 'z'"):
        PositionLinks(pos, [11], cfg, np.random.default_rng(0), pairs=[("a", "z")])
    with pytest.raises(ConfigError, match="itself"):
        PositionLinks(pos, [11], cfg, np.random.default_rng(0), pairs=[("a", "a")])
    with pytest.raises(ConfigError, match="channel 27"):
        PositionLinks(pos, [11, 27], cfg, np.random.default_rng(0))
    with pytest.raises(ConfigError, match="not finite"):
        PositionLinks({"a": (0.0, math.inf), "b": (1.0, 1.0)}, [11], cfg, np.random.default_rng(0))


def _grid(n: int, step: float = 7.0) -> dict[str, tuple[float, float]]:
    return {f"n{i:02d}": (step * (i % 8) + 0.1 * i, step * (i // 8)) for i in range(n)}


def test_shadowing_statistics() -> None:
    sigma = 4.0
    cfg = PathLossConfig(sigma_db=sigma)
    lq = PositionLinks(_grid(40), ALL_CHANNELS, cfg, np.random.default_rng(2024))
    x = np.array(
        [[lq.mean_rssi_dbm[a, b] - lq.rssi(a, b, ch) for ch in ALL_CHANNELS] for a, b in lq.links]
    )
    n = x.size
    assert n == 780 * 16
    assert abs(x.mean()) < 4 * sigma / math.sqrt(n)
    assert abs(x.std(ddof=1) - sigma) < 4 * sigma / math.sqrt(2 * n)
    # independent per channel: the correlation across links of two channels is near 0
    r = np.corrcoef(x[:, 0], x[:, 1])[0, 1]
    assert abs(r) < 4 / math.sqrt(len(lq.links))
    # reciprocal: the same draw both ways
    a, b = lq.links[17]
    assert lq.rssi(a, b, 20) == lq.rssi(b, a, 20)


def test_shadowing_draw_order_is_the_documented_one() -> None:
    sigma, seed = 3.0, 7
    pos = {"c": (0.0, 0.0), "a": (10.0, 0.0), "b": (0.0, 12.0), "d": (9.0, 9.0)}
    chans = [26, 11, 15]
    lq = PositionLinks(pos, chans, PathLossConfig(sigma_db=sigma), np.random.default_rng(seed))
    links = [("a", "b"), ("a", "c"), ("a", "d"), ("b", "c"), ("b", "d"), ("c", "d")]
    assert list(lq.links) == links
    draws = np.random.default_rng(seed).normal(0.0, sigma, size=(len(links), 3))
    for i, (a, b) in enumerate(links):
        for j, ch in enumerate([11, 15, 26]):
            assert lq.mean_rssi_dbm[a, b] - lq.rssi(b, a, ch) == pytest.approx(draws[i, j])
    # the same whatever the order of the positions and channels given
    rev = dict(reversed(list(pos.items())))
    lq2 = PositionLinks(rev, chans[::-1], PathLossConfig(sigma_db=sigma), np.random.default_rng(7))
    assert all(lq2.rssi(a, b, ch) == lq.rssi(a, b, ch) for a, b in lq.pairs for ch in chans)


def test_generator_state_after_construction() -> None:
    pos = _grid(5)
    for sigma in (0.0, 4.0):
        rng = np.random.default_rng(99)
        PositionLinks(pos, [11, 12], PathLossConfig(sigma_db=sigma), rng)
        ref = np.random.default_rng(99)
        ref.normal(0.0, 1.0, size=(10, 2))
        assert rng.random() == ref.random()


# ---------------------------------------------------------------------------------- k7


def test_k7_fixture_header_and_layout() -> None:
    tr = read_k7(SMALL)
    assert isinstance(tr, K7Trace)
    assert tr.header["location"] == "hand-written"
    assert tr.start == datetime(2018, 1, 11, 16, 33, 0)
    assert tr.duration_s == 120.0
    assert tr.nodes == ("1", "2", "3")
    assert tr.channels == (11, 12, 13)
    assert tr.skipped_lines == (8,)  # empty src
    assert set(tr.series) == {
        ("1", "2", 11),
        ("1", "2", 12),
        ("2", "1", 11),
        ("1", "3", 11),
        ("1", "3", 12),
        ("1", "3", 13),
    }
    assert tr.series["1", "2", 11].times == (0.0, 30.0, 120.0)


@pytest.mark.parametrize(
    ("t", "pdr", "rssi"),
    [
        (-5.0, 0.9, -80.5),  # before the first row: the first row, backfilled
        (0.0, 0.9, -80.5),
        (29.999, 0.9, -80.5),
        (30.0, 0.25, -90.25),  # a row holds from its own time on
        (119.9, 0.25, -90.25),
        (120.0, 0.95, -61.0),  # two rows at 120 s: the later line wins
        (1e6, 0.95, -61.0),  # after the last row: the last values hold
    ],
)
def test_k7_piecewise_constant_values(t: float, pdr: float, rssi: float) -> None:
    tr = read_k7(SMALL)
    assert tr.pdr("1", "2", 11, t) == pdr
    assert tr.rssi("1", "2", 11, t) == rssi
    lq = TraceLinks(tr)
    assert lq.pdr("1", "2", 11, t) == pdr
    assert lq.rssi("1", "2", 11, t) == rssi


def test_k7_other_series_and_unknown_links() -> None:
    lq = TraceLinks(read_k7(SMALL))
    assert lq.pdr("1", "2", 12, 500.0) == 0.6
    assert lq.pdr("2", "1", 11, 20.0) == 0.0 and lq.rssi("2", "1", 11, 20.0) is None  # "None"
    for ch in (11, 12, 13):  # empty channel: every channel of the header
        assert lq.pdr("1", "3", ch, 0.0) == 1.0 and lq.rssi("1", "3", ch, 60.0) == -70.0
    assert lq.pdr("1", "3", 14, 60.0) == 0.0 and lq.rssi("1", "3", 14, 60.0) is None
    assert lq.pdr("3", "1", 11, 60.0) == 0.0
    assert lq.pdr("2", "3", 11, 60.0) == 0.0  # the skipped empty-src row gives nothing


def test_k7_node_map() -> None:
    tr = read_k7(SMALL)
    lq = TraceLinks(tr, {"1": "s1", "2": "gw"})
    assert lq.pdr("s1", "gw", 11, 0.0) == 0.9
    assert lq.pdr("gw", "s1", 11, 0.0) == 0.0
    assert lq.pdr("1", "2", 11, 0.0) == 0.0  # trace ids are no longer names
    assert lq.pdr("s1", "3", 11, 60.0) == 0.0  # "3" is not mapped
    with pytest.raises(ConfigError, match="'9' is not in the trace"):
        TraceLinks(tr, {"1": "s1", "9": "x"})
    with pytest.raises(ConfigError, match="several ids"):
        TraceLinks(tr, {"1": "s1", "2": "s1"})


def test_k7_gzip_list_channels_and_iso_t_datetimes(tmp_path: Path) -> None:
    text = (
        '{"location": "x", "channels": [11, 12, 13]}\n'
        "datetime,src,dst,channels,mean_rssi,pdr,transaction_id\n"
        "2020-05-01T10:00:00.500000,7,8,[11;13],-88.0,0.5,0\n"
        "2020-05-01T10:00:02.000000,7,8,[13],,0.75,0\n"
        "2020-05-01T10:00:03.250000,8,7,12,-70,1,0\n"
    )
    path = tmp_path / "t.k7.gz"
    with gzip.open(path, "wt", encoding="utf-8") as fh:
        fh.write(text)
    tr = read_k7(path)
    assert tr.duration_s == pytest.approx(2.75)
    assert tr.pdr("7", "8", 11, 10.0) == 0.5
    assert tr.pdr("7", "8", 13, 1.4) == 0.5 and tr.rssi("7", "8", 13, 1.4) == -88.0
    assert tr.pdr("7", "8", 13, 1.5) == 0.75 and tr.rssi("7", "8", 13, 1.5) is None
    assert tr.pdr("7", "8", 12, 1.5) == 0.0
    assert tr.pdr("8", "7", 12, 0.0) == 1.0


HEADER = '{"location": "x", "channels": [11, 12]}\n'
COLS = "datetime,src,dst,channel,mean_rssi,pdr,tx_count\n"
ROW = "2018-01-11 16:33:00,1,2,11,-80.0,0.9,100\n"


@pytest.mark.parametrize(
    ("content", "line", "what"),
    [
        ("", 1, "empty file"),
        ("{not json\n" + COLS + ROW, 1, "bad JSON header"),
        ("[1, 2]\n" + COLS + ROW, 1, "bad JSON header: expected an object"),
        ('{"channels": [11, 40]}\n' + COLS + ROW, 1, "channel 40 outside"),
        (HEADER, 2, "missing CSV header"),
        (HEADER + "datetime,src,dst,channel,mean_rssi,tx_count\n" + ROW, 2, "missing column 'pdr'"),
        (HEADER + "datetime,src,dst,mean_rssi,pdr\n", 2, "'channel' or 'channels'"),
        (HEADER + COLS, 3, "no data rows"),
        (HEADER + COLS + ROW + "2018-01-11 16:33:01,1,2,11,-80,high,100\n", 4, "non-numeric pdr"),
        (HEADER + COLS + ROW + "2018-01-11 16:33:01,1,2,11,-80,1.5,100\n", 4, "outside [0, 1]"),
        (HEADER + COLS + ROW + "2018-01-11 16:33:01,1,2,11,-80,-0.1,100\n", 4, "outside [0, 1]"),
        (HEADER + COLS + ROW + "2018-01-11 16:33:01,1,2,11,-80,nan,100\n", 4, "outside [0, 1]"),
        (HEADER + COLS + "2018-01-11 16:33:00,1,2,11;12,-80,0.9,1\n", 3, "unknown channel format"),
        (HEADER + COLS + "2018-01-11 16:33:00,1,2,ch11,-80,0.9,1\n", 3, "unknown channel format"),
        (HEADER + COLS + "2018-01-11 16:33:00,1,2,[],-80,0.9,1\n", 3, "unknown channel format"),
        (HEADER + COLS + "2018-01-11 16:33:00,1,2,27,-80,0.9,1\n", 3, "channel 27 outside"),
        ('{"x": 1}\n' + COLS + "2018-01-11 16:33:00,1,2,,-80,0.9,1\n", 3, "lists no 'channels'"),
        (HEADER + COLS + ROW + ROW + "2018-01-11 16:32:59,1,2,11,-80,0.9,1\n", 5, "backwards"),
        (HEADER + COLS + "11/01/2018 16:33,1,2,11,-80,0.9,1\n", 3, "bad datetime"),
        (HEADER + COLS + ROW + "2018-01-11 16:33:01,1,2,11,-80,0.9\n", 4, "expected 7 fields"),
        (HEADER + COLS + "2018-01-11 16:33:00,1,2,11,loud,0.9,1\n", 3, "non-numeric mean_rssi"),
    ],
)
def test_k7_malformed_names_file_and_line(
    tmp_path: Path, content: str, line: int, what: str
) -> None:
    path = tmp_path / "bad.k7"
    path.write_text(content, encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        read_k7(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}:{line}: "), msg
    assert what in msg, msg
    assert isinstance(info.value, ValueError)


def test_k7_blank_lines_are_ignored_but_counted() -> None:
    lines = [HEADER, COLS, "\n", ROW, "2018-01-11 16:33:00,1,2,11,-80,2,1\n"]
    with pytest.raises(ConfigError, match=r"^mem:5: pdr 2 outside"):
        parse_k7(lines, source="mem")


# ---------------------------------------------------------------------------------- interference


class Constant:
    """A link model with one PDR everywhere."""

    def __init__(self, p: float) -> None:
        self.p = p

    def pdr(self, a: str, b: str, channel: int, t: float) -> float:
        return self.p

    def rssi(self, a: str, b: str, channel: int, t: float) -> float | None:
        return -80.0


def test_burst_window_is_start_included_end_excluded() -> None:
    lq = WithInterference(
        Constant(0.9), [InterferenceBurst(t_start=10, t_end=20, channels=(11,), prr=0.3)]
    )
    assert lq.pdr("a", "b", 11, 9.999) == 0.9
    assert lq.pdr("a", "b", 11, 10.0) == 0.3
    assert lq.pdr("a", "b", 11, 19.999) == 0.3
    assert lq.pdr("a", "b", 11, 20.0) == 0.9
    assert lq.pdr("a", "b", 12, 15.0) == 0.9  # other channel
    assert lq.rssi("a", "b", 11, 15.0) == -80.0  # RSSI unchanged


def test_overlapping_bursts_take_the_minimum_and_cap_only_downwards() -> None:
    lq = WithInterference(Constant(0.9))
    lq.add(InterferenceBurst(t_start=10, t_end=20, channels=(11, 12), prr=0.3))
    lq.add(InterferenceBurst(t_start=15, t_end=25, channels=(11,), prr=0.1))
    lq.add(InterferenceBurst(t_start=0, t_end=100, channels=(13,), prr=0.95))
    assert lq.pdr("a", "b", 11, 12.0) == 0.3
    assert lq.pdr("a", "b", 11, 15.0) == 0.1
    assert lq.pdr("a", "b", 11, 22.0) == 0.1
    assert lq.pdr("a", "b", 12, 22.0) == 0.9
    assert lq.pdr("a", "b", 13, 50.0) == 0.9  # min(0.9, 0.95)
    assert len(lq.bursts) == 3


def test_burst_on_some_receivers_only() -> None:
    burst = InterferenceBurst(t_start=0, t_end=5, channels=(11,), prr=0.0, receivers={"gw"})
    lq = WithInterference(Constant(0.8), [burst])
    assert lq.pdr("s1", "gw", 11, 1.0) == 0.0
    assert lq.pdr("gw", "s1", 11, 1.0) == 0.8
    assert burst.active(11, 0.0) and not burst.active(11, 5.0) and not burst.active(12, 1.0)


def test_burst_validation() -> None:
    with pytest.raises(ValidationError, match="after t_start"):
        InterferenceBurst(t_start=5, t_end=5, channels=(11,), prr=0.5)
    with pytest.raises(ValidationError, match="outside 11..26"):
        InterferenceBurst(t_start=0, t_end=5, channels=(10,), prr=0.5)
    with pytest.raises(ValidationError):
        InterferenceBurst(t_start=0, t_end=5, channels=(), prr=0.5)
    with pytest.raises(ValidationError):
        InterferenceBurst(t_start=0, t_end=5, channels=(11,), prr=1.5)


def test_interference_on_a_trace_and_the_table() -> None:
    lq = WithInterference(TraceLinks(read_k7(SMALL)))
    lq.add(InterferenceBurst(t_start=100, t_end=200, channels=(11,), prr=0.5))
    assert lq.pdr("1", "2", 11, 50.0) == 0.25
    assert lq.pdr("1", "2", 11, 150.0) == 0.5  # min(0.95, 0.5)
    assert lq.pdr("1", "3", 11, 150.0) == 0.5
    assert lq.pdr("1", "2", 12, 150.0) == 0.6
    m = table(lq, ["3", "1", "2"], [12, 11], 150.0)
    assert list(m) == [("1", "2"), ("1", "3"), ("2", "1"), ("2", "3"), ("3", "1"), ("3", "2")]
    assert m["1", "2"] == {11: 0.5, 12: 0.6}
    assert list(m["1", "2"]) == [11, 12]
    assert m["2", "1"] == {11: 0.0, 12: 0.0}
    assert m["1", "3"] == {11: 0.5, 12: 1.0}


def test_every_model_satisfies_the_protocol() -> None:
    pos = PositionLinks(_grid(3), [11], PathLossConfig(), np.random.default_rng(0))
    tr = TraceLinks(read_k7(SMALL))
    for lq in (pos, tr, WithInterference(pos), Constant(1.0)):
        assert isinstance(lq, LinkQuality)
