"""The long calls release the GIL: another Python thread runs while a fit runs, and two fits
in two threads give the same models as one after the other. The speed-up is measured and
reported (not asserted: CI machines are shared)."""

from __future__ import annotations

import threading
import time

import numpy as np

import biasctl


def _log(rows: int, seed: int) -> biasctl.Log:
    rng = np.random.default_rng(seed)
    t = np.arange(rows, dtype=np.float64) * 1e-3
    track = np.cumsum(rng.normal(0.0, 3.0, rows)) % 4000.0
    d = np.sign(np.diff(track, prepend=track[0]))
    bias = 50 + 0.01 * track + 6.0 * d + rng.normal(0, 0.5, rows)
    return biasctl.Log.from_arrays(t, track, bias)


MODEL = "poly2,direction,dahl:4"


def test_python_runs_while_a_fit_runs():
    log = _log(200_000, 1)
    window = {}

    def work():
        window["start"] = time.perf_counter()
        biasctl.fit(log, MODEL, threads=1)
        window["end"] = time.perf_counter()

    th = threading.Thread(target=work)
    ticks = []
    th.start()
    while th.is_alive():
        ticks.append(time.perf_counter())
    th.join()
    a, b = window["start"], window["end"]
    lo, hi = a + 0.25 * (b - a), a + 0.75 * (b - a)
    inside = sum(lo < t < hi for t in ticks)
    # Holding the GIL, the fit would leave this loop no turn in the middle of its run.
    assert inside > 100, (inside, b - a)


def test_two_threads_fit_as_one_after_the_other(record_property):
    """One library worker per fit, so that each Python thread keeps one core busy."""
    logs = [_log(300_000, 1), _log(300_000, 2)]
    t0 = time.perf_counter()
    seq = [biasctl.fit(log, MODEL, threads=1) for log in logs]
    t_seq = time.perf_counter() - t0
    assert seq[0].to_json() == biasctl.fit(logs[0], MODEL).to_json()  # same for any pool
    out = [None, None]

    def work(i):
        out[i] = biasctl.fit(logs[i], MODEL, threads=1)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(2)]
    t0 = time.perf_counter()
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    t_par = time.perf_counter() - t0
    assert [m.to_json() for m in out] == [m.to_json() for m in seq]
    record_property("two_thread_ratio", round(t_par / t_seq, 3))
    print(f"\ntwo fits: one after the other {t_seq:.2f} s, two threads {t_par:.2f} s, "
          f"ratio {t_par / t_seq:.2f}")


def test_other_long_calls_release_the_gil(data):
    """predict, score and diagnose let another thread run too (same check, shorter)."""
    train = biasctl.read_log(data / "train.csv")
    test = biasctl.read_log(data / "test.csv")
    m = biasctl.fit(train, "poly2,direction")
    calls = (
        lambda: m.diagnose(test, threads=1),
        lambda: biasctl.ladder(train, test, "poly2,direction,dahl:4", threads=1),
        lambda: biasctl.discover(train, test=test, max_steps=1, threads=1),
    )
    for call in calls:
        window = {}

        def work():
            window["start"] = time.perf_counter()
            call()
            window["end"] = time.perf_counter()

        th = threading.Thread(target=work)
        ticks = []
        th.start()
        while th.is_alive():
            ticks.append(time.perf_counter())
        th.join()
        a, b = window["start"], window["end"]
        lo, hi = a + 0.25 * (b - a), a + 0.75 * (b - a)
        # Holding the GIL, the call would leave this loop no turn in the middle of its run.
        assert sum(lo < t < hi for t in ticks) > 10, b - a
