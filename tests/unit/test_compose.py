"""compose.yaml: a secure router service and every node service run commands the CLI accepts,
for exactly the benchmark scenario's nodes (plus the clock and historian), on the router's run
and with their own credentials; the image holds every package the project installs."""

from __future__ import annotations

import tomllib

import yaml

from cli.main import build_parser
from runtime.nodes import check_node
from scenario import load_scenario
from tests.conftest import ROOT


def test_compose_services_match_the_scenario():
    compose = yaml.safe_load((ROOT / "compose.yaml").read_text())
    services = compose["services"]
    parser = build_parser()
    router = parser.parse_args(services["router"]["command"][1:])
    assert router.command == "router" and not router.insecure  # secure: the default
    assert router.listen == "tcp/0.0.0.0:7447" and router.run_id
    health = services["router"]["healthcheck"]["test"]
    assert health == ["CMD", "test", "-f", f"{router.out}/run.json"]  # written once it listens
    scenarios = {router.scenario}
    names = set()
    for name, svc in services.items():
        if name == "router":
            continue
        cmd = svc["command"]
        assert cmd[0] == "wncs"
        args = parser.parse_args(cmd[1:])  # exits (SystemExit) if the command does not parse
        assert args.command == "node" and args.name == name
        assert args.connect == "tcp/router:7447" and args.run_id == router.run_id
        assert svc["depends_on"] == {"router": {"condition": "service_healthy"}}
        assert svc["environment"]["WNCS_SECURITY"] == f"{router.out}/security"
        assert any(v.endswith(":/runs") for v in svc["volumes"])
        scenarios.add(args.scenario)
        names.add(args.name)
    assert len(scenarios) == 1
    scenario = load_scenario(ROOT / scenarios.pop())
    assert names == {"clock", *scenario.participants()}
    for name in names - {"clock"}:
        check_node(scenario, name)  # every service is a node of the scenario


def test_the_image_holds_every_package_the_project_installs():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    packages = {p.rstrip("*") for p in project["tool"]["setuptools"]["packages"]["find"]["include"]}
    copied = {
        line.split()[1]
        for line in (ROOT / "Dockerfile").read_text().splitlines()
        if line.startswith("COPY ")
    }
    assert packages <= copied
    assert "requirements.lock" in copied  # installed from the lock, as make does
