from os import PathLike
from typing import Any, Iterable, Literal, Mapping, Sequence

import numpy as np
import numpy.typing as npt
import pandas as pd

from ._biasctl import BiasctlError as BiasctlError
from ._biasctl import FitError as FitError
from ._biasctl import LogError as LogError
from ._biasctl import ModelError as ModelError
from ._biasctl import Predictor as Predictor
from ._biasctl import SettleError as SettleError

__version__: str

_Path = str | PathLike[str]
_Array = npt.ArrayLike
_Terms = str | Sequence[str]

class Log:
    @classmethod
    def from_arrays(
        cls,
        time: _Array,
        track: _Array,
        bias: _Array | None = None,
        *,
        bias_unit: str | None = None,
        track_unit: str | None = None,
        **covariates: _Array,
    ) -> Log: ...
    @classmethod
    def from_pandas(
        cls,
        df: pd.DataFrame,
        *,
        time: str = "time_s",
        track: str = "track",
        bias: str = "bias",
        bias_unit: str | None = None,
        track_unit: str | None = None,
    ) -> Log: ...
    def to_pandas(self) -> pd.DataFrame: ...
    def __len__(self) -> int: ...
    @property
    def columns(self) -> list[str]: ...
    @property
    def units(self) -> dict[str, str]: ...
    @property
    def covariates(self) -> list[str]: ...
    @property
    def has_bias(self) -> bool: ...
    @property
    def file(self) -> str: ...
    @property
    def notes(self) -> list[str]: ...
    def to_csv(self, path: _Path | None = None) -> str | None: ...

def read_log(
    path: _Path,
    *,
    time_col: str | None = None,
    track_col: str | None = None,
    bias_col: str | None = None,
    bias_unit: str | None = None,
    track_unit: str | None = None,
    delimiter: str | None = None,
) -> Log: ...
def simulate(
    sequence: str = "random",
    *,
    n: int | None = None,
    span: float | None = None,
    seed: int = 1,
    drive: _Path = "paper1997",
    center: float | None = None,
    dwell_min: float | None = None,
    dwell_max: float | None = None,
    disable: Sequence[str] | str | None = None,
) -> Log: ...
def fit(
    log: Log | pd.DataFrame,
    model: _Terms,
    *,
    deadband: float | None = None,
    velocity_col: str | None = None,
    rank_tolerance: float | None = None,
    grid: int | None = None,
    refine: int | None = None,
    threads: int | None = None,
) -> Model: ...

class Model:
    @classmethod
    def from_json(cls, text: str | bytes) -> Model: ...
    @classmethod
    def load(cls, path: _Path) -> Model: ...
    def to_json(self) -> str: ...
    def save(self, path: _Path) -> None: ...
    @property
    def spec(self) -> str: ...
    @property
    def terms(self) -> list[str]: ...
    @property
    def warnings(self) -> list[str]: ...
    @property
    def residual_std(self) -> float: ...
    @property
    def params(self) -> pd.DataFrame: ...
    def predict(
        self,
        log: Log | pd.DataFrame,
        *,
        handoff: bool | _Path | None = None,
        bias_uncertainty: float | None = None,
    ) -> pd.DataFrame: ...
    def score(self, log: Log | pd.DataFrame, *, feedback_every: int = 0) -> dict[str, Any]: ...
    def diagnose(
        self,
        log: Log | pd.DataFrame,
        *,
        verify: bool = True,
        seed: int = 1,
        alpha: float = 0.01,
        permutations: int = 199,
        folds: int = 5,
        verify_folds: int = 3,
        threads: int | None = None,
    ) -> Diagnosis: ...
    def predictor(self) -> Predictor: ...
    def export_c(
        self,
        out_dir: _Path,
        float32: bool = False,
        *,
        handoff: bool | _Path | None = None,
        bias_uncertainty: float | None = None,
    ) -> list[str]: ...

class Diagnosis:
    def to_json(self) -> str: ...
    def to_dict(self) -> dict[str, Any]: ...
    @property
    def summary(self) -> str: ...
    @property
    def features(self) -> pd.DataFrame: ...
    @property
    def best_edit(self) -> str | None: ...
    @property
    def best_edit_text(self) -> str | None: ...
    def svg(self, top: int = 6) -> str: ...
    def plot(self, ax: Any = None, feature: str | None = None) -> Any: ...
    def _repr_html_(self) -> str: ...

class Discovery:
    model: Model
    def to_json(self) -> str: ...
    def to_dict(self) -> dict[str, Any]: ...
    @property
    def steps(self) -> pd.DataFrame: ...
    @property
    def final_terms(self) -> list[str]: ...

def discover(
    train: Log | pd.DataFrame,
    *,
    test: Log | pd.DataFrame | None = None,
    start: _Terms | Model | PathLike[str] = "poly2",
    max_steps: int = 8,
    alpha: float = 0.01,
    seed: int = 1,
    verify_folds: int = 3,
    threads: int | None = None,
) -> Discovery: ...
def ladder(
    train: Log | pd.DataFrame,
    test: Log | pd.DataFrame,
    terms: _Terms,
    *,
    deadband: float | None = None,
    velocity_col: str | None = None,
    threads: int | None = None,
) -> pd.DataFrame: ...
def ladder_json(
    train: Log | pd.DataFrame,
    test: Log | pd.DataFrame,
    terms: _Terms,
    *,
    deadband: float | None = None,
    velocity_col: str | None = None,
    threads: int | None = None,
) -> dict[str, Any]: ...
def settle(preset: str = "paper1997", **spec: Any) -> dict[str, Any]: ...
