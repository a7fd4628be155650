#!/usr/bin/env python3
"""The peer harness: biasctl's hot paths against numba / numpy / polars / pandas
doing the same work, both sides in the same run, printed as the ratio table of README's
Benchmarks section. Run it through `benches/peers/run.sh` (it makes the venv and builds biasctl).

Every peer is first checked against biasctl's own output on a small input (the check says what
it compares); a failed check stops the run. Timings: biasctl from criterion (median of the
`--warm-up-time 1 --measurement-time 3` run, read from target/criterion) or, where the work is
a command, the median of 3 CLI runs; peers by the median of several repeats. On a shared machine
the clock is CPU time where it can be: criterion benches built with `bench_main!`
(benches/common/cputime.rs) measure the thread's CPU time when run.sh sets BIASCTL_BENCH_CPU=1,
and their peers are then timed by the process's CPU time (`time.process_time`: every thread
polars or BLAS starts counts); commands by their user + system CPU time (`getrusage` of the
children). A bench without `bench_main!` measures wall time, and its peer is timed by wall time
too. Each row says which clock it used; only the ratios mean something.
"""

import argparse
import json
import math
import os
import re
import resource
import subprocess
import sys
import time

os.environ.setdefault("POLARS_MAX_THREADS", "1")  # polars on 1 thread, as biasctl reads
# numpy's BLAS on 1 thread: its idle threads spin while they wait for work, and on a loaded
# machine that spinning counted in the CPU time as several times the solve itself.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numba  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import polars as pl  # noqa: E402

N = 1_000_000


def sh(*args, **kw):
    return subprocess.run(args, check=True, capture_output=True, text=True, **kw)


class Timing:
    """Median times (s) of repeated calls: wall clock and CPU (this process's CPU time, plus
    the CPU time of the commands it ran and waited for)."""

    def __init__(self, wall, cpu):
        self.wall, self.cpu = wall, cpu

    def on(self, clock):
        return self.cpu if clock == "cpu" else self.wall


def children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def median_of(f, repeats):
    """Median wall and CPU time of `repeats` calls of f (s), as criterion reports its median,
    and f's last result."""
    walls, cpus, out = [], [], None
    for _ in range(repeats):
        w, c, k = time.perf_counter(), time.process_time(), children_cpu()
        out = f()
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c + children_cpu() - k)
    return Timing(float(np.median(walls)), float(np.median(cpus))), out


def bench_clock(root, bench_id):
    """"cpu" if the criterion bench measured thread CPU time (built with `bench_main!` and run
    with BIASCTL_BENCH_CPU=1, as run.sh does), else "wall"."""
    name = bench_id.split("/")[0]
    with open(os.path.join(root, "benches", f"{name}.rs")) as f:
        uses_cpu = re.search(r"bench_main!\s*\(", f.read()) is not None
    return "cpu" if uses_cpu and os.environ.get("BIASCTL_BENCH_CPU", "0") != "0" else "wall"


def criterion_median(root, bench_id):
    """Median time (s) of one criterion benchmark, from its last run's estimates, and the
    clock it was measured with."""
    path = os.path.join(root, "target", "criterion", *bench_id.split("/"), "new", "estimates.json")
    with open(path) as f:
        return json.load(f)["median"]["point_estimate"] * 1e-9, bench_clock(root, bench_id)


def row(what, ours, peer_name, peer):
    """A table row: `ours` is (seconds, clock); the peer's Timing is read on the same clock."""
    t, clock = ours
    return (what, t, peer_name, peer.on(clock), clock)


def check(ok, what):
    if not ok:
        sys.exit(f"peer check FAILED: {what}")
    print(f"  check ok: {what}")


# ---------------------------------------------------------------- Dahl predictor (eq. 8-9)
TABLE = 256  # biasctl tabulates r^n for integer seek lengths below this


@numba.njit(cache=True)
def dahl_pow_table(r):
    ln_r = math.log(r)
    t = np.empty(TABLE)
    for n in range(TABLE):
        t[n] = math.exp(ln_r * n)
    return t


@numba.njit(cache=True)
def dahl_predict(xs, c0, c1, c2, fc, r, pow_table, out):
    """bias_k = c0 + c1 x + c2 x^2 + Fc G_k, G_k = s + (G_{k-1} - s) r^|dx| (eq. 8-9), the
    arithmetic of biasctl's DahlPredictor (integer |dx| < 256 from the table). Returns the sum."""
    ln_r = math.log(r)
    g = 0.0
    acc = 0.0
    prev = math.nan
    for i in range(xs.shape[0]):
        x = xs[i]
        dx = 0.0 if i == 0 else x - prev
        prev = x
        a = abs(dx)
        n = int(a)
        d = pow_table[n] if (n < TABLE and n == a) else math.exp(ln_r * a)
        if dx > 0.0:
            g = 1.0 + (g - 1.0) * d
        elif dx < 0.0:
            g = -1.0 + (g + 1.0) * d
        b = c0 + x * (c1 + x * c2) + fc * g
        out[i] = fc * g
        acc += b
    return acc


@numba.njit(cache=True)
def dahl_predict_affine(xs, c0, c1, c2, fc, r, pow_table, out):
    """The same predictions as `dahl_predict`, written as biasctl's DahlPredictor runs them:
    G <- G*d + sgn(dx)*(1 - d) with the sign taken without a branch (random seeks would
    mispredict half of the branches). Returns the sum."""
    ln_r = math.log(r)
    g = 0.0
    acc = 0.0
    prev = math.nan
    for i in range(xs.shape[0]):
        x = xs[i]
        dx = 0.0 if i == 0 else x - prev
        prev = x
        a = abs(dx)
        n = int(a)
        d = pow_table[n] if (n < TABLE and n == a) else math.exp(ln_r * a)
        s = np.float64(dx > 0.0) - np.float64(dx < 0.0)
        g = g * d + s * (1.0 - d)
        b = c0 + x * (c1 + x * c2) + fc * g
        out[i] = b
        acc += b
    return acc


def find_param(model, name):
    """The value of the parameter `name` anywhere in a model file."""
    stack = [model]
    while stack:
        v = stack.pop()
        if isinstance(v, dict):
            if v.get("name") == name and "value" in v:
                return float(v["value"])
            stack.extend(v.values())
        elif isinstance(v, list):
            stack.extend(v)
    raise KeyError(name)


def dahl(exe, work, root):
    print("Dahl predictor, 1M seeks")
    train, test = os.path.join(work, "dahl_train.csv"), os.path.join(work, "dahl_test.csv")
    model, pred = os.path.join(work, "dahl.json"), os.path.join(work, "dahl_pred.csv")
    sh(exe, "simulate", "--sequence", "random", "--n", "3000", "--seed", "3", "--out", train)
    sh(exe, "simulate", "--sequence", "random", "--n", "500", "--seed", "4", "--out", test)
    sh(exe, "fit", "--data", train, "--terms", "poly2,dahl", "--out", model)
    sh(exe, "predict", "--model", model, "--data", test, "--out", pred)
    with open(model) as f:
        m = json.load(f)
    fc, r = find_param(m, "dahl.Fc"), find_param(m, "dahl.r")
    p = pd.read_csv(pred, comment="#")
    xs = p["track"].to_numpy(dtype=float)
    out = np.empty_like(xs)
    dahl_predict(xs, 0.0, 0.0, 0.0, fc, r, dahl_pow_table(r), out)
    err = np.max(np.abs(out - p["dahl"].to_numpy()))
    # the CSV has 4 decimals and Fc, r are printed in the model file with their own rounding
    check(err < 2e-3 * max(1.0, abs(fc)), f"numba Fc*G equals biasctl predict's `dahl` column (max diff {err:.1e}, Fc {fc:.3f}, r {r:.5f})")
    out2 = np.empty_like(xs)
    dahl_predict_affine(xs, 0.0, 0.0, 0.0, fc, r, dahl_pow_table(r), out2)
    err2 = np.max(np.abs(out2 - out))
    check(err2 <= 1e-12 * max(1.0, abs(fc)), f"numba G*d + b form equals the eq. 8 form (max diff {err2:.1e})")
    rng = np.random.default_rng(1)
    xs = 1000.0 + rng.integers(0, 250, N).astype(float)  # the criterion bench's workload
    out = np.empty(N)
    table = dahl_pow_table(1.0 - 1.2 / 15.0)
    args = (xs, 5.0, 0.01, -1e-6, 15.0, 1.0 - 1.2 / 15.0, table, out)
    dahl_predict(*args)
    t_eq8, _ = median_of(lambda: dahl_predict(*args), 30)
    dahl_predict_affine(*args)
    t_aff, _ = median_of(lambda: dahl_predict_affine(*args), 30)
    eq8 = ("numba loop, eq. 8 as written (branch on the sign)", t_eq8)
    aff = ("numba loop, biasctl's branch-free G·d + b", t_aff)
    return [
        row("Dahl predictor, 1M seeks, `step` per seek (criterion `dahl/predictor_1M_seeks`)", criterion_median(root, "dahl/predictor_1M_seeks"), *eq8),
        row("the same, `step` per seek", criterion_median(root, "dahl/predictor_1M_seeks"), *aff),
        row("Dahl predictor, 1M seeks, `step_many` (criterion `dahl/step_many_1M_seeks`)", criterion_median(root, "dahl/step_many_1M_seeks"), *eq8),
        row("the same, `step_many`", criterion_median(root, "dahl/step_many_1M_seeks"), *aff),
    ]


# ---------------------------------------------------------------- handoff (eq. 14-16)
@numba.njit(cache=True)
def bounds_into(pe, pv, pu, w, zk, zce, zcv, zcu, e0, v0, du, delta, upper, lower, umin_out, lmax_out):
    """biasctl's bounds_into on four plain arrays: eq. 14 per sample, zero-gain samples, the
    backward running min/max of eq. 15."""
    n = pe.shape[0]
    for k in range(n):
        mid = pe[k] * e0 + pv[k] * v0 + pu[k] * du
        half = w[k] * delta
        upper[k] = mid + half
        lower[k] = mid - half
    for j in range(zk.shape[0]):
        c = zce[j] * e0 + zcv[j] * v0 + zcu[j] * du
        if c != c or abs(c) > delta:
            upper[zk[j]] = -np.inf
            lower[zk[j]] = np.inf
    umin, lmax = np.inf, -np.inf
    for k in range(n - 1, -1, -1):
        umin = min(umin, upper[k])
        lmax = max(lmax, lower[k])
        umin_out[k] = umin
        lmax_out[k] = lmax


@numba.njit(cache=True)
def bounds_repeat(reps, pe, pv, pu, w, zk, zce, zcv, zcu, e0, v0, du, delta, upper, lower, umin_out, lmax_out):
    """`reps` calls inside compiled code, so Python's call overhead is not timed. Each call is
    followed by the search for k* (the first k ≤ N − 1 with L*(k) ≤ U*(k)), as the criterion
    bench follows `bounds_into` with `Bounds::optimal`."""
    acc = 0.0
    n = pe.shape[0]
    for _ in range(reps):
        bounds_into(pe, pv, pu, w, zk, zce, zcv, zcu, e0, v0, du, delta, upper, lower, umin_out, lmax_out)
        for k in range(n):
            if lmax_out[k] <= umin_out[k]:
                acc += k + lmax_out[k] + umin_out[k]
                break
    return acc


def solve_numpy(pe, pv, pu, w, zk, zce, zcv, zcu, e0, v0, du, delta, hold, shift):
    """The same answers as HandoffTable::solve, vectorised: all bounds, reversed cumulative
    min/max, first index meeting each condition."""
    mid = pe * e0 + pv * v0 + pu * du
    half = w * delta
    upper, lower = mid + half, mid - half
    c = zce * e0 + zcv * v0 + zcu * du
    bad = np.isnan(c) | (np.abs(c) > delta)
    upper[zk[bad]], lower[zk[bad]] = -np.inf, np.inf
    um = np.fmin.accumulate(upper[::-1])[::-1]
    lm = np.fmax.accumulate(lower[::-1])[::-1]
    top = len(pe) - hold
    um, lm = um[: top + 1], lm[: top + 1]

    def first(ok):
        i = int(np.argmax(ok))
        return i if ok[i] else None

    k_opt = first(um - lm >= 0.0)
    interval = None if k_opt is None else (lm[k_opt], um[k_opt])
    return k_opt, interval, first(um - lm >= 2.0 * shift), first((lm <= -shift) & (um >= shift))


def read_bounds(path):
    b = pd.read_csv(path)
    return b["upper"].to_numpy(dtype=float), b["lower"].to_numpy(dtype=float), b


def handoff(exe, work, root):
    print("Handoff at horizon 64 (paper1997)")
    n, delta = 64, 0.5
    res = {}
    for step in (15.0, 5.0):
        path = os.path.join(work, f"bounds_{step:g}.csv")
        out = sh(exe, "settle", "--preset", "paper1997", "--horizon", str(n), "--step-um", str(step), "--bounds-out", path, "--json").stdout
        res[step] = (json.loads(out), *read_bounds(path))
    # The table's coefficients, recovered from the 15 µm run: w = (U - L)/2δ, pe = mid/e0.
    # Sample 0 has a_0 = 0 (no bound at k = 0: empty cells), the zero-gain sample.
    _, u15, l15, _ = res[15.0]
    e0 = -15.0
    zero = ~np.isfinite(u15)
    w = np.where(zero, np.inf, (u15 - l15) / (2 * delta))
    pe = np.where(zero, 0.0, 0.5 * (u15 + l15) / e0)
    pv, pu = np.zeros(n), np.zeros(n)  # v0 = 0 and u_prev = bias in these handoffs
    zk = np.flatnonzero(zero).astype(np.int64)
    zce, zcv, zcu = np.ones(len(zk)), np.zeros(len(zk)), np.zeros(len(zk))  # c_0 = e0
    bufs = [np.empty(n) for _ in range(4)]
    # Check on the other step length: same bounds, running bounds and answers as biasctl.
    j5, u5, l5, b5 = res[5.0]
    bounds_into(pe, pv, pu, w, zk, zce, zcv, zcu, -5.0, 0.0, 0.0, delta, *bufs)
    for got, col in zip(bufs, ["upper", "lower", "upper_min", "lower_max"]):
        want = b5[col].to_numpy(dtype=float)
        fin = np.isfinite(want)
        check(np.array_equal(fin, np.isfinite(got)) and np.allclose(got[fin], want[fin], rtol=1e-9, atol=1e-9), f"numba {col} equals `biasctl settle --step-um 5 --bounds-out`")
    shift = abs(j5["dz_dbias"]) * 8.0
    k, interval, k_rob, k_zero = solve_numpy(pe, pv, pu, w, zk, zce, zcv, zcu, -5.0, 0.0, 0.0, delta, 1, shift)
    check(k == j5["k_star"] and np.allclose(interval, j5["ff_interval"], rtol=1e-9), f"numpy solve: k* {k} and the optimal interval equal settle --json")
    check(k_rob == j5["worst_case"]["robust_k"] and k_zero == j5["worst_case"]["zero_ff_k"], f"numpy solve: robust k {k_rob}, zero-ff worst k {k_zero} equal settle --json")
    # Timing: the bench's handoff (e0 = -15 µm, v0 = 0, u_prev = bias, Δb = 8 counts).
    reps = 20_000
    args = (pe, pv, pu, w, zk, zce, zcv, zcu, -15.0, 0.0, 0.0, delta, *bufs)
    bounds_repeat(10, *args)
    t_b, _ = median_of(lambda: bounds_repeat(reps, *args), 30)
    t_b = Timing(t_b.wall / reps, t_b.cpu / reps)
    shift15 = abs(res[15.0][0]["dz_dbias"]) * 8.0
    solve = lambda: [solve_numpy(pe, pv, pu, w, zk, zce, zcv, zcu, -15.0, 0.0, 0.0, delta, 1, shift15) for _ in range(200)]
    t_s, _ = median_of(solve, 15)
    t_s = Timing(t_s.wall / 200, t_s.cpu / 200)
    return [
        row("handoff bounds, horizon 64 (`bounds_into`, then k* from the curves)", criterion_median(root, "handoff/bounds_into/64"), "numba, same arithmetic on four plain arrays, then the same search for k*", t_b),
        row("handoff solve, horizon 64", criterion_median(root, "handoff/solve/64"), "numpy vectorised", t_s),
    ]


# ---------------------------------------------------------------- reading a 1M-row log
def read(exe, work, root, log, cli):
    print("Reading a 1M-row log")
    out = sh(exe, "check", "--data", log).stdout
    first = out.splitlines()[0]  # "<file>: R rows, M measured"
    rows, measured = int(first.split(": ")[1].split()[0]), int(first.split(", ")[1].split()[0])
    pol = lambda: pl.read_csv(log, comment_prefix="#")
    pan = lambda: pd.read_csv(log, comment="#")
    t_pl, df = median_of(pol, 3)
    t_pd, dp = median_of(pan, 3)
    check(df.height == rows and df["bias"].null_count() == rows - measured, f"polars reads {rows} rows, {measured} measured, as `biasctl check`")
    check(len(dp) == rows and int(dp["bias"].notna().sum()) == measured, "pandas reads the same rows")
    mb = os.path.getsize(log) / 1e6
    return [
        row(f"reading a 1M-row, {mb:.0f} MB log (`check`, CLI)", (cli["check"].cpu, "cpu"), "polars `read_csv` (1 thread)", t_pl),
        row("reading the same log (criterion `read/check_summarise_1M_rows`)", criterion_median(root, "read/check_summarise_1M_rows"), "pandas `read_csv`", t_pd),
        row("the same criterion bench", criterion_median(root, "read/check_summarise_1M_rows"), "polars `read_csv` (1 thread)", t_pl),
    ]


# ---------------------------------------------------------------- fit
def peak_rss_mb(*args):
    """Peak resident memory (MB) of one run of a command, as GNU time reports it (`%M`). Not
    this process's own rusage of the child: a child forked from this Python (numpy, polars and
    their arrays loaded) starts with this process's pages resident and reports them."""
    r = subprocess.run(["/usr/bin/time", "-f", "%M", *args], check=True, capture_output=True, text=True)
    return int(r.stderr.strip().splitlines()[-1]) / 1024  # kB


def fit_memory(exe, work, log_1m):
    """`fit --model calibration`'s peak RSS on 300k and 1M rows of the same kind of log: bytes
    per row as the slope between the two (what each more row costs) and as the 1M-row peak over
    its rows (which also counts the fixed part: the binary, thread stacks, buffers)."""
    log_300k = os.path.join(work, "random_300k.csv")
    sh(exe, "simulate", "--sequence", "random", "--n", "300000", "--seed", "1", "--out", log_300k)
    out = os.path.join(work, "fit_mem.json")
    peak = {}
    for n, log in ((300_000, log_300k), (N, log_1m)):
        peak[n] = min(peak_rss_mb(exe, "fit", "--data", log, "--model", "calibration", "--out", out) for _ in range(3))
    slope = (peak[N] - peak[300_000]) * 1024 * 1024 / (N - 300_000)
    whole = peak[N] * 1024 * 1024 / N
    print(f"  fit --model calibration peak RSS (least of 3): {peak[300_000]:.1f} MB at 300k rows, {peak[N]:.1f} MB at 1M rows: slope {slope:.0f} B/row, peak/rows {whole:.0f} B/row")


def fit(exe, work, root, cli, t_read):
    print("Fit: normal equations")
    train, test = os.path.join(work, "pd_train.csv"), os.path.join(work, "pd_test.csv")
    model, pred = os.path.join(work, "pd.json"), os.path.join(work, "pd_pred.csv")
    sh(exe, "simulate", "--sequence", "random", "--n", "2000", "--seed", "5", "--out", train)
    sh(exe, "fit", "--data", train, "--terms", "poly2,direction", "--out", model)
    sh(exe, "predict", "--model", model, "--data", train, "--out", pred)
    p = pd.read_csv(pred, comment="#")
    x = p["track"].to_numpy(dtype=float)
    d = np.sign(np.diff(x, prepend=np.nan))
    d = pd.Series(d).replace(0.0, np.nan).ffill().fillna(0.0).to_numpy()  # last non-zero seek
    xs = (x - x.mean()) / x.std()
    design = np.column_stack([np.ones_like(x), xs, xs * xs, d])
    y = p["bias"].to_numpy(dtype=float)
    beta = np.linalg.solve(design.T @ design, design.T @ y)
    err = np.max(np.abs(design @ beta - p["predicted"].to_numpy()))
    check(err < 2e-3, f"numpy normal equations on [1, x, x², direction] reproduce `biasctl fit --terms poly2,direction` predictions (max diff {err:.1e})")
    rng = np.random.default_rng(2)
    a = rng.standard_normal((N, 30))
    y = a @ rng.standard_normal(30) + rng.standard_normal(N)
    t_np, _ = median_of(lambda: np.linalg.solve(a.T @ a, a.T @ y), 3)
    both = Timing(t_np.wall + t_read.wall, t_np.cpu + t_read.cpu)
    return [
        row("`fit --model calibration` (29 parameters), 1M rows, CLI", (cli["fit"].cpu, "cpu"), "polars `read_csv` of the log + numpy normal equations, 1M × 30 design", both),
        row("the same", (cli["fit"].cpu, "cpu"), "numpy normal equations alone, on a design handed to it", t_np),
        row("the same fit in-process (criterion `fit`)", criterion_median(root, "fit/calibration_1M_rows"), "numpy normal equations, 1M × 30 design", t_np),
    ]


# ---------------------------------------------------------------- writing the predict CSV
def write(exe, work, root, cli, pred_csv):
    print("Writing a 1M-row predict CSV")
    frame = pl.read_csv(pred_csv, comment_prefix="#")
    out = os.path.join(work, "polars_written.csv")
    t_pl, _ = median_of(lambda: frame.write_csv(out), 3)
    small = frame.head(1000)
    small.write_csv(out)
    again = pl.read_csv(out)
    same = all(np.allclose(again[c].to_numpy(), small[c].to_numpy(), equal_nan=True) for c in small.columns)
    check(same and again.columns == small.columns, "polars writes the same columns and values as `biasctl predict` (first 1000 rows read back)")
    mb = os.path.getsize(pred_csv) / 1e6
    # biasctl predict formats on a second thread: its wall time is compared with polars given
    # the same 2 threads too (a fresh process: the pool size is fixed at import).
    t_pl2 = polars_write_2_threads(pred_csv, out)
    return [
        row(f"`predict` 1M rows → {mb:.0f} MB CSV (CLI, CPU of both threads)", (cli["predict"].cpu, "cpu"), "polars `write_csv` of the same frame (1 thread)", t_pl),
        row("the same, wall clock (CLI: also reads the log and syncs the file to disk)", (cli["predict"].wall, "wall"), "polars `write_csv` (1 thread)", t_pl),
        row("the same, wall clock", (cli["predict"].wall, "wall"), "polars `write_csv` (2 threads)", t_pl2),
        row("replay + CSV into memory (criterion `predict/replay_and_write_1M_rows`, process CPU)", criterion_median(root, "predict/replay_and_write_1M_rows"), "polars `write_csv` of the same frame (1 thread)", t_pl),
    ]


def polars_write_2_threads(pred_csv, out):
    """Median wall and CPU time of polars `write_csv` of the predict frame with
    POLARS_MAX_THREADS=2, timed in a child Python (3 repeats)."""
    code = (
        "import json, sys, time, statistics as st, polars as pl\n"
        "f = pl.read_csv(sys.argv[1], comment_prefix='#')\n"
        "w, c = [], []\n"
        "for _ in range(3):\n"
        "    a, b = time.perf_counter(), time.process_time()\n"
        "    f.write_csv(sys.argv[2])\n"
        "    w.append(time.perf_counter() - a); c.append(time.process_time() - b)\n"
        "print(json.dumps([st.median(w), st.median(c)]))\n"
    )
    env = dict(os.environ, POLARS_MAX_THREADS="2")
    r = subprocess.run([sys.executable, "-c", code, pred_csv, out], check=True, capture_output=True, text=True, env=env)
    wall, cpu = json.loads(r.stdout)
    return Timing(wall, cpu)


def fmt_t(s):
    if s < 1e-6:
        return f"{s * 1e9:.1f} ns"
    if s < 1e-3:
        return f"{s * 1e6:.2f} µs"
    if s < 1:
        return f"{s * 1e3:.2f} ms"
    return f"{s:.2f} s"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--root", required=True)
    ap.add_argument("--exe", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--cli-repeats", type=int, default=3)
    ap.add_argument("--only", default="dahl,handoff,read,fit,write", help="comma-separated sections to run")
    a = ap.parse_args()
    only = set(a.only.split(","))
    os.makedirs(a.work, exist_ok=True)
    rows = []
    if "dahl" in only:
        rows += dahl(a.exe, a.work, a.root)
    if "handoff" in only:
        rows += handoff(a.exe, a.work, a.root)
    if only & {"read", "fit", "write"}:
        log = os.path.join(a.work, "random_1M.csv")
        cal, model, pred = (os.path.join(a.work, f) for f in ("cal.csv", "cal.json", "pred_1M.csv"))
        sh(a.exe, "simulate", "--sequence", "random", "--n", str(N), "--seed", "1", "--out", log)
        sh(a.exe, "simulate", "--sequence", "calibration", "--seed", "1", "--out", cal)
        sh(a.exe, "fit", "--data", cal, "--model", "calibration", "--out", model)
        cli = {
            "check": median_of(lambda: sh(a.exe, "check", "--data", log), a.cli_repeats)[0],
            "fit": median_of(lambda: sh(a.exe, "fit", "--data", log, "--model", "calibration", "--out", os.path.join(a.work, "fit_1M.json")), a.cli_repeats)[0],
            "predict": median_of(lambda: sh(a.exe, "predict", "--model", model, "--data", log, "--out", pred), a.cli_repeats)[0],
        }
        if "read" in only:
            rows += read(a.exe, a.work, a.root, log, cli)
        if "fit" in only:
            t_read, _ = median_of(lambda: pl.read_csv(log, comment_prefix="#"), 3)
            rows += fit(a.exe, a.work, a.root, cli, t_read)
            if os.path.exists("/usr/bin/time"):
                fit_memory(a.exe, a.work, log)
        if "write" in only:
            rows += write(a.exe, a.work, a.root, cli, pred)
    print()
    print(f"numba {numba.__version__}, numpy {np.__version__}, polars {pl.__version__}, pandas {pd.__version__}; {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f} {os.getloadavg()[1]:.1f} {os.getloadavg()[2]:.1f}; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print()
    print("| work | biasctl | peer, same run | peer | clock | biasctl / peer |")
    print("|---|---|---|---|---|---|")
    for what, ours, peer_name, peer, clock in rows:
        print(f"| {what} | {fmt_t(ours)} | {peer_name} | {fmt_t(peer)} | {clock} | **{ours / peer:.2f}** |")


if __name__ == "__main__":
    main()
