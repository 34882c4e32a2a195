"""Save what the environment draws at the paper's decision point (the README's picture).

    python scripts/render_snapshot.py [--out docs/loop_corridor_decision.png] [--seed 0]

Left: the true world, the robot (red) and its true path (green). Right: the expected
map, the particles (blue) and the best particle's path (orange).
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import emmi_gym  # noqa: E402

gym.register_envs(emmi_gym)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/loop_corridor_decision.png")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    env = gym.make("emmi_gym/LoopCorridor-v0", render_mode="rgb_array")
    _, info = env.reset(seed=args.seed)
    plt.imsave(args.out, env.render())
    print(f"wrote {args.out}: EMMI {info['emmi']:.3f} bits/cell, coverage {info['coverage']:.2f}, "
          f"ATE {info['ate']:.2f} m at the decision point")


if __name__ == "__main__":
    main()
