"""How many CPU threads the network's batches run on, chosen while they run.

torch runs each operation on a team of OpenMP threads that spin while they wait for one another. On a machine
whose cores another process holds (a second bake, a render, the farm's other jobs) a team of a thread per core
waits for a core at every one of the thousands of small operations a frame takes: the model's network on the
2-core Zen 4 took 34-260 ms a frame with 2 threads beside a busy process, 11 ms with one; on the idle machine
2 threads take 7.6 ms, one 10.5 ms. No count is right for both, and another process can start or stop during
a bake, so `ThreadTuner` times the batches themselves: from torch's count (the cores, or what OMP_NUM_THREADS or
`bake --workers` set), halving down to one, it tries the chosen count's neighbours (half and twice as many
threads), keeps the fastest, and tries again after a while, less often while the choice holds: a round costs two
batches on other counts where it changes nothing (trying every count each round cost an idle 16-core machine
13 %). The network's frames do not depend on the count (to float rounding; the
same bits with 1 and 2 threads on the Zen 4: `tests/core/test_threads.py`). `garment train --threads auto` times
its steps with it too (by their vertex-frames; a training step's bits do depend on the count, so it is opt-in
there: 327 against 151 ms a step beside a busy process, benchmarks/results/train_threads.md).
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from contextlib import contextmanager

import torch

#: Batches a deform runs on torch's count before its first round of trials: its first batches are slow with
#: first-use work (on the Zen 4, 2-3x a later batch), whatever the count.
WARMUP_BATCHES = 4
#: Timed batches per thread count in a round of trials (their median counts), after one untimed batch on a count
#: just switched to (the threads woken or parked take a batch to settle).
TRIAL_BATCHES = 3
#: Another count replaces the chosen one where its median is this much faster: batch times vary by 20 % from
#: batch to batch on an idle machine; a busy machine's difference is 3-20x.
SWITCH_MARGIN = 1.15
#: A count whose timed batch takes this many times the best count's median is dropped from the round at once: it
#: would not be chosen (SWITCH_MARGIN), and a team waiting for busy cores can be 20x slower, one thread on an idle
#: machine 1.4x (its trial batches were 5 % of an idle bake's time when each count ran all three).
GIVE_UP_RATIO = 1.3
#: Batches run on the chosen count before the next round of trials, doubled while the choice holds (up to
#: MAX_HOLD_BATCHES), back to this when it changes.
HOLD_BATCHES = 32
MAX_HOLD_BATCHES = 1024


@contextmanager
def torch_threads(n: int | None):
    """Within the block, torch's CPU threads `n` where given (not None or 0: `--threads N`); after it, the count
    torch had before."""
    before = torch.get_num_threads()
    if n:
        torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def thread_counts(most: int) -> list[int]:
    """The counts tried: `most`, then halving down to 1 (16 -> 16, 8, 4, 2, 1)."""
    counts = [max(1, most)]
    while counts[-1] > 1:
        counts.append(counts[-1] // 2)
    return counts


class ThreadTuner:
    """Chooses torch's intra-op thread count batch by batch (see the module docstring).

    Call `before()` ahead of each batch and `after(n_frames)` when its results are computed, and `close()` at
    the end (it restores the count torch had). `report()`: the counts tried, the frames run on each, the count
    chosen last. `set_threads` and `clock` are torch.set_num_threads and time.perf_counter, for tests.
    """

    def __init__(self, most: int | None = None, set_threads: Callable[[int], None] = torch.set_num_threads,
                 clock: Callable[[], float] = time.perf_counter):
        self.start = torch.get_num_threads()
        self.counts = thread_counts(self.start if most is None else most)
        self._set, self._clock = set_threads, clock
        self.chosen = self.counts[0]
        self.frames = {n: 0 for n in self.counts}
        self.rounds = 0
        self._hold = HOLD_BATCHES
        self._left = WARMUP_BATCHES  # untimed batches on the chosen count before the next round of trials
        self._settle = False  # the batch just run was the untimed one on a count switched to
        self._trials: list[int] = []  # counts still to try in this round
        self._times: dict[int, list[float]] = {}  # seconds per frame of this round's timed batches
        self._current = self.chosen
        self._t = 0.0
        self._set(self.chosen)

    @property
    def active(self) -> bool:
        return len(self.counts) > 1

    def before(self) -> None:
        if self.active:
            self._t = self._clock()

    def after(self, n_frames: int) -> None:
        self.frames[self._current] += n_frames
        if not self.active:
            return
        seconds = (self._clock() - self._t) / max(n_frames, 1)
        if self._settle:
            self._settle = False
            return
        if self._trials:  # in a round of trials: time the count being tried
            times = self._times.setdefault(self._current, [])
            times.append(seconds)
            best = min((statistics.median(t) for n, t in self._times.items() if n != self._current and t),
                       default=None)
            if len(times) >= TRIAL_BATCHES or (best is not None and seconds > GIVE_UP_RATIO * best):
                self._trials.pop(0)
                if self._trials:
                    self._use(self._trials[0])
                else:
                    self._decide()
            return
        self._left -= 1
        if self._left <= 0:  # the next round of trials, the chosen count first (its time now is the bar)
            self.rounds += 1
            self._times = {}
            i = self.counts.index(self.chosen)  # then its neighbours: half as many threads, then twice as many
            self._trials = [self.chosen] + [self.counts[j] for j in (i + 1, i - 1) if 0 <= j < len(self.counts)]
            self._use(self._trials[0])

    def _decide(self) -> None:
        median = {n: statistics.median(t) for n, t in self._times.items()}
        fastest = min(median, key=median.get)
        if self.chosen in median and median[fastest] * SWITCH_MARGIN > median[self.chosen]:
            fastest = self.chosen
        self._hold = min(2 * self._hold, MAX_HOLD_BATCHES) if fastest == self.chosen else HOLD_BATCHES
        self.chosen, self._left = fastest, self._hold
        self._use(fastest)

    def _use(self, n: int) -> None:
        if n != self._current:
            self._set(n)
            self._current, self._settle = n, True

    def close(self) -> None:
        self._set(self.start)

    def report(self) -> dict:
        return {"most": self.counts[0], "chosen": self.chosen, "rounds": self.rounds,
                "frames_by_threads": {str(n): f for n, f in self.frames.items() if f}}
