"""Quick probe of the paper's A/B effect: EMMI from the decision point to the first goal, per policy.

    python scripts/ab_probe.py [--seeds 3] [--particles 15] [--slam '{"logodds_free": -0.7}']

For each seed, runs ``close_loop_first`` (A) and ``explore_first`` (B) in LoopCorridor-v0
(coverage_target 1.0, so nothing ends early) until the policy reaches its first goal
(A: back at the start; B: in the new area), and prints EMMI, the best particle's mean
information and their gap (particle disagreement) at the decision point and at that
goal, the pose entropy, and the resamplings in between. A diagnostic for the A/B
experiment, not the experiment itself.
"""

from __future__ import annotations

import argparse
import json

import gymnasium as gym
import numpy as np

import emmi_gym
from emmi_gym.policies import make_policy

gym.register_envs(emmi_gym)


def probe(seed: int, name: str, particles: int, slam: dict) -> dict:
    env = gym.make("emmi_gym/LoopCorridor-v0", particles=particles, coverage_target=1.0, slam=slam)
    _, info = env.reset(seed=seed)
    policy = make_policy(name)
    policy.reset(seed)
    rows = list(info["rbpf_updates"])
    decision = len(rows)
    for _ in range(30):
        _, _, terminated, truncated, info = env.step(policy(env))
        rows += info["rbpf_updates"]
        policy(env)  # notice a goal reached by that step
        if policy.phase >= 1 or terminated or truncated:
            break
    env.close()
    at = {"decision": rows[decision - 1], "goal": rows[-1]}
    return {"at": at, "resamplings": sum(r["resampled"] for r in rows[decision:]), "reached": policy.phase >= 1}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--particles", type=int, default=15)
    parser.add_argument("--slam", default="{}", help="RBPFConfig overrides as JSON")
    args = parser.parse_args()
    slam = json.loads(args.slam)
    deltas = {"close_loop_first": [], "explore_first": []}
    for seed in range(args.seeds):
        for name in deltas:
            result = probe(seed, name, args.particles, slam)
            d, g = result["at"]["decision"], result["at"]["goal"]
            deltas[name].append(g["emmi"] - d["emmi"])
            print(f"seed {seed} {name:17s} EMMI {d['emmi']:.3f} -> {g['emmi']:.3f} ({g['emmi'] - d['emmi']:+.3f}); "
                  f"best MI {d['mean_information_best']:.3f} -> {g['mean_information_best']:.3f}; gap "
                  f"{d['mean_information_best'] - d['emmi']:.3f} -> {g['mean_information_best'] - g['emmi']:.3f}; "
                  f"pose entropy {d['pose_entropy']:.1f} -> {g['pose_entropy']:.1f}; "
                  f"{result['resamplings']} resamplings{'' if result['reached'] else ' (goal not reached)'}",
                  flush=True)
    a, b = np.array(deltas["close_loop_first"]), np.array(deltas["explore_first"])
    print(f"\nmean EMMI change: A {a.mean():+.3f}, B {b.mean():+.3f}; A > B on {int(np.sum(a > b))} of {a.size} seeds")


if __name__ == "__main__":
    main()
