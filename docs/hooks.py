"""MkDocs hook: the reference pages, generated from the code every time the site is built.

``on_files`` adds these pages to the site without writing them to disk, so they cannot go stale
or be edited by hand:

* ``reference/cli.md`` from the argparse parser of :mod:`cli.main` (``build_parser``);
* ``reference/scenario/*.md`` from the pydantic models: :class:`scenario.Scenario`, one
  page per node kind of :data:`scenario.kinds.NODE_KINDS`, the plant models
  (:data:`plants.registry.MODELS`), control laws (:data:`controllers.registry.LAWS`) and per-hop
  delay models (:data:`gateway.delay_models.DELAY_MODELS`): every field with its type, unit (where
  the description ends with one), default, bounds and description;
* ``reference/bus.md`` from :mod:`bus_schemas` (the key builders, the envelope, every body);
* ``reference/bench.md``: each ``bench/*.py`` with the first paragraph of its docstring (read
  with ``ast``, nothing imported).

:func:`pages` returns them as ``{path: markdown}``; ``tests/unit/test_docs.py`` checks them
against the models.
"""

from __future__ import annotations

import argparse
import ast
import html
import inspect
import math
import re
import types
import typing
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import annotated_types
from mkdocs.structure.files import File, Files
from pydantic import BaseModel
from pydantic.fields import FieldInfo

from bus_schemas import bodies, keys
from bus_schemas.envelope import SCHEMA_VERSION, Envelope
from cli.main import EXAMPLES, build_parser
from controllers.registry import LAWS
from core.registry import Registry
from gateway.delay_models import DELAY_MODELS
from plants.registry import MODELS
from scenario import NODE_KINDS, Scenario

__all__ = ["pages", "on_config", "on_files", "SCENARIO_DIR", "kind_page", "field_names"]

ROOT = Path(__file__).resolve().parents[1]
SCENARIO_DIR = "reference/scenario"
_WIDTH = 100  # usage lines of the CLI reference

# -- the scenario reference -------------------------------------------------------------------


def kind_page(kind: str) -> str:
    """The page of node kind ``kind`` (``reference/scenario/<kind>.md``)."""
    return f"{SCENARIO_DIR}/{kind}.md"


def field_names(model: type[BaseModel]) -> list[str]:
    """The names a scenario file uses for ``model``'s fields (aliases where a field has one)."""
    return [f.alias or name for name, f in model.model_fields.items()]


_REGISTRY_PAGES: tuple[tuple[Registry[Any], str], ...] = (
    (NODE_KINDS, "{name}.md"),
    (LAWS, "laws.md#{name}"),
    (DELAY_MODELS, "delay-models.md#{name}"),
)


def _registry_link(model: type[BaseModel]) -> str | None:
    """Where ``model`` is documented if it configures a registered kind (pages of the same
    directory), else ``None``."""
    for registry, page in _REGISTRY_PAGES:
        for name, kind in registry.kinds.items():
            if kind.config is model:
                return page.format(name=name)
    return None


def _registry_of(members: Iterable[Any]) -> tuple[str, str] | None:
    """``(what, link)`` when ``members`` are exactly the configurations of one registry."""
    members = set(members)
    for registry, page in _REGISTRY_PAGES:
        if members == {k.config for k in registry.kinds.values()}:
            target = page.split("#")[0] if registry is not NODE_KINDS else "index.md#node-kinds"
            return registry.what, target
    return None


def _anchor(model: type[BaseModel]) -> str:
    return model.__name__.lower()


def _bounds(metadata: Iterable[Any]) -> list[str]:
    out = []
    for m in metadata:
        for attr, sign in (("gt", ">"), ("ge", "≥"), ("lt", "<"), ("le", "≤")):
            if isinstance(m, getattr(annotated_types, attr.capitalize())):
                out.append(f"{sign} {_plain(getattr(m, attr))}")
        if isinstance(m, annotated_types.MinLen):
            out.append(f"length ≥ {m.min_length}")
        if isinstance(m, annotated_types.MaxLen):
            out.append(f"length ≤ {m.max_length}")
    return out


class _Types:
    """Renders annotations as Markdown, collecting the nested models a page must document."""

    def __init__(self) -> None:
        self.nested: list[type[BaseModel]] = []

    def __call__(self, ann: Any) -> str:
        origin = typing.get_origin(ann)
        args = typing.get_args(ann)
        if ann is type(None):
            return "`null`"
        if ann is Any:
            return "any"
        if origin is typing.Annotated:
            inner = self(args[0])
            extra: list[str] = []
            for meta in args[1:]:
                if isinstance(meta, FieldInfo):
                    extra += _bounds(meta.metadata)
            return f"{inner} ({', '.join(extra)})" if extra else inner
        if origin is typing.Literal:
            return " or ".join(f"`{_plain(a)}`" for a in args)
        if origin in (typing.Union, types.UnionType):
            known = _registry_of(a for a in args if a is not type(None))
            if known is not None:
                what, link = known
                text = f"a [{what}]({link})"
                return f"{text} or `null`" if type(None) in args else text
            return " or ".join(self(a) for a in args)
        if origin is dict:
            return f"mapping {self(args[0])} → {self(args[1])}"
        if origin in (list, tuple, set, frozenset):
            if origin is tuple and not (len(args) == 2 and args[1] is Ellipsis):
                return "[" + ", ".join(self(a) for a in args) + "]"
            return f"list of {self(args[0])}"
        if isinstance(ann, type) and issubclass(ann, BaseModel):
            link = _registry_link(ann)
            if link is not None:
                return f"[{ann.__name__}]({link})"
            if ann not in self.nested:
                self.nested.append(ann)
            return f"[{ann.__name__}](#{_anchor(ann)})"
        if isinstance(ann, type):
            return f"`{ann.__name__}`"
        return f"`{_plain(ann)}`"


def _plain(value: Any) -> str:
    """A value as YAML flow text (floats without numpy's repr, ``inf``, ``null``)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float) or hasattr(value, "dtype"):
        value = float(value)
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, list | tuple | set | frozenset):
        return "[" + ", ".join(_plain(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {_plain(v)}" for k, v in value.items()) + "}"
    return str(value)


def _default(field: FieldInfo) -> str:
    if field.is_required():
        return "required"
    value = field.default_factory() if field.default_factory is not None else field.default  # type: ignore[call-arg]
    if isinstance(value, BaseModel):
        return "its defaults"
    return f"`{_plain(value)}`"


_UNIT_TOKEN = re.compile(r"^\(?[A-Za-z%]{1,4}(\^-?\d+)?\)?$|[/^]")
_UNIT_WORDS = {"time", "unit", "units", "scenario", "samples", "percentage", "points", "per-unit"}
_NOT_UNITS = {
    *("the", "a", "an", "of", "or", "and", "to", "in", "is", "one", "at", "by", "on", "for"),
    *("if", "any", "all", "none", "not", "no", "each", "per", "as", "then", "else", "its"),
}


def unit_of(description: str) -> str:
    """The unit a description ends with (``..., m^3/h``; ``..., time units``), or ``""``."""
    text = re.sub(r"\s+\([^()]*\)\s*$", "", description.strip())
    if "," not in text:
        return ""
    last = text.rsplit(",", 1)[1].strip()
    words = last.split()
    if not 1 <= len(words) <= 3 or any(w.lower() in _NOT_UNITS for w in words):
        return ""
    if all(w in _UNIT_WORDS or _UNIT_TOKEN.search(w) for w in words):
        return last
    return ""


def _escape(text: str) -> str:
    """Markdown text without raw HTML or emphasis; code spans (in backticks) kept as they are."""
    parts = text.replace("``", "`").split("`")  # RST literals are code spans too
    for i in range(0, len(parts), 2):
        parts[i] = html.escape(parts[i], quote=False).replace("*", "\\*")
    return "`".join(parts)


def _cell(text: str) -> str:
    """Text safe in a Markdown table cell: :func:`_escape`, and no column breaks."""
    return _escape(" ".join(text.split())).replace("|", "&#124;")


def _first_paragraph(doc: str | None) -> str:
    if not doc:
        return ""
    return inspect.cleandoc(doc).split("\n\n")[0].replace("\n", " ")


def _doc_text(doc: str | None) -> str:
    """A docstring's first paragraph as Markdown: RST ``literals`` become code spans."""
    text = _first_paragraph(doc)
    text = re.sub(r":\w+:`~?([^`]+)`", r"`\1`", text)
    return _escape(text.replace("``", "`"))


def model_table(model: type[BaseModel], render: _Types) -> list[str]:
    """One row per field of ``model``: name, type, unit, default, bounds, description."""
    rows = [
        "| field | type | unit | default | bounds | description |",
        "|---|---|---|---|---|---|",
    ]
    for name, field in model.model_fields.items():
        description = field.description or ""
        cells = (
            f"`{field.alias or name}`",
            render(field.annotation),
            _cell(unit_of(description)),
            _default(field),
            ", ".join(_bounds(field.metadata)),
            _cell(description),
        )
        rows.append(f"| {' | '.join(cells)} |")
    return rows


def model_sections(
    root: type[BaseModel], *, level: int = 2, intro: str = "", title: str | None = None
) -> list[str]:
    """``root``'s table and, after it, one section per nested model it refers to."""
    render = _Types()
    out: list[str] = []
    queue: list[type[BaseModel]] = [root]
    done: set[type[BaseModel]] = set()
    while queue:
        model = queue.pop(0)
        if model in done:
            continue
        done.add(model)
        heading = title if model is root and title else model.__name__
        out += [f"{'#' * level} {heading}", ""]
        text = intro if model is root and intro else _doc_text(model.__doc__)
        if text:
            out += [text, ""]
        out += [*model_table(model, render), ""]
        queue += [m for m in render.nested if m not in done]
    return out


_LEGEND = (
    "Columns: the field's name in the YAML file; its type (a link names a model documented "
    "below or on another page); the unit where the field's description gives one; the default "
    "(`required`: the field must be given); bounds checked on load; the description from the "
    "model. Generated from the pydantic models when the site is built."
)


def _scenario_index() -> str:
    lines = [
        "# Scenario reference",
        "",
        "A scenario file is YAML validated into `scenario.Scenario` before anything runs "
        "(see [Scenario files](../../scenarios.md)). `wncs schema` prints the same models as a "
        "JSON Schema.",
        "",
        _LEGEND,
        "",
        "## Node kinds",
        "",
        "Each entry of `nodes:` is one of these, chosen by its `kind:` field:",
        "",
        "| `kind:` | configuration | what |",
        "|---|---|---|",
    ]
    for name, kind in NODE_KINDS.kinds.items():
        what = kind.doc or _first_paragraph(kind.config.__doc__)
        lines.append(f"| [`{name}`]({name}.md) | `{kind.config.__name__}` | {_cell(what)} |")
    lines += [
        "",
        "Plant models (`model:` of a plant node): [plant models](plants.md); control laws "
        "(`law:` of a controller node): [control laws](laws.md); per-hop delay models of a "
        "gateway's topology: [delay models](delay-models.md).",
        "",
    ]
    lines += model_sections(Scenario, title="The scenario file (top level)")
    return "\n".join(lines)


def _kind_page(name: str) -> str:
    kind = NODE_KINDS[name]
    intro = _doc_text(kind.config.__doc__) or _escape(kind.doc)
    lines = [
        f"# Node kind `{name}`",
        "",
        f"`kind: {name}` in `nodes:` (configuration `{kind.config.__module__}."
        f"{kind.config.__name__}`). [All node kinds](index.md#node-kinds).",
        "",
        _LEGEND,
        "",
    ]
    lines += model_sections(kind.config, intro=intro, title=f"`{name}` fields")
    return "\n".join(lines)


def _registry_page(registry: Registry[Any], title: str, intro: str, tag_note: str) -> str:
    lines = [f"# {title}", "", intro, "", _LEGEND, ""]
    for name, kind in registry.kinds.items():
        text = kind.doc or _first_paragraph(kind.config.__doc__)
        lines += model_sections(
            kind.config,
            title=name,
            intro=f"{_cell(text)} ({tag_note.format(name=name)}, configuration "
            f"`{kind.config.__module__}.{kind.config.__name__}`).",
        )
    return "\n".join(lines)


def scenario_pages() -> dict[str, str]:
    """The scenario reference: the index, one page per node kind, models, laws, delay models."""
    out = {f"{SCENARIO_DIR}/index.md": _scenario_index()}
    for name in NODE_KINDS.kinds:
        out[kind_page(name)] = _kind_page(name)
    out[f"{SCENARIO_DIR}/plants.md"] = _registry_page(
        MODELS,
        "Plant models",
        "A plant node names its model (`model:`) and gives its parameters (`params:`, by the "
        "paper's symbols). The tables are the parameter models.",
        "`model: {name}`",
    )
    out[f"{SCENARIO_DIR}/laws.md"] = _registry_page(
        LAWS,
        "Control laws",
        "A controller node's `law:` is one of these, chosen by its `type:` field.",
        "`type: {name}`",
    )
    out[f"{SCENARIO_DIR}/delay-models.md"] = _registry_page(
        DELAY_MODELS,
        "Per-hop delay models",
        "A gateway topology's `delay:` (and a link's own `delay:`) is one of these, chosen by its "
        "`type:` field: the delay of one transmission attempt over one hop.",
        "`type: {name}`",
    )
    return out


# -- the CLI reference -----------------------------------------------------------------------


def _usage(parser: argparse.ArgumentParser) -> str:
    fmt = argparse.HelpFormatter(parser.prog, width=_WIDTH)
    fmt.add_usage(parser.usage, parser._actions, parser._mutually_exclusive_groups)
    return fmt.format_help().strip()


def _arguments(parser: argparse.ArgumentParser) -> list[str]:
    rows = ["| argument | help | default |", "|---|---|---|"]
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction | argparse._SubParsersAction):
            continue
        if action.option_strings:
            name = ", ".join(action.option_strings)
            if action.nargs != 0:
                name += f" {action.metavar or action.dest.upper()}"
        else:
            name = action.metavar or action.dest
        help_text = action.help or ""
        if action.choices:
            help_text += f" (one of: {', '.join(map(str, action.choices))})"
        if action.required and action.option_strings:
            help_text += " (required)"
        default = action.default
        shown = "" if default in (None, False, [], argparse.SUPPRESS) else f"`{default}`"
        rows.append(f"| `{name}` | {_cell(help_text)} | {shown} |")
    return rows


def cli_page() -> str:
    """The CLI reference: usage, arguments and examples of ``wncs`` and each subcommand."""
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    lines = [
        "# Command line reference",
        "",
        "Generated from the argparse parser of `cli/` when the site is built; "
        "`wncs COMMAND --help` prints the same.",
        "",
        "```text",
        _usage(parser),
        "```",
        "",
        _escape(parser.description or ""),
        "",
        "| command | what |",
        "|---|---|",
    ]
    helps = {a.dest: a.help for a in sub._choices_actions}
    for name in sub.choices:
        lines.append(f"| [`wncs {name}`](#wncs-{name}) | {_cell(helps.get(name) or '')} |")
    lines += ["", *_arguments(parser), ""]
    for name, command in sub.choices.items():
        lines += [
            f"## wncs {name}",
            "",
            "```text",
            _usage(command),
            "```",
            "",
            "```text",
            command.description or "",
            "```",
            "",
            *_arguments(command),
            "",
            "Examples:",
            "",
            "```bash",
            *EXAMPLES[name],
            "```",
            "",
        ]
    return "\n".join(lines)


# -- the bus contract ------------------------------------------------------------------------

_NOT_BUILDERS = {"check_name", "intersects", "full", "relative", "run_prefix"}


def _key_builders() -> list[tuple[str, Callable[..., str]]]:
    return [
        (name, getattr(keys, name))
        for name in keys.__all__
        if callable(getattr(keys, name)) and name not in _NOT_BUILDERS
    ]


def key_pattern(builder: Callable[..., str]) -> str:
    """The key ``builder`` makes, with its arguments as ``<name>``."""
    params = list(inspect.signature(builder).parameters)
    key = builder(*(f"ARG{i}" for i in range(len(params))))
    for i, param in enumerate(params):
        key = key.replace(f"ARG{i}", f"<{param}>")
    return key


def bus_page() -> str:
    """Key builders, the envelope and every message body, from ``bus_schemas``."""
    lines = [
        "# Bus reference: keys and bodies",
        "",
        "Generated from `bus_schemas/` when the site is built. See [the bus contract]"
        "(../bus.md) for how messages travel and how the schemas are versioned.",
        "",
        "## Keys",
        "",
        f"Every key is under `{keys.PREFIX}/<run>/`; the builders of `bus_schemas/keys.py` make "
        "the run-relative part, and check that each name is one key chunk "
        f"(`{keys.NAME_PATTERN}`).",
        "",
        "| builder | key | what |",
        "|---|---|---|",
    ]
    for name, builder in _key_builders():
        what = _cell(_first_paragraph(builder.__doc__))
        lines.append(f"| `keys.{name}` | `{key_pattern(builder)}` | {what} |")
    lines += [
        "",
        f"## Envelope (schema version {SCHEMA_VERSION})",
        "",
    ]
    lines += model_sections(Envelope, level=3, title="Envelope")
    lines += ["## Bodies", ""]
    done: set[type[BaseModel]] = set()
    for name in bodies.__all__:
        model = getattr(bodies, name)
        if model in done:
            continue
        done.add(model)
        lines += model_sections(model, level=3)
    return "\n".join(lines)


# -- the benchmarks --------------------------------------------------------------------------


def bench_page() -> str:
    """Each ``bench/*.py`` with the first paragraph of its docstring."""
    lines = [
        "# Benchmark scripts",
        "",
        "Every script in `bench/` with the first paragraph of its docstring (read from the "
        "source when the site is built). Run one with `.venv/bin/python bench/NAME.py`; "
        "measured figures are on [Benchmarks](../benchmarks.md) and the seed pages.",
        "",
        "| script | what |",
        "|---|---|",
    ]
    for path in sorted((ROOT / "bench").glob("*.py")):
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
        text = _first_paragraph(doc).rstrip(":").replace("``", "`")
        lines.append(f"| `bench/{path.name}` | {_cell(text)} |")
    return "\n".join(lines) + "\n"


# -- mkdocs ----------------------------------------------------------------------------------


def pages() -> dict[str, str]:
    """Every generated page, ``{path under docs/: markdown}``."""
    out = scenario_pages()
    out["reference/cli.md"] = cli_page()
    out["reference/bus.md"] = bus_page()
    out["reference/bench.md"] = bench_page()
    return out


def scenario_nav() -> list[Any]:
    """The navigation of the scenario reference: the index, each node kind, the registries."""
    return [
        f"{SCENARIO_DIR}/index.md",
        *({name: kind_page(name)} for name in NODE_KINDS.kinds),
        {"Plant models": f"{SCENARIO_DIR}/plants.md"},
        {"Control laws": f"{SCENARIO_DIR}/laws.md"},
        {"Delay models": f"{SCENARIO_DIR}/delay-models.md"},
    ]


def _expand_nav(items: list[Any]) -> None:
    index = f"{SCENARIO_DIR}/index.md"
    for item in items:
        if not isinstance(item, dict):
            continue
        for title, value in item.items():
            if value == index:
                item[title] = scenario_nav()
            elif isinstance(value, list):
                _expand_nav(value)


def on_config(config: Any) -> Any:
    """MkDocs event: the nav entry of the scenario reference becomes a page per node kind."""
    _expand_nav(config["nav"] or [])
    return config


def on_files(files: Files, config: Any) -> Files:
    """MkDocs event: add the generated pages to the site."""
    for path, content in pages().items():
        files.append(File.generated(config, path, content=content))
    return files
