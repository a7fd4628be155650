"""Fleet throughput: fit_many and diagnose_many on a Dask LocalCluster against the serial loop.

Simulates a fleet of drives (``--drives`` logs of ``--seeks`` random seeks each, written to a
temporary folder), then times, best of ``--repeat``:

- the serial loop: ``biasctl.fit(biasctl.read_log(p), model)`` for every path (the library's
  default pool: one worker per core), and the same with ``threads=1``;
- ``fit_many(paths, model, client=...)`` on a ``LocalCluster(n_workers=2, threads_per_worker=1,
  processes=False)`` (``--processes`` for worker processes), in batches of ``--batch``;
- ``fit_many(paths, model)`` on the local thread pool;
- ``diagnose_many`` on the cluster against a serial loop of the per-drive screens.

Prints drives per second and rows per second for each, the ratios to the serial loop, the load
average before and after, and the peak resident memory of this process (the threaded cluster's
workers live in it).

    python python/bench/fleet_throughput.py [--drives 40] [--seeks 6000] [--model poly2,direction,dahl:4]
"""

from __future__ import annotations

import argparse
import os
import resource
import tempfile
import time
from pathlib import Path

import biasctl
import biasctl.fleet as fleet


def _best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drives", type=int, default=40)
    ap.add_argument("--seeks", type=int, default=6000)
    ap.add_argument("--model", default="poly2,direction,dahl:4")
    ap.add_argument("--batch", type=int, default=4)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--processes", action="store_true")
    ap.add_argument("--diagnose-drives", type=int, default=12)
    a = ap.parse_args()
    from distributed import Client, LocalCluster

    load0 = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        paths = []
        for k in range(a.drives):
            p = Path(tmp) / f"drive{k:04}.csv"
            biasctl.simulate("random", n=a.seeks, seed=k + 1).to_csv(p)
            paths.append(str(p))
        rows = sum(len(biasctl.read_log(p)) for p in paths)
        print(f"cores: {os.cpu_count()}; {a.drives} drives x {a.seeks} seeks ({rows:,} rows), "
              f"model {a.model}; load average at start {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}")
        ref = fleet.fit_many(paths, a.model)  # warm up, and the reference table

        def loop(**kw):
            return [biasctl.fit(biasctl.read_log(p), a.model, **kw) for p in paths]

        t_loop = _best(loop, a.repeat)
        t_loop1 = _best(lambda: loop(threads=1), a.repeat)
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=a.processes,
                               dashboard_address=None)
        client = Client(cluster)
        got = fleet.fit_many(paths, a.model, client=client, batch=a.batch)
        assert got.equals(ref), "the cluster's table differs from the local one"
        t_dask = _best(lambda: fleet.fit_many(paths, a.model, client=client, batch=a.batch),
                       a.repeat)
        t_pool = _best(lambda: fleet.fit_many(paths, a.model), a.repeat)

        def line(label: str, t: float) -> None:
            print(f"{label:<44} {t:7.2f} s  {a.drives / t:7.1f} drives/s  "
                  f"{rows / t / 1e6:6.2f} M rows/s  rate x{t_loop / t:.2f} of the loop")

        print("fit")
        line("  serial loop (library pool, 2 workers)", t_loop)
        line("  serial loop, threads=1", t_loop1)
        line(f"  fit_many, LocalCluster 2 workers{' (processes)' if a.processes else ''}", t_dask)
        line("  fit_many, local thread pool", t_pool)

        dpaths = paths[: a.diagnose_drives]

        def screens():
            return [biasctl._biasctl.screen_drive(p, a.model, path=p) for p in dpaths]

        if dpaths:
            t_dloop = _best(screens, 1)
            t_ddask = _best(
                lambda: fleet.diagnose_many(dpaths, a.model, client=client, batch=2), 1)
            print(f"diagnose ({len(dpaths)} drives)")
            print(f"  serial loop of drive screens               {t_dloop:7.2f} s  "
                  f"{len(dpaths) / t_dloop:7.2f} drives/s")
            print(f"  diagnose_many, LocalCluster 2 workers      {t_ddask:7.2f} s  "
                  f"{len(dpaths) / t_ddask:7.2f} drives/s  rate x{t_dloop / t_ddask:.2f} of "
                  f"the loop")
        client.close()
        cluster.close()
    load1 = os.getloadavg()
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS of this process {peak:.0f} MiB; load average at end "
          f"{load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")


if __name__ == "__main__":
    main()
