"""Plots of the MRAC's signals against time (seed 003, Fig. 6.3-6.5) and of its adaptation.

The figure functions draw arrays of any origin: ``bench/mrac_study.py`` passes its own discrete
runs, and the run report (``wncs run`` / ``wncs report``, through :mod:`controllers.law_plots`)
passes a platform run's executions to :func:`figures`, which replays the law over them
(:func:`series`, built on :func:`controllers.mrac.replay`): ``x_m``, ``e`` and ``theta`` are the
law's own and not on the bus.

* :func:`states_figure`: plant states ``x`` (as the law used them, one dot per execution) and the
  reference model's ``x_m`` (Fig. 6.3);
* :func:`outputs_figure`: outputs ``y`` and ``y_m = C_m x_m`` (Fig. 6.4);
* :func:`errors_figure`: the state error ``e = x - x_m`` (Fig. 6.5);
* :func:`theta_figure`: the adaptive parameters' drift ``theta - theta0`` (what the divergence
  test of :class:`controllers.mrac.MRAC` bounds).

Matplotlib (Agg backend) is imported only when a figure is drawn.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controllers.mrac import MRAC, MRACConfig, replay

__all__ = [
    "series",
    "states_figure",
    "outputs_figure",
    "errors_figure",
    "theta_figure",
    "figures",
]

Array = NDArray[np.float64]


def _figure(figsize: tuple[float, float]) -> Any:
    """A figure of its own (no pyplot: a notebook's backend and current figure are left alone)."""
    from matplotlib.figure import Figure

    return Figure(figsize=figsize)


def series(
    config: MRACConfig,
    loops: Sequence[str],
    executions: Iterable[tuple[float, Mapping[str, float], Mapping[str, float]]],
) -> dict[str, Array]:
    """What the MRAC figures of a run draw: the law replayed over the run's executions
    (``config``, ``loops`` and ``executions`` as :func:`controllers.mrac.replay` takes them; loop
    ``i`` measures ``x_i``, moves ``u_i``, its set point is ``u_c,i``).

    Returns
    -------
    dict
        :func:`controllers.mrac.replay`'s ``t, x, x_m, e, y_m, u_c, u, theta`` (one row per
        execution), plus ``y = C_m x`` (the output of the law's model at the state it used: with
        ``measurement="output"`` the measured ``y - y_bar``) and ``drift = theta - theta0``.

    Notes
    -----
    The law is replayed with ``on_divergence="freeze"`` whatever the run used, so that a run
    stopped by a divergence can still be drawn (up to its last execution, ``theta`` held at its
    last bounded value from the divergence on).
    """
    if config.on_divergence != "freeze":
        config = config.model_copy(update={"on_divergence": "freeze"})
    out = replay(config, loops, executions)
    n = len(loops)
    for key in ("x", "x_m", "e", "u_c", "u"):
        out[key] = out[key].reshape(-1, n)  # (0, n) for a run without executions
    out["y_m"] = out["y_m"].reshape(-1, len(config.C_m))
    out["theta"] = out["theta"].reshape(-1, 2 * n * n)
    out["y"] = out["x"] @ np.array(config.C_m, dtype=float).T
    out["drift"] = out["theta"] - MRAC(config).theta0
    return out


def _panels(n: int) -> tuple[Any, list[Any]]:
    fig = _figure((6.4, 1.2 + 2.0 * n))
    axes = fig.subplots(n, 1, sharex=True, squeeze=False)
    return fig, list(axes[:, 0])


def _finish(fig: Any, axes: list[Any], *, unit: str, title: str | None, legend: bool) -> Any:
    for ax in axes:
        ax.grid(True, alpha=0.3)
        if legend:
            ax.legend(loc="best", fontsize=8)
    axes[-1].set_xlabel(f"t ({unit})")
    if title:
        axes[0].set_title(title, fontsize=9)
    fig.tight_layout()
    return fig


def _ylabel(ax: Any, base: str, names: Sequence[str] | None, i: int) -> None:
    ax.set_ylabel(base if names is None else f"{base}\n(loop {names[i]})")


def states_figure(
    t: Array,
    x: Array,
    x_m: Array,
    *,
    names: Sequence[str] | None = None,
    unit: str = "h",
    title: str | None = None,
) -> Any:
    """Fig. 6.3: each state ``x_i`` (dots, one per execution) and reference state ``x_m,i``.

    Parameters
    ----------
    t : array_like
        Execution times, shape ``(k,)``.
    x, x_m : array_like
        Plant and reference-model states, shape ``(k, n)``; one panel per state.
    names : sequence of str, optional
        A name per state for the axis labels (a run's loop names).
    unit : str
        Time unit for the axis label.
    title : str, optional
        Title of the top panel.

    Returns
    -------
    matplotlib.figure.Figure
        Panel ``i`` holds the line ``x_m,i`` then the dots ``x_i``.
    """
    x, x_m = np.asarray(x, dtype=float), np.asarray(x_m, dtype=float)
    fig, axes = _panels(x.shape[1])
    for i, ax in enumerate(axes):
        ax.plot(t, x_m[:, i], "-", label=f"x_m{i + 1}")
        ax.plot(t, x[:, i], ".", ms=3, label=f"x{i + 1}")
        _ylabel(ax, f"x{i + 1}", names, i)
    return _finish(fig, axes, unit=unit, title=title, legend=True)


def outputs_figure(
    t: Array,
    y: Array,
    y_m: Array,
    *,
    names: Sequence[str] | None = None,
    y_label: str = "y{i}",
    unit: str = "h",
    title: str | None = None,
) -> Any:
    """Fig. 6.4: each output ``y_i`` (dots) and reference output ``y_m,i = (C_m x_m)_i`` (line).

    ``y_label`` names output ``i`` (``"y{i} - y_bar{i}"`` for deviations); otherwise as
    :func:`states_figure`.
    """
    y, y_m = np.asarray(y, dtype=float), np.asarray(y_m, dtype=float)
    fig, axes = _panels(y.shape[1])
    for i, ax in enumerate(axes):
        label = y_label.format(i=i + 1)
        ax.plot(t, y_m[:, i], "-", label=f"y_m{i + 1}")
        ax.plot(t, y[:, i], ".", ms=3, label=label)
        _ylabel(ax, label, names, i)
    return _finish(fig, axes, unit=unit, title=title, legend=True)


def errors_figure(
    t: Array,
    e: Array,
    *,
    names: Sequence[str] | None = None,
    unit: str = "h",
    title: str | None = None,
) -> Any:
    """Fig. 6.5: each state error ``e_i = x_i - x_m,i``; otherwise as :func:`states_figure`."""
    e = np.asarray(e, dtype=float)
    fig, axes = _panels(e.shape[1])
    for i, ax in enumerate(axes):
        ax.plot(t, e[:, i], "-o", ms=2)
        ax.axhline(0.0, color="k", lw=0.6)
        _ylabel(ax, f"e{i + 1}", names, i)
    return _finish(fig, axes, unit=unit, title=title, legend=False)


def theta_figure(
    t: Array,
    drift: Array,
    *,
    bound: float | None = None,
    unit: str = "h",
    title: str | None = None,
) -> Any:
    """The adaptive parameters' drift ``theta_j - theta0_j`` (held between executions).

    Parameters
    ----------
    t : array_like
        Execution times, shape ``(k,)``.
    drift : array_like
        ``theta - theta0``, shape ``(k, 2 n^2)``, ``theta = (vec L, vec M)`` row by row.
    bound : float, optional
        The divergence bound on ``max |theta - theta0|`` (``theta_bound``), quoted in the title.
    unit, title
        As :func:`states_figure`.

    Returns
    -------
    matplotlib.figure.Figure
        One panel; line ``j`` is ``theta_(j+1) - theta0_(j+1)``.
    """
    drift = np.asarray(drift, dtype=float)
    fig = _figure((6.4, 4.0))
    ax = fig.subplots()
    n2 = drift.shape[1] // 2
    n = round(n2**0.5)
    for j in range(drift.shape[1]):
        gain, k = ("L", j) if j < n2 else ("M", j - n2)
        ax.step(
            t,
            drift[:, j],
            where="post",
            ls="-" if j < n2 else "--",
            label=f"th{j + 1} ({gain}{k // n + 1}{k % n + 1})",
        )
    ax.set_ylabel("theta - theta0")
    peak = float(np.max(np.abs(drift))) if drift.size else 0.0
    note = f"max |theta - theta0| = {peak:.3g}"
    if bound is not None:
        note += f" (divergence bound {bound:g})"
    ax.legend(loc="best", fontsize=7, ncol=2)
    return _finish(fig, [ax], unit=unit, title=f"{title}\n{note}" if title else note, legend=False)


def figures(
    config: MRACConfig,
    loops: Sequence[str],
    executions: Iterable[tuple[float, Mapping[str, float], Mapping[str, float]]],
    *,
    title: str = "",
    unit: str = "h",
) -> dict[str, Any]:
    """The MRAC figures of a run: ``states``, ``outputs``, ``errors`` and ``theta``.

    Parameters
    ----------
    config, loops, executions
        As :func:`series`.
    title : str
        Prefix of every figure's title (e.g. the scenario and controller).
    unit : str
        The run's time unit.

    Returns
    -------
    dict of str to matplotlib.figure.Figure
        The caller saves and closes them.
    """
    s = series(config, loops, executions)
    names = list(loops)
    y_label = "y{i} - y_bar{i}" if config.measurement == "output" else "y{i}"
    head = f"{title}: " if title else ""
    return {
        "states": states_figure(
            s["t"], s["x"], s["x_m"], names=names, unit=unit, title=f"{head}states x and x_m"
        ),
        "outputs": outputs_figure(
            s["t"],
            s["y"],
            s["y_m"],
            names=names,
            y_label=y_label,
            unit=unit,
            title=f"{head}outputs and y_m = C_m x_m",
        ),
        "errors": errors_figure(
            s["t"], s["e"], names=names, unit=unit, title=f"{head}state error e = x - x_m"
        ),
        "theta": theta_figure(
            s["t"],
            s["drift"],
            bound=config.theta_bound,
            unit=unit,
            title=f"{head}adaptive parameters",
        ),
    }
