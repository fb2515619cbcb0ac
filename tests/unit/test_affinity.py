"""``--affinity NAME=CPUS`` (runtime.affinity): parsed as taskset -c reads CPU lists, and refused
before anything starts, naming the item, when malformed or not applicable to the run."""

from __future__ import annotations

import os

import pytest

from core.errors import ConfigError
from runtime.affinity import check_affinity, cpus_of, parse_affinity

NAMES = ["clock", "historian", "reactor"]


def test_cpu_lists_and_ranges_parse_as_taskset_reads_them():
    affinity = parse_affinity(["*=0", "historian=1,3", "reactor=0-2,5", "router= 2 "])
    assert affinity == {
        "*": frozenset({0}),
        "historian": frozenset({1, 3}),
        "reactor": frozenset({0, 1, 2, 5}),
        "router": frozenset({2}),
    }
    # a process's own entry, else the others' ('*'), else any CPU
    assert cpus_of(affinity, "historian") == {1, 3}
    assert cpus_of(affinity, "clock") == {0}
    assert cpus_of({"reactor": frozenset({1})}, "clock") is None


@pytest.mark.parametrize(
    ("item", "says"),
    [
        ("reactor", "expected NAME=CPUS"),
        ("=0", "expected NAME=CPUS"),
        ("reactor=", "expected NAME=CPUS"),
        ("reactor=a", "'a' is not a CPU number or range"),
        ("reactor=0-x", "'0-x' is not a CPU number or range"),
        ("reactor=3-1", "'3-1' is not a CPU range"),
        ("reactor=-1", "'-1' is not a CPU number or range"),
    ],
)
def test_a_malformed_item_is_refused_naming_it(item, says):
    with pytest.raises(ConfigError, match=f"--affinity '{item}': .*{says}"):
        parse_affinity([item])


def test_a_process_given_twice_is_refused():
    with pytest.raises(ConfigError, match="'reactor' is given twice"):
        parse_affinity(["reactor=0", "reactor=1"])


def test_what_a_run_cannot_apply_is_refused_naming_the_process():
    usable = os.sched_getaffinity(0)
    one = frozenset({min(usable)})
    check_affinity({"*": one, "reactor": one, "router": one}, NAMES, "processes")  # fine
    check_affinity({"*": one, "router": one}, NAMES, "threads")  # fine
    with pytest.raises(ConfigError, match="pump=...: not a process of this run"):
        check_affinity({"pump": one}, NAMES, "processes")
    with pytest.raises(ConfigError, match="reactor=...: the threads engine runs .* in one"):
        check_affinity({"reactor": one}, NAMES, "threads")
    with pytest.raises(ConfigError, match="the direct engine"):
        check_affinity({"*": one}, NAMES, "direct")
    beyond = max(usable) + 1
    with pytest.raises(ConfigError, match=rf"reactor=...: CPU\(s\) \[{beyond}\] not available"):
        check_affinity({"reactor": frozenset({beyond})}, NAMES, "processes")
