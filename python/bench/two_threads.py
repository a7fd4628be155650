"""Two threads fitting two logs: the speed-up from releasing the GIL.

Fits the same model to two synthetic logs one after the other (serial), then in two Python
threads at once, and reports the ratio two-thread wall time / serial wall time (below 0.7: the
two fits ran on two cores; 1.0: no overlap). Each fit uses one library worker (`threads=1`), so
each Python thread keeps one core busy and the ratio measures the GIL release alone; the
library's default pool (one worker per core) is reported too.

A shared machine gives a ratio only as good as the second core it has free, so the script
measures that alongside, in the same minutes:

- the load average before and after (``os.getloadavg``) and the core count;
- the process CPU time of each run (serial and two-thread runs do the same work: equal CPU
  time, so a two-thread wall time near the serial one with the same CPU is a busy machine, not
  a held lock);
- a control that shares nothing: two pure-Python processes each spinning a fixed loop, one
  after the other and then at once. Its ratio is what this machine gives two independent
  workers at the moment; the fits' ratio is read against it.

Serial and two-thread runs alternate (serial, two threads, control, ...) ``--repeat`` times,
so drifting load hits both alike; medians and minima are reported.

    python python/bench/two_threads.py [--rows 1000000] [--model poly2,direction,dahl:4] [--repeat 5]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import statistics
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


def _spin(turns: int) -> None:
    x = 0
    for i in range(turns):
        x += i & 7


def _timed(fn) -> tuple[float, float]:
    """(wall, process CPU) seconds of one call."""
    w0, c0 = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - w0, time.process_time() - c0


def _in_threads(calls) -> None:
    workers = [threading.Thread(target=c) for c in calls]
    for th in workers:
        th.start()
    for th in workers:
        th.join()


def _control(turns: int) -> tuple[float, float]:
    """Wall seconds of two spinning processes one after the other, then at once."""
    ctx = mp.get_context("fork")

    def run(together: bool) -> float:
        procs = [ctx.Process(target=_spin, args=(turns,)) for _ in range(2)]
        t0 = time.perf_counter()
        if together:
            for p in procs:
                p.start()
            for p in procs:
                p.join()
        else:
            for p in procs:
                p.start()
                p.join()
        return time.perf_counter() - t0

    return run(False), run(True)


def _report(label: str, serial: list, two: list) -> float:
    s_wall = [w for w, _ in serial]
    p_wall = [w for w, _ in two]
    ratio = statistics.median(p_wall) / statistics.median(s_wall)
    print(
        f"{label}: serial {statistics.median(s_wall):.2f} s (min {min(s_wall):.2f}, CPU "
        f"{statistics.median(c for _, c in serial):.2f} s); two threads "
        f"{statistics.median(p_wall):.2f} s (min {min(p_wall):.2f}, CPU "
        f"{statistics.median(c for _, c in two):.2f} s); ratio of medians {ratio:.2f}, "
        f"of minima {min(p_wall) / min(s_wall):.2f}"
    )
    return ratio


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=1_000_000)
    ap.add_argument("--model", default="poly2,direction,dahl:4")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--spin", type=int, default=0,
                    help="loop turns of the control (default: about one fit's wall time)")
    a = ap.parse_args()
    logs = [synthetic_log(a.rows, 1), synthetic_log(a.rows, 2)]
    load0 = os.getloadavg()
    print(f"cores: {os.cpu_count()}, rows per log: {a.rows:,}, model: {a.model}, "
          f"load average (1, 5, 15 min) at start: {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}")
    want = [biasctl.fit(log, a.model, threads=1).to_json() for log in logs]  # warm up
    spin = a.spin
    if spin == 0:
        one_fit, _ = _timed(lambda: biasctl.fit(logs[0], a.model, threads=1))
        w, _ = _timed(lambda: _spin(2_000_000))
        spin = max(1, int(2_000_000 * one_fit / w))
    runs = {"one": ([], []), "pool": ([], []), "control": ([], [])}
    for _ in range(a.repeat):
        for key, opts in (("one", {"threads": 1}), ("pool", {})):
            out: list = [None, None]

            def work(i: int, opts=opts, out=out) -> None:
                out[i] = biasctl.fit(logs[i], a.model, **opts)

            runs[key][0].append(_timed(lambda: [work(0), work(1)]))
            assert [m.to_json() for m in out] == want
            out[:] = [None, None]
            runs[key][1].append(_timed(lambda: _in_threads([lambda: work(0), lambda: work(1)])))
            assert [m.to_json() for m in out] == want  # the same models either way
        s, p = _control(spin)
        runs["control"][0].append((s, 0.0))
        runs["control"][1].append((p, 0.0))
    load1 = os.getloadavg()
    fits = _report("fits, threads=1 per fit ", *runs["one"])
    _report("fits, default pool      ", *runs["pool"])
    c_s = [w for w, _ in runs["control"][0]]
    c_p = [w for w, _ in runs["control"][1]]
    control = statistics.median(c_p) / statistics.median(c_s)
    print(f"control, two processes  : serial {statistics.median(c_s):.2f} s; together "
          f"{statistics.median(c_p):.2f} s; ratio {control:.2f}")
    print(f"load average at end: {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")
    print(f"RESULT ratio {fits:.2f} (two threads / serial, threads=1); the machine's own "
          f"two-process ratio at the time {control:.2f}")


if __name__ == "__main__":
    main()
