"""The README and the documentation site (issue 17, items 1 and 2).

* The README is a front door: under 200 lines, the two commands, every shipped scenario named.
* Every fenced block marked ``<!-- runnable -->`` in the README and under ``docs/`` is run, one
  command a line, in a temporary directory with a copy of ``scenarios/`` and a link to the venv
  (the convention is in ``docs/contributing.md``); each command must exit 0.
* The generated scenario reference (``docs/hooks.py``) has, for every node kind, the scenario, the
  plant models, the laws and the delay models, a table whose rows are exactly the model's fields,
  and one for every model nested in them; the models are walked here independently of the hook.
* The CLI and bus references name every command, option, key builder and body.
* ``mkdocs build --strict`` succeeds (slow).
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import typing
from pathlib import Path
from typing import Any

import pytest
from pydantic import BaseModel

from bus_schemas import bodies
from cli.main import build_parser
from controllers.registry import LAWS
from core.registry import Registry
from gateway.delay_models import DELAY_MODELS
from plants.registry import MODELS
from scenario import NODE_KINDS, Scenario

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
DOCS = ROOT / "docs"
VENV = Path(sys.prefix)  # the venv the tests run in (make test: the repository's .venv)
MARKER = "<!-- runnable -->"


def _load_hooks() -> Any:
    spec = importlib.util.spec_from_file_location("docs_hooks", DOCS / "hooks.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


HOOKS = _load_hooks()
PAGES: dict[str, str] = HOOKS.pages()


# -- the README -------------------------------------------------------------------------------


def test_the_readme_is_a_front_door_under_200_lines():
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) < 200
    first_block = text.split("```")[1]
    assert "make demo" in first_block and "make test" in first_block
    for target in ("demo:", "test:", "docs:"):
        assert f"\n{target}" in (ROOT / "Makefile").read_text(encoding="utf-8"), target
    for scenario in sorted((ROOT / "scenarios").glob("*.yaml")):
        assert scenario.stem in text, f"README names no {scenario.name}"
    assert "../shared" not in text  # the design notes are not in the repository


def test_every_seed_page_exists_and_is_linked_from_the_readme():
    text = README.read_text(encoding="utf-8")
    seeds = sorted((DOCS / "seeds").glob("*.md"))
    assert [p.name[:3] for p in seeds] == ["000", "001", "002", "003", "004"]
    for page in seeds:
        assert f"(docs/seeds/{page.name})" in text


# -- runnable commands ------------------------------------------------------------------------


def runnable_blocks(text: str, where: str = "<text>") -> list[list[str]]:
    """The commands of each fenced block right after a ``<!-- runnable -->`` line."""
    lines = text.splitlines()
    blocks = []
    for i, line in enumerate(lines):
        if line.strip() != MARKER:
            continue
        j = i + 1
        if j >= len(lines) or not lines[j].startswith("```"):
            raise ValueError(f"{where}: line {i + 1}: {MARKER} must be followed by a fenced block")
        commands = []
        for body in lines[j + 1 :]:
            if body.startswith("```"):
                break
            if body.strip() and not body.lstrip().startswith("#"):
                commands.append(body.strip())
        else:
            raise ValueError(f"{where}: line {j + 1}: the fenced block is not closed")
        blocks.append(commands)
    return blocks


def _documents() -> list[Path]:
    return [README, *sorted(DOCS.rglob("*.md"))]


COMMANDS = [
    (str(path.relative_to(ROOT)), command)
    for path in _documents()
    for block in runnable_blocks(path.read_text(encoding="utf-8"), str(path))
    for command in block
]


def test_the_runnable_marker_is_parsed_and_misuse_refused():
    text = f"a\n{MARKER}\n```bash\nwncs --help   # a comment\n\n# only a comment\nwncs x\n```\n"
    assert runnable_blocks(text) == [["wncs --help   # a comment", "wncs x"]]
    with pytest.raises(ValueError, match="must be followed by a fenced block"):
        runnable_blocks(f"{MARKER}\n\n```bash\nx\n```\n")
    with pytest.raises(ValueError, match="not closed"):
        runnable_blocks(f"{MARKER}\n```bash\nx\n")
    readme = [c for where, c in COMMANDS if where == "README.md"]
    assert any("wncs analyze" in c for c in readme) and any("wncs validate" in c for c in readme)


@pytest.mark.parametrize(
    ("where", "command"), COMMANDS, ids=[f"{w}: {c[:60]}" for w, c in COMMANDS]
)
def test_a_runnable_command_exits_0(where, command, tmp_path):
    shutil.copytree(ROOT / "scenarios", tmp_path / "scenarios")
    (tmp_path / ".venv").symlink_to(VENV, target_is_directory=True)
    env = {**os.environ, "PATH": f"{VENV / 'bin'}{os.pathsep}{os.environ.get('PATH', '')}"}
    env["MPLBACKEND"] = "Agg"
    result = subprocess.run(
        ["bash", "-e", "-o", "pipefail", "-c", command],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert result.returncode == 0, (
        f"{where}: {command!r} exited {result.returncode}\n"
        f"{result.stdout[-3000:]}\n{result.stderr[-3000:]}"
    )


# -- the scenario reference -------------------------------------------------------------------


def _sections(page: str) -> dict[str, set[str]]:
    """Heading text -> the first column (field names) of the table under it."""
    out: dict[str, set[str]] = {}
    current = None
    for line in page.splitlines():
        heading = re.match(r"^#{1,6} (.+)$", line)
        if heading:
            current = heading.group(1).strip()
            out.setdefault(current, set())
            continue
        row = re.match(r"^\| `([^`]+)` \|", line)
        if row and current is not None:
            out[current].add(row.group(1))
    return out


def _fields(model: type[BaseModel]) -> set[str]:
    return {f.alias or name for name, f in model.model_fields.items()}


def _registered() -> set[type[BaseModel]]:
    registries: list[Registry[Any]] = [NODE_KINDS, LAWS, DELAY_MODELS]
    return {k.config for r in registries for k in r.kinds.values()}


def _nested(model: type[BaseModel]) -> list[type[BaseModel]]:
    """Every model reachable from ``model``'s fields, other than registered configurations
    (documented on their own pages), in no particular order."""
    found: list[type[BaseModel]] = []
    todo = [f.annotation for f in model.model_fields.values()]
    while todo:
        ann = todo.pop()
        if isinstance(ann, type) and issubclass(ann, BaseModel):
            if ann not in found and ann not in _registered() and ann is not model:
                found.append(ann)
                todo += [f.annotation for f in ann.model_fields.values()]
            continue
        todo += list(typing.get_args(ann))  # unions, containers, Annotated (FieldInfo: no args)
    return found


def _assert_documented(page: str, heading: str, model: type[BaseModel], where: str) -> None:
    sections = _sections(page)
    assert heading in sections, f"{where}: no section {heading!r}"
    assert sections[heading] == _fields(model), f"{where}: {heading}"
    for nested in _nested(model):
        assert nested.__name__ in sections, f"{where}: no section for {nested.__name__}"
        assert sections[nested.__name__] == _fields(nested), f"{where}: {nested.__name__}"


@pytest.mark.parametrize("kind", sorted(NODE_KINDS.kinds))
def test_every_field_of_every_node_kind_is_on_its_page(kind):
    config = NODE_KINDS[kind].config
    page = PAGES[HOOKS.kind_page(kind)]
    _assert_documented(page, f"`{kind}` fields", config, kind)
    rows = {m.group(1): m.group(0) for m in re.finditer(r"^\| `([^`]+)` \|.*$", page, re.M)}
    for name, field in config.model_fields.items():
        cells = [c.strip() for c in rows[field.alias or name].split(" | ")]
        if field.is_required():
            assert cells[3] == "required", (kind, name)
        for meta in field.metadata:
            for attr, sign in (("gt", ">"), ("ge", "≥"), ("lt", "<"), ("le", "≤")):
                if hasattr(meta, attr):
                    assert sign in cells[4], (kind, name, cells[4])


def test_the_scenario_and_every_plant_law_and_delay_model_are_documented():
    scenario = PAGES[f"{HOOKS.SCENARIO_DIR}/index.md"]
    _assert_documented(scenario, "The scenario file (top level)", Scenario, "index")
    for kind in NODE_KINDS.kinds:
        assert f"]({kind}.md)" in scenario
    for registry, page in (
        (MODELS, "plants.md"),
        (LAWS, "laws.md"),
        (DELAY_MODELS, "delay-models.md"),
    ):
        text = PAGES[f"{HOOKS.SCENARIO_DIR}/{page}"]
        for name, kind in registry.kinds.items():
            _assert_documented(text, name, kind.config, page)


def test_a_field_added_to_a_model_is_missed_by_a_stale_page():
    """The check compares the page with the model: a page without the new field's row fails."""

    class Grown(NODE_KINDS["operator"].config):  # type: ignore[misc, valid-type]
        extra_field: int = 0

    page = PAGES[HOOKS.kind_page("operator")]
    with pytest.raises(AssertionError):
        _assert_documented(page, "`operator` fields", Grown, "operator")


def test_units_come_from_the_descriptions():
    assert HOOKS.unit_of("fresh feed flow to CSTR 1, m^3/h") == "m^3/h"
    assert HOOKS.unit_of("gas constant, kJ/(kmol K)") == "kJ/(kmol K)"
    assert HOOKS.unit_of("dead time from the move to the primary, samples (default: d1 + d2)") == (
        "samples"
    )
    assert HOOKS.unit_of("between monitoring and control: loops open, faster reports") == ""
    assert HOOKS.unit_of("largest RK4 integration step") == ""
    plants = PAGES[f"{HOOKS.SCENARIO_DIR}/plants.md"]
    assert "| `F0` | `float` | m^3/h | required | > 0 |" in plants


# -- the CLI and bus references ---------------------------------------------------------------


def test_the_cli_reference_names_every_command_and_option():
    page = PAGES["reference/cli.md"]
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, command in sub.choices.items():
        assert f"## wncs {name}" in page
        for action in command._actions:
            if isinstance(action, argparse._HelpAction):
                continue  # -h/--help: on every command, not listed
            for option in action.option_strings:
                assert f"`{option}" in page or f", {option}" in page, (name, option)


def test_the_bus_reference_has_every_body_and_key_builder():
    page = PAGES["reference/bus.md"]
    sections = _sections(page)
    for name in bodies.__all__:
        assert sections.get(name) == _fields(getattr(bodies, name)), name
    for name in ("sensor", "meas", "move", "net_proposal", "wncsca_rates", "monitor_assessment"):
        assert f"`keys.{name}`" in page
    assert "`plant/<plant>/sensor/<signal>`" in page


def test_the_bench_page_lists_every_script():
    page = PAGES["reference/bench.md"]
    for script in sorted((ROOT / "bench").glob("*.py")):
        assert f"`bench/{script.name}`" in page


# -- the site ---------------------------------------------------------------------------------


@pytest.mark.slow
def test_the_site_builds_in_strict_mode(tmp_path):
    site = tmp_path / "site"
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
        cwd=ROOT,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    for kind in NODE_KINDS.kinds:
        assert (site / "reference" / "scenario" / kind / "index.html").is_file()
    assert (site / "seeds" / "000-wncsca" / "index.html").is_file()
