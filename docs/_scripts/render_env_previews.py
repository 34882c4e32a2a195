"""Draw the preview picture of each environment id for docs/envs/ (what ``env.render()`` shows).

    python docs/_scripts/render_env_previews.py [--out docs/envs] [--seed 0] [--decisions 12] [--steps 600]

Waypoint ids: after ``reset`` and ``--decisions`` decisions of the frontier policy (ExplorePlans-v1: 40;
LoopCorridor-v1: right after ``reset``, at the decision point); the velocity id: after ``--steps`` steps driving ahead
and turning. Left: the true world, the robot (red) and its true path (green); right: the expected
map, the particles (blue) and the best particle's path (orange).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import emmi_gym  # noqa: E402
from emmi_gym.env.registration import ENV_IDS  # noqa: E402
from emmi_gym.tools.commands import arguments  # noqa: E402
from emmi_gym.tools.policies import make_policy  # noqa: E402

gym.register_envs(emmi_gym)

#: Decisions before the picture where the default is too few to show the world.
DECISIONS = {"ExplorePlans-v1": 40}


def preview(name: str, seed: int, decisions: int, steps: int) -> np.ndarray:
    env = gym.make(f"emmi_gym/{name}", render_mode="rgb_array")
    env.reset(seed=seed)
    if ENV_IDS[name].get("start_at") != "decision":
        if env.unwrapped.config.action_mode == "waypoint":
            policy = make_policy("frontier")
            for _ in range(DECISIONS.get(name, decisions)):
                if any(env.step(policy(env))[2:4]):
                    break
        else:
            for t in range(steps):
                if any(env.step(np.array([0.8, 0.6 if (t // 40) % 3 == 0 else 0.0], dtype=np.float32))[2:4]):
                    break
    frame = env.render()
    env.close()
    return frame


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/envs")
    parser.add_argument("--seed", type=arguments.SEED, default=0)
    parser.add_argument("--decisions", type=arguments.integer(1), default=12)
    parser.add_argument("--steps", type=arguments.integer(1), default=600)
    parser.add_argument("--ids", nargs="*", default=list(ENV_IDS))
    args = parser.parse_args()
    for name in args.ids:
        path = Path(args.out) / f"{name}.png"
        plt.imsave(path, preview(name, args.seed, args.decisions, args.steps))
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
