"""The RBPF on a real laser log: the first loop of the Intel Research Lab (180 beams, 0.05 m cells)."""


import numpy as np
import pytest
from helpers import DATA

from emmi_gym.formats.carmen import read_log
from emmi_gym.slam import RBPFConfig
from emmi_gym.tools.experiments.replay import replay

pytestmark = pytest.mark.slow  # replays the first Intel loop (module fixture, 2.7 s), which both tests share

LOG = DATA / "intel-first-loop.log.gz"
BACK_AT_START = 98  # keyframe at which the corrected path first returns to the start


@pytest.fixture(scope="module")
def intel_loop():
    return replay(read_log(LOG), RBPFConfig.preset("radish-noisy", particles=15, resolution=0.05), max_range=30.0,
                  every_scan=True)


def test_the_first_intel_loop_closes(intel_loop):
    """72 m round the lab with real 180-degree scans and noisy odometry: the filter tracks the corrected
    path (ATE 0.05 m when measured; dead reckoning 0.51 m), and the loop closes: the path's end
    agrees with the corrected one as well as its middle does."""
    result = intel_loop
    assert len(result.rows) == 130
    ate, dead_reckoning = result.ate(), result.dead_reckoning_ate()
    assert ate < 0.1 and ate < 0.2 * dead_reckoning, (ate, dead_reckoning)
    path = result.slam.paths[result.slam.best]
    truth = np.array(result.true_poses)
    # after closing, the pose relative to the start is that of the truth: no map built twice
    offset = (path[BACK_AT_START:, :2] - path[0, :2]) - (truth[BACK_AT_START:, :2] - truth[0, :2])
    assert np.median(np.hypot(*offset.T)) < 0.3


def test_weights_keep_the_particles_until_the_loop_closes(intel_loop):
    """Calibrated weights: no resampling along the first 90 keyframes (corridor driving), so the
    particles still disagree when the loop closes; Neff falls below M / 2 as it closes."""
    resampled = [r.step for r in intel_loop.rows if r.resampled]
    assert not [step for step in resampled if step < 90], resampled
    assert [step for step in resampled if BACK_AT_START - 8 <= step <= BACK_AT_START + 10], resampled
