"""What a ``wncs`` sub-command is: a row of the command table (:data:`cli.main.COMMANDS`).

A :class:`Command` has its name, its one-line help, its description, the examples its help ends
with, and the pair that makes it: ``add(parser)`` declares its arguments and ``run(args)`` runs
it (an exit code). Each command module keeps the two side by side. The helpers here are the
arguments several commands share.
"""

from __future__ import annotations

import argparse
import textwrap
from collections.abc import Callable
from dataclasses import dataclass

__all__ = ["Command", "positive_float", "add_set", "fill"]

WIDTH = 79  # descriptions are filled to this; the examples are kept as written


@dataclass(frozen=True)
class Command:
    """One ``wncs`` sub-command."""

    name: str
    help: str
    add: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]
    examples: tuple[str, ...]
    """The commands its help ends with: shipped scenarios only (a test parses each)."""
    description: str | None = None
    """Its description (default: the help, capitalised); laid out already if it has lines."""

    def declare(self, sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
        """Add this command to ``sub`` with its arguments; its help ends with its examples."""
        parser = sub.add_parser(
            self.name,
            help=self.help,
            description=fill(self.description or self.help[0].upper() + self.help[1:] + "."),
            epilog=epilog(self.examples),
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        self.add(parser)


def fill(text: str) -> str:
    """A description filled to the help's width, unless it is laid out already (has lines)."""
    return text if "\n" in text else textwrap.fill(text, WIDTH)


def epilog(examples: tuple[str, ...]) -> str:
    """The end of a help: its examples, one command a line."""
    return "examples:\n" + "\n".join(f"  {line}" for line in examples)


def positive_float(text: str) -> float:
    """An argument that must be a number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value


def add_set(parser: argparse.ArgumentParser) -> None:
    """``--set PATH=VALUE`` (repeatable): an override of the scenario before it is validated."""
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="PATH=VALUE",
        help="override a field of the scenario before it is validated, e.g. "
        "loops.level.tau_s=0.2 or setpoints.0.value=0.8 (the value is YAML; repeatable)",
    )
