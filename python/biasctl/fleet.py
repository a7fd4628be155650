"""A fleet of drives: one model fitted to every drive's log, the drives that deviate.

``fit_many`` fits one model to many logs, on a local thread pool (the GIL released) or, given
a ``dask.distributed.Client``, on a Dask cluster in batches; the table is the same either way,
and the same as a loop of :func:`biasctl.fit` calls (each row is made by the library function
``biasctl fleet fit`` runs). ``outliers`` names the drives whose parameters stand out (the
library's robust z, as ``biasctl fleet outliers``). ``diagnose_many`` screens every drive's
residual as ``diagnose`` does and pools the drives' statistics, naming an effect too weak for
any one drive (as ``biasctl fleet diagnose``). Dask is needed only with a client:
``pip install './python[fleet]'``.
"""

from __future__ import annotations

import json as _json
import os as _os
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Sequence

from . import BiasctlError, FitError, Log, _biasctl as _ext, _pandas, _terms

__all__ = ["FleetDiagnosis", "diagnose_many", "fit_many", "outliers", "score_many", "to_csv"]

_READ_OPTIONS = ("time_col", "track_col", "bias_col", "bias_unit", "track_unit", "delimiter")
_FIT_OPTIONS = ("deadband", "velocity_col", "rank_tolerance", "grid", "refine")
_COLUMNS_HEAD = ["source", "rows", "terms"]
_COLUMNS_TAIL = ["std", "warnings", "error"]
_OUTLIER_COLUMNS = ["source", "parameter", "value", "median", "sigma", "z", "rule"]


def _items(logs: Sequence[Any]) -> list[tuple[str, Any]]:
    """(source, path or Log) for every log: a path as given, a Log by its file name (or its
    place in the list when it was made from arrays)."""
    if isinstance(logs, (str, bytes, _os.PathLike, Log)):
        raise BiasctlError("logs must be a list of paths or of biasctl.Log, not one log")
    out = []
    for i, item in enumerate(logs):
        if isinstance(item, Log):
            name = item.file
            out.append((name if name and not name.startswith("<") else f"<log {i}>", item))
        else:
            try:
                path = _os.fspath(item)
            except TypeError:
                raise BiasctlError(
                    f"logs[{i}] must be a path or a biasctl.Log, got {type(item).__name__}"
                ) from None
            if isinstance(path, bytes):
                path = _os.fsdecode(path)
            out.append((path, path))
    return out


def _fit_one(item: tuple[str, Any], model: str, options: dict, threads: int | None) -> tuple:
    """(the drive's row, its model file's text or None)."""
    source, what = item
    if isinstance(what, Log):
        return _ext.fit_drive(source, model, log=what._inner, threads=threads, keep_model=True,
                              **options)
    return _ext.fit_drive(source, model, path=what, threads=threads, keep_model=True, **options)


def _fit_batch(items: list, model: str, options: dict) -> list[tuple]:
    """One Dask task: a batch of drives, one after the other, each fit on one library worker
    (Dask runs as many tasks at once as the workers have threads)."""
    return [_fit_one(item, model, options, 1) for item in items]


def _frame(rows: list[tuple]):
    """The fleet table of the library's rows: source, rows, terms, each parameter and its
    standard error (``<name>.se``), std, warnings, error."""
    pd = _pandas()
    names: list[str] = []
    for r in rows:
        for name, _, _ in r[3]:
            if name not in names:
                names.append(name)
    data: dict[str, list] = {c: [] for c in _COLUMNS_HEAD}
    for n in names:
        data[n] = []
        data[n + ".se"] = []
    for c in _COLUMNS_TAIL:
        data[c] = []
    nan = float("nan")
    for source, used, terms, params, std, warnings, error in rows:
        data["source"].append(source)
        data["rows"].append(used)
        data["terms"].append(terms)
        have = {name: (value, se) for name, value, se in params}
        for n in names:
            value, se = have.get(n, (nan, None))
            data[n].append(value)
            data[n + ".se"].append(nan if se is None else se)
        data["std"].append(nan if std is None else std)
        data["warnings"].append("; ".join(warnings))
        data["error"].append(error)
    df = pd.DataFrame(data)
    df["rows"] = df["rows"].astype("Int64")
    df["error"] = df["error"].astype(object).where(df["error"].notna(), None)
    return df


def fit_many(
    logs: Sequence[Any],
    model: Any,
    *,
    client: Any = None,
    batch: int = 64,
    workers: int | None = None,
    **options: Any,
):
    """Fits ``model`` to every log of ``logs`` (paths, read where the fit runs, or
    :class:`biasctl.Log`); one row per log, in the order given: ``source``, ``rows`` (measured
    rows used), ``terms``, one column per parameter (``poly2.c1``) and its standard error
    (``poly2.c1.se``), ``std`` (residual std), ``warnings``, ``error`` (why a log could not be
    read or fitted; ``None`` for a fitted one). One bad log never fails the fleet.

    ``options``: how paths are read (``time_col``, ``track_col``, ``bias_col``, ``bias_unit``,
    ``track_unit``, ``delimiter``, as :func:`biasctl.read_log`) and fitted (``deadband``,
    ``velocity_col``, ``rank_tolerance``, ``grid``, ``refine``, as :func:`biasctl.fit`).

    With a ``dask.distributed.Client`` the logs go to the cluster in batches of ``batch``;
    without, they run on a local thread pool of ``workers`` threads (default: one per core),
    one library worker each. The table is the same either way. Each fitted drive's model file
    is kept in ``fits.attrs["models"]`` (source → text) for :func:`score_many`."""
    unknown = [k for k in options if k not in _READ_OPTIONS + _FIT_OPTIONS]
    if unknown:
        raise FitError(
            f"fit_many: unknown option `{unknown[0]}` (options: "
            f"{', '.join(_READ_OPTIONS + _FIT_OPTIONS)})"
        )
    if not (isinstance(batch, int) and batch >= 1):
        raise BiasctlError(f"fit_many: batch must be a whole number ≥ 1, got {batch!r}")
    spec = _terms(model)
    items = _items(logs)
    if client is not None:
        batches = [items[i : i + batch] for i in range(0, len(items), batch)]
        futures = client.map(_fit_batch, batches, model=spec, options=options, pure=False)
        done = [r for part in client.gather(futures) for r in part]
    else:
        n = workers or _os.cpu_count() or 1
        with ThreadPoolExecutor(max_workers=n) as pool:
            done = list(pool.map(lambda it: _fit_one(it, spec, options, 1), items))
    df = _frame([r for r, _ in done])
    # Each fitted drive's model file, for score_many.
    df.attrs["models"] = {r[0]: m for r, m in done if m is not None}
    return df


def to_csv(fits, path: Any = None) -> str | None:
    """The fleet table as ``biasctl fleet fit --out`` writes it (the same text for the same
    fits); written to ``path`` if given."""
    text = _ext.fits_csv(_rows(fits))
    if path is None:
        return text
    with open(_os.fspath(path), "w", encoding="utf-8", newline="") as f:
        f.write(text)
    return None


def _rows(fits) -> list[tuple]:
    """The library's rows of a fleet table (a DataFrame from :func:`fit_many`)."""
    pd = _pandas()
    if not isinstance(fits, pd.DataFrame):
        raise BiasctlError(f"fits must be the DataFrame fit_many returns, got {type(fits).__name__}")
    cols = list(fits.columns)
    if cols[:3] != _COLUMNS_HEAD or cols[-3:] != _COLUMNS_TAIL:
        raise BiasctlError(
            "fits must be the DataFrame fit_many returns: source, rows, terms, the parameters, "
            "std, warnings, error"
        )
    names = [c for c in cols[3:-3] if not c.endswith(".se")]

    def num(x):
        return None if pd.isna(x) else float(x)

    rows = []
    for r in fits.itertuples(index=False, name=None):
        d = dict(zip(cols, r))
        params = [(n, float(d[n]), num(d[n + ".se"])) for n in names if not pd.isna(d[n])]
        warnings = d["warnings"]
        rows.append((
            str(d["source"]),
            None if pd.isna(d["rows"]) else int(d["rows"]),
            "" if pd.isna(d["terms"]) else str(d["terms"]),
            params,
            num(d["std"]),
            [] if pd.isna(warnings) or warnings == "" else str(warnings).split("; "),
            None if d["error"] is None or pd.isna(d["error"]) else str(d["error"]),
        ))
    return rows


def outliers(fits, *, threshold: float = 4.0):
    """The drives whose parameters deviate from the fleet: for every parameter, the fleet's
    median and robust spread (1.4826·MAD) over the fitted drives; a drive's z is its distance
    from the median over the larger of that spread and its own standard error (``rule``: which
    of the two it was), and |z| > ``threshold`` is an outlier. ``fits``: the table of
    :func:`fit_many` (or the path of a table ``biasctl fleet fit`` wrote). A DataFrame:
    source, parameter, value, median, sigma, z, rule, one row per deviating parameter."""
    pd = _pandas()
    if isinstance(fits, pd.DataFrame):
        text, name = to_csv(fits), "<fits>"
    else:
        name = _os.fspath(fits)
        with open(name, encoding="utf-8") as f:
            text = f.read()
    found = _ext.fleet_outliers(text, float(threshold), name)
    return pd.DataFrame(found, columns=_OUTLIER_COLUMNS)


_DIAGNOSE_OPTIONS = _READ_OPTIONS + ("deadband", "velocity_col")


def _screen_one(item: tuple[str, Any], model: str, settings: dict, options: dict,
                threads: int | None) -> tuple:
    source, what = item
    if isinstance(what, Log):
        return _ext.screen_drive(source, model, log=what._inner, threads=threads, **settings,
                                 **options)
    return _ext.screen_drive(source, model, path=what, threads=threads, **settings, **options)


def _screen_batch(items: list, model: str, settings: dict, options: dict) -> list[tuple]:
    """One Dask task: a batch of drives fitted and screened, one after the other, each on one
    library worker."""
    return [_screen_one(item, model, settings, options, 1) for item in items]


def _refit_one(item: tuple[str, Any], model: str, terms: list[str], verify_folds: int,
               options: dict, threads: int | None) -> list[tuple]:
    source, what = item
    if isinstance(what, Log):
        return _ext.verify_drive(source, model, terms, log=what._inner,
                                 verify_folds=verify_folds, threads=threads, **options)
    return _ext.verify_drive(source, model, terms, path=what, verify_folds=verify_folds,
                             threads=threads, **options)


def _refit_batch(items: list, model: str, terms: list[str], verify_folds: int,
                 options: dict) -> list[list[tuple]]:
    """One Dask task: a batch of drives refitted without and with each candidate term, one
    after the other, each on one library worker."""
    return [_refit_one(item, model, terms, verify_folds, options, 1) for item in items]


def _run(fn, items: list, client: Any, batch: int, workers: int | None, batch_fn, **kw) -> list:
    """``fn(item, **kw, threads=1)`` for every item, in order: on the client in batches of
    ``batch`` (``batch_fn``), else on a local thread pool."""
    if client is not None:
        batches = [items[i : i + batch] for i in range(0, len(items), batch)]
        futures = client.map(batch_fn, batches, **kw, pure=False)
        return [r for part in client.gather(futures) for r in part]
    n = workers or _os.cpu_count() or 1
    with ThreadPoolExecutor(max_workers=n) as pool:
        return list(pool.map(lambda it: fn(it, **kw, threads=1), items))


class FleetDiagnosis:
    """The pooled screen of a fleet (:func:`diagnose_many`): ``to_dict()`` equals
    ``biasctl fleet diagnose --json``; ``features`` a DataFrame (name, explained: the mean
    out-of-sample share per drive, p_value: family-wise of the pooled statistic, p_value_raw,
    flagged, reason: the rule that decided, drives_alone: drives whose own screen finds it
    significant, drives: drives that tested it, suggested_term, alternatives); ``summary``;
    ``failed``: the drives that could not be screened, with their messages; ``verification``:
    the pooled suggestion refitted on every drive (feature, term, candidates, try_all, edit,
    terms, folds, drives, gain, z, z_bar, verified, reason: the rule that decided, why,
    drives_verified_alone, tried: each candidate's figures, per_drive: each drive's, failed);
    ``best_edit``: its term when the fleet verifies it."""

    def __init__(self, json_text: str) -> None:
        self._json = json_text
        self._dict = _json.loads(json_text)

    def to_json(self) -> str:
        return self._json

    def to_dict(self) -> dict:
        return _json.loads(self._json)

    @property
    def summary(self) -> str:
        return self._dict["summary"]

    @property
    def failed(self) -> list[tuple[str, str]]:
        return [tuple(f) for f in self._dict["failed"]]

    @property
    def features(self):
        pd = _pandas()
        cols = ["name", "explained", "p_value", "p_value_raw", "flagged", "reason",
                "drives_alone", "drives", "suggested_term", "alternatives"]
        return pd.DataFrame(self._dict["features"], columns=cols)

    @property
    def flagged(self) -> list[str]:
        return [f["name"] for f in self._dict["features"] if f["flagged"]]

    @property
    def best_edit(self) -> str | None:
        return self._dict["best_edit"]

    @property
    def verification(self) -> dict:
        return _json.loads(self._json)["verification"]

    def __repr__(self) -> str:
        return f"FleetDiagnosis({self.summary!r})"


def diagnose_many(
    logs: Sequence[Any],
    model: Any,
    *,
    client: Any = None,
    seed: int = 1,
    alpha: float = 0.01,
    permutations: int = 199,
    folds: int = 5,
    verify: bool = True,
    verify_folds: int = 3,
    batch: int = 64,
    workers: int | None = None,
    **options: Any,
) -> FleetDiagnosis:
    """Fits ``model`` to every drive's log, screens each residual as ``diagnose`` does (the
    same features, smoothers, ``seed``, ``folds`` and ``permutations`` block permutations), and
    pools them: per feature the drives' statistics summed, the sum's family-wise p-value
    counted over the same permutations applied within each drive. An effect too weak to be
    significant in any one drive but present in all is flagged; with nothing missing from the
    model the family-wise false-alarm rate stays at ``alpha`` however many drives are pooled.

    With ``verify`` the pooled suggestion (the first flagged feature's suggested term, and the
    alternatives the drives would try) is then verified across the fleet: every screened drive
    refitted without and with each on ``verify_folds`` folds of consecutive seeks (as
    ``diagnose`` verifies an edit), per term the fleet's gain Σ(SSE_before − SSE_after) /
    Σ SSE_before and its z Σ Tᵢ / √(Σ sᵢ²) (each drive's paired-loss gain and its standard
    error); the term is chosen as ``diagnose`` chooses among a feature's terms, and verified
    iff its z reaches the single drive's bar and its gain is positive (``verification``,
    ``best_edit``).

    ``logs``, ``client``, ``batch``, ``workers`` and the read options as :func:`fit_many`
    (fit options: ``deadband``, ``velocity_col``). A drive that cannot be read, fitted or
    screened is left out of the pool and named in ``failed``."""
    unknown = [k for k in options if k not in _DIAGNOSE_OPTIONS]
    if unknown:
        raise FitError(
            f"diagnose_many: unknown option `{unknown[0]}` (options: "
            f"{', '.join(_DIAGNOSE_OPTIONS)})"
        )
    if not (isinstance(batch, int) and batch >= 1):
        raise BiasctlError(f"diagnose_many: batch must be a whole number ≥ 1, got {batch!r}")
    spec = _terms(model)
    settings = {"seed": seed, "alpha": alpha, "permutations": permutations, "folds": folds}
    # The settings are checked once, before any drive runs.
    _ext.pool_screens([], **settings, verify_folds=verify_folds)
    items = _items(logs)
    screens = _run(_screen_one, items, client, batch, workers, _screen_batch, model=spec,
                   settings=settings, options=options)
    pooled = _ext.pool_screens(screens, **settings, verify_folds=verify_folds)
    terms = _json.loads(pooled)["verification"]["candidates"]
    if not verify or not terms:
        return FleetDiagnosis(pooled)
    # The drives the pool screened, each refitted with every candidate term.
    screened = [it for it, s in zip(items, screens) if s[1] is None]
    refits = _run(_refit_one, screened, client, batch, workers, _refit_batch, model=spec,
                  terms=terms, verify_folds=verify_folds, options=options)
    refits = [r for drive in refits for r in drive]
    return FleetDiagnosis(_ext.pool_screens(screens, **settings, verify_folds=verify_folds,
                                            refits=refits))


_SCORE_COLUMNS = ["source", "test", "n", "mean", "std", "rms", "median_abs", "error"]


def _score_one(source: str, model_json: str | None, error: str | None, test: tuple[str, Any],
               read: dict, feedback_every: int) -> tuple:
    name, what = test
    if model_json is None:
        return (source, name, None, None, None, None, None, f"no fit: {error}")
    try:
        from . import Model, read_log

        log = what if isinstance(what, Log) else read_log(what, **read)
        s = Model.from_json(model_json).score(log, feedback_every=feedback_every)
    except BiasctlError as e:
        return (source, name, None, None, None, None, None, str(e))
    return (source, name, s["n"], s["mean"], s["std"], s["rms"], s["median_abs"], None)


def _score_batch(jobs: list, read: dict, feedback_every: int) -> list[tuple]:
    return [_score_one(*job, read, feedback_every) for job in jobs]


def score_many(fits, logs, *, client: Any = None, batch: int = 64, workers: int | None = None,
               feedback_every: int = 0, **read_options: Any):
    """Each drive's model (from :func:`fit_many`) scored on another log of the same drive, as
    ``biasctl score --json``: ``logs`` a mapping source → path or :class:`biasctl.Log` (the
    ``source`` column pairs them), or a list in the order of the rows of ``fits``. A
    DataFrame: source, test (the scored log), n, mean, std, rms, median_abs, error (a drive
    without a fit or whose test log cannot be read or scored keeps the message)."""
    pd = _pandas()
    unknown = [k for k in read_options if k not in _READ_OPTIONS]
    if unknown:
        raise FitError(
            f"score_many: unknown option `{unknown[0]}` (options: {', '.join(_READ_OPTIONS)}, "
            "feedback_every)"
        )
    models = getattr(fits, "attrs", {}).get("models")
    if not isinstance(fits, pd.DataFrame) or models is None:
        raise BiasctlError("fits must be the DataFrame fit_many returns (it keeps the models)")
    sources = [str(s) for s in fits["source"]]
    if isinstance(logs, dict):
        missing = [s for s in sources if s not in logs]
        if missing:
            raise BiasctlError(f"score_many: no test log for the drive {missing[0]}")
        tests = [logs[s] for s in sources]
    else:
        tests = list(logs)
        if len(tests) != len(sources):
            raise BiasctlError(
                f"score_many: {len(tests)} test logs for {len(sources)} drives (pass a list in "
                "the order of fits, or a dict source → log)"
            )
    items = _items(tests)
    errors = fits["error"].tolist()
    jobs = [(s, models.get(s), e, it) for s, e, it in zip(sources, errors, items)]
    if client is not None:
        batches = [jobs[i : i + batch] for i in range(0, len(jobs), batch)]
        futures = client.map(_score_batch, batches, read=read_options,
                             feedback_every=feedback_every, pure=False)
        rows = [r for part in client.gather(futures) for r in part]
    else:
        n = workers or _os.cpu_count() or 1
        with ThreadPoolExecutor(max_workers=n) as pool:
            rows = list(pool.map(lambda j: _score_one(*j, read_options, feedback_every), jobs))
    df = pd.DataFrame(rows, columns=_SCORE_COLUMNS)
    df["n"] = df["n"].astype("Int64")
    return df
