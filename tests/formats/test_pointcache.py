"""Tests of formats/pointcache.py: PC2 and MDD written as 3ds Max and LightWave lay them out (checked field by
field against the formats' headers), read back; damaged files one line naming them."""

import struct

import numpy as np
import pytest

from core.errors import InputError
from formats.pointcache import read_point_cache, write_point_cache


def test_pc2_and_mdd_round_trip_with_their_headers(tmp_path):
    rng = np.random.default_rng(0)
    points = rng.normal(size=(4, 5, 3)).astype(np.float32)
    pc2 = write_point_cache(tmp_path / "a.pc2", points, fps=24.0, start_frame=1001).read_bytes()
    assert pc2[:12] == b"POINTCACHE2\0" and struct.unpack_from("<iiffi", pc2, 12) == (1, 5, 1001.0, 1.0, 4)
    assert len(pc2) == 32 + 4 * 5 * 3 * 4
    np.testing.assert_array_equal(np.frombuffer(pc2, "<f4", offset=32).reshape(4, 5, 3), points)
    mdd = write_point_cache(tmp_path / "a.mdd", points, fps=24.0, start_frame=2).read_bytes()
    assert struct.unpack_from(">ii", mdd) == (4, 5)
    np.testing.assert_allclose(np.frombuffer(mdd, ">f4", 4, 8), [2 / 24, 3 / 24, 4 / 24, 5 / 24], rtol=1e-6)
    np.testing.assert_array_equal(np.frombuffer(mdd, ">f4", offset=8 + 16).reshape(4, 5, 3), points)
    for name, stamps in (("a.pc2", [1001, 1002, 1003, 1004]), ("a.mdd", np.arange(2, 6) / 24)):
        read, read_stamps = read_point_cache(tmp_path / name)
        np.testing.assert_array_equal(read, points)
        np.testing.assert_allclose(read_stamps, stamps, rtol=1e-6)
    with pytest.raises(ValueError, match="expected a .pc2 or .mdd path"):
        write_point_cache(tmp_path / "a.abc", points, fps=24.0)


def assert_each_refused(path, cases):
    """Each (bytes, expected fragment) written to `path` is refused by read_point_cache in one line naming it."""
    for data, expected in cases:
        path.write_bytes(data)
        with pytest.raises(InputError) as info:
            read_point_cache(path)
        message = str(info.value)
        assert "\n" not in message and message.startswith(f"point cache '{path}': ") and expected in message, message


def test_a_damaged_point_cache_is_one_line(tmp_path):
    points = np.zeros((3, 4, 3), np.float32)
    pc2 = write_point_cache(tmp_path / "good.pc2", points, fps=30.0).read_bytes()
    mdd = write_point_cache(tmp_path / "good.mdd", points, fps=30.0).read_bytes()
    assert_each_refused(tmp_path / "bad.pc2", [(pc2[:40], "cut short or damaged (its header's frames and points "
                                                         "exceed its 40 bytes)"),
                                               (b"POINTCACHE3\0" + pc2[12:], "expected a PC2 file"),
                                               (pc2[:16] + struct.pack("<i", -4) + pc2[20:], "expected a header of "
                                                "at least 1 frame and 1 point, got 3 and -4")])
    assert_each_refused(tmp_path / "bad.mdd", [(mdd[:30], "cut short or damaged"),
                                               (struct.pack(">ii", 0, 4) + mdd[8:], "got 0 and 4")])
    (tmp_path / "good.txt").write_bytes(pc2)
    with pytest.raises(InputError, match="expected a .pc2 or .mdd file"):
        read_point_cache(tmp_path / "good.txt")
    with pytest.raises(InputError, match="cannot be read"):
        read_point_cache(tmp_path / "gone.pc2")
