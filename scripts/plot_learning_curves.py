"""Learning curves of training runs: the held-out evaluations' ground truth against decisions trained.

    python scripts/plot_learning_curves.py runs/plans_emmi_seed0=scratch runs/plans_emmi_bc_seed0=clone+RL \\
        --baselines-csv results/test50.csv --out docs/plans_learning_curves.png
    python scripts/plot_learning_curves.py runs/bench/runs/emmi_seed0=emmi runs/bench/runs/emmi_seed1=emmi \\
        runs/bench/runs/pose_entropy_seed0=pose_entropy runs/bench/runs/pose_entropy_seed1=pose_entropy --out c.png

Each run folder's ``eval_ground_truth.csv`` (written by ``emmi-gym train``; ``--scores
checkpoint_scores.csv``: the file of ``scripts/score_checkpoints.py``) gives one line per measure;
runs given the same LABEL (the seeds of one configuration) are drawn as their mean over the
evaluations they all reached, the band spanning them;
``--baselines-csv`` (``episodes.csv`` of ``emmi-gym evaluate --out``, or ``benchmark_episodes.csv`` of
``emmi-gym benchmark``) draws each scripted policy's mean there as a level line, for scale (its
episodes are not the periodic evaluation's).
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from emmi_gym.experiments.report import read_csv  # noqa: E402

MEASURES = {"oracle_accuracy": "accuracy against the oracle map", "ate": "ATE (m)",
            "sim_steps": "simulator steps", "coverage": "coverage"}
BASELINES = ("frontier", "active_loop_closing", "random")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", help="RUN_DIR or RUN_DIR=LABEL")
    parser.add_argument("--scores", default="eval_ground_truth.csv",
                        help="the file of each run folder to draw (checkpoint_scores.csv: score_checkpoints.py's)")
    parser.add_argument("--baselines-csv", type=Path, default=None)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    fig, axes = plt.subplots(1, len(MEASURES), figsize=(4 * len(MEASURES), 3.4))
    groups: dict[str, list[list[dict]]] = {}
    for run in args.runs:
        folder, _, label = run.partition("=")
        with open(Path(folder) / args.scores, newline="") as f:
            groups.setdefault(label or folder, []).append(list(csv.DictReader(f)))
    for k, (label, runs) in enumerate(groups.items()):
        length = min(len(rows) for rows in runs)
        steps = [int(float(r["timesteps"])) for r in runs[0][:length]]
        for ax, measure in zip(axes, MEASURES):
            values = np.array([[float(r[measure]) for r in rows[:length]] for rows in runs])
            name = label if len(runs) == 1 else f"{label} ({len(runs)} runs)"
            ax.plot(steps, values.mean(axis=0), marker="o", ms=3, color=f"C{k}", label=name)
            if len(runs) > 1:
                ax.fill_between(steps, values.min(axis=0), values.max(axis=0), color=f"C{k}", alpha=0.15)
    if args.baselines_csv is not None:
        episodes = [dict(r, policy=r.get("policy", r.get("variant"))) for r in read_csv(args.baselines_csv)]
        for k, policy in enumerate(p for p in BASELINES if any(r["policy"] == p for r in episodes)):
            for ax, measure in zip(axes, MEASURES):
                mean = np.nanmean([r[measure] for r in episodes if r["policy"] == policy])
                ax.axhline(mean, color=f"C{len(groups) + k}", ls="--", lw=1, label=policy)
    for ax, measure in zip(axes, MEASURES):
        ax.set_xlabel("decisions trained")
        ax.set_title(f"held-out: {MEASURES[measure]}", fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(args.out, dpi=100)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
