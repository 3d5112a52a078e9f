"""--quality auto: scene features with known answers, and the choice on a synthetic calibration."""

import numpy as np
import pytest

from core.errors import InputError
from core.garment import Garment
from core.geometry import vertex_normals
from core.motion import Motion
from core.quality import Calibration, add_scene, choose, scene_features
from tests.meshes import tiny_body


def shell(body, offset):
    v = body.v_template + offset * vertex_normals(body.v_template, body.faces)
    return Garment(v.astype(np.float32), body.faces.astype(np.int64))


def test_scene_features_known_answers():
    body = tiny_body()
    T = 10
    poses = np.zeros((T, body.n_joints, 3), np.float32)
    trans = np.zeros((T, 3), np.float32)
    trans[:, 0] = np.arange(T) / 30.0 * 1.5  # 1.5 m/s along x at 30 fps, no rotation
    motion = Motion(poses=poses, trans=trans, fps=30.0)
    for offset in (0.01, 0.05):
        f = scene_features(shell(body, offset), body, motion)
        # Each vertex moved `offset` along its normal: its distance to the body is about the offset.
        assert f["looseness_m"] == pytest.approx(offset, rel=0.15)
        assert f["speed_m_s"] == pytest.approx(1.5, rel=1e-4)
        assert f["vertices"] == body.v_template.shape[0] and f["frames"] == T
    still = Motion(poses=poses[:1], trans=trans[:1], fps=30.0)
    assert scene_features(shell(body, 0.01), body, still)["speed_m_s"] == 0.0


def synthetic_calibration(lbs_limited: bool = False):
    """lbs, the model and the simulator on 16 scenes; with `lbs_limited`, LBS with its strain limit too (twice
    LBS's cost, 80 % of its error)."""
    cal = Calibration({})
    for loose in (0.005, 0.01, 0.03, 0.1):
        for speed in (0.2, 1.0, 3.0, 6.0):
            lbs = 100.0 * loose * speed * 10  # mm: grows with looseness and speed
            limited = [{"config": "lbs +strain-limit 1.5", "method": "lbs", "seconds_per_frame": 2e-4,
                        "e_verts": 0.8 * lbs, "options": {"strain_limit": 1.5}}] if lbs_limited else []
            rows = [{"config": "lbs", "method": "lbs", "seconds_per_frame": 1e-4, "e_verts": lbs}, *limited,
                    {"config": "model float32", "method": "model", "seconds_per_frame": 1e-2,
                     "e_verts": 0.4 * lbs + 2.0, "options": {"precision": "float32", "push_out": False}},
                    {"config": "sim", "method": "sim", "seconds_per_frame": 1.0, "e_verts": 0.0, "reference": True,
                     "options": {"substeps": 10, "self_contact": True}}]
            add_scene(cal, {"looseness_m": loose, "speed_m_s": speed, "vertices": 1000}, rows)
    return cal


def test_choose_cheapest_within_budget():
    cal = synthetic_calibration()
    tight_slow = {"looseness_m": 0.006, "speed_m_s": 0.3, "vertices": 4000}
    loose_run = {"looseness_m": 0.09, "speed_m_s": 5.0, "vertices": 4000}
    pick = choose(cal, tight_slow, budget_mm=20.0)
    assert pick["config"] == "lbs" and pick["expected_mm"] < 20 and "lbs" in pick["reason"]
    pick = choose(cal, loose_run, budget_mm=250.0)
    assert pick["config"] == "model float32" and "'lbs' is cheaper but expected" in pick["reason"]
    assert pick["ms_per_frame"] == pytest.approx(40.0)  # 10 ms per 1k vertices x 4k
    pick = choose(cal, loose_run, budget_mm=5.0)
    assert pick["config"] == "sim" and "'model float32' is cheaper but expected at" in pick["reason"]
    # the reference is not "expected at 0.0 mm": that is its definition, and two valid simulations differ more
    assert "'sim' is the calibration's reference, 0 mm by definition (two equally valid simulations of a scene " \
           "differ by 5.6-8.3 mm" in pick["reason"] and "expected at 0.0" not in pick["reason"]
    # A calibration without the reference: nothing meets the budget -> the most accurate, said so.
    del cal.configs["sim"]
    pick = choose(cal, loose_run, budget_mm=5.0)
    assert pick["config"] == "model float32" and "no configuration is expected within 5 mm" in pick["reason"]


def test_calibration_round_trip_and_bad_file(tmp_path):
    cal = synthetic_calibration()
    cal.save(tmp_path / "c.json")
    again = Calibration.load(tmp_path / "c.json")
    assert again.configs == cal.configs
    (tmp_path / "bad.json").write_text('{"configs": {"lbs": {"method": "lbs", "ms_per_frame_per_kvert": 1, '
                                       '"points": [[0.1, 1.0]]}}}')
    with pytest.raises(InputError, match="bad.json"):
        Calibration.load(tmp_path / "bad.json")
    (tmp_path / "motion.npz").write_bytes(b"PK\x03\x04\xf3\x00 a zip")  # a motion given as --calibrate
    with pytest.raises(InputError, match=r"motion.npz': expected the JSON .* writes, got binary content$"):
        Calibration.load(tmp_path / "motion.npz")


def test_psd_candidate_scales_lbs_by_the_share_the_fit_kept():
    from core.errors import InputError
    from core.quality import PSD_COST_OVER_LBS, psd_candidate

    cal = synthetic_calibration()
    scene = {"looseness_m": 0.03, "speed_m_s": 1.0, "vertices": 2000}
    lbs = cal.expected_error("lbs", scene)
    c = psd_candidate(cal, scene, {"errors": {"test": {"psd_mm": 5.0, "lbs_mm": 20.0}}})
    assert c["expected_mm"] == pytest.approx(0.25 * lbs) and c["method"] == "psd"
    assert c["ms_per_frame"] == pytest.approx(PSD_COST_OVER_LBS * 0.1 * 2)  # LBS: 1e-4 s a frame per 1k vertices
    both = {"val": {"psd_mm": 10.0, "lbs_mm": 20.0}, "test": {"psd_mm": 5.0, "lbs_mm": 20.0}}
    assert psd_candidate(cal, scene, {"errors": both})["expected_mm"] == pytest.approx(0.5 * lbs)  # val first
    assert psd_candidate(cal, scene, {})["expected_mm"] == pytest.approx(lbs)  # nothing measured: LBS's
    with pytest.raises(InputError, match="no 'lbs' configuration"):
        psd_candidate(Calibration({}), scene, {})


def test_a_scene_beyond_the_calibration_expects_the_learned_methods_no_better_than_lbs():
    cal = synthetic_calibration()  # looseness 0.005-0.1 m, speeds 0.2-6 m/s
    still = {"looseness_m": 0.09, "speed_m_s": 0.05, "vertices": 1000}
    lbs, model = cal.expected_error("lbs", still), cal.expected_error("model float32", still)
    assert model < 15.0 < lbs < 30.0  # the calibration alone would take the model within 15 mm
    pick = choose(cal, still, budget_mm=15.0)
    assert pick["config"] == "sim" and pick["outside_calibration"] == [
        {"feature": "speed_m_s", "value": 0.05, "calibrated": [0.2, 6.0]}]
    m = next(c for c in pick["candidates"] if c["config"] == "model float32")
    assert m["expected_mm"] == pytest.approx(lbs) and m["expected_mm_calibration"] == pytest.approx(model)
    assert "speed 0.05 m/s, under the smallest calibrated, 0.2" in pick["reason"]
    assert "no better than lbs" in pick["reason"]
    # the simulator chosen for that alone says what the model would have been expected at, and its cost
    ratio = pick["ms_per_frame"] / m["ms_per_frame"]
    assert (f"(the calibration's nearest scenes would expect 'model float32' at {model:.1f} mm: `--method model` "
            f"bakes it regardless, {ratio:.0f}x cheaper)") in pick["reason"]
    assert "would expect" not in choose(cal, {**still, "speed_m_s": 1.0}, budget_mm=15.0)["reason"]
    assert choose(cal, still, budget_mm=30.0)["config"] == "lbs"  # as good and cheaper
    # Within OUTSIDE_FACTOR of the range it is a calibrated scene; beyond it on either side or feature, not.
    for features, outside in (({"looseness_m": 0.09, "speed_m_s": 0.2 / 1.2}, []),
                              ({"looseness_m": 0.09, "speed_m_s": 6.0 * 1.2}, []),
                              ({"looseness_m": 0.09, "speed_m_s": 6.0 * 1.3}, ["speed_m_s"]),
                              ({"looseness_m": 0.3, "speed_m_s": 1.0}, ["looseness_m"]),
                              ({"looseness_m": 0.001, "speed_m_s": 100.0}, ["looseness_m", "speed_m_s"])):
        pick = choose(cal, {**features, "vertices": 1000}, budget_mm=1000.0)
        assert [o["feature"] for o in pick["outside_calibration"]] == outside
        assert ("beyond the calibration" in pick["reason"]) == bool(outside)
    # Without an lbs configuration the scene is still named beyond the calibration, the expectations kept.
    del cal.configs["lbs"]
    pick = choose(cal, still, budget_mm=15.0)
    assert pick["config"] == "model float32" and pick["outside_calibration"]
    assert "no better than lbs" not in pick["reason"]


def test_a_self_contact_row_the_scene_analysis_skipped_gives_its_error_not_its_cost():
    """A tradeoff row '+self-contact' that the simulator ran without it (no distant parts meet) measured the plain
    row: its error is the configuration's on that scene, its cost is not (the calibration priced self-contact at
    the cost without it)."""
    cal = Calibration({})

    def row(seconds, skipped):
        return {"config": "sim +self-contact", "method": "sim", "seconds_per_frame": seconds, "e_verts": 5.0,
                "options": {"substeps": 10, "self_contact": True}, "self_contact_skipped": skipped}

    scene = {"looseness_m": 0.02, "speed_m_s": 1.0, "vertices": 1000}
    add_scene(cal, scene, [row(1.0, True)])  # none measured with it yet: the row's cost stands in
    c = cal.configs["sim +self-contact"]
    assert c["ms_per_frame_per_kvert"] == pytest.approx(1000.0) and c["costed_scenes"] == 0 and c["scenes"] == 1
    add_scene(cal, scene, [row(4.0, False)])  # measured with it: its cost replaces the stand-in
    assert c["ms_per_frame_per_kvert"] == pytest.approx(4000.0) and c["costed_scenes"] == 1
    add_scene(cal, scene, [row(1.0, True)])  # skipped again: its error counted, its cost not
    assert c["ms_per_frame_per_kvert"] == pytest.approx(4000.0) and c["scenes"] == 3 and len(c["points"]) == 3
    add_scene(cal, scene, [row(2.0, False)])
    assert c["ms_per_frame_per_kvert"] == pytest.approx(3000.0) and c["costed_scenes"] == 2
