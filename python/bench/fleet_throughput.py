"""Fleet throughput: fit_many and diagnose_many on a Dask LocalCluster against the serial loop.

Simulates a fleet of drives (``--drives`` logs of ``--seeks`` random seeks each, written to a
temporary folder), then times, best of ``--repeat``:

- the serial loop: ``biasctl.fit(biasctl.read_log(p), model)`` for every path (the library's
  default pool: one worker per core), and the same with ``threads=1``;
- ``fit_many(paths, model, client=...)`` on a ``LocalCluster(n_workers=2, threads_per_worker=1,
  processes=False)`` (``--processes`` for worker processes), in batches of ``--batch``;
- ``fit_many(paths, model)`` on the local thread pool;
- ``diagnose_many`` (verified: the screens, the pool, and every screened drive refitted with the
  pooled suggestion) on the cluster against the same work as a serial loop (each drive screened,
  then refitted, on the library's default pool), on ``--diagnose-drives`` drives of
  ``--diagnose-seeks`` seeks (the first drives of the fit fleet when the sizes agree);
  ``--no-fit`` times only the diagnosis.

Prints drives per second and rows per second for each, the ratios to the serial loop, the
screens' and the refits' shares of the loop (wall and CPU time per drive), the load average
before and after, and the peak resident memory of this process after each phase (the threaded
cluster's workers live in it).

    python python/bench/fleet_throughput.py [--drives 40] [--seeks 6000] [--model poly2,direction,dahl:4]
    python python/bench/fleet_throughput.py --no-fit --diagnose-drives 2 --diagnose-seeks 1000000
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import tempfile
import time
from pathlib import Path

import biasctl
from biasctl import _biasctl as _ext
from biasctl import fleet


def _best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def _peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _simulate(folder: str, drives: int, seeks: int, prefix: str) -> list[str]:
    paths = []
    for k in range(drives):
        p = Path(folder) / f"{prefix}{k:04}.csv"
        biasctl.simulate("random", n=seeks, seed=k + 1).to_csv(p)
        paths.append(str(p))
    return paths


def _fit(paths: list[str], a, client) -> None:
    """fit_many on the cluster and on the thread pool against the serial loop."""
    rows = sum(len(biasctl.read_log(p)) for p in paths)
    print(f"fit: {len(paths)} drives x {a.seeks} seeks ({rows:,} rows), batch {a.batch}")
    ref = fleet.fit_many(paths, a.model)  # warm up, and the reference table

    def loop(**kw):
        return [biasctl.fit(biasctl.read_log(p), a.model, **kw) for p in paths]

    t_loop = _best(loop, a.repeat)
    t_loop1 = _best(lambda: loop(threads=1), a.repeat)
    got = fleet.fit_many(paths, a.model, client=client, batch=a.batch)
    assert got.equals(ref), "the cluster's table differs from the local one"
    t_dask = _best(lambda: fleet.fit_many(paths, a.model, client=client, batch=a.batch),
                   a.repeat)
    t_pool = _best(lambda: fleet.fit_many(paths, a.model), a.repeat)

    def line(label: str, t: float) -> None:
        print(f"{label:<44} {t:7.2f} s  {len(paths) / t:7.1f} drives/s  "
              f"{rows / t / 1e6:6.2f} M rows/s  rate x{t_loop / t:.2f} of the loop")

    line("  serial loop (library pool, 2 workers)", t_loop)
    line("  serial loop, threads=1", t_loop1)
    line(f"  fit_many, LocalCluster 2 workers{' (processes)' if a.processes else ''}", t_dask)
    line("  fit_many, local thread pool", t_pool)
    print(f"  peak RSS {_peak_mib():.0f} MiB")


def _diagnose(paths: list[str], model: str, client, batch: int) -> None:
    """diagnose_many on the cluster against the same work in a serial loop: each drive
    screened, the screens pooled, each screened drive refitted with the pooled suggestion's
    candidates (the library's default pool inside each drive)."""
    rows = sum(len(biasctl.read_log(p)) for p in paths)
    t0, c0 = time.perf_counter(), time.process_time()
    screens = [_ext.screen_drive(p, model, path=p) for p in paths]
    t_screens, c_screens = time.perf_counter() - t0, time.process_time() - c0
    pooled = _ext.pool_screens(screens)
    terms = json.loads(pooled)["verification"]["candidates"]
    t1, c1 = time.perf_counter(), time.process_time()
    refits = [r for p in paths for r in _ext.verify_drive(p, model, terms, path=p)] if terms else []
    t_refits, c_refits = time.perf_counter() - t1, time.process_time() - c1
    loop = fleet.FleetDiagnosis(_ext.pool_screens(screens, refits=refits or None))
    t_loop = time.perf_counter() - t0
    peak_loop = _peak_mib()
    t2 = time.perf_counter()
    d = fleet.diagnose_many(paths, model, client=client, batch=batch)
    t_dask = time.perf_counter() - t2
    assert d.to_dict() == loop.to_dict(), "the cluster's diagnosis differs from the loop's"
    v = d.verification
    print(f"diagnose ({len(paths)} drives, {rows:,} rows, batch {batch}): candidates {terms}; "
          f"{v['reason']} {v['term']} gain {v['gain']} z {v['z']}")
    print(f"  serial loop (library pool, 2 workers)      {t_loop:7.2f} s  "
          f"{len(paths) / t_loop:7.2f} drives/s  {rows / t_loop / 1e6:6.3f} M rows/s "
          f"(screens {t_screens:.2f} s, refits of {len(terms)} terms {t_refits:.2f} s)")
    n = len(paths)
    print(f"  CPU per drive in the loop: screen {c_screens / n:.2f} s, refits {c_refits / n:.2f} s "
          f"(this process's CPU time: the threads of both cores)")
    print(f"  diagnose_many, LocalCluster 2 workers      {t_dask:7.2f} s  "
          f"{len(paths) / t_dask:7.2f} drives/s  {rows / t_dask / 1e6:6.3f} M rows/s  "
          f"rate x{t_loop / t_dask:.2f} of the loop")
    print(f"  peak RSS after the loop {peak_loop:.0f} MiB, after the cluster {_peak_mib():.0f} MiB")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drives", type=int, default=40)
    ap.add_argument("--seeks", type=int, default=6000)
    ap.add_argument("--model", default="poly2,direction,dahl:4")
    ap.add_argument("--batch", type=int, default=4)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--processes", action="store_true")
    ap.add_argument("--diagnose-drives", type=int, default=12)
    ap.add_argument("--diagnose-seeks", type=int, default=None,
                    help="seeks per diagnosed drive (default: --seeks)")
    ap.add_argument("--diagnose-batch", type=int, default=2)
    ap.add_argument("--no-fit", action="store_true", help="time only the diagnosis")
    a = ap.parse_args()
    from distributed import Client, LocalCluster

    load0 = os.getloadavg()
    print(f"cores: {os.cpu_count()}; model {a.model}; load average at start "
          f"{load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}")
    with tempfile.TemporaryDirectory() as tmp:
        paths = [] if a.no_fit else _simulate(tmp, a.drives, a.seeks, "drive")
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=a.processes,
                               dashboard_address=None)
        client = Client(cluster)
        if paths:
            _fit(paths, a, client)
        seeks = a.diagnose_seeks or a.seeks
        if seeks == a.seeks and paths:
            dpaths = paths[: a.diagnose_drives]
        else:
            dpaths = _simulate(tmp, a.diagnose_drives, seeks, "diag")
        if dpaths:
            _diagnose(dpaths, a.model, client, a.diagnose_batch)
        client.close()
        cluster.close()
    load1 = os.getloadavg()
    print(f"peak RSS of this process {_peak_mib():.0f} MiB; load average at end "
          f"{load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")

if __name__ == "__main__":
    main()
