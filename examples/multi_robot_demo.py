"""Two robots in a symmetric arena localize faster together than alone?

The arena (``map="symmetric"``) repeats its identical-looking landmarks under a 180-degree
rotation, except for one cue landmark. Both robots start with a uniform MCL belief (global
localization). Alone, a robot's belief stays split between its true pose and the rotated one
until it sees the cue. Together, a robot that detects its teammate also reweights its particles
by where the teammate's belief says it must be (reciprocal sampling, Fox et al. 2000), so once
one of them has seen the cue, the other is disambiguated at their next meeting.

Each seeded episode is run twice, with ``fuse_detections=True`` and ``False``, under the same
scripted policy: a wander of slowly varying curvature that turns on the spot after a bump. The
policy reads only the bumper (the collision count in ``info``), never the belief, so the two
runs of a seed drive the same paths until a robot localizes (and stops) and see the same world
noise (the env draws it from its own stream). A robot's episode ends when its belief is
confident (position std <= 0.2 m, heading std <= 0.1 rad); *success* means confident and right
(within 0.5 m and 0.25 rad of the truth), and "steps" is the step at which it became confident
(a robot that never succeeds counts as ``--max-cycles`` in the censored mean).

    python examples/multi_robot_demo.py --episodes 20 --seed 0
"""

from __future__ import annotations

import argparse
import math
import time
from typing import Any

import numpy as np

from active_loc.envs.multi_robot import parallel_env

#: the arena and the filters of the demonstration
DEMO_CONFIG: dict[str, Any] = {
    "belief": "mcl",
    "map": "symmetric",
    "map_size": (10.0, 6.0),
    "n_landmarks": (9, 9),  # 4 symmetric pairs and the cue
    "max_landmarks": 9,
    "initial_belief": "uniform",
    "n_particles": 20000,
    "likelihood_exponent": 0.3,  # tempered: a few particles must not take all the weight
    "range_std": 0.3,  # a coarse landmark sensor (m, rad)
    "bearing_std": 0.1,
    "fov": math.pi,
    "max_range": 5.0,
    "detection_fov": 2 * math.pi,
    "detection_max_range": 8.0,
    "fusion_interval": 10,
    "localized_position_std": 0.2,  # confident: largest position std (m), heading std (rad)
    "localized_heading_std": 0.1,
    "success_position_tol": 0.5,  # right: within 2.5 of those stds of the truth
    "success_heading_tol": 0.25,
}


def wander(step: int, robot: int, bumped: int) -> np.ndarray:
    """The scripted policy: forward at 0.6 m/s with a slowly varying turn rate; after a bump,
    turn on the spot (``bumped`` steps left of the turn)."""
    if bumped > 0:
        return np.array([-1.0, 1.0], dtype=np.float32)
    turn = 0.35 * math.sin(0.07 * step + 2.0 * robot)
    return np.array([0.2, turn], dtype=np.float32)


def run_episode(seed: int, fuse: bool, max_cycles: int) -> dict[str, dict[str, Any]]:
    """One episode; per robot: confident (bool), success (bool), step it became confident."""
    env = parallel_env(2, fuse_detections=fuse, max_cycles=max_cycles, **DEMO_CONFIG)
    _, infos = env.reset(seed=seed)
    collisions = {a: 0 for a in env.agents}
    turning = {a: 0 for a in env.agents}
    result = {a: {"localized": False, "success": False, "steps": max_cycles, "fusions": 0}
              for a in env.agents}
    step = 0
    while env.agents:
        actions = {a: wander(step, int(a[-1]), turning[a]) for a in env.agents}
        _, _, terminated, _, infos = env.step(actions)
        step += 1
        for a, info in infos.items():
            turning[a] = max(turning[a] - 1, 0)
            if info["collisions"] > collisions[a]:
                collisions[a] = info["collisions"]
                turning[a] = 6
            result[a]["fusions"] += int(info["fused"])
            if terminated[a]:
                result[a].update(localized=True, success=info["is_success"], steps=step)
    env.close()
    return result


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0, help="first episode seed")
    parser.add_argument("--max-cycles", type=int, default=200)
    args = parser.parse_args(argv)
    start = time.perf_counter()
    runs: dict[str, list[dict[str, dict[str, Any]]]] = {"together": [], "alone": []}
    for seed in range(args.seed, args.seed + args.episodes):
        runs["together"].append(run_episode(seed, True, args.max_cycles))
        runs["alone"].append(run_episode(seed, False, args.max_cycles))
    print(f"{args.episodes} episodes (seeds {args.seed}..{args.seed + args.episodes - 1}), "
          f"2 robots, MCL global localization in the symmetric arena, "
          f"max {args.max_cycles} steps\n")
    header = (f"{'robot':8} {'mode':9} {'success':>8} {'localized':>9} {'steps (succ.)':>14} "
              f"{'steps (cens.)':>14} {'fusions':>8}")
    print(header)
    print("-" * len(header))
    for robot in ("robot_0", "robot_1", "both"):
        for mode in ("together", "alone"):
            rows = [r[a] for r in runs[mode]
                    for a in (("robot_0", "robot_1") if robot == "both" else (robot,))]
            success = np.mean([row["success"] for row in rows])
            localized = np.mean([row["localized"] for row in rows])
            ok = [row["steps"] for row in rows if row["success"]]
            steps_ok = f"{np.mean(ok):.1f}" if ok else "-"
            censored = np.mean([row["steps"] if row["success"] else args.max_cycles
                                for row in rows])
            fusions = np.mean([row["fusions"] for row in rows])
            print(f"{robot:8} {mode:9} {success:8.2f} {localized:9.2f} {steps_ok:>14} "
                  f"{censored:14.1f} {fusions:8.1f}")
    paired = [
        (t[a]["steps"] if t[a]["success"] else args.max_cycles)
        - (s[a]["steps"] if s[a]["success"] else args.max_cycles)
        for t, s in zip(runs["together"], runs["alone"], strict=True) for a in t
    ]
    faster = sum(d < 0 for d in paired)
    slower = sum(d > 0 for d in paired)
    print(f"\npaired by seed and robot (censored steps): together faster in {faster}, "
          f"slower in {slower}, equal in {len(paired) - faster - slower} of {len(paired)}; "
          f"mean difference {np.mean(paired):+.1f} steps")
    print(f"({time.perf_counter() - start:.0f} s)")


if __name__ == "__main__":
    main()
