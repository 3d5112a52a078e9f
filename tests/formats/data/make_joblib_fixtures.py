"""Writes the joblib fixtures of tests/formats/test_motion_pickles.py (run once; joblib is no dependency):

    pip install joblib==1.6.0 && python tests/formats/data/make_joblib_fixtures.py

`wham_like.pkl`: two tracked people as WHAM's `joblib.dump` writes them ({track id: {'pose', 'trans', 'pose_world',
'trans_world', 'betas', 'verts', 'frame_ids'}}), uncompressed; `wham_like_zlib.pkl`: the same, compress=3 (zlib).
"""

from pathlib import Path

import numpy as np


def people() -> dict:
    rng = np.random.default_rng(0)

    def person(frames, first):
        return {"pose": rng.normal(scale=0.2, size=(frames, 72)).astype(np.float32),
                "trans": rng.normal(size=(frames, 3)).astype(np.float32),
                "pose_world": rng.normal(scale=0.2, size=(frames, 72)).astype(np.float32),
                "trans_world": rng.normal(size=(frames, 3)).astype(np.float32),
                "betas": rng.normal(scale=0.05, size=(frames, 10)).astype(np.float32),
                "verts": rng.normal(size=(frames, 4, 3)).astype(np.float32),
                "frame_ids": np.delete(np.arange(first, first + frames + 1), 3)}  # frame first+3 untracked

    return {np.int64(0): person(6, 0), np.int64(7): person(4, 10)}


if __name__ == "__main__":
    import joblib

    here = Path(__file__).parent
    joblib.dump(people(), here / "wham_like.pkl")
    joblib.dump(people(), here / "wham_like_zlib.pkl", compress=3)
