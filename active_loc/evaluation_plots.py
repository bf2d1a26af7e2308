"""Pictures of an evaluation (:mod:`active_loc.evaluation`): PNG plots and GIFs.

* :func:`plot_entropy`: the belief's entropy against the step, per agent the mean over its
  episodes with a 95% confidence band of the mean (:func:`~active_loc.evaluation.entropy_curves`).
* :func:`plot_success`: the fraction of episodes with ``is_success`` against the step, with
  Wilson 95% bands (:func:`~active_loc.evaluation.success_curves`).
* :func:`write_gifs`: one rendered episode per agent (``render_mode="rgb_array"``, imageio).

Needs the ``render`` extra (matplotlib, imageio). Figures are drawn on a
:class:`matplotlib.figure.Figure` with the Agg canvas, never through pyplot's global state.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
from numpy.typing import NDArray

from active_loc.evaluation import (
    EpisodeRecord,
    StepCurve,
    entropy_curves,
    run_episode,
    success_curves,
)

#: file names of the plots in the output directory
ENTROPY_PNG = "entropy_vs_step.png"
SUCCESS_PNG = "success_vs_step.png"


def _plot_curves(
    curves: Mapping[str, StepCurve], path: Path, title: str, ylabel: str, ylim: Any = None
) -> Path:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.0, 4.2), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    for k, (name, curve) in enumerate(curves.items()):
        color = f"C{k % 10}"
        ax.plot(curve.steps, curve.mean, color=color, label=name, linewidth=1.6)
        ax.fill_between(curve.steps, curve.lower, curve.upper, color=color, alpha=0.2,
                        linewidth=0)
    ax.set_xlabel("step")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize="medium")
    if ylim is not None:
        ax.set_ylim(*ylim)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    return path


def _title(records: Sequence[EpisodeRecord], what: str) -> str:
    n = len({r.episode for r in records})
    return f"{records[0].env_id}, {n} episodes per agent\n{what}"


def plot_entropy(records: Sequence[EpisodeRecord], path: str | Path) -> Path:
    """Entropy (nats) against the step: per agent the mean and its 95% band. An ended episode
    counts with its final entropy at later steps."""
    return _plot_curves(
        entropy_curves(records), Path(path), _title(records, "belief entropy, mean and 95% CI"),
        "entropy (nats)",
    )


def plot_success(records: Sequence[EpisodeRecord], path: str | Path) -> Path:
    """Fraction of episodes with ``is_success`` against the step, with Wilson 95% bands. An
    ended episode counts with its final value at later steps."""
    return _plot_curves(
        success_curves(records), Path(path), _title(records, "success rate, Wilson 95% CI"),
        "success rate", ylim=(-0.02, 1.02),
    )


def write_plots(records: Sequence[EpisodeRecord], out_dir: str | Path) -> list[Path]:
    """Write :data:`ENTROPY_PNG` and :data:`SUCCESS_PNG` into ``out_dir``."""
    out = Path(out_dir)
    return [plot_entropy(records, out / ENTROPY_PNG), plot_success(records, out / SUCCESS_PNG)]


def safe_name(name: str) -> str:
    """``name`` as a file-name fragment: runs of characters other than letters, digits, ``-``,
    ``_`` and ``.`` become ``_`` (``"sb3:models/ppo.zip"`` -> ``"sb3_models_ppo.zip"``)."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_") or "agent"


def record_frames(
    env_id: str, env_kwargs: Mapping[str, Any] | None, agent: Any, seed: int, name: str = "agent"
) -> tuple[list[NDArray], EpisodeRecord]:
    """Play one episode (reset seed ``seed``) with ``render_mode="rgb_array"``: the frames
    (after reset and after every step) and the episode's record."""
    frames: list[NDArray] = []
    env = gym.make(env_id, render_mode="rgb_array", **dict(env_kwargs or {}))
    try:
        record = run_episode(env, agent, seed, agent_name=name,
                             callback=lambda e: frames.append(e.render()))
    finally:
        env.close()
    return frames, record


def write_gifs(
    env_id: str,
    env_kwargs: Mapping[str, Any] | None,
    agents: Mapping[str, Any],
    seed: int,
    out_dir: str | Path,
    fps: int = 10,
) -> list[Path]:
    """One rendered episode per agent, reset with ``seed``, as ``out_dir/episode_<agent>.gif``
    (the agent's name through :func:`safe_name`). With freshly made agents this is episode 0
    of an evaluation with base seed ``seed``."""
    import imageio.v2 as imageio

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, agent in agents.items():
        frames, _ = record_frames(env_id, env_kwargs, agent, seed, name)
        path = out / f"episode_{safe_name(name)}.gif"
        imageio.mimsave(path, frames, duration=1000 / fps, loop=0)
        paths.append(path)
    return paths
