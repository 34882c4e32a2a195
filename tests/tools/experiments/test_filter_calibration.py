"""The filter's calibration measured over episodes (every update watched) and over a real log."""

import math

import gymnasium as gym
import numpy as np
import pytest
from helpers import DATA

import emmi_gym  # noqa: F401
from emmi_gym.formats.carmen import read_log
from emmi_gym.slam import RBPFConfig
from emmi_gym.tools.experiments.calibration import (
    CalibrationRecord,
    LogChecks,
    UpdateChecks,
    calibrate_episode,
    loop_checks,
    spread_against_error,
    summary,
)
from emmi_gym.tools.experiments.replay import replay
from emmi_gym.tools.policies import make_policy

TINY = dict(particles=4, max_decisions=3)


def test_every_filter_update_of_an_episode_is_checked_against_the_truth():
    """The watcher sees the drive to the decision point and every step's updates: one pose check per update
    (the truth's count), relative checks once the path is long enough; the checks read the episode's truth."""
    env = gym.make("emmi_gym/LoopCorridor-v1", **TINY)
    checks = UpdateChecks(windows=(1, 10))
    env.unwrapped.watch_updates(checks)
    record = calibrate_episode(env, make_policy("frontier"), 3, checks)
    core = env.unwrapped
    updates = len(core.episode.true_poses_at_updates)
    assert len(record.checks["pose"]) == updates > 10
    assert len(record.checks["relative_1"]) == updates - 1 and len(record.checks["relative_10"]) == updates - 10
    last = record.checks["pose"][-1]
    mean_xy = core.slam.weights @ core.slam.poses[:, :2]
    assert last.error == pytest.approx(float(np.hypot(*(mean_xy - core.episode.true_poses_at_updates[-1, :2]))))
    figures = summary(record.checks["pose"])
    assert figures["moments"] == updates and 0.0 <= figures["xy_inside_95"] <= 1.0
    spread, error, counts = spread_against_error(record.checks["pose"], bins=4)
    assert counts.sum() == updates and np.all(np.diff(spread) >= 0)
    env.close()


def test_a_revisit_targets_check_has_its_loop_spread():
    """At the decision point of the corridor loop the env offers revisit targets: each one's check spreads as
    its loop spread (the same particles' displacements since the place it revisits)."""
    env = gym.make("emmi_gym/LoopCorridor-v1", **TINY)
    env.reset(seed=0)
    spreads = [s for t, s in zip(env.unwrapped.targets, env.unwrapped.loop_spreads, strict=True)
               if t is not None and t.kind == "revisit"]
    checks = loop_checks(env)
    assert spreads and len(checks) == len(spreads)
    assert [c.spread for c in checks] == pytest.approx(spreads)
    env.close()


def test_watch_updates_takes_a_callable():
    env = gym.make("emmi_gym/LoopCorridor-v1", **TINY)
    with pytest.raises(TypeError, match="callable"):
        env.unwrapped.watch_updates("not a function")
    env.close()


@pytest.mark.slow
def test_a_real_logs_relative_motions_are_checked_against_its_reference():
    """The first Intel loop: every window's relative motion at every keyframe is checked (the log has a
    reference at each), with errors of centimetres over one keyframe."""
    checks = LogChecks(windows=(1, 10))
    result = replay(read_log(DATA / "intel-first-loop.log.gz"), RBPFConfig.preset("radish-noisy", particles=6,
                    resolution=0.05), max_range=30.0, every_scan=True, on_update=checks)
    record: CalibrationRecord = checks.record(result.true_poses)
    assert len(record.checks["relative_1"]) == len(result.rows) - 1
    assert len(record.checks["relative_10"]) == len(result.rows) - 10
    one = summary(record.checks["relative_1"])
    assert 0.0 < one["rms_error"] < 0.1 and math.isfinite(one["xy_median"])


def test_the_unweighted_diagnosis_checks_the_plain_mean_of_the_cloud():
    env = gym.make("emmi_gym/LoopCorridor-v1", **TINY)
    checks = UpdateChecks(windows=(1,), unweighted=True)
    env.unwrapped.watch_updates(checks)
    checks.start(record := CalibrationRecord())
    env.reset(seed=1)
    core = env.unwrapped
    truth = core.episode.true_poses_at_updates[-1, :2]
    plain = float(np.hypot(*(core.slam.poses[:, :2].mean(axis=0) - truth)))
    assert record.checks["pose"][-1].error == pytest.approx(plain)
    env.close()
