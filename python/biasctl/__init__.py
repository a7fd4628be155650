"""biasctl: predict, diagnose and compensate actuator bias, in Python.

The Rust library ``biasctl`` (without its command line) behind numpy and pandas: read or build
a log, fit a bias model, predict, score and diagnose it, discover the missing terms, compute the
settle-optimal integrator start value, export the model as C. Every result equals what the
``biasctl`` command line writes for the same files and options (the JSON of ``--json``, the
columns of ``predict --out``, the model file of ``fit --out``).

Long calls (``fit``, ``predict``, ``score``, ``diagnose``, ``discover``, ``ladder``) release the
GIL. Every error is a :class:`BiasctlError` (a ``ValueError``) carrying the library's message.
"""

from __future__ import annotations

import html as _html
import json as _json
import os as _os
from typing import Any, Iterable, Mapping, Sequence

import numpy as _np

from . import _biasctl as _ext
from ._biasctl import BiasctlError, FitError, LogError, ModelError, SettleError, Predictor

__version__: str = _ext.__version__

__all__ = [
    "BiasctlError",
    "Diagnosis",
    "Discovery",
    "FitError",
    "Log",
    "LogError",
    "Model",
    "ModelError",
    "Predictor",
    "SettleError",
    "discover",
    "fit",
    "ladder",
    "read_log",
    "settle",
    "simulate",
]

_FIT_OPTIONS = ("deadband", "velocity_col", "rank_tolerance", "grid", "refine", "threads")


def _pandas():
    import pandas

    return pandas


def _path(path: Any) -> str:
    try:
        return _os.fspath(path)
    except TypeError:
        raise BiasctlError(
            f"a path must be a str or os.PathLike, got {type(path).__name__}"
        ) from None


def _column(name: str, values: Any, n: int | None, source: str) -> _np.ndarray:
    """`values` as a contiguous 1-D float64 array, or a LogError naming the column."""
    if hasattr(values, "to_numpy"):
        try:
            values = values.to_numpy(dtype=_np.float64, na_value=_np.nan)
        except (TypeError, ValueError):
            pass
    try:
        a = _np.asarray(values)
        if a.dtype.kind not in "biuf":
            raise TypeError(a.dtype)
        a = _np.ascontiguousarray(a, dtype=_np.float64)
    except (TypeError, ValueError) as e:
        raise LogError(
            f"{source}: column `{name}` is not numeric ({e}); every column must hold numbers"
        ) from None
    if a.ndim != 1:
        raise LogError(f"{source}: column `{name}` must be one-dimensional, got shape {a.shape}")
    if n is not None and len(a) != n:
        raise LogError(f"{source}: column `{name}` has {len(a)} values, the time column {n}")
    return a


class Log:
    """A measurement log: time (s), position, measured bias (may be absent or partly
    unmeasured) and covariate columns. Immutable. Make one with :func:`read_log`,
    :meth:`Log.from_pandas`, :meth:`Log.from_arrays` or :func:`simulate`."""

    __slots__ = ("_inner",)

    def __init__(self, inner: Any) -> None:
        if not isinstance(inner, _ext.Log):
            raise TypeError(
                "make a Log with biasctl.read_log, Log.from_pandas, Log.from_arrays or "
                "biasctl.simulate"
            )
        self._inner = inner

    @classmethod
    def _from_columns(
        cls,
        source: str,
        names: list[str],
        columns: list[_np.ndarray],
        bias_unit: str | None,
        track_unit: str | None,
    ) -> "Log":
        return cls(_ext.log_from_columns(source, names, columns, bias_unit, track_unit))

    @classmethod
    def from_arrays(
        cls,
        time: Any,
        track: Any,
        bias: Any = None,
        *,
        bias_unit: str | None = None,
        track_unit: str | None = None,
        **covariates: Any,
    ) -> "Log":
        """A log from arrays: ``time`` (s), ``track`` (position) and, optionally, ``bias`` (a
        NaN is a move whose bias was not measured; ``None``: a plan); every other keyword is a
        covariate column (a NaN is a missing value, an empty cell in a file: the reader leaves
        such a column out with a note, see ``Log.notes``). Checked by the library's reader
        (finite values, time order, limits): a message names the column and the line, line 2
        being row 0."""
        source = "<arrays>"
        t = _column("time_s", time, None, source)
        cols = [t, _column("track", track, len(t), source)]
        names = ["time_s", "track", ""]
        if bias is not None:
            cols.append(_column("bias", bias, len(t), source))
            names[2] = "bias"
        for k, v in covariates.items():
            cols.append(_column(k, v, len(t), source))
            names.append(k)
        return cls._from_columns(source, names, cols, bias_unit, track_unit)

    @classmethod
    def from_pandas(
        cls,
        df: Any,
        *,
        time: str = "time_s",
        track: str = "track",
        bias: str = "bias",
        bias_unit: str | None = None,
        track_unit: str | None = None,
    ) -> "Log":
        """A log from a DataFrame: the ``time``, ``track`` and ``bias`` columns (without a
        ``bias`` column: a plan; a NaN bias: not measured, as an empty cell in a file); every
        other numeric column becomes a covariate (other columns are left out)."""
        pd = _pandas()
        if not isinstance(df, pd.DataFrame):
            raise LogError(f"Log.from_pandas takes a pandas DataFrame, got {type(df).__name__}")
        source = "<DataFrame>"
        for role, name in (("time", time), ("track", track)):
            if name not in df.columns:
                raise LogError(
                    f"{source}: no column `{name}` (the {role} column; columns: "
                    f"{', '.join(map(str, df.columns))})"
                )
        n = len(df)
        names = [str(time), str(track), ""]
        cols = [_column(str(time), df[time], None, source), _column(str(track), df[track], n, source)]
        if bias in df.columns:
            cols.append(_column(str(bias), df[bias], n, source))
            names[2] = str(bias)
        for c in df.columns:
            if c in (time, track, bias):
                continue
            s = df[c]
            if not (pd.api.types.is_numeric_dtype(s.dtype) and not pd.api.types.is_bool_dtype(s.dtype)):
                continue
            cols.append(_column(str(c), s, n, source))
            names.append(str(c))
        return cls._from_columns(source, names, cols, bias_unit, track_unit)

    def to_pandas(self):
        """The columns as a DataFrame (float64; an unmeasured bias is NaN)."""
        pd = _pandas()
        arrays = self._inner.arrays()
        df = pd.DataFrame(dict(enumerate(arrays)), copy=False)
        df.columns = self.columns
        return df

    def __len__(self) -> int:
        return len(self._inner)

    @property
    def columns(self) -> list[str]:
        """Time, position, bias (when the log has one), then the covariates."""
        return self._inner.columns

    @property
    def units(self) -> dict[str, str]:
        """``{"bias": …, "position": …}``: the unit labels (metadata, argument or defaults)."""
        return self._inner.units

    @property
    def covariates(self) -> list[str]:
        return self._inner.covariates

    @property
    def has_bias(self) -> bool:
        """Whether the log has a bias column (``False``: a plan)."""
        return self._inner.has_bias

    @property
    def file(self) -> str:
        """The name the log goes by in messages (its path, ``<DataFrame>``, …)."""
        return self._inner.file

    @property
    def notes(self) -> list[str]:
        """What the reader noticed and the command line prints as ``note:`` (a column left out,
        a dialect guessed, …)."""
        return self._inner.notes

    def to_csv(self, path: Any = None) -> str | None:
        """The log as CSV text that reads back to the same values; written to ``path`` if
        given."""
        text = self._inner.to_csv()
        if path is None:
            return text
        with open(_path(path), "w", encoding="utf-8", newline="") as f:
            f.write(text)
        return None

    def __reduce__(self):
        roles = self._inner.roles
        names = [roles[0], roles[1], roles[2] if self.has_bias else "", *self.covariates]
        u, given = self.units, self._inner.units_given
        return (
            _restore_log,
            (
                self.file, names, self._inner.arrays(), u["bias"] if given[0] else None,
                u["position"] if given[1] else None, self._inner.metadata,
            ),
        )

    def __repr__(self) -> str:
        return repr(self._inner)


def _restore_log(source, names, arrays, bias_unit, track_unit, metadata=None):
    return Log(
        _ext.log_from_columns(
            source, names, [_np.ascontiguousarray(a) for a in arrays], bias_unit, track_unit,
            metadata,
        )
    )


def read_log(
    path: Any,
    *,
    time_col: str | None = None,
    track_col: str | None = None,
    bias_col: str | None = None,
    bias_unit: str | None = None,
    track_unit: str | None = None,
    delimiter: str | None = None,
) -> Log:
    """Reads a CSV log with the command line's reader (same checks, same messages naming the
    file, line and column). A log without its bias column is read as a plan (``predict``
    works on it; ``fit``, ``score`` and ``diagnose`` raise the reader's message)."""
    return Log(
        _ext.read_log(_path(path), time_col, track_col, bias_col, bias_unit, track_unit, delimiter)
    )


def simulate(
    sequence: str = "random",
    *,
    n: int | None = None,
    span: float | None = None,
    seed: int = 1,
    drive: Any = "paper1997",
    center: float | None = None,
    dwell_min: float | None = None,
    dwell_max: float | None = None,
    disable: Sequence[str] | str | None = None,
) -> Log:
    """The log ``biasctl simulate`` writes: ``sequence`` (``random``, ``table1`` … ``table7``,
    ``dwell``, ``calibration``) on ``drive`` (``paper1997`` or a drive TOML file), effects in
    ``disable`` switched off."""
    if isinstance(disable, str):
        disable = [d for d in disable.split(",") if d]
    drive = drive if drive == "paper1997" else _path(drive)
    return Log(
        _ext.simulate(
            sequence, n, span, seed, drive, center, dwell_min, dwell_max,
            None if disable is None else list(disable),
        )
    )


def _terms(model: Any) -> str:
    if isinstance(model, str):
        return model
    if isinstance(model, Iterable):
        items = list(model)
        if all(isinstance(t, str) for t in items):
            return ",".join(items)
    raise ModelError(
        f"a model is a preset name, a term list such as \"poly2,dahl:4\" or a list of term "
        f"strings, got {type(model).__name__}"
    )


def _log(log: Any, what: str = "log") -> Any:
    if isinstance(log, Log):
        return log._inner
    pd = _pandas()
    if isinstance(log, pd.DataFrame):
        return Log.from_pandas(log)._inner
    raise LogError(f"{what} must be a biasctl.Log (or a pandas DataFrame), got {type(log).__name__}")


def _check_options(options: Mapping[str, Any], known: Sequence[str], what: str, error=FitError) -> None:
    unknown = [k for k in options if k not in known]
    if unknown:
        raise error(
            f"{what}: unknown option `{unknown[0]}` (options: {', '.join(known)})"
        )


def fit(log: Any, model: Any, **options: Any) -> "Model":
    """Fits ``model`` (a preset such as ``calibration``, a term list ``"poly2,dahl:4"`` or a
    list of term strings) to ``log``, as ``biasctl fit``. Options: ``deadband`` or
    ``velocity_col`` (how direction is read), the library's ``rank_tolerance``, ``grid``,
    ``refine``, and ``threads`` (workers of the library's parallel parts for this call;
    default one per core)."""
    _check_options(options, _FIT_OPTIONS, "fit")
    return Model(_ext.fit(_log(log), _terms(model), **options))


class Model:
    """A fitted bias model. Immutable; ``pickle`` and :meth:`to_json` round-trip it bit for
    bit."""

    __slots__ = ("_inner",)

    def __init__(self, inner: Any) -> None:
        if not isinstance(inner, _ext.Model):
            raise TypeError("make a Model with biasctl.fit or Model.from_json")
        self._inner = inner

    @classmethod
    def from_json(cls, text: str) -> "Model":
        """A model from the text of its file (what ``biasctl fit --out`` writes)."""
        if isinstance(text, (bytes, bytearray)):
            text = bytes(text).decode("utf-8")
        if not isinstance(text, str):
            raise ModelError(f"Model.from_json takes the file's text, got {type(text).__name__}")
        return cls(_ext.Model.from_json(text))

    @classmethod
    def load(cls, path: Any) -> "Model":
        """Reads a model file."""
        p = _path(path)
        with open(p, encoding="utf-8") as f:
            return cls(_ext.Model.from_json(f.read(), p))

    def to_json(self) -> str:
        """The model file's text: the bytes ``biasctl fit --out`` writes."""
        return self._inner.to_json()

    def save(self, path: Any) -> None:
        with open(_path(path), "w", encoding="utf-8", newline="") as f:
            f.write(self.to_json())

    def __reduce__(self):
        return (_restore_model, (self.to_json(),))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Model) and self.to_json() == other.to_json()

    def __hash__(self) -> int:
        return hash(self.to_json())

    @property
    def spec(self) -> str:
        """The model's term list as text (``poly2,direction``)."""
        return self._inner.spec

    @property
    def terms(self) -> list[str]:
        """The fitted terms (with an ``intercept`` the fit added)."""
        return self._inner.terms

    @property
    def warnings(self) -> list[str]:
        return self._inner.warnings

    @property
    def residual_std(self) -> float:
        """The fit's residual std (the default Δb of a handoff)."""
        return self._inner.residual_std

    @property
    def params(self):
        """A DataFrame of every parameter: term, name, value, std_error (NaN where none),
        identifiable (not dropped by the solve, and its standard error within |value|)."""
        pd = _pandas()
        rows = self._inner.param_rows()
        dropped = set(self._inner.dropped)
        return pd.DataFrame(
            {
                "term": [r[0] for r in rows],
                "name": [r[1] for r in rows],
                "value": _np.array([r[2] for r in rows], dtype=_np.float64),
                "std_error": _np.array(
                    [_np.nan if r[3] is None else r[3] for r in rows], dtype=_np.float64
                ),
                "identifiable": [
                    r[1] not in dropped and (r[3] is None or r[3] <= abs(r[2])) for r in rows
                ],
            }
        )

    def predict(self, log: Any, *, handoff: bool | str | None = None, bias_uncertainty: float | None = None):
        """The columns and values of ``biasctl predict --out``: the log's columns,
        ``predicted``, ``residual`` (NaN where the bias is not measured), with ``handoff`` (a
        plant preset, a plant TOML file, or ``True`` for ``paper1997``) ``integrator_start``,
        then one column per term. A plan (a log without bias) works."""
        if handoff is True:
            handoff = "paper1997"
        elif handoff is False:
            handoff = None
        elif handoff is not None:
            handoff = _path(handoff)
        names, arrays = self._inner.predict(_log(log), handoff, bias_uncertainty)
        pd = _pandas()
        df = pd.DataFrame(dict(enumerate(arrays)), copy=False)
        df.columns = names
        return df

    def score(self, log: Any, *, feedback_every: int = 0) -> dict:
        """Error statistics on ``log``: equal to ``biasctl score --json``."""
        return _json.loads(self._inner.score(_log(log), feedback_every))

    def diagnose(
        self,
        log: Any,
        *,
        verify: bool = True,
        seed: int = 1,
        alpha: float = 0.01,
        permutations: int = 199,
        folds: int = 5,
        verify_folds: int = 3,
        threads: int | None = None,
    ) -> "Diagnosis":
        """Which missing effect the residual follows: equal to ``biasctl diagnose --json``
        (``verify=False``: ``--no-verify``; ``threads``: as ``--threads``, for this call)."""
        return Diagnosis(
            _ext.diagnose(
                self._inner, _log(log), verify, seed, alpha, permutations, folds, verify_folds,
                threads,
            )
        )

    def predictor(self) -> Predictor:
        """The online predictor at the start of a log: ``step(track, time_s, bias=None)``
        predicts one seek and advances; ``peek(track)`` predicts without advancing."""
        return self._inner.predictor()

    def export_c(
        self,
        out_dir: Any,
        float32: bool = False,
        *,
        handoff: bool | str | None = None,
        bias_uncertainty: float | None = None,
    ) -> list[str]:
        """Writes ``bias_model.h``, ``bias_model.c`` and ``replay.c`` into ``out_dir`` (as
        ``biasctl export c``); returns their paths."""
        if handoff is True:
            handoff = "paper1997"
        elif handoff is False:
            handoff = None
        elif handoff is not None:
            handoff = _path(handoff)
        return self._inner.export_c(_path(out_dir), bool(float32), handoff, bias_uncertainty)

    def __repr__(self) -> str:
        return repr(self._inner)


def _restore_model(text: str) -> Model:
    return Model.from_json(text)


class Diagnosis:
    """A diagnosis of a model on a log (``Model.diagnose``)."""

    __slots__ = ("_inner", "_dict")

    def __init__(self, inner: Any) -> None:
        self._inner = inner
        self._dict: dict | None = None

    def to_json(self) -> str:
        """The JSON ``biasctl diagnose --json`` prints."""
        return self._inner.to_json()

    def to_dict(self) -> dict:
        """Equal to ``biasctl diagnose --json``."""
        if self._dict is None:
            self._dict = _json.loads(self._inner.to_json())
        return _json.loads(_json.dumps(self._dict))

    @property
    def summary(self) -> str:
        return self.to_dict()["summary"]

    @property
    def features(self):
        """One row per candidate feature, strongest first: name, explained, p_value, flagged,
        suggested_term, shape, … (the binned residual curve left out)."""
        pd = _pandas()
        rows = [{k: v for k, v in f.items() if k != "curve"} for f in self.to_dict()["features"]]
        return pd.DataFrame(rows)

    @property
    def best_edit(self) -> str | None:
        """The model's terms after the best verified edit (a term string for :func:`fit`), or
        ``None`` when no edit was verified (or ``verify=False``)."""
        return self._inner.best_edit

    @property
    def best_edit_text(self) -> str | None:
        """The best verified edit in words (``add play:8``), or ``None``."""
        return self._inner.best_edit_text

    def svg(self, top: int = 6) -> str:
        """The residual figure of the report (SVG): the residual against the ``top``
        strongest features."""
        return self._inner.svg(top)

    def plot(self, ax: Any = None, feature: str | None = None):
        """The residual against ``feature`` (default: the leading one), with the binned mean;
        returns the matplotlib Axes (needs matplotlib: ``pip install matplotlib``)."""
        try:
            import matplotlib.pyplot as plt
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError("Diagnosis.plot needs matplotlib: pip install matplotlib") from e
        feats = self.to_dict()["features"]
        if feature is None:
            if not feats:
                raise BiasctlError("the diagnosis has no feature to plot")
            feature = feats[0]["name"]
        x, r = self._inner.feature_residuals(feature)
        if ax is None:
            _, ax = plt.subplots(figsize=(6, 4))
        ax.scatter(x, r, s=4, alpha=0.4, label="residual")
        for f in feats:
            if f["name"] == feature:
                bins = [b for b in f.get("curve", []) if b.get("centre") is not None]
                if bins:
                    ax.plot([b["centre"] for b in bins], [b["mean"] for b in bins], "o-",
                            color="C3", label="binned mean")
        unit = self.to_dict().get("units", {}).get("bias", "")
        ax.set_xlabel(feature)
        ax.set_ylabel(f"residual ({unit})" if unit else "residual")
        ax.legend(loc="best")
        return ax

    def _repr_html_(self) -> str:
        d = self.to_dict()
        cols = ["name", "explained", "p_value", "flagged", "suggested_term"]
        head = "".join(f"<th>{c}</th>" for c in cols)
        body = []
        for f in d["features"][:12]:
            cells = []
            for c in cols:
                v = f.get(c)
                if isinstance(v, float):
                    v = f"{v:.4g}"
                cells.append(f"<td>{_html.escape('' if v is None else str(v))}</td>")
            body.append("<tr>" + "".join(cells) + "</tr>")
        best = self.best_edit_text
        return (
            f"<div><p>{_html.escape(d['summary'])}</p>"
            + (f"<p>best verified edit: <code>{_html.escape(best)}</code></p>" if best else "")
            + f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"
            + f"<div>{self.svg()}</div></div>"
        )

    def __repr__(self) -> str:
        return f"<biasctl.Diagnosis: {self.summary}>"


class Discovery:
    """The result of :func:`discover`: the ladder of verified edits and the final model."""

    __slots__ = ("_json", "_text", "model")

    def __init__(self, json_text: str, text: str, model: Model) -> None:
        self._json = json_text
        self._text = text
        self.model = model

    def to_json(self) -> str:
        return self._json

    def to_dict(self) -> dict:
        """Equal to ``biasctl discover --json``."""
        return _json.loads(self._json)

    @property
    def steps(self):
        """One row per applied edit (edit, feature, reason, std_before, std_after, terms)."""
        return _pandas().DataFrame(self.to_dict()["steps"])

    @property
    def final_terms(self) -> list[str]:
        return self.to_dict()["final_terms"]

    def __str__(self) -> str:
        return self._text

    def __repr__(self) -> str:
        return f"<biasctl.Discovery: {','.join(self.final_terms)}>"


def discover(
    train: Any,
    *,
    test: Any = None,
    start: Any = "poly2",
    max_steps: int = 8,
    alpha: float = 0.01,
    seed: int = 1,
    verify_folds: int = 3,
    threads: int | None = None,
) -> Discovery:
    """Fit, diagnose, apply the best verified edit, repeat (``biasctl discover``); ``start``
    a preset, a term list, a model file or a :class:`Model` (its terms)."""
    if isinstance(start, Model):
        start = start.spec
    elif isinstance(start, _os.PathLike):
        start = _os.fspath(start)
    else:
        start = _terms(start)
    j, text, model = _ext.discover(
        _log(train, "train"), None if test is None else _log(test, "test"), start, max_steps,
        alpha, seed, verify_folds, threads,
    )
    return Discovery(j, text, Model(model))


def ladder_json(
    train: Any,
    test: Any,
    terms: Any,
    *,
    deadband: float | None = None,
    velocity_col: str | None = None,
    threads: int | None = None,
) -> dict:
    """As :func:`ladder`, the dict ``biasctl ladder --json`` prints."""
    return _json.loads(
        _ext.ladder(
            _log(train, "train"), _log(test, "test"), _terms(terms), deadband, velocity_col,
            threads,
        )
    )


def ladder(
    train: Any,
    test: Any,
    terms: Any,
    *,
    deadband: float | None = None,
    velocity_col: str | None = None,
    threads: int | None = None,
):
    """Adds ``terms`` one at a time, refits on ``train`` and scores on ``test``
    (``biasctl ladder``): a DataFrame with a row per step (terms, std, reduction, …)."""
    j = ladder_json(
        train, test, terms, deadband=deadband, velocity_col=velocity_col, threads=threads
    )
    return _pandas().DataFrame(j["steps"])


def _plain(v: Any) -> Any:
    if isinstance(v, _np.generic):
        return v.item()
    if isinstance(v, _np.ndarray):
        return v.tolist()
    raise TypeError(f"a setting must be a number or a list of numbers, got {type(v).__name__}")


def settle(preset: str = "paper1997", **spec: Any) -> dict:
    """The settle-optimal integrator start value at handoff (``biasctl settle --json``):
    ``preset`` (``paper1997``, ``modern``) or ``plant=`` a plant TOML file, with any setting
    of the description overridden by name (``step_um``, ``window_um``, ``bias``,
    ``bias_uncertainty``, ``horizon``, ``hold``, ``ts_s``, …)."""
    plant = spec.pop("plant", None)
    source = preset if plant is None else _path(plant)
    spec = {k: v for k, v in spec.items() if v is not None}
    try:
        overrides = _json.dumps(spec, default=_plain) if spec else None
    except (TypeError, ValueError) as e:
        raise SettleError(f"settings: {e}") from None
    return _json.loads(_ext.settle(source, overrides))
