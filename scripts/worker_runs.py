"""Train a small agent with rollout workers again and again (``policy_lag`` 0 and 1 in turn) and count the runs
that succeed without printing a traceback: a shutdown must be quiet however the workers' last fragments end.

    python scripts/worker_runs.py --runs 20
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml

AGENT = {"env": {"id": "emmi_gym/LoopCorridor-v1", "kwargs": {"particles": 3, "max_decisions": 3}},
         "algorithm": "MaskablePPO", "policy": "MultiInputPolicy",
         "hyperparameters": {"n_steps": 6, "batch_size": 6, "n_epochs": 1, "policy_kwargs": {"net_arch": [16]}},
         "n_envs": 2, "vec_env": "workers", "total_timesteps": 48, "checkpoint_freq": 12, "eval": {"freq": 0},
         "seed": 7}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    args = parser.parse_args()
    clean = 0
    with tempfile.TemporaryDirectory() as tmp:
        for run in range(args.runs):
            config = Path(tmp) / f"agent{run}.yaml"
            config.write_text(yaml.safe_dump(dict(AGENT, policy_lag=run % 2)))
            done = subprocess.run([sys.executable, "-m", "emmi_gym.tools.cli", "train", str(config), "--out",
                                   str(Path(tmp) / f"run{run}"), "--quiet"], capture_output=True, text=True)
            output = done.stdout + done.stderr
            ok = done.returncode == 0 and "Traceback" not in output and "Error" not in output
            clean += ok
            print(f"run {run + 1} (policy_lag {run % 2}): exit {done.returncode}, "
                  f"{'clean' if ok else 'NOT CLEAN: ' + output.strip().splitlines()[-1]}", flush=True)
    print(f"{clean} of {args.runs} runs succeeded without a traceback")


if __name__ == "__main__":
    main()
