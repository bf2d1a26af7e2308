"""PPO on an ``ActiveLoc`` id's native vector env, in one file (CleanRL style).

    python examples/cleanrl_ppo.py --env-id ActiveLoc/LandmarkEKF-v0 --num-envs 64 \\
        --total-timesteps 300000 --seed 1 [--action-type discrete] [--track-tb] [--save ppo.pt]

Clipped-objective PPO with GAE, optional value clipping, per-minibatch advantage normalization,
an entropy bonus, global gradient-norm clipping and a linearly annealed learning rate, in plain
torch. A Gaussian policy with a state-independent log std drives ``Box`` actions (sampled
actions are clipped to the bounds before they reach the env; the log-probabilities are those
of the unclipped samples); a categorical policy drives ``Discrete`` ones.

The envs come from ``gymnasium.make_vec(id, n, vectorization_mode="vector_entry_point")``:
:class:`active_loc.envs.vector_env.ActiveLocalizationVectorEnv`, sub-env i seeded seed + i.

Autoreset (gymnasium 1.x ``NEXT_STEP``, the vector env's default). When a sub-env's episode
ends at step t (terminated or truncated), step t returns the episode's *last* observation, and
step t + 1 resets that sub-env: the action given at t + 1 is ignored, its reward is 0 and its
flags are False, and it returns the new episode's first observation. This script therefore

* keeps ``valid[t] = not ended[t - 1]`` per sub-env (carried across rollouts) and leaves the
  reset steps out of every loss term (they are dropped from the minibatches) and out of the
  episode statistics;
* cuts the GAE recursion after an ended step: ``A_t = delta_t + gamma lambda (1 - ended_t)
  A_{t+1}``;
* bootstraps truncated episodes correctly: on a reset step the stored observation ``obs[t+1]``
  is exactly the last observation of the episode that ended at t, so ``values[t+1]`` is
  V(final observation) and ``delta_t = r_t + gamma (1 - terminated_t) values[t+1] - values[t]``
  needs no ``final_obs`` bookkeeping (a terminated episode bootstraps with 0).

Episode statistics come from the ended steps: the return is the sum of the episode's rewards,
the success ``info["is_success"]`` where ``info["_is_success"]`` marks it, on the step that
ended the episode.
"""

from __future__ import annotations

import json
import math
import random
import time
from collections import deque
from dataclasses import asdict, dataclass
from typing import Literal

import gymnasium as gym
import numpy as np
import torch
import tyro
from torch import nn
from torch.distributions import Categorical, Normal

import active_loc  # noqa: F401  (registers the ActiveLoc ids)


@dataclass
class Args:
    env_id: str = "ActiveLoc/LandmarkEKF-v0"
    """a registered ActiveLoc id"""
    action_type: Literal["continuous", "discrete"] | None = None
    """the env's action_type kwarg (None: the env's default; Maze-v0 takes none)"""
    env_kwargs: str = "{}"
    """JSON object of further gymnasium.make_vec kwargs, e.g. '{"max_episode_steps": 100}'"""
    seed: int = 1
    """seeds python, numpy, torch and the envs (sub-env i gets seed + i)"""
    num_envs: int = 64
    """sub-envs of the vector env"""
    total_timesteps: int = 200_000
    """env steps (over all sub-envs) to train for"""
    num_steps: int = 64
    """steps per sub-env per rollout (the batch is num_envs * num_steps)"""
    learning_rate: float = 3e-4
    anneal_lr: bool = True
    """decay the learning rate linearly to 0 over the updates"""
    gamma: float = 0.98
    gae_lambda: float = 0.95
    num_minibatches: int = 8
    update_epochs: int = 10
    norm_adv: bool = True
    """normalize the advantages per minibatch"""
    clip_coef: float = 0.2
    clip_vloss: bool = True
    """clip the value loss as in the PPO2 implementation"""
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    target_kl: float | None = None
    """stop an update's epochs early when the approximate KL exceeds this"""
    hidden: int = 64
    """units of the two tanh hidden layers of the actor and of the critic"""
    threads: int = 1
    """torch.set_num_threads (small MLPs are fastest on one thread)"""
    torch_deterministic: bool = True
    log_every: int = 5
    """print (and write to tensorboard) every this many updates"""
    stats_window: int = 200
    """the final summary's return and success rate are over the last this many episodes"""
    track_tb: bool = False
    """write tensorboard scalars to {log_dir}/{run name}"""
    log_dir: str = "runs/cleanrl"
    save: str | None = None
    """save the model (state dict and args) to this path at the end"""


def layer_init(layer: nn.Linear, std: float = math.sqrt(2), bias: float = 0.0) -> nn.Linear:
    nn.init.orthogonal_(layer.weight, std)
    nn.init.constant_(layer.bias, bias)
    return layer


def mlp(n_in: int, hidden: int, n_out: int, out_std: float) -> nn.Sequential:
    return nn.Sequential(
        layer_init(nn.Linear(n_in, hidden)), nn.Tanh(),
        layer_init(nn.Linear(hidden, hidden)), nn.Tanh(),
        layer_init(nn.Linear(hidden, n_out), std=out_std),
    )


class Agent(nn.Module):
    """Separate actor and critic MLPs; Gaussian (state-independent log std) or categorical."""

    def __init__(self, obs_dim: int, action_space: gym.Space, hidden: int) -> None:
        super().__init__()
        self.continuous = isinstance(action_space, gym.spaces.Box)
        self.critic = mlp(obs_dim, hidden, 1, out_std=1.0)
        if self.continuous:
            act_dim = int(np.prod(action_space.shape))
            self.actor = mlp(obs_dim, hidden, act_dim, out_std=0.01)
            self.actor_logstd = nn.Parameter(torch.zeros(1, act_dim))
        elif isinstance(action_space, gym.spaces.Discrete):
            self.actor = mlp(obs_dim, hidden, int(action_space.n), out_std=0.01)
        else:
            raise ValueError(f"unsupported action space {action_space}")

    def value(self, x: torch.Tensor) -> torch.Tensor:
        return self.critic(x).squeeze(-1)

    def distribution(self, x: torch.Tensor) -> Normal | Categorical:
        if self.continuous:
            mean = self.actor(x)
            return Normal(mean, self.actor_logstd.expand_as(mean).exp())
        return Categorical(logits=self.actor(x))

    def act_and_value(
        self, x: torch.Tensor, action: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """``(action, log-prob, entropy, value)``; samples the action when none is given."""
        dist = self.distribution(x)
        if action is None:
            action = dist.sample()
        logprob, entropy = dist.log_prob(action), dist.entropy()
        if self.continuous:  # independent dimensions
            logprob, entropy = logprob.sum(-1), entropy.sum(-1)
        return action, logprob, entropy, self.value(x)


def main(args: Args) -> dict[str, float]:
    env_kwargs = json.loads(args.env_kwargs)
    if not isinstance(env_kwargs, dict):
        raise SystemExit(f"--env-kwargs must be a JSON object, got {args.env_kwargs!r}")
    if args.action_type is not None:
        env_kwargs["action_type"] = args.action_type
    batch_size = args.num_envs * args.num_steps
    minibatch_size = max(1, batch_size // args.num_minibatches)
    num_updates = max(1, args.total_timesteps // batch_size)
    run_name = f"{args.env_id.replace('/', '_')}__ppo__{args.seed}__{int(time.time())}"

    random.seed(args.seed)
    np.random.seed(args.seed)  # noqa: NPY002  (the legacy global RNG, for any code using it)
    torch.manual_seed(args.seed)
    torch.backends.cudnn.deterministic = args.torch_deterministic
    torch.set_num_threads(args.threads)

    writer = None
    if args.track_tb:
        from torch.utils.tensorboard import SummaryWriter

        writer = SummaryWriter(f"{args.log_dir}/{run_name}")
        writer.add_text("hyperparameters", "\n".join(f"{k}: {v}" for k, v in asdict(args).items()))

    envs = gym.make_vec(
        args.env_id, args.num_envs, vectorization_mode="vector_entry_point", **env_kwargs
    )
    assert getattr(envs, "autoreset_mode", None) == gym.vector.AutoresetMode.NEXT_STEP, (
        "this script's masking assumes NEXT_STEP autoreset"
    )
    obs_space, act_space = envs.single_observation_space, envs.single_action_space
    obs_dim = gym.spaces.flatdim(obs_space)
    continuous = isinstance(act_space, gym.spaces.Box)
    agent = Agent(obs_dim, act_space, args.hidden)
    optimizer = torch.optim.Adam(agent.parameters(), lr=args.learning_rate, eps=1e-5)

    n, steps = args.num_envs, args.num_steps
    act_shape = act_space.shape if continuous else ()
    obs_buf = torch.zeros((steps, n, obs_dim))
    act_buf = torch.zeros((steps, n, *act_shape), dtype=torch.float32 if continuous else torch.long)
    logp_buf = torch.zeros((steps, n))
    rew_buf = torch.zeros((steps, n))
    term_buf = torch.zeros((steps, n))  # 1: the step's episode terminated (bootstrap with 0)
    ended_buf = torch.zeros((steps, n))  # 1: terminated or truncated (cut the GAE recursion)
    valid_buf = torch.zeros((steps, n), dtype=torch.bool)  # 0: a reset step (action ignored)
    val_buf = torch.zeros((steps, n))
    if continuous:
        low = np.asarray(act_space.low, dtype=np.float32)
        high = np.asarray(act_space.high, dtype=np.float32)

    def as_tensor(o: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(np.asarray(o, dtype=np.float32).reshape(n, obs_dim))

    obs, _ = envs.reset(seed=args.seed)
    next_obs = as_tensor(obs)
    next_valid = torch.ones(n, dtype=torch.bool)  # False: the next step resets that sub-env
    ep_return = np.zeros(n)
    ep_length = np.zeros(n, dtype=np.int64)
    recent: deque[tuple[float, float, int]] = deque(maxlen=args.stats_window)
    window: list[tuple[float, float, int]] = []  # episodes ended since the last log line
    global_step = 0
    start = time.perf_counter()

    for update in range(1, num_updates + 1):
        if args.anneal_lr:
            optimizer.param_groups[0]["lr"] = args.learning_rate * (
                1.0 - (update - 1.0) / num_updates
            )
        # --- rollout -------------------------------------------------------------------------
        for t in range(steps):
            global_step += n
            obs_buf[t] = next_obs
            valid_buf[t] = next_valid
            with torch.no_grad():
                action, logprob, _, value = agent.act_and_value(next_obs)
            act_buf[t], logp_buf[t], val_buf[t] = action, logprob, value
            if continuous:
                env_action = np.clip(action.numpy(), low, high)
            else:
                env_action = action.numpy().astype(np.int64)
            obs, reward, terminated, truncated, info = envs.step(env_action)
            ended = np.logical_or(terminated, truncated)
            rew_buf[t] = torch.as_tensor(reward, dtype=torch.float32)
            term_buf[t] = torch.as_tensor(terminated, dtype=torch.float32)
            ended_buf[t] = torch.as_tensor(ended, dtype=torch.float32)
            next_obs = as_tensor(obs)
            # reset steps carry reward 0 and flags False, so they add nothing here
            ep_return += reward
            ep_length += valid_buf[t].numpy()
            if ended.any():
                success = info.get("is_success", np.zeros(n, dtype=bool))
                has = info.get("_is_success", np.zeros(n, dtype=bool))
                for i in np.flatnonzero(ended):
                    done = (float(ep_return[i]), float(bool(success[i]) and bool(has[i])),
                            int(ep_length[i]))
                    recent.append(done)
                    window.append(done)
                ep_return[ended] = 0.0
                ep_length[ended] = 0
            next_valid = torch.as_tensor(~ended)

        # --- GAE (see the module docstring for the NEXT_STEP masking) -------------------------
        with torch.no_grad():
            next_value = agent.value(next_obs)
            advantages = torch.zeros((steps, n))
            last = torch.zeros(n)
            for t in reversed(range(steps)):
                following = next_value if t == steps - 1 else val_buf[t + 1]
                delta = rew_buf[t] + args.gamma * (1.0 - term_buf[t]) * following - val_buf[t]
                last = delta + args.gamma * args.gae_lambda * (1.0 - ended_buf[t]) * last
                advantages[t] = last
            returns = advantages + val_buf

        # --- optimize over the valid transitions only ------------------------------------------
        valid = valid_buf.reshape(-1)
        b_obs = obs_buf.reshape(-1, obs_dim)[valid]
        b_act = act_buf.reshape(-1, *act_shape)[valid]
        b_logp = logp_buf.reshape(-1)[valid]
        b_adv = advantages.reshape(-1)[valid]
        b_ret = returns.reshape(-1)[valid]
        b_val = val_buf.reshape(-1)[valid]
        size = int(valid.sum())
        clipfracs: list[float] = []
        approx_kl = old_approx_kl = torch.zeros(())
        pg_loss = v_loss = entropy_loss = torch.zeros(())
        for _epoch in range(args.update_epochs):
            order = torch.randperm(size)
            for lo in range(0, size, minibatch_size):
                mb = order[lo : lo + minibatch_size]
                _, newlogp, entropy, newvalue = agent.act_and_value(b_obs[mb], b_act[mb])
                logratio = newlogp - b_logp[mb]
                ratio = logratio.exp()
                with torch.no_grad():
                    old_approx_kl = (-logratio).mean()
                    approx_kl = ((ratio - 1) - logratio).mean()
                    clipfracs.append(((ratio - 1.0).abs() > args.clip_coef).float().mean().item())
                mb_adv = b_adv[mb]
                if args.norm_adv and len(mb) > 1:
                    mb_adv = (mb_adv - mb_adv.mean()) / (mb_adv.std() + 1e-8)
                pg_loss = torch.max(
                    -mb_adv * ratio,
                    -mb_adv * torch.clamp(ratio, 1 - args.clip_coef, 1 + args.clip_coef),
                ).mean()
                if args.clip_vloss:
                    v_unclipped = (newvalue - b_ret[mb]) ** 2
                    v_clipped = b_val[mb] + torch.clamp(
                        newvalue - b_val[mb], -args.clip_coef, args.clip_coef
                    )
                    v_loss = 0.5 * torch.max(v_unclipped, (v_clipped - b_ret[mb]) ** 2).mean()
                else:
                    v_loss = 0.5 * ((newvalue - b_ret[mb]) ** 2).mean()
                entropy_loss = entropy.mean()
                loss = pg_loss - args.ent_coef * entropy_loss + v_loss * args.vf_coef
                optimizer.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(agent.parameters(), args.max_grad_norm)
                optimizer.step()
            if args.target_kl is not None and approx_kl > args.target_kl:
                break

        # --- log --------------------------------------------------------------------------------
        if update % args.log_every == 0 or update == num_updates:
            elapsed = time.perf_counter() - start
            sps = global_step / elapsed
            ret = float(np.mean([e[0] for e in window])) if window else math.nan
            succ = float(np.mean([e[1] for e in window])) if window else math.nan
            length = float(np.mean([e[2] for e in window])) if window else math.nan
            y_pred, y_true = b_val.numpy(), b_ret.numpy()
            var_y = np.var(y_true)
            explained_var = math.nan if var_y == 0 else float(1 - np.var(y_true - y_pred) / var_y)
            print(
                f"update {update}/{num_updates} step {global_step} SPS {sps:.0f} "
                f"episodes {len(window)} return {ret:.3f} success {succ:.3f} length {length:.1f} "
                f"| pg {pg_loss.item():.4f} v {v_loss.item():.4f} ent {entropy_loss.item():.3f} "
                f"kl {approx_kl.item():.4f}",
                flush=True,
            )
            if writer is not None:
                scalars = {
                    "charts/learning_rate": optimizer.param_groups[0]["lr"],
                    "charts/SPS": sps,
                    "losses/value_loss": v_loss.item(),
                    "losses/policy_loss": pg_loss.item(),
                    "losses/entropy": entropy_loss.item(),
                    "losses/old_approx_kl": old_approx_kl.item(),
                    "losses/approx_kl": approx_kl.item(),
                    "losses/clipfrac": float(np.mean(clipfracs)) if clipfracs else 0.0,
                    "losses/explained_variance": explained_var,
                }
                if window:
                    scalars.update({"charts/episodic_return": ret, "charts/success_rate": succ,
                                    "charts/episodic_length": length})
                for key, value in scalars.items():
                    writer.add_scalar(key, value, global_step)
            window = []

    wall = time.perf_counter() - start
    envs.close()
    if writer is not None:
        writer.close()
    final_return = float(np.mean([e[0] for e in recent])) if recent else math.nan
    final_success = float(np.mean([e[1] for e in recent])) if recent else math.nan
    stats = {"steps": global_step, "wall_time": wall, "sps": global_step / wall,
             "final_return": final_return, "final_success_rate": final_success,
             "episodes": len(recent)}
    if args.save:
        torch.save({"model": agent.state_dict(), "args": asdict(args), "obs_dim": obs_dim,
                    "action_space": repr(act_space)}, args.save)
        print(f"saved the model to {args.save}")
    print(
        f"summary: steps {global_step} wall_time {wall:.1f}s SPS {global_step / wall:.0f} "
        f"final_return {final_return:.3f} final_success_rate {final_success:.3f} "
        f"(last {len(recent)} episodes)",
        flush=True,
    )
    return stats


if __name__ == "__main__":
    main(tyro.cli(Args))
