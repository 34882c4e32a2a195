"""Without the 'ros' extra (the rosbags library) a bag, or a bag to write, is one line naming the extra
and the pip command, and exit 2, before any work; CARMEN logs need nothing more."""

from __future__ import annotations

import sys

import pytest

from emmi_gym.tools.cli import main


@pytest.fixture
def without_rosbags(monkeypatch):
    """Imports of rosbags fail, as where it is not installed."""
    for name in [name for name in sys.modules if name == "rosbags" or name.startswith("rosbags.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "rosbags", None)


@pytest.mark.parametrize("bag_out", [False, True])
def test_bags_without_the_extra_are_one_line_and_exit_2(tmp_path, capsys, without_rosbags, bag_out):
    if bag_out:  # a CARMEN log, but a bag to write: refused before the replay
        log = tmp_path / "run.log"
        log.write_text("ODOM 0 0 0 0 0 0 1.0 h 1.0\n")
        args = [str(log), "--bag-out", str(tmp_path / "maps")]
    else:
        (tmp_path / "run.bag").write_bytes(b"#ROSBAG V2.0\n")
        args = [str(tmp_path / "run.bag")]
    with pytest.raises(SystemExit) as exit_info:
        main(["replay", *args, "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert exit_info.value.code == 2
    assert err == ("emmi-gym replay: error: ROS bags need the 'ros' extra (the rosbags library): "
                   "pip install 'emmi-gym[ros]'\n")
