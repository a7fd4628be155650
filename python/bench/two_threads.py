"""Two threads fitting two logs: the speed-up from releasing the GIL.

Fits the same model to two synthetic logs one after the other, then in two threads at once,
and prints both wall times and their ratio (below 0.7 means the two fits ran on two cores).
Measured twice: with one library worker per fit (`threads=1`: each Python thread keeps one
core busy), and with the library's default pool (one worker per core, which a single fit
already uses in part).

    python python/bench/two_threads.py [--rows 1000000] [--model poly2,direction,dahl:4] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import threading
import time

import numpy as np

import biasctl


def synthetic_log(rows: int, seed: int) -> biasctl.Log:
    """A dense random-seek log: position (tracks), a bias of position, direction and a
    Dahl-like memory, plus noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(rows, dtype=np.float64) * 1e-3
    track = np.cumsum(rng.normal(0.0, 3.0, rows)) % 4000.0
    direction = np.sign(np.diff(track, prepend=track[0]))
    bias = 50 + 0.01 * track - 2e-6 * track**2 + 6.0 * direction + rng.normal(0, 0.5, rows)
    return biasctl.Log.from_arrays(t, np.round(track, 3), np.round(bias, 4))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=1_000_000)
    ap.add_argument("--model", default="poly2,direction,dahl:4")
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    logs = [synthetic_log(a.rows, 1), synthetic_log(a.rows, 2)]
    print(f"cores: {os.cpu_count()}, rows per log: {a.rows}, model: {a.model}")
    for threads in (1, None):
        opts = {} if threads is None else {"threads": threads}
        biasctl.fit(logs[0], a.model, **opts)  # warm up (page in, allocator)
        seq, par = [], []
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            one = [biasctl.fit(log, a.model, **opts) for log in logs]
            seq.append(time.perf_counter() - t0)
            out: list = [None, None]

            def work(i: int) -> None:
                out[i] = biasctl.fit(logs[i], a.model, **opts)

            workers = [threading.Thread(target=work, args=(i,)) for i in range(2)]
            t0 = time.perf_counter()
            for th in workers:
                th.start()
            for th in workers:
                th.join()
            par.append(time.perf_counter() - t0)
            assert [m.to_json() for m in out] == [m.to_json() for m in one]
        s, p = min(seq), min(par)
        label = "threads=1 per fit" if threads else "default pool     "
        print(f"{label}: one after the other {s:.2f} s; two threads {p:.2f} s; ratio {p / s:.2f}")


if __name__ == "__main__":
    main()
