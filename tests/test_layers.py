"""The layers of DESIGN section 2, enforced on the source (an ``ast`` walk, no imports run).

Lowest first; a module imports only from its own layer or below::

    0 bus_schemas   the contract (message models, keys, codec): imports nothing of ours
    1 core          ticks, errors, metrics, records, the behaviour base, the round planner
    2 cores         plants/, controllers/, gateway/, agents/ (numpy, scipy, control, pydantic)
    3 behaviours    <package>/behaviour.py: what a node kind does at time t, bus-free
    3 kernel        kernel/: round loop, clock, zenoh sessions; imports only core + bus_schemas
    4 scenario      scenario/: the YAML schema, the checks across it, one typed spec per node,
                    the node kinds' registry, reading the file (positions, --set)
    5 application   runtime/ (launcher, engines, reports, inject, assess, sweeps), wncs/ (the
                    notebook API), dashboard/ (the live web page); runtime/ may not import
                    the dashboard (the CLI joins them)
    6 cli           cli/: the wncs command line, a table of sub-commands

and: only the kernel imports zenoh; only the codec imports msgpack; no import inside a function
except optional heavy ones (matplotlib). ``test_the_rules_catch_*`` checks that each rule fails
on a forbidden import, so this test can fail.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = (
    "bus_schemas",
    "core",
    "plants",
    "controllers",
    "gateway",
    "agents",
    "kernel",
    "runtime",
    "scenario",
    "wncs",
    "cli",
    "dashboard",
)

BUS, CORE, CORES, BEHAVIOURS, KERNEL, SCENARIO, APPLICATION, CLI = 0, 1, 2, 3, 3, 4, 5, 6
NAMES = {
    0: "bus_schemas",
    1: "core",
    2: "cores",
    3: "behaviours/kernel",
    4: "scenario",
    5: "app",
    6: "cli",
}

LAZY_ALLOWED = (
    "matplotlib",
    "pandas",
    "control",
    "scipy.stats",
    "scipy.signal",
)
"""Heavy imports that may sit inside functions: optional ones, and those a node rarely needs
(python-control brings matplotlib.pyplot, scipy.signal and scipy.stats half a second each: the
fork server would import them for every run, and the benchmark's nodes never call them;
``bench/startup.py``)."""

# What the foundation refit (issue 13) has not cut yet, as ``module -> imported``: each entry is
# a known violation, listed so the rest is enforced today. The list may only shrink
# (``test_no_stale_exceptions``); an import not on it fails the test.
NOT_YET_CUT: dict[str, set[str]] = {}  # everything is cut (issue 13); keep it empty


@dataclass(frozen=True)
class Import:
    module: str  # the importing module
    target: str  # what it imports (dotted)
    line: int
    in_function: bool


def layer(module: str) -> int:
    top = module.split(".")[0]
    if top == "bus_schemas":
        return BUS
    if top == "core":
        return CORE
    if top == "kernel":
        return KERNEL
    if top == "scenario":
        return SCENARIO
    if top == "cli":
        return CLI
    if top in ("runtime", "wncs", "dashboard"):
        return APPLICATION
    if module.rsplit(".", 1)[-1] == "behaviour":
        return BEHAVIOURS
    return CORES


def imports_of(module: str, source: str) -> list[Import]:
    tree = ast.parse(source)
    found: list[Import] = []

    def visit(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            inner = in_function or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef)
            if isinstance(child, ast.Import):
                found.extend(Import(module, a.name, child.lineno, in_function) for a in child.names)
            elif isinstance(child, ast.ImportFrom) and child.module and child.level == 0:
                found.append(Import(module, child.module, child.lineno, in_function))
                found.extend(
                    Import(module, f"{child.module}.{a.name}", child.lineno, in_function)
                    for a in child.names
                    if _is_module(f"{child.module}.{a.name}")
                )
            visit(child, inner)

    visit(tree, False)
    return found


def _is_module(dotted: str) -> bool:
    path = ROOT.joinpath(*dotted.split("."))
    return path.with_suffix(".py").exists() or (path / "__init__.py").exists()


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def project_imports() -> list[Import]:
    out: list[Import] = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            out += imports_of(_module_name(path), path.read_text())
    return out


def violations(imports: list[Import]) -> list[str]:
    bad: list[str] = []
    for imp in imports:
        top = imp.target.split(".")[0]
        where = f"{imp.module}:{imp.line}: imports {imp.target}"
        if top == "zenoh" and not imp.module.startswith("kernel."):
            bad.append(f"{where} (only the kernel imports zenoh)")
        if top == "msgpack" and imp.module != "bus_schemas.codec":
            bad.append(f"{where} (only bus_schemas.codec imports msgpack)")
        if imp.in_function and not any(
            imp.target == lazy or imp.target.startswith(lazy + ".") for lazy in LAZY_ALLOWED
        ):
            bad.append(f"{where} inside a function (only {LAZY_ALLOWED} may be lazy)")
        if top not in PACKAGES:
            continue
        mine, theirs = layer(imp.module), layer(imp.target)
        in_kernel = imp.module.split(".")[0] == "kernel"
        if in_kernel and top not in ("kernel", "core", "bus_schemas"):
            bad.append(f"{where} (the kernel imports only core and bus_schemas)")
        elif not in_kernel and top == "kernel" and mine < SCENARIO:
            bad.append(f"{where} ({NAMES[mine]} may not import the kernel)")
        elif theirs > mine:
            bad.append(f"{where} ({NAMES[mine]} may not import {NAMES[theirs]})")
        elif imp.module.split(".")[0] == "runtime" and top == "dashboard":
            bad.append(f"{where} (runtime may not import the dashboard; the CLI joins them)")
    return bad


def _known(imp: Import) -> bool:
    return imp.target in NOT_YET_CUT.get(imp.module, ())


def test_the_project_keeps_its_layers():
    bad = violations([imp for imp in project_imports() if not _known(imp)])
    assert not bad, "layer violations:\n" + "\n".join(bad)


def test_no_stale_exceptions():
    """Every listed exception is still a violation: a cut one must leave the list."""
    flagged = {(i.module, i.target) for i in project_imports() if violations([i])}
    stale = [(m, t) for m, ts in NOT_YET_CUT.items() for t in ts if (m, t) not in flagged]
    assert not stale, f"no longer violations, remove from NOT_YET_CUT: {stale}"


@pytest.mark.parametrize(
    ("module", "source", "why"),
    [
        ("bus_schemas.keys", "from core.errors import ConfigError\n", "bus_schemas may not"),
        ("core.record", "from plants.jcstr import JCSTR\n", "core may not"),
        ("plants.jcstr", "from scenario import Scenario\n", "cores may not"),
        ("controllers.pi", "import zenoh\n", "only the kernel imports zenoh"),
        ("gateway.carrier", "import msgpack\n", "only bus_schemas.codec"),
        ("kernel.node", "from plants.registry import PLANTS\n", "the kernel imports only"),
        ("gateway.behaviour", "from kernel.node import BusNode\n", "may not import the kernel"),
        ("scenario.schema", "from runtime.launcher import launch\n", "scenario may not import app"),
        ("runtime.launcher", "from cli.main import main\n", "app may not import cli"),
        ("runtime.launcher", "from dashboard import command\n", "runtime may not import the dash"),
        ("agents.wncsca.model", "def f():\n    from runtime.direct import simulate\n", "inside"),
    ],
)
def test_the_rules_catch_a_forbidden_import(module, source, why):
    bad = violations(imports_of(module, source))
    assert any(why in b for b in bad), bad


def test_a_lazy_matplotlib_import_is_allowed():
    assert violations(imports_of("agents.wncsca.plots", "def f():\n    import matplotlib\n")) == []


# -- dispatch through registries -------------------------------------------------------------
# Generic code asks a registry (core.registry) or a scenario's typed accessors (nodes_of,
# carriers, is_wireless), never compares a node kind's, law's or plant model's name itself.
# Where such a name means something else, the use is listed with why.
NAME_COMPARES_ALLOWED = {
    # a WSN topology's own node roles (gateway, relay, sensor), not node kinds
    ("gateway.topology", "gateway"),
    ("scenario.schema", "gateway"),
}
TAG_FIELDS = ("kind", "type", "model")


def _registered_names() -> set[str]:
    names: set[str] = set()
    for registry in ("scenario/kinds.py", "controllers/registry.py", "plants/registry.py"):
        tree = ast.parse((ROOT / registry).read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "Kind":
                first = node.args[0] if node.args else None
                if isinstance(first, ast.Constant) and isinstance(first.value, str):
                    names.add(first.value)
    return names


def name_compares(module: str, source: str, names: set[str]) -> list[str]:
    """``x.kind == "plant"``, ``cfg.type != "pi"``, ``node.kind in ("network", ...)``."""
    found: list[str] = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Compare):
            continue
        sides = [node.left, *node.comparators]
        tagged = any(isinstance(s, ast.Attribute) and s.attr in TAG_FIELDS for s in sides)
        if not tagged:
            continue
        for side in sides:
            consts = side.elts if isinstance(side, ast.Tuple | ast.List | ast.Set) else [side]
            for c in consts:
                if isinstance(c, ast.Constant) and c.value in names:
                    if (module, c.value) not in NAME_COMPARES_ALLOWED:
                        found.append(f"{module}:{node.lineno}: compares a name: {c.value!r}")
    return found


def test_generic_code_dispatches_through_registries():
    names = _registered_names()
    assert {"plant", "controller", "gateway", "pi", "jcstr"} <= names  # the walk finds them
    bad: list[str] = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            bad += name_compares(_module_name(path), path.read_text(), names)
    assert not bad, "compare names instead of asking a registry:\n" + "\n".join(bad)


@pytest.mark.parametrize(
    "source",
    [
        'if cfg.kind == "plant":\n    pass\n',
        'ok = node.kind in ("network", "gateway")\n',
        'if law.type != "pi":\n    pass\n',
    ],
)
def test_the_dispatch_rule_catches_a_name_compare(source):
    assert name_compares("runtime.records", source, _registered_names())


# -- no scenario below the scenario layer -----------------------------------------------------
# Below the scenario layer nothing may take a scenario: each node kind and core is handed a
# typed spec computed once (scenario/views.py: PlantSpec, ..., AgentSpec, RunShape). A core that
# could not import the Scenario type would take one as ``Any``; so below the layer no function
# has a parameter named ``scenario``, and no module names ``Scenario`` (an alias such as
# ``Scenario = Any``, a string annotation, a TYPE_CHECKING import the layer rule already bans).
SCENARIO_NAMES = ("scenario", "Scenario")


def scenario_uses(module: str, source: str) -> list[str]:
    """Where ``source`` (module ``module``) takes or names a scenario."""
    if layer(module) >= SCENARIO:
        return []
    found: list[str] = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.arg) and node.arg in SCENARIO_NAMES:
            found.append(f"{module}:{node.lineno}: takes a scenario ({node.arg!r})")
        elif isinstance(node, ast.Name) and node.id == "Scenario":
            found.append(f"{module}:{node.lineno}: names Scenario")
        elif isinstance(node, ast.Constant) and node.value == "Scenario":
            found.append(f"{module}:{node.lineno}: names Scenario (a string annotation)")
    return found


def test_nothing_below_the_scenario_layer_takes_a_scenario():
    bad: list[str] = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            bad += scenario_uses(_module_name(path), path.read_text())
    assert not bad, "a scenario below the scenario layer (hand it a spec):\n" + "\n".join(bad)


@pytest.mark.parametrize(
    ("module", "source"),
    [
        ("agents.wncsca.trials", "from typing import Any\nScenario = Any\n"),
        ("agents.wncsca.coordinator", "def build(scenario, name):\n    return scenario\n"),
        ("agents.monitor.columns", "def f(x: 'Scenario') -> None:\n    pass\n"),
        ("gateway.carrier", "class C:\n    def __init__(self, *, scenario=None):\n        pass\n"),
    ],
)
def test_the_scenario_rule_catches_a_scenario_below_its_layer(module, source):
    assert scenario_uses(module, source)


def test_the_scenario_layer_and_the_application_may_take_a_scenario():
    source = "def spec(scenario: Scenario) -> None:\n    pass\n"
    assert scenario_uses("scenario.views", source) == []
    assert scenario_uses("runtime.launcher", source) == []


# -- no import circle ------------------------------------------------------------------------
# Modules that import each other (directly or around a circle) are one room in two files, and
# the order in which they load decides what works: no circle, anywhere. (The scenario package,
# issue 34, dissolved the last one: the schema and the node specs.)


def import_circles(imports: list[Import]) -> list[frozenset[str]]:
    """The sets of modules that import each other, directly or around a circle (the strongly
    connected components of the import graph with more than one module)."""
    modules = {imp.module for imp in imports}
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for imp in imports:
        target = imp.target
        while target and target not in modules:  # `from a.b import name` imports module a.b
            target = target.rpartition(".")[0]
        if target and target != imp.module:
            graph[imp.module].add(target)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles: list[frozenset[str]] = []

    def visit(v: str) -> None:  # Tarjan's algorithm
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                circles.append(frozenset(component))

    for m in sorted(modules):
        if m not in index:
            visit(m)
    return circles


def test_no_module_imports_itself_around_a_circle():
    circles = [sorted(c) for c in import_circles(project_imports())]
    assert not circles, f"import circles: {circles}"


def test_the_circle_rule_catches_a_circle():
    imports = [
        *imports_of("agents.wncsca.model", "from agents.wncsca.trials import Trials\n"),
        *imports_of("agents.wncsca.trials", "from agents.wncsca.spec import Step\n"),
        *imports_of("agents.wncsca.spec", "from agents.wncsca.model import LoopModel\n"),
        *imports_of("agents.wncsca.paper", "from agents.wncsca.model import LoopModel\n"),
    ]
    assert import_circles(imports) == [
        frozenset({"agents.wncsca.model", "agents.wncsca.trials", "agents.wncsca.spec"})
    ]


# -- ticks only through core/time.py ---------------------------------------------------------
TICK_MODULE = "core.time"


def tick_literals(module: str, source: str) -> list[str]:
    """Where ``source`` writes the ticks per time unit itself (``1_000_000``, ``1e6``) instead of
    converting through :mod:`core.time` (``to_ticks``, ``to_units``, ``TICKS_PER_UNIT``)."""
    if module == TICK_MODULE:
        return []
    return [
        f"{module}:{node.lineno}: {node.value!r} (convert with core.time)"
        for node in ast.walk(ast.parse(source))
        if isinstance(node, ast.Constant)
        and type(node.value) in (int, float)
        and node.value == 1_000_000
    ]


def test_time_is_converted_only_through_core_time():
    bad: list[str] = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            bad += tick_literals(_module_name(path), path.read_text())
    assert not bad, "tick arithmetic outside core/time.py:\n" + "\n".join(bad)


@pytest.mark.parametrize("source", ["t = x / 1e6\n", "n = round(p * 1_000_000)\n"])
def test_the_tick_rule_catches_a_literal(source):
    assert tick_literals("agents.monitor.run_data", source)
