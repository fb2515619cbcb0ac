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
from runtime.scenario import load_scenario
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
