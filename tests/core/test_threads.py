"""core.threads: the network's CPU thread count chosen from the batches' own times (a fake clock here)."""

import numpy as np
import pytest
import torch

from core.threads import GIVE_UP_RATIO, HOLD_BATCHES, TRIAL_BATCHES, WARMUP_BATCHES, ThreadTuner, thread_counts
from tests.core.model_fixtures import TINY_CONFIG, perturbed_model, sequence, tube
from tests.meshes import tiny_body


def test_thread_counts_halve_down_to_one():
    assert thread_counts(16) == [16, 8, 4, 2, 1]
    assert thread_counts(6) == [6, 3, 1]
    assert thread_counts(1) == [1] and thread_counts(0) == [1]


class _Machine:
    """A fake CPU: a batch of `frames` takes cost(threads) seconds a frame; set_threads and clock for the tuner."""

    def __init__(self, cost):
        self.cost, self.threads, self.now, self.set_calls = cost, None, 0.0, []

    def set_threads(self, n):
        self.threads = n
        self.set_calls.append(n)

    def clock(self):
        return self.now

    def run(self, tuner, batches, frames=2):
        for _ in range(batches):
            tuner.before()
            self.now += frames * self.cost(self.threads)
            tuner.after(frames)


def _tuner(machine, most):
    return ThreadTuner(most, set_threads=machine.set_threads, clock=machine.clock)


def _run_until(m, t, threads, most_batches):
    """Batches run until the tuner has chosen `threads` (at most `most_batches`); how many ran."""
    for n in range(1, most_batches + 1):
        m.run(t, 1)
        if t.chosen == threads and not t._trials:
            return n
    raise AssertionError(f"still {t.chosen} threads after {most_batches} batches")


def test_the_tuner_keeps_the_fastest_count_and_follows_a_change():
    # An idle 4-core machine: 4 threads fastest. The round tries 4, then its neighbour 2 (dropped after one timed
    # batch: more than GIVE_UP_RATIO slower), and keeps 4; 1 thread is not tried.
    idle = {4: 1.0, 2: 2.5, 1: 4.0}
    m = _Machine(lambda n: idle[n])
    t = _tuner(m, 4)
    assert t.active and m.threads == 4
    first = WARMUP_BATCHES + TRIAL_BATCHES + 1 + 1
    m.run(t, first)
    assert t.chosen == 4 and t.rounds == 1 and m.threads == 4
    assert t.frames[2] == 4 and t.frames[1] == 0  # a settling and a timed batch of 2 frames
    # Another job takes three cores: a team of 4 waits for them, one thread runs on. Later rounds step down to 1.
    busy = {4: 20.0, 2: 6.0, 1: 1.2}
    m.cost = lambda n: busy[n]
    ran = _run_until(m, t, 1, 8 * HOLD_BATCHES)
    assert m.threads == 1 and t.rounds >= 3
    # It ends: back up to 4.
    m.cost = lambda n: idle[n]
    ran += _run_until(m, t, 4, 16 * HOLD_BATCHES)
    t.close()
    assert m.set_calls[-1] == t.start  # torch's own count restored
    r = t.report()
    assert r["most"] == 4 and r["chosen"] == 4 and sum(r["frames_by_threads"].values()) == 2 * (first + ran)


def test_on_many_idle_cores_the_trials_cost_little():
    """16 cores, idle: the rounds try 16's neighbour only; over a 137-batch bake (273 frames) under 7 % of the
    frames run on another count (trying every count each round: 18 %)."""
    cost = {16: 1.0, 8: 1.2, 4: 1.7, 2: 2.8, 1: 5.0}
    m = _Machine(lambda n: cost[n])
    t = _tuner(m, 16)
    m.run(t, 137)
    assert t.chosen == 16 and t.frames[16] / sum(t.frames.values()) > 0.93
    assert t.frames[4] == t.frames[2] == t.frames[1] == 0


def test_a_close_count_does_not_replace_the_chosen_one_and_the_hold_grows():
    # 2 threads 5 % faster than 4 (within the noise of a batch's time): 4 stays, and rounds come less often.
    m = _Machine(lambda n: {4: 1.0, 2: 0.95, 1: 3.0}[n])
    t = _tuner(m, 4)
    m.run(t, 2000)
    assert t.chosen == 4
    assert t.rounds < 2000 / HOLD_BATCHES / 2  # the hold doubled while the choice held
    assert GIVE_UP_RATIO > 1


def test_one_thread_is_no_tuning():
    m = _Machine(lambda n: 1.0)
    t = _tuner(m, 1)
    m.run(t, 50)
    assert not t.active and t.chosen == 1 and m.set_calls == [1]
    assert t.report()["frames_by_threads"] == {"1": 100}


def test_the_models_frames_do_not_depend_on_the_tuner():
    """Tuning only changes how many threads compute the batches: the frames agree with torch's count throughout
    (to float rounding; the same bits on the machines tried), the report says what ran, and torch's count is
    restored."""
    from core.garment import Garment
    from core.model_deform import ModelDeformer
    from core.motion import Motion

    body = tiny_body()
    model = perturbed_model(TINY_CONFIG, scale=0.3, seed=2)
    v, f = tube(12, 6)
    garment = Garment(v, f)
    poses, trans, _ = sequence(body, v, f, 40, 0, None)
    motion = Motion(poses=poses, trans=trans, fps=30.0)
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        tuned = ModelDeformer(model, batch_frames=1, contact_guard=False)
        out = tuned.deform(garment, body, motion)
        assert torch.get_num_threads() == 2
        fixed = ModelDeformer(model, batch_frames=1, contact_guard=False)
        fixed.tune_threads = False
        np.testing.assert_allclose(out, fixed.deform(garment, body, motion), atol=1e-6)
    finally:
        torch.set_num_threads(before)
    r = tuned.report["cpu_threads"]
    assert r["most"] == 2 and r["rounds"] >= 1 and sum(r["frames_by_threads"].values()) == 40
    assert "cpu_threads" not in fixed.report


@pytest.mark.parametrize("most", [2, 3])
def test_the_first_round_starts_after_the_warmup(most):
    m = _Machine(lambda n: 1.0)
    t = _tuner(m, most)
    m.run(t, WARMUP_BATCHES - 1)
    assert t.rounds == 0 and m.set_calls == [most]
    m.run(t, 1)  # the last of the warm-up: the round's trials start with the next batch
    assert t.rounds == 1 and not t._times
