"""One registry shape (issue 13 item 4): what a registry refuses, and that a new control law is
its own module plus one registry entry, nothing else.

The second test copies the project's packages, adds a module with a trivial proportional law and
one ``Kind`` entry (with its import) to the copy's ``controllers/registry.py``, checks that these
are the only differences, and runs a scenario using the law on the direct engine in a fresh
process: every move must be the law's formula of the measurement it was computed from.
"""

from __future__ import annotations

import filecmp
import json
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Literal

import pytest
import yaml
from pydantic import BaseModel, ValidationError

from core.registry import Kind, Registry
from tests.test_layers import PACKAGES, ROOT


class _A(BaseModel):
    type: Literal["a"] = "a"
    x: float = 0.0


class _B(BaseModel):
    type: Literal["b"] = "b"


def test_a_registry_refuses_a_second_entry_and_a_tag_that_does_not_name_the_kind():
    reg: Registry[object] = Registry("thing", tag="type", kinds=[Kind("a", _A)])
    with pytest.raises(ValueError, match="thing 'a' is registered twice"):
        reg.register(Kind("a", _A))
    with pytest.raises(ValueError, match=r"_B.type must be Literal\['c'\]"):
        reg.register(Kind("c", _B))
    with pytest.raises(KeyError, match=r"unknown thing 'z' \(known: \['a'\]\)"):
        reg["z"]


def test_the_union_is_made_from_the_entries_and_builds_dispatch_by_tag():
    reg: Registry[object] = Registry(
        "thing", tag="type", kinds=[Kind("a", _A, lambda c: ("built a", c.x)), Kind("b", _B)]
    )

    class Holder(BaseModel):
        thing: reg.union()  # type: ignore[valid-type]

    a = Holder.model_validate({"thing": {"type": "a", "x": 2.5}}).thing
    assert isinstance(a, _A) and reg.build(a) == ("built a", 2.5)
    b = Holder.model_validate({"thing": {"type": "b"}}).thing
    assert reg.build(b) is b  # no build: the configuration is the object
    with pytest.raises(ValidationError, match="does not match any of the expected tags"):
        Holder.model_validate({"thing": {"type": "c"}})


LAW_MODULE = '''
"""A trivial law for the registry test: u = u0 + k (r - y), clipped."""

from typing import Literal

from pydantic import BaseModel, ConfigDict


class PropConfig(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")
    type: Literal["prop"] = "prop"
    k: float
    u0: float
    u_min: float
    u_max: float


class Prop:
    def __init__(self, config, *, u_bar=0.0):
        self.config = config

    def reset(self):
        pass

    def resume(self, t):
        pass

    def step(self, t, y, r):
        c = self.config
        return min(max(c.u0 + c.k * (r - y), c.u_min), c.u_max)
'''

ENTRY = '        Kind("prop", PropConfig, Prop, "test: a proportional law"),\n'
IMPORT = "from controllers.prop import Prop, PropConfig\n"

RUN = """
import json, sys
sys.path.insert(0, sys.argv[1])
from runtime.direct import simulate
from scenario import load_scenario
rec = simulate(load_scenario(sys.argv[2]))
loop = rec.loops["level"]
print(json.dumps({"y": loop.y, "u": loop.u, "t": loop.t, "sp": loop.setpoints}))
"""


def _run(tree: Path, scenario: Path) -> subprocess.CompletedProcess[str]:
    """``scenario`` on the direct engine in a fresh process importing the packages of ``tree``."""
    return subprocess.run(
        [sys.executable, "-c", RUN, str(tree), str(scenario)],
        capture_output=True,
        text=True,
        check=False,
        cwd=scenario.parent,
    )


def _copy_with_law(tree: Path) -> None:
    for pkg in PACKAGES:
        shutil.copytree(ROOT / pkg, tree / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    (tree / "controllers" / "prop.py").write_text(LAW_MODULE)
    registry = tree / "controllers" / "registry.py"
    text = registry.read_text()
    anchor = "from core.registry import Kind, Registry\n"
    assert anchor in text and "    kinds=[\n" in text
    text = text.replace(anchor, IMPORT + anchor, 1)
    text = text.replace(
        '    "law",\n    tag="type",\n    kinds=[\n',
        '    "law",\n    tag="type",\n    kinds=[\n' + ENTRY,
        1,
    )
    registry.write_text(text)


def _differences(a: Path, b: Path, where: str = "") -> list[str]:
    """Files that differ or exist on one side only, relative to ``a`` and ``b``."""
    cmp = filecmp.dircmp(a, b, ignore=["__pycache__"])
    found = [f"{where}{n}" for n in cmp.diff_files + cmp.right_only + cmp.left_only]
    for name in cmp.common_dirs:
        found += _differences(a / name, b / name, f"{where}{name}/")
    return found


@pytest.mark.slow
def test_a_new_law_is_a_module_and_a_registry_entry(tmp_path):
    tree = tmp_path / "tree"
    _copy_with_law(tree)
    changed = [f"{pkg}/{d}" for pkg in PACKAGES for d in _differences(ROOT / pkg, tree / pkg)]
    assert sorted(changed) == ["controllers/prop.py", "controllers/registry.py"]
    registry_lines = set((tree / "controllers" / "registry.py").read_text().splitlines())
    original = set((ROOT / "controllers" / "registry.py").read_text().splitlines())
    assert registry_lines - original == {ENTRY.rstrip("\n"), IMPORT.rstrip("\n")}

    data = yaml.safe_load((ROOT / "scenarios" / "jcstr_benchmark.yaml").read_text())
    law = {"type": "prop", "k": -3.0, "u0": 9.0, "u_min": 0.0, "u_max": 19.0}
    data["nodes"]["level_controller"]["law"] = law
    scenario = tmp_path / "prop.yaml"
    scenario.write_text(yaml.safe_dump(data))
    done = _run(tree, scenario)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    setpoints = sorted(out["sp"])
    assert len(out["u"]) > 50
    clipped = 0
    for t, y, u in zip(out["t"], out["y"], out["u"], strict=True):
        r = [v for ts, v in setpoints if ts <= t][-1]
        expected = min(max(9.0 + -3.0 * (r - y), 0.0), 19.0)
        assert u == expected, (t, y, r, u)
        clipped += expected in (0.0, 19.0)
    assert clipped < len(out["u"])  # the law acted, not only its limits

    # the same scenario is refused by the project as it is: no such law
    refused = _run(ROOT, scenario)
    assert refused.returncode != 0 and "'prop'" in refused.stderr


# -- a node kind -----------------------------------------------------------------------------
KIND_MODULE = '''
"""A trivial node kind for the registry test: a beacon that publishes its count every period."""

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from bus_schemas import Setpoint
from core.behaviour import Behaviour
from core.time import to_ticks


class BeaconConfig(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")
    kind: Literal["beacon"]
    period: float = Field(gt=0)


class BeaconBehaviour(Behaviour):
    def __init__(self, name, config):
        super().__init__(name)
        self.count = 0
        self.every(to_ticks(config.period), self._beat)

    def _beat(self):
        self.publish("events/beacon", Setpoint(value=float(self.count)))
        self.count += 1
'''

KIND_IMPORT = "from agents.beacon import BeaconBehaviour, BeaconConfig\n"
KIND_ENTRY = (
    '        Kind("beacon", BeaconConfig, BehaviourBuild(BeaconBehaviour, '
    "lambda scenario, name: scenario.node(name, BeaconConfig))),\n"
)
UNION_MEMBER = "    | BeaconConfig\n"

RUN_KIND = """
import json, sys
sys.path.insert(0, sys.argv[1])
from core.time import to_ticks
from runtime.direct import behaviour_of
from runtime.engine import DirectEngine
from scenario import load_scenario
sc = load_scenario(sys.argv[2])
seen = []
DirectEngine(
    {n: behaviour_of(sc, n) for n in sorted(sc.nodes)},
    end=to_ticks(sc.end_time),
    max_microsteps=sc.clock.max_microsteps,
    on_round=lambda ms: seen.extend((m.t, m.body.value) for m in ms if m.key == "events/beacon"),
).run()
print(json.dumps(seen))
"""


def _copy_with_kind(tree: Path) -> None:
    for pkg in PACKAGES:
        shutil.copytree(ROOT / pkg, tree / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    (tree / "agents" / "beacon.py").write_text(KIND_MODULE)
    kinds = tree / "scenario" / "kinds.py"
    text = kinds.read_text()
    anchor, entries = "from core.behaviour import Behaviour\n", '    tag="kind",\n    kinds=[\n'
    assert anchor in text and entries in text
    kinds.write_text(
        text.replace(anchor, KIND_IMPORT + anchor, 1).replace(entries, entries + KIND_ENTRY, 1)
    )
    schema = tree / "scenario" / "schema.py"
    text = schema.read_text()
    anchor, last = "from bus_schemas import Setpoint, keys\n", "    | MonitorNodeConfig,\n"
    assert anchor in text and last in text
    text = text.replace(anchor, KIND_IMPORT + anchor, 1)
    schema.write_text(text.replace(last, UNION_MEMBER + last, 1))


@pytest.mark.slow
def test_a_new_node_kind_is_a_module_a_registry_entry_and_its_union_member(tmp_path):
    tree = tmp_path / "tree"
    _copy_with_kind(tree)
    changed = [f"{pkg}/{d}" for pkg in PACKAGES for d in _differences(ROOT / pkg, tree / pkg)]
    assert sorted(changed) == ["agents/beacon.py", "scenario/kinds.py", "scenario/schema.py"]
    data = yaml.safe_load((ROOT / "scenarios" / "jcstr_benchmark.yaml").read_text())
    data["nodes"]["beacon"] = {"kind": "beacon", "period": 0.5}
    scenario = tmp_path / "beacon.yaml"
    scenario.write_text(yaml.safe_dump(data))
    done = subprocess.run(
        [sys.executable, "-c", RUN_KIND, str(tree), str(scenario)],
        capture_output=True,
        text=True,
        check=False,
        cwd=scenario.parent,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    seen = json.loads(done.stdout.strip().splitlines()[-1])
    n = int(data["end_time"] / 0.5) + 1  # at 0, 0.5, ..., end_time: the timers due up to the end
    assert seen == [[k * 500_000, float(k)] for k in range(n)]
    refused = _run(ROOT, scenario)  # the project as it is has no such kind
    assert refused.returncode != 0 and "beacon" in refused.stderr
