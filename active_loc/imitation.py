"""A warm start for a learned policy: DAgger from one of the package's planners.

DAgger (Ross, Gordon and Bagnell, 2011): round 0 rolls the planner out; each later round rolls
out the policy being trained, and the planner labels every state the rollout visits with the
action it would take there. After each round the policy is fitted to all the labels gathered
so far, by maximum likelihood of the planner's actions under the policy's action
distribution; the value head is fitted to the discounted returns of the rollouts, so that the
reinforcement learning that follows starts with a critic that agrees with its actor. The
planner sees the env's belief through ``env.unwrapped.planner_view()``, as in an evaluation;
the policy sees only the observation.
"""

from __future__ import annotations

import csv
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from numpy.typing import NDArray
from stable_baselines3.common.policies import ActorCriticPolicy

#: minibatch of the fits (labelled states)
FIT_BATCH = 256
#: the weight of the value loss beside the actions' negative log-likelihood
VALUE_WEIGHT = 0.5


@dataclass(frozen=True)
class Rollout:
    """The states one round visited, in order, with the planner's labels.

    Attributes:
        observations: ``(N, *obs_shape)`` the policy's observations.
        labels: ``(N, *action_shape)`` the planner's action at each.
        returns: ``(N,)`` the discounted return from each state on (rewards of the executed
            actions; an episode cut by the end of the round counts its rewards so far).
        agreement: the fraction of the states where the executed policy's action was the
            planner's (None in a round the planner drove).
        episodes: episodes begun.
    """

    observations: NDArray
    labels: NDArray
    returns: NDArray[np.float64]
    agreement: float | None
    episodes: int


@dataclass(frozen=True)
class ImitationRound:
    """One row of ``imitation.csv`` (``agreement`` empty, None, when the planner drove)."""

    round: int
    driver: str
    steps: int
    labels_total: int
    agreement: float | None
    episodes: int
    nll: float
    value_mse: float
    seconds: float


def discounted_returns(rewards: NDArray[np.float64], ends: NDArray[np.bool_],
                       gamma: float) -> NDArray[np.float64]:
    """``G_t = r_t + gamma G_{t+1}`` over a run of steps ``(N,)``, restarted after every step
    where ``ends`` is True (the episode's last step)."""
    out = np.empty(rewards.shape[0])
    running = 0.0
    for t in range(rewards.shape[0] - 1, -1, -1):
        if ends[t]:
            running = 0.0
        running = float(rewards[t]) + gamma * running
        out[t] = running
    return out


def rollout(
    env: gym.Env, planner: Any, act: Callable[[Any], Any] | None, steps: int, seed: int,
    gamma: float,
) -> Rollout:
    """``steps`` steps of ``env`` (first reset with ``seed``, then on), driven by the planner
    (``act`` None) or by ``act(observation) -> action``, every state labelled by
    ``planner.act(observation, env.unwrapped.planner_view())``."""
    observations, labels, rewards, ends = [], [], [], []
    agree = 0
    observation, _ = env.reset(seed=seed)
    episodes = 1
    for t in range(steps):
        label = planner.act(observation, env.unwrapped.planner_view())
        action = label if act is None else act(observation)
        agree += bool(np.all(np.asarray(action) == np.asarray(label)))
        observations.append(observation)
        labels.append(label)
        observation, reward, terminated, truncated, _ = env.step(action)
        rewards.append(float(reward))
        ended = terminated or truncated
        ends.append(ended)
        if ended and t < steps - 1:
            observation, _ = env.reset()
            episodes += 1
    return Rollout(
        observations=np.asarray(observations), labels=np.asarray(labels),
        returns=discounted_returns(np.asarray(rewards), np.asarray(ends), gamma),
        agreement=None if act is None else agree / steps, episodes=episodes,
    )


def fit(
    policy: ActorCriticPolicy, observations: NDArray, labels: NDArray,
    returns: NDArray[np.float64], epochs: int, learning_rate: float, seed: int,
) -> tuple[float, float]:
    """``epochs`` passes of Adam over the labelled states in shuffled minibatches of
    :data:`FIT_BATCH`, minimizing the planner's actions' mean negative log-likelihood under
    ``policy`` plus :data:`VALUE_WEIGHT` x the value head's mean squared error against
    ``returns``; returns the last epoch's mean ``(nll, value mse)``."""
    device = policy.device
    obs = torch.as_tensor(observations, device=device)
    actions = torch.as_tensor(labels, device=device)
    targets = torch.as_tensor(returns, dtype=torch.float32, device=device)
    optimizer = torch.optim.Adam(policy.parameters(), lr=learning_rate)
    order_rng = np.random.default_rng(seed)
    policy.set_training_mode(True)
    nll_sum = mse_sum = 0.0
    for _ in range(epochs):
        nll_sum = mse_sum = 0.0
        order = order_rng.permutation(obs.shape[0])
        for start in range(0, order.shape[0], FIT_BATCH):
            batch = torch.as_tensor(order[start : start + FIT_BATCH], device=device)
            values, log_prob, _ = policy.evaluate_actions(obs[batch], actions[batch])
            nll = -log_prob.mean()
            mse = torch.nn.functional.mse_loss(values.flatten(), targets[batch])
            loss = nll + VALUE_WEIGHT * mse
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            nll_sum += float(nll.detach()) * batch.shape[0]
            mse_sum += float(mse.detach()) * batch.shape[0]
    policy.set_training_mode(False)
    return nll_sum / obs.shape[0], mse_sum / obs.shape[0]


def dagger(
    policy: ActorCriticPolicy, make_env: Callable[[], gym.Env],
    make_planner: Callable[[gym.Env], Any], rounds: int, steps: int, epochs: int,
    learning_rate: float, gamma: float, seed: int, log_file: Path,
    deadline: float | None = None,
) -> list[ImitationRound]:
    """Warm-start ``policy`` with ``rounds`` rounds of DAgger of ``steps`` labelled states each
    (round 0 driven by the planner, the others by the policy's most likely action), each
    round followed by :func:`fit` on every label so far. Round ``i`` rolls out a new env
    from ``make_env()`` reset with ``seed + i``; ``make_planner(env)`` makes its planner.
    Each round's :class:`ImitationRound` is appended to ``log_file`` (CSV) as it ends; no
    round starts after ``deadline`` (``time.perf_counter()`` seconds)."""
    done: list[ImitationRound] = []
    observations: list[NDArray] = []
    labels: list[NDArray] = []
    returns: list[NDArray[np.float64]] = []

    def act(observation: Any) -> Any:
        action, _ = policy.predict(observation, deterministic=True)
        return action

    with log_file.open("w", newline="") as stream:
        writer = csv.DictWriter(stream, fieldnames=list(ImitationRound.__dataclass_fields__))
        writer.writeheader()
        for i in range(rounds):
            if deadline is not None and time.perf_counter() >= deadline:
                break
            start = time.perf_counter()
            env = make_env()
            try:
                run = rollout(env, make_planner(env), None if i == 0 else act, steps,
                              seed + i, gamma)
            finally:
                env.close()
            observations.append(run.observations)
            labels.append(run.labels)
            returns.append(run.returns)
            nll, mse = fit(policy, np.concatenate(observations), np.concatenate(labels),
                           np.concatenate(returns), epochs, learning_rate, seed + i)
            row = ImitationRound(
                round=i, driver="planner" if i == 0 else "policy", steps=steps,
                labels_total=sum(len(x) for x in labels), agreement=run.agreement,
                episodes=run.episodes, nll=nll, value_mse=mse,
                seconds=time.perf_counter() - start,
            )
            writer.writerow(asdict(row))
            stream.flush()
            done.append(row)
    return done
