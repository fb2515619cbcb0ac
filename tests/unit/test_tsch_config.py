"""A TSCH gateway's bad configuration is refused before anything runs (issue 15), naming the
file, the field and, for a link trace, the trace's line: ``wncs validate`` exits 2."""

from __future__ import annotations

import pytest

from cli.main import main
from core.errors import ConfigError
from runtime.inject import build_request
from tests.conftest import SCENARIOS, write_variant

TSCH = SCENARIOS / "jcstr_tsch.yaml"


def _tsch(**fields):
    def edit(data):
        data["nodes"]["network"]["tsch"].update(fields)

    return edit


def _no_position(data):
    del data["nodes"]["network"]["topology"]["nodes"]["r5"]["position"]


def _interference_per_hop(data):
    data["nodes"]["network"]["mac"] = "per_hop"
    del data["nodes"]["network"]["tsch"]


def _trace(tmp_path, body):
    def edit(data):
        path = tmp_path / "links.k7"
        path.write_text(body)
        data["nodes"]["network"]["tsch"].update(
            {"link_model": "trace", "trace": {"file": "links.k7"}}
        )

    return edit


HEADER = (
    '{"location": "test", "channels": [11, 12]}\ndatetime,src,dst,channel,mean_rssi,pdr,tx_count\n'
)
CELL = {"slot": 3, "channel": 0, "tx": "r1", "rx": "r2"}


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (
            _tsch(schedule=[CELL, {**CELL, "channel": 1, "rx": "gw", "tx": "r1"}]),
            "tsch.schedule[1]: node 'r1' is in two cells of slot 3",
        ),
        (
            _tsch(schedule=[CELL, {**CELL, "tx": "s_temp", "rx": "gw"}]),
            "tsch.schedule[1]: channel offset 0 of slot 3 is already used",
        ),
        (_tsch(schedule=[{**CELL, "channel": 9}]), "tsch.schedule[0].channel: channel offset 9"),
        (_tsch(schedule=[{**CELL, "slot": 240}]), "tsch.schedule[0].slot: 240 is outside"),
        (_tsch(schedule=[{**CELL, "tx": "r9"}]), "tsch.schedule[0].tx: unknown node 'r9'"),
        (_tsch(hopping=[11, 30]), "hopping[1]: channel 30 is not in channels"),
        (_tsch(channels=[10, 11]), "channels[0]: 10 is not an IEEE 802.15.4 channel"),
        (
            _tsch(slot_duration=0),
            "nodes.network.gateway.tsch.slot_duration: Input should be greater than 0",
        ),
        (_tsch(slot_duration=-0.01), "tsch.slot_duration: Input should be greater than 0"),
        (_tsch(slot_duration=1e-7), "must be a whole number >= 1 of ticks"),
        (_tsch(channel_offsets=20), "channel_offsets: 20 offsets need as many channels"),
        (_tsch(min_be=5, max_be=3), "min_be (5) must not exceed max_be (3)"),
        (_tsch(radio="cc9999"), "radio: unknown radio 'cc9999'"),
        (_tsch(link_model="trace"), "trace: link_model trace needs a trace"),
        (_no_position, "pathloss needs every node's position; 'r5' has none"),
        (_interference_per_hop, "interference needs a TSCH network (mac: tsch)"),
    ],
)
def test_a_bad_tsch_configuration_is_refused_naming_the_field(edit, message, tmp_path, capsys):
    path = write_variant(tmp_path, TSCH, "bad.yaml", edit)
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and message in err, err


@pytest.mark.parametrize(
    ("rows", "message"),
    [
        ("2018-01-11 16:33:00,1,2,11,-80,1.5,100\n", "links.k7:3:"),
        ("2018-01-11 16:33:00,1,2,11,-80,high,100\n", "links.k7:3:"),
        ("2018-01-11 16:33:00,1,2,99,-80,0.9,100\n", "links.k7:3:"),
        (
            "2018-01-11 16:33:00,1,2,11,-80,0.9,100\n2018-01-11 16:32:00,1,2,11,-80,0.9,100\n",
            "links.k7:4:",
        ),
    ],
)
def test_a_malformed_link_trace_is_refused_naming_its_line(rows, message, tmp_path, capsys):
    path = write_variant(tmp_path, TSCH, "bad.yaml", _trace(tmp_path, HEADER + rows))
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert message in err, err


def test_a_trace_is_read_from_the_scenarios_folder(tmp_path, capsys):
    rows = "".join(
        f"2018-01-11 16:33:00,{a},{b},{ch},-70,1.0,100\n"
        for a, b in (("s_level", "r1"), ("r1", "r2"), ("r2", "gw"), ("s_temp", "r2"))
        for a, b in ((a, b), (b, a))
        for ch in range(11, 27)
    )
    path = write_variant(
        tmp_path,
        TSCH,
        "good.yaml",
        _trace(tmp_path, HEADER.replace('"channels": [11, 12]', '"channels": []') + rows),
    )
    assert main(["validate", str(path)]) == 0, capsys.readouterr().err


def test_interference_is_injected_into_a_tsch_run_only(tmp_path):
    """``wncs inject DIR interference channels=[..] prr=..``: checked against the run's scenario
    (a TSCH gateway, known receivers) before anything is sent."""
    run = tmp_path / "run"
    run.mkdir()
    (run / "scenario.yaml").write_text(TSCH.read_text())
    words = ["channels=[15,20]", "prr=0.3", "duration=2"]
    request = build_request("interference", words, run_dir=run, network=None)
    assert request.event == {
        "type": "interference",
        "channels": [15, 20],
        "prr": 0.3,
        "duration": 2.0,
        "receivers": None,
    }
    with pytest.raises(ConfigError, match="receivers: unknown node 'r9'"):
        build_request("interference", [*words, 'receivers=["r9"]'], run_dir=run, network=None)
    with pytest.raises(ConfigError, match="channels"):
        build_request("interference", ["channels=[5]", "prr=0.3"], run_dir=run, network=None)
    wsn = tmp_path / "wsn"
    wsn.mkdir()
    (wsn / "scenario.yaml").write_text((SCENARIOS / "jcstr_wsn.yaml").read_text())
    with pytest.raises(ConfigError, match="interference needs a TSCH network"):
        build_request("interference", words, run_dir=wsn, network=None)
