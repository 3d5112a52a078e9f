"""benchmarks/model_by_sequence.py's summary: the mean error per garment, split and body, and the model's share."""

import importlib.util
from pathlib import Path

import pytest

_spec = importlib.util.spec_from_file_location(
    "model_by_sequence", Path(__file__).resolve().parents[2] / "benchmarks" / "model_by_sequence.py")
mbs = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(mbs)


def test_summary_rows_average_per_body_then_over_all_bodies():
    assert mbs.body_of("tshirt__kick_left__c00__b02") == "b02"
    rows = [{"garment": "g", "split": "train", "body": "b00", "lbs": 30.0, "model": 15.0},
            {"garment": "g", "split": "train", "body": "b00", "lbs": 10.0, "model": 9.0},
            {"garment": "g", "split": "train", "body": "b01", "lbs": 40.0, "model": 10.0, "psd": 5.0},
            {"garment": "g", "split": "test", "body": "b01", "lbs": 20.0, "model": 30.0}]
    out = {(r["split"], r["body"]): r for r in mbs.summary_rows(rows, ["lbs", "model", "psd"])}
    assert list(out) == [("train", "b00"), ("train", "b01"), ("train", "all"), ("test", "b01"), ("test", "all")]
    b00 = out[("train", "b00")]
    assert (b00["sequences"], b00["lbs"], b00["model"]) == (2, 20.0, 12.0) and "psd" not in b00
    assert b00["model / LBS"] == pytest.approx(0.6)  # the ratio of the means, not the mean of the ratios (0.625)
    everything = out[("train", "all")]
    assert everything["sequences"] == 3 and everything["lbs"] == pytest.approx(80 / 3)
    assert everything["model / LBS"] == pytest.approx(34 / 80) and everything["psd"] == 5.0
    assert out[("test", "all")]["model / LBS"] == pytest.approx(1.5)  # worse than LBS shows as such
