"""The notebook API (issue 17, item 5): ``docs/notebook.md`` runs as a notebook would and its
numbers equal the command line's; overrides are validated like the file; plots leave the
backend alone; the linearised loop is checked against the direct engine and closed forms.
"""

from __future__ import annotations

import csv
import json
import re
import shutil
from pathlib import Path

import control  # noqa: TID253 - not a node: imports what it uses at the top
import numpy as np
import pytest

import wncs
from cli.main import main
from controllers.pi import PI, PIConfig
from controllers.pi_linear import pi_state_space
from plants.sampled import sampled_with_delay, zoh_with_delay
from runtime.report import write_plots

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "notebook.md"
BENCH = ROOT / "scenarios" / "jcstr_benchmark.yaml"


def notebook_cells(text: str) -> list[str]:
    """The python blocks right after a ``<!-- notebook -->`` line, in order."""
    return re.findall(r"<!-- notebook -->\n```python\n(.*?)```", text, re.S)


@pytest.fixture(scope="module")
def notebook(tmp_path_factory):
    """The page's cells run in order in one namespace, in a directory with ``scenarios/``."""
    where = tmp_path_factory.mktemp("notebook")
    shutil.copytree(ROOT / "scenarios", where / "scenarios")
    cells = notebook_cells(PAGE.read_text(encoding="utf-8"))
    assert len(cells) >= 5
    import matplotlib.pyplot as plt

    namespace: dict = {}
    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(where)
        for k, cell in enumerate(cells):
            exec(compile(cell, f"{PAGE.name}, cell {k + 1}", "exec"), namespace)  # noqa: S102
    plt.close("all")
    return where, namespace


def _csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def _num(cell: str) -> float | None:
    return None if cell == "" else float(cell)


def test_the_notebook_equals_the_command_line(notebook, tmp_path, capsys):
    _, ns = notebook
    out = tmp_path / "cli"
    args = ["--engine", "direct", "--set", "loops.level.tau_s=0.2", "--out", str(out), "--quiet"]
    assert main(["run", str(BENCH), *args]) == 0
    summary = json.loads((out / "summary.json").read_text())
    figures = ns["result"].figures()
    for loop, entry in summary["loops"].items():
        for name in ("overshoot_pct", "settling_time", "iae"):
            assert figures.loc[loop, name] == entry[name], (loop, name)
    # the DataFrame is wncs export's CSV of the CLI's run
    assert main(["export", str(out), "--csv", "--out", str(tmp_path / "csv")]) == 0
    rows = _csv(tmp_path / "csv" / "loop_level.csv")
    level = ns["level"]
    assert list(level.columns) == list(rows[0])
    for column in level.columns:
        assert list(level[column]) == [_num(r[column]) for r in rows], column
    # the threads run over Zenoh equals the direct run
    assert ns["same"] is True
    assert (
        ns["bus"].summary["loops"]["level"]["overshoot_pct"]
        == figures.loc["level", "overshoot_pct"]
    )
    # the sweep is wncs sweep's table
    grid = ["--grid", "loops.level.tau_s=0.1,0.2,0.3", "--jobs", "1"]
    assert main(["sweep", str(BENCH), *grid, "--out", str(tmp_path / "sweep")]) == 0
    cli_rows = _csv(tmp_path / "sweep" / "sweep.csv")
    table = ns["table"]
    assert len(table) == len(cli_rows) == 3
    for column in cli_rows[0]:
        assert list(table[column]) == [_num(r[column]) for r in cli_rows], column


def test_the_notebook_refusal_names_the_field(notebook):
    _, ns = notebook
    assert "loops.level.tau_s: Input should be greater than 0" in ns["refused"]


def test_values_are_validated_like_the_file():
    sc = wncs.load(BENCH)
    with pytest.raises(wncs.ConfigError) as from_python:
        wncs.with_values(sc, {"loops.level.tau_s": -0.1})
    with pytest.raises(wncs.ConfigError) as from_file:
        wncs.load(BENCH, ["loops.level.tau_s=-0.1"])
    field = "loops.level.tau_s: Input should be greater than 0"
    assert field in str(from_python.value) and field in str(from_file.value)
    with pytest.raises(wncs.ConfigError, match="loops has no key 'levle'"):
        wncs.with_values(sc, {"loops.levle.tau_s": 0.2})
    with pytest.raises(wncs.ConfigError, match="end_time"):
        wncs.run(sc, {"end_time": "soon"})
    changed = wncs.with_values(sc, {"loops.level.tau_s": 0.2, "seed": 3})
    assert changed.loops["level"].tau_s == 0.2 and changed.seed == 3
    assert sc.loops["level"].tau_s == 0.1  # the original is untouched


def test_plots_leave_the_backend_and_pyplots_figures_alone(tmp_path):
    import matplotlib
    import matplotlib.pyplot as plt

    backend = matplotlib.get_backend()
    plt.close("all")
    result = wncs.run(BENCH, {"end_time": 3.0})
    before = plt.get_fignums()
    write_plots(result.record, tmp_path)
    assert (tmp_path / "level.png").is_file()
    assert plt.get_fignums() == before and matplotlib.get_backend() == backend
    fig = plt.figure()
    axes = result.plot(["level"])
    assert plt.gcf() is fig and len(fig.axes) == 2 and axes[0] is fig.axes[0]
    t, y = result.record.plants["reactor"].signal("H")
    line = axes[0].lines[0]
    assert np.array_equal(line.get_xdata(), t) and np.array_equal(line.get_ydata(), y)
    assert matplotlib.get_backend() == backend
    plt.close("all")


# -- the linear loop -----------------------------------------------------------------------


def _linear_against_engine(values: dict, loop: str, step_at: float, size: float):
    """The loop's closed linear response to the scenario's set points, against the direct
    engine started at the equilibrium: (largest error in y, largest in u, largest |y - y_bar|)."""
    sc = wncs.load(BENCH, values)
    lin = wncs.linearized_loop(sc, loop)
    at_rest = {"nodes.reactor.x0": lin.x_bar, "nodes.reactor.u0": lin.u_bar}
    steps = {"setpoints": [{"t": step_at, "loop": loop, "value": lin.y_bar + size}]}
    df = wncs.run(wncs.with_values(sc, {**at_rest, **steps})).loops[loop].to_pandas()
    r = df["setpoint"].to_numpy() - lin.y_bar
    resp = control.forced_response(lin.closed, T=np.arange(len(r)) * lin.tau_s, U=r)
    y = resp.outputs[0] + lin.y_bar
    u = resp.outputs[1] + lin.u_bar[lin.actuator]
    y_run, u_run = df["y"].to_numpy(), df["u"].to_numpy()
    return np.abs(y - y_run).max(), np.abs(u - u_run).max(), np.abs(y_run - lin.y_bar).max()


@pytest.mark.parametrize(
    "values",
    [
        {},
        {"loops.level.tau_d": 0.2},  # a whole number of periods
        {"loops.level.tau_d": 0.17},  # a fractional delay
        {"loops.level.tau_s": 0.25, "loops.level.tau_d": 0.17, "loops.level.tau_a": 0.05},
    ],
    ids=["no delay", "two periods", "fractional", "sensor and actuator paths"],
)
def test_the_linear_level_loop_is_the_direct_engines(values):
    """The JCSTR level is linear (dH/dt = (F_in - F_out)/A_B) and its PI does not saturate on a
    0.05 pu step: the exact discretisation must give the engine's samples and moves."""
    dy, du, moved = _linear_against_engine({**values, "end_time": 6.0}, "level", 1.0, 0.05)
    assert moved > 0.04  # the loop did respond
    assert dy < 1e-10 and du < 1e-10


def test_the_linear_temperature_loop_errs_by_the_square_of_the_step():
    """The temperature dynamics are non-linear: the linear model's error is second order in the
    step, so halving the step quarters it (a first-order mistake would only halve it)."""
    values = {"end_time": 4.0}
    big, _, moved_big = _linear_against_engine(values, "temperature", 1.0, 0.4)
    small, _, moved_small = _linear_against_engine(values, "temperature", 1.0, 0.2)
    assert moved_big > 0.4 and moved_small > 0.2
    assert 3.0 < big / small < 5.0
    assert small < 0.02 * 0.2


def test_zoh_with_a_fractional_delay_has_the_first_order_closed_form():
    """x' = -a x + b u, delay tau_d = l h + theta: Gamma0 = b/a (1 - e^{-a (h - theta)}),
    Gamma1 = e^{-a (h - theta)} b/a (1 - e^{-a theta}) (Astrom & Wittenmark, section 2.3)."""
    a, b, h = 2.0, 3.0, 0.1
    for tau_d, whole, theta in ((0.0, 0, 0.0), (0.07, 0, 0.07), (0.17, 1, 0.07), (0.3, 3, 0.0)):
        Phi, g0, g1, got_whole = zoh_with_delay(np.array([[-a]]), np.array([[b]]), h, tau_d)
        assert got_whole == whole
        assert Phi[0, 0] == pytest.approx(np.exp(-a * h), rel=1e-12)
        assert g0[0, 0] == pytest.approx(b / a * (1 - np.exp(-a * (h - theta))), rel=1e-12)
        expected = np.exp(-a * (h - theta)) * b / a * (1 - np.exp(-a * theta))
        assert g1[0, 0] == pytest.approx(expected, rel=1e-12, abs=1e-15)


def test_a_whole_delay_is_the_zoh_system_times_z_to_the_minus_l():
    plant = control.ss([[-1.0, 0.5], [0.0, -3.0]], [[0.0], [2.0]], [[1.0, 0.0]], [[0.0]])
    h = 0.1
    delayed = sampled_with_delay(plant, h, 3 * h)
    expected = control.sample_system(plant, h, "zoh") * control.tf([1], [1, 0, 0, 0], h)
    w = np.exp(1j * np.linspace(0.01, 3.0, 25))
    got = np.array([complex(delayed(z)) for z in w])
    want = np.array([complex(expected(z)) for z in w])
    assert np.allclose(got, want, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("integration", ["forward", "backward"])
def test_the_pi_state_space_is_the_pi_law(integration):
    """The discrete PI as a state space equals the law executed at a constant period (no
    saturation), from its second execution on (the first has no integral increment in both)."""
    cfg = PIConfig(Kp=1.7, Ki=0.9, integration=integration, feedforward="none")
    h = 0.25
    rng = np.random.default_rng(4)
    r = rng.normal(size=40)
    y = rng.normal(size=40)
    law = PI(cfg)
    u_law = np.array([law.step(k * h, y[k], r[k]) for k in range(40)])
    sys = pi_state_space(cfg, h)
    # the law's first execution adds no increment: start the state at -Ki h e_0 (backward)
    x0 = [-cfg.Ki * h * (r[0] - y[0])] if integration == "backward" else [0.0]
    resp = control.forced_response(sys, T=np.arange(40) * h, U=np.vstack([r, y]), X0=x0)
    assert np.allclose(resp.outputs, u_law, rtol=0, atol=1e-12)
