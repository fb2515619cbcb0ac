"""Key-expression builders (DESIGN section 4).

Builders return keys *relative* to the run (``plant/reactor/sensor/H``); :func:`full` puts them
under ``wncs/<run>/``. Nodes, the historian and summaries speak relative keys, so a history does
not depend on the run id. Every name is checked to be one key chunk.
"""

from __future__ import annotations

import functools
import re

__all__ = [
    "PREFIX",
    "NAME_PATTERN",
    "check_name",
    "intersects",
    "full",
    "relative",
    "run_prefix",
    "tick",
    "tick_to",
    "done",
    "done_all",
    "working",
    "working_all",
    "stop",
    "tick_log",
    "alive",
    "alive_all",
    "sensor",
    "actuator",
    "plant_state",
    "meas",
    "move",
    "link_tx",
    "link_rx",
    "setpoint",
    "setpoint_all",
    "net_lost",
    "net_applied",
    "net_stats",
    "net_proposal",
    "inject",
    "network_events",
    "sampling",
    "drift",
    "loop_setpoint",
    "ops_mode",
    "wncsca_decision",
    "wncsca_rates",
    "wncsca_timing",
    "wncsca_model",
    "monitor_assessment",
    "DATA_ROOTS",
    "data_all",
]

PREFIX = "wncs"
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_\-]*$"
_NAME = re.compile(NAME_PATTERN)


def check_name(name: str, what: str = "name") -> str:
    """Return ``name`` if it is a valid single key chunk, else raise ``ValueError``."""
    if not isinstance(name, str) or not _is_name(name):
        raise ValueError(
            f"{what} {name!r} is not a valid key chunk (letters, digits, '_' and '-' only)"
        )
    return name


@functools.lru_cache(maxsize=4096)
def _is_name(name: str) -> bool:
    # nodes build the same few keys every round: match each name once
    return _NAME.match(name) is not None


def intersects(pattern: str, key: str) -> bool:
    """Whether key expression ``pattern`` matches the concrete key ``key`` (zenoh's semantics
    for the wildcards our patterns use: ``*`` is exactly one chunk, ``**`` zero or more).

    Engines that pass messages without a bus route by it; a test checks it against
    ``zenoh.KeyExpr.intersects`` on every key of the scenarios.
    """
    return _match(pattern.split("/"), key.split("/"))


def _match(pat: list[str], key: list[str]) -> bool:
    if not pat:
        return not key
    head = pat[0]
    if head == "**":
        return any(_match(pat[1:], key[i:]) for i in range(len(key) + 1))
    if not key:
        return False
    return (head == "*" or head == key[0]) and _match(pat[1:], key[1:])


def run_prefix(run: str) -> str:
    """``wncs/<run>``."""
    return f"{PREFIX}/{check_name(run, 'run id')}"


def full(run: str, rel: str) -> str:
    """The absolute key of run-relative key ``rel``."""
    return f"{run_prefix(run)}/{rel}"


def relative(run: str, key: str) -> str:
    """The run-relative part of absolute key ``key`` (``ValueError`` if it is not in the run)."""
    prefix = run_prefix(run) + "/"
    if not key.startswith(prefix):
        raise ValueError(f"key {key!r} is not under {prefix!r}")
    return key[len(prefix) :]


DATA_ROOTS = ("events", "link", "loop", "monitor", "net", "ops", "plant", "wncsca")
"""The first chunk of every data key. The rest of a run's keys are the clock's (``clock/...``:
ticks, Dones, the stop) and liveliness tokens (``alive/...``): control, not data."""


def data_all() -> tuple[str, ...]:
    """Every data key of a run, one key expression per root: what the historian records. (``**``
    would also bring it every tick addressed to a node and every node's Done, each a wake-up of
    its thread only to be dropped: about a third of what it received on the JCSTR benchmark.)"""
    return tuple(f"{root}/**" for root in DATA_ROOTS)


def tick() -> str:
    """The root of the ticks addressed to nodes (``clock/tick/<node>``); every tick is logged
    on :func:`tick_log`."""
    return "clock/tick"


def tick_to(node: str) -> str:
    """Where the clock sends ``node`` the ticks of the rounds it takes part in (and a tick every
    so many rounds, so that it knows how far the run has gone): ``clock/tick/<node>``."""
    return f"clock/tick/{check_name(node, 'node')}"


def done(node: str) -> str:
    return f"clock/done/{check_name(node, 'node')}"


def done_all() -> str:
    return "clock/done/*"


def working(node: str) -> str:
    """Where ``node`` says it is still working on a long round (``Working``, its progress
    heartbeat): ``clock/working/<node>``."""
    return f"clock/working/{check_name(node, 'node')}"


def working_all() -> str:
    return "clock/working/*"


def stop() -> str:
    return "clock/stop"


def tick_log() -> str:
    """Where the clock publishes its log of ticks (``TickLog``: every tick since the last log,
    and the stop at the end) for the observers and the run's watchers: ``clock/log``. One key
    carries both, so an observer sees the stop after every tick (zenoh's Python callbacks run
    in a thread per subscriber: two subscriptions have no common order)."""
    return "clock/log"


def alive(node: str) -> str:
    return f"alive/{check_name(node, 'node')}"


def alive_all() -> str:
    return "alive/*"


def sensor(plant: str, signal: str) -> str:
    """Sample taken at the sensor node, before the radio."""
    return f"plant/{check_name(plant, 'plant')}/sensor/{check_name(signal, 'signal')}"


def actuator(plant: str, input_name: str) -> str:
    """Command as delivered at the actuator."""
    return f"plant/{check_name(plant, 'plant')}/actuator/{check_name(input_name, 'input')}"


def plant_state(plant: str) -> str:
    """The plant's true state on its monitoring grid (for reports, not for control)."""
    return f"plant/{check_name(plant, 'plant')}/state"


def meas(loop: str) -> str:
    """Sample as delivered to the loop's controller."""
    return f"loop/{check_name(loop, 'loop')}/meas"


def move(loop: str) -> str:
    """Controller output, before the network."""
    return f"loop/{check_name(loop, 'loop')}/u"


def link_tx(link: str) -> str:
    """What a controller transmits on a link, before the network."""
    return f"link/{check_name(link, 'link')}/tx"


def link_rx(link: str) -> str:
    """What the network delivers on a link to the receiving controller."""
    return f"link/{check_name(link, 'link')}/rx"


def inject() -> str:
    """External inputs for the clock (not a participant's key)."""
    return "ops/inject"


def network_events(network: str) -> str:
    """Reconfiguration events for one gateway node, as stamped by the clock."""
    return f"events/{check_name(network, 'network')}"


def net_applied() -> str:
    """The network configuration in force, after each change."""
    return "net/applied"


def net_proposal() -> str:
    """A gateway's proposed configuration, for the coordination agent."""
    return "net/proposal"


def net_stats() -> str:
    """Energy of the WSN's nodes (per gateway node; the source names it)."""
    return "net/stats"


def net_lost() -> str:
    """Packets the network lost (one message per packet)."""
    return "net/lost"


def setpoint(loop: str) -> str:
    return f"ops/setpoint/{check_name(loop, 'loop')}"


def setpoint_all() -> str:
    return "ops/setpoint/*"


def drift(plant: str) -> str:
    """A change of the plant's physical parameters (the true plant's, not a model's)."""
    return f"plant/{check_name(plant, 'plant')}/drift"


def sampling(plant: str, signal: str) -> str:
    """Sampling period of one sensor, set by the network that carries its loop."""
    return f"plant/{check_name(plant, 'plant')}/sampling/{check_name(signal, 'signal')}"


def loop_setpoint(loop: str) -> str:
    """Set point as passed on to the controllers by the coordination agent."""
    return f"loop/{check_name(loop, 'loop')}/sp"


def ops_mode() -> str:
    """Operating-mode requests for the coordination agent."""
    return "ops/mode"


def wncsca_decision() -> str:
    """The coordination agent's verdicts."""
    return "wncsca/decision"


def wncsca_rates() -> str:
    """The coordination agent's sampling periods and loop states."""
    return "wncsca/rates"


def wncsca_timing() -> str:
    """Wall-clock decision times of the agent: measurements, excluded from the history digest."""
    return "wncsca/timing"


def wncsca_model() -> str:
    """The coordination agent's identified model: the estimate, its uncertainty and its fit."""
    return "wncsca/model"


def monitor_assessment(loop: str) -> str:
    """A performance monitor's assessment of one loop (Harris index, cascade opportunities)."""
    return f"monitor/assessment/{check_name(loop, 'loop')}"
