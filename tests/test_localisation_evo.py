"""Cross-check against evo (the reference tool; GPL, test-only dependency: `pip install .[evo]`).

Same bag, same association (truth interpolated at the ICP stamps shifted by our delay, or nearest
stamp within max_diff), same alignment (Umeyama SE(3), no scale): our APE statistics on the
translation part must equal evo's to 1e-6 m.
"""

from __future__ import annotations

import pytest

pytest.importorskip("evo", reason="evo not installed (test-only GPL reference tool): pip install -e .[evo]")

from cobot_analysis.localisation import synth  # noqa: E402
from cobot_analysis.localisation.analysis import Options, analyse_run  # noqa: E402


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    d = tmp_path_factory.mktemp("evo")
    run = synth.make_run(synth.SynthParams(n_goals=2, seed=3))
    return {"ros1": synth.write_ros1(run, d / "run.bag"), "ros2": synth.write_ros2(run, d / "run_ros2"),
            "mcap": synth.write_mcap(run, d / "run.mcap")}


def _evo_ape(path, kind, delay, method):
    from evo.core import metrics, sync
    from evo.core.sync_method import SyncMethod
    from evo.tools import file_interface
    from rosbags.rosbag1 import Reader as Reader1
    from rosbags.rosbag2 import Reader as Reader2

    with (Reader1 if kind == "ros1" else Reader2)(path) as reader:
        ref = file_interface.read_bag_trajectory(reader, "/mocap/pose")
        est = file_interface.read_bag_trajectory(reader, "/icp/pose")
    ref, est = sync.associate_trajectories(ref, est, sync_method=SyncMethod(method), max_diff=0.01, offset_2=-delay)
    est.align(ref)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, est))
    return ape.get_all_statistics(), est.num_poses


@pytest.mark.parametrize("kind", ["ros1", "ros2", "mcap"])
@pytest.mark.parametrize("association", ["interpolate", "nearest"])
def test_ape_equals_evo(bags, kind, association):
    opts = Options(alignment="se3", association=association, max_diff=0.01)
    ours = analyse_run((str(bags[kind]), "run", "", opts))["row"]
    stats, n = _evo_ape(bags[kind], kind, ours["delay"], "interpolation" if association == "interpolate" else "nearest_time")
    assert ours["n"] == n
    assert abs(ours["delay"] - 0.55) < 0.005
    for ours_key, evo_key in (("ape_rmse", "rmse"), ("ape_mean", "mean"), ("ape_max", "max"), ("ape_median", "median"),
                              ("ape_std", "std"), ("ape_min", "min")):
        assert ours[ours_key] == pytest.approx(stats[evo_key], abs=1e-6), ours_key
