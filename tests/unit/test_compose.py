"""compose.yaml: every node service runs a `wncs node` command the CLI accepts, for exactly the
benchmark scenario's nodes (plus the clock and historian), against the router service."""

from __future__ import annotations

import yaml

from runtime.cli import build_parser
from runtime.nodes import check_node
from runtime.scenario import load_scenario
from tests.conftest import ROOT


def test_compose_services_match_the_scenario():
    compose = yaml.safe_load((ROOT / "compose.yaml").read_text())
    services = compose["services"]
    assert "router" in services
    parser = build_parser()
    scenarios = set()
    names = set()
    for name, svc in services.items():
        if name == "router":
            continue
        cmd = svc["command"]
        assert cmd[0] == "wncs"
        args = parser.parse_args(cmd[1:])  # exits (SystemExit) if the command does not parse
        assert args.command == "node" and args.name == name
        assert args.connect == "tcp/router:7447"
        scenarios.add(args.scenario)
        names.add(args.name)
        assert "router" in svc["depends_on"]
    assert len(scenarios) == 1
    scenario = load_scenario(ROOT / scenarios.pop())
    assert names == {"clock", *scenario.participants()}
    for name in names - {"clock"}:
        check_node(scenario, name)  # every service is a node of the scenario
