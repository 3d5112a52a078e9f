"""Dataset planning (splits, betas, clips) and the sequence storage round trip."""

import numpy as np
import pytest

from core.dataset import (build_manifest, clip_ranges, manifest_bodies, manifest_motion_splits, plan_items, sample_betas,
                          settings_difference, split_motions)
from core.errors import InputError
from formats.dataset import Sequence, read_sequence, write_sequence


def test_betas_are_seeded_in_range_with_a_mean_body():
    b = sample_betas(4, 10, 2.0, seed=1)
    assert b.shape == (4, 10) and b.dtype == np.float32
    assert np.all(b[0] == 0) and np.abs(b).max() <= 2.0 and np.abs(b[1:]).min() > 0
    np.testing.assert_array_equal(b, sample_betas(4, 10, 2.0, seed=1))
    assert not np.array_equal(b, sample_betas(4, 10, 2.0, seed=2))
    with pytest.raises(InputError, match="--bodies"):
        sample_betas(0, 10)


def test_splits_share_no_motion_and_test_holds_an_unseen_garment():
    motions = {f"m{i:02d}": 40 for i in range(20)}
    garments = ["dress", "skirt", "tshirt", "trousers"]
    items, splits = plan_items(garments, motions, n_bodies=3, frames_per_clip=None, seed=0)
    by_split = {s: {it.motion for it in items if it.split == s} for s in ("train", "val", "test")}
    assert by_split["train"] and by_split["val"] and by_split["test"]
    assert not (by_split["train"] & by_split["val"]) and not (by_split["train"] & by_split["test"])
    assert not (by_split["val"] & by_split["test"])
    assert len(by_split["train"]) == 14 and len(by_split["test"]) == 3
    held = splits["held_out_garments"]
    assert len(held) == 1
    train_garments = {it.garment for it in items if it.split in ("train", "val")}
    test_garments = {it.garment for it in items if it.split == "test"}
    assert held[0] not in train_garments and held[0] in test_garments and test_garments == set(garments)
    assert len({it.id for it in items}) == len(items)
    assert {it.body for it in items} == {0, 1, 2}
    # deterministic
    assert items == plan_items(garments, motions, 3, None, seed=0)[0]


def test_split_naive_small_cases():
    assert set(split_motions(["a"]).values()) == {"train"}
    assert sorted(split_motions(["a", "b"]).values()) == ["test", "train"]
    with pytest.raises(InputError, match="distinct"):
        split_motions(["a", "a"])


def test_a_resume_keeps_its_motions_splits_and_splits_the_new_ones_among_themselves():
    old = [f"m{i:02d}" for i in range(10)]
    added = ["n0", "n1", "n2", "n3"]
    before = split_motions(old, seed=0)
    assert any(split_motions(old + added, seed=0)[m] != before[m] for m in old)  # a fresh plan moves old motions
    after = split_motions(old + added, seed=0, kept=before)
    assert {m: after[m] for m in old} == before
    assert {m: after[m] for m in added} == split_motions(added, seed=0)  # as a plan of the new ones alone
    assert sorted(after[m] for m in added) == ["test", "train", "train", "val"]
    assert after == split_motions(added + old, seed=0, kept=before)  # deterministic, whatever the order given
    # A motion removed since is no longer planned; the others keep theirs.
    assert split_motions(old[1:], seed=0, kept=before) == {m: before[m] for m in old[1:]}
    with pytest.raises(InputError, match="split of motion 'm00': expected train, val or test, got 'dev'"):
        split_motions(old, kept={"m00": "dev"})


def test_a_motion_added_on_resume_keeps_the_items_planned_before():
    """With --bodies-per-clip the bodies go round in motion order: the motions planned before take theirs first,
    so a motion added ahead of them in the list changes none of their items (nor their splits)."""
    motions = {f"m{i}": 40 for i in range(5)}
    before, splits = plan_items(["a", "b"], motions, 3, bodies_per_clip=1, seed=0)
    kept = {m: s for s, names in splits["motions"].items() for m in names}
    after, _ = plan_items(["a", "b"], {"new": 40, **motions}, 3, bodies_per_clip=1, seed=0, kept_splits=kept)
    assert set(before) <= set(after) and {it.motion for it in set(after) - set(before)} == {"new"}
    assert plan_items(["a", "b"], motions, 3, bodies_per_clip=1, seed=0, kept_splits=kept)[0] == before


def test_a_motion_removed_on_resume_keeps_the_other_motions_items():
    """A motion removed would move the bodies' turns of the motions after it: the manifest's bodies are kept."""
    motions = {f"m{i}": 40 for i in range(5)}
    before, splits = plan_items(["a", "b"], motions, 3, bodies_per_clip=1, seed=0)
    manifest = build_manifest({}, before, splits, np.zeros((3, 10)), {}, {})
    fewer = {m: n for m, n in motions.items() if m != "m0"}
    moved, _ = plan_items(["a", "b"], fewer, 3, bodies_per_clip=1, seed=0, kept_splits=manifest_motion_splits(manifest))
    assert not set(moved) <= set(before)  # the turns moved: finished sequences would be simulated again
    after, _ = plan_items(["a", "b"], fewer, 3, bodies_per_clip=1, seed=0, kept_splits=manifest_motion_splits(manifest),
                          kept_bodies=manifest_bodies(manifest))
    assert set(after) == {it for it in before if it.motion != "m0"}
    # a manifest of another make (items without clip or body) keeps what it can and plans the rest afresh
    odd = {"items": [{"id": "x", "motion": "m1", "split": "val"}, "junk", {"garment": "a", "motion": "m2"}]}
    assert manifest_bodies(odd) == {} and manifest_motion_splits(odd) == {"m1": "val"}


def test_clips_cover_the_motion_in_order():
    assert clip_ranges(100, None) == [(0, 100)]
    assert clip_ranges(100, 40) == [(0, 40), (40, 80), (80, 100)]
    assert clip_ranges(85, 40) == [(0, 40), (40, 80)]  # a 5-frame tail is dropped (< a quarter clip)


def test_sequence_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    s = Sequence(positions=rng.normal(size=(5, 7, 3)).astype(np.float32), poses=rng.normal(size=(5, 24, 3)),
                 trans=rng.normal(size=(5, 3)), betas=np.arange(10), fps=30.0, n_settle=2, garment="dress",
                 garment_sha256="ab" * 32, body="default")
    p = tmp_path / "x" / "seq.npz"
    write_sequence(p, s)
    r = read_sequence(p)
    np.testing.assert_array_equal(r.positions, s.positions)
    np.testing.assert_allclose(r.poses, s.poses, rtol=1e-6)
    assert r.poses.dtype == np.float32 and r.betas.dtype == np.float32
    assert (r.fps, r.n_settle, r.garment, r.garment_sha256, r.body) == (30.0, 2, "dress", "ab" * 32, "default")
    assert [f.name for f in p.parent.iterdir()] == ["seq.npz"]  # no temporary left
    with pytest.raises(InputError, match="share T=5"):
        write_sequence(p, Sequence(s.positions, s.poses[:3], s.trans, s.betas, 30.0, 0, "d", "x", "b"))


def test_motion_library_keeps_the_examples_and_is_varied():
    from core.motiongen import generate_example_motions, generate_motion_library

    lib = generate_motion_library(fps=30.0)
    ex = generate_example_motions(fps=30.0)
    assert len(lib) >= 24
    for name, m in ex.items():
        np.testing.assert_array_equal(lib[name].poses, m.poses)
        np.testing.assert_array_equal(lib[name].trans, m.trans)
    for name, m in lib.items():
        assert m.name == name and m.poses.shape[1:] == (24, 3)
        assert np.all(np.isfinite(m.poses)) and np.all(np.isfinite(m.trans))
        assert 0.3 < m.trans[:, 2].min() and m.trans[:, 2].max() < 1.4  # pelvis above the ground, below 1.4 m
    # variations differ from their base clip
    for a, b in (("walk", "walk_fast"), ("turn", "turn_right"), ("jump", "jump_high"), ("kick_left", "kick_right")):
        assert not np.allclose(lib[a].poses[: min(lib[a].n_frames, lib[b].n_frames)],
                               lib[b].poses[: min(lib[a].n_frames, lib[b].n_frames)])


def test_max_clips_per_motion_keeps_the_first_clips():
    items, _ = plan_items(["a"], {"m": 100}, 1, frames_per_clip=30, max_clips_per_motion=2)
    assert [(it.start_frame, it.n_frames) for it in items] == [(0, 30), (30, 30)]


def test_bodies_per_clip_takes_the_bodies_in_turn_and_held_out_is_chosen():
    motions = {f"m{i}": 40 for i in range(10)}
    full, _ = plan_items(["a", "b", "c"], motions, 3, held_out="c")
    items, splits = plan_items(["a", "b", "c"], motions, 3, bodies_per_clip=1, held_out="c")
    assert splits["held_out_garments"] == ["c"]
    assert {it.garment for it in items if it.split != "test"} == {"a", "b"}
    assert "c" in {it.garment for it in items if it.split == "test"}
    # One body per (garment, clip), every body used about equally, a subset of the full plan.
    pairs = {(it.garment, it.motion, it.clip) for it in items}
    assert len(items) == len(pairs) == len(full) // 3
    counts = np.bincount([it.body for it in items], minlength=3)
    assert counts.max() - counts.min() <= 1
    assert {it.id for it in items} <= {it.id for it in full}
    two, _ = plan_items(["a", "b"], motions, 3, bodies_per_clip=2)
    assert len(two) == 2 * len({(it.garment, it.motion) for it in two})
    with pytest.raises(InputError, match="--held-out"):
        plan_items(["a", "b"], motions, 1, held_out="z")
    every, splits = plan_items(["a", "b", "c"], motions, 1, held_out=False)
    assert splits["held_out_garments"] == [] and {it.garment for it in every if it.split == "train"} == {"a", "b", "c"}


def test_settings_difference_names_nested_added_and_removed_keys():
    old = {"seed": 0, "solver": {"substeps": 10, "pin": "auto"}, "gone": 1}
    new = {"seed": 0, "solver": {"substeps": 20, "pin": "auto", "contact_buffer_mb": 512}}
    assert settings_difference(old, new) == ("gone: 1 -> absent; solver.contact_buffer_mb: absent -> 512; "
                                             "solver.substeps: 10 -> 20")
    assert settings_difference(old, new, limit=1) == "gone: 1 -> absent; 2 more"
    assert settings_difference(new, new) == ""


def test_preroll_leads_into_every_clip_that_does_not_start_its_motion():
    from core.dataset import item_frames, item_motion, simulate_item
    from core.motion import Motion

    items, _ = plan_items(["a"], {"m": 100}, 1, frames_per_clip=30, max_clips_per_motion=3, preroll=12)
    assert [(it.start_frame, it.preroll) for it in items] == [(0, 0), (30, 12), (60, 12)]
    assert [it.preroll for it in plan_items(["a"], {"m": 100}, 1, frames_per_clip=30, preroll=45)[0]] == [0, 30, 45, 45]
    assert item_frames(items[1], {"settle": 4}) == 4 + 12 + 30
    with pytest.raises(InputError, match="--preroll: expected a non-negative number of frames, got -1"):
        plan_items(["a"], {"m": 100}, 1, frames_per_clip=30, preroll=-1)
    rng = np.random.default_rng(0)
    motion = Motion(poses=rng.normal(0, 0.3, (100, 24, 3)).astype(np.float32),
                    trans=np.cumsum(np.full((100, 3), 0.01, np.float32), axis=0), fps=30.0, name="m")
    m = item_motion(motion, items[1], np.zeros(10, np.float32), settle_frames=4)
    # The settle blend into source frame 18, then frames 18..59: the pre-roll and the clip, in the motion's own poses.
    assert m.n_frames == 4 + 12 + 30 and m.n_settle == 4
    np.testing.assert_array_equal(m.poses[4:], motion.poses[18:60])
    np.testing.assert_array_equal(m.trans[:5], np.repeat(motion.trans[18:19], 5, axis=0))

    class Echo:  # a deformer whose positions are the root translation: where the frames come from
        report = {"checks": {}}

        def deform(self, garment, body, motion):
            return np.repeat(motion.trans[:, None], 2, axis=1)

    from tests.meshes import tiny_body
    r = simulate_item(None, tiny_body(), m, Echo(), preroll=items[1].preroll)
    assert r["n_settle"] == 4 + 12  # the settle blend and the pre-roll: neither is the clip's data
    np.testing.assert_array_equal(r["positions"][r["n_settle"]:, 0], motion.trans[30:60])


def test_items_that_would_share_a_name_are_refused():
    """Garment a__b on motion c and garment a on motion b__c were both named a__b__c__c00__b00: simulated into one
    sequence file, one item lost, the manifest's train item pointing at the other garment's cloth."""
    with pytest.raises(InputError, match=r"items of garment 'a__b' on motion 'c' and of garment 'a' on motion 'b__c' "
                                         r"would both be named 'a__b__c__c00__b00' \(one sequence file\): rename a "
                                         r"garment or motion file so that no name holds '__'"):
        plan_items(["a", "a__b"], {"c": 10, "b__c": 10}, 1, held_out=False)
    with pytest.raises(InputError, match="names that differ in case only"):
        plan_items(["dress", "Dress"], {"walk": 10}, 1, held_out=False)
    items, _ = plan_items(["a", "a__b"], {"c": 10, "d": 10}, 1, held_out=False)  # '__' alone is no clash
    assert len({it.id for it in items}) == len(items) == 4
