"""The extension module under the `biasctl` package (use `biasctl` itself)."""

from typing import Any

import numpy as np
import numpy.typing as npt

__version__: str

class BiasctlError(ValueError): ...
class LogError(BiasctlError): ...
class ModelError(BiasctlError): ...
class FitError(BiasctlError): ...
class SettleError(BiasctlError): ...

_F64 = npt.NDArray[np.float64]

class Log:
    def __len__(self) -> int: ...
    @property
    def columns(self) -> list[str]: ...
    @property
    def roles(self) -> tuple[str, str, str]: ...
    @property
    def covariates(self) -> list[str]: ...
    @property
    def has_bias(self) -> bool: ...
    @property
    def units_given(self) -> tuple[bool, bool]: ...
    @property
    def units(self) -> dict[str, str]: ...
    @property
    def file(self) -> str: ...
    @property
    def notes(self) -> list[str]: ...
    @property
    def metadata(self) -> list[str]: ...
    def arrays(self) -> list[_F64]: ...
    def to_csv(self) -> str: ...

class Predictor:
    def step(
        self,
        track: float,
        time_s: float,
        bias: float | None = None,
        covariates: list[float] | None = None,
    ) -> float: ...
    def peek(
        self, track: float, time_s: float | None = None, covariates: list[float] | None = None
    ) -> float: ...

class Model:
    def to_json(self) -> str: ...
    @staticmethod
    def from_json(text: str, name: str = "<json>") -> Model: ...
    @property
    def spec(self) -> str: ...
    @property
    def terms(self) -> list[str]: ...
    @property
    def dropped(self) -> list[str]: ...
    @property
    def warnings(self) -> list[str]: ...
    def param_rows(self) -> list[tuple[str, str, float, float | None]]: ...
    @property
    def columns(self) -> tuple[str, str, str, list[str]]: ...
    @property
    def residual_std(self) -> float: ...
    def predict(
        self, log: Log, handoff: str | None = None, bias_uncertainty: float | None = None
    ) -> tuple[list[str], list[_F64]]: ...
    def score(self, log: Log, feedback_every: int = 0) -> str: ...
    def check(self, log: Log) -> None: ...
    def predictor(self) -> Predictor: ...
    def export_c(
        self,
        out_dir: str,
        float32: bool = False,
        handoff: str | None = None,
        bias_uncertainty: float | None = None,
    ) -> list[str]: ...

class Diagnosis:
    def to_json(self) -> str: ...
    @property
    def best_edit(self) -> str | None: ...
    @property
    def best_edit_text(self) -> str | None: ...
    def svg(self, top: int = 6) -> str: ...
    def feature_residuals(self, feature: str) -> tuple[_F64, _F64]: ...

def read_log(
    path: str,
    time_col: str | None = None,
    track_col: str | None = None,
    bias_col: str | None = None,
    bias_unit: str | None = None,
    track_unit: str | None = None,
    delimiter: str | None = None,
) -> Log: ...
def log_from_columns(
    source: str,
    names: list[str],
    columns: list[_F64],
    bias_unit: str | None = None,
    track_unit: str | None = None,
    metadata: list[str] | None = None,
) -> Log: ...
def fit(
    log: Log,
    model: str,
    deadband: float | None = None,
    velocity_col: str | None = None,
    rank_tolerance: float | None = None,
    grid: int | None = None,
    refine: int | None = None,
    threads: int | None = None,
) -> Model: ...
def simulate(
    sequence: str = "random",
    n: int | None = None,
    span: float | None = None,
    seed: int = 1,
    drive: str = "paper1997",
    center: float | None = None,
    dwell_min: float | None = None,
    dwell_max: float | None = None,
    disable: list[str] | None = None,
) -> Log: ...
def diagnose(
    model: Model,
    log: Log,
    verify: bool = True,
    seed: int = 1,
    alpha: float = 0.01,
    permutations: int = 199,
    folds: int = 5,
    verify_folds: int = 3,
    threads: int | None = None,
) -> Diagnosis: ...
def discover(
    train: Log,
    test: Log | None = None,
    start: str = "poly2",
    max_steps: int = 8,
    alpha: float = 0.01,
    seed: int = 1,
    verify_folds: int = 3,
    threads: int | None = None,
) -> tuple[str, str, Model]: ...
def ladder(
    train: Log,
    test: Log,
    terms: str,
    deadband: float | None = None,
    velocity_col: str | None = None,
    threads: int | None = None,
) -> str: ...
def settle(plant: str = "paper1997", overrides: str | None = None) -> str: ...
def _panic() -> None: ...

_Row = tuple[
    str,
    int | None,
    str,
    list[tuple[str, float, float | None]],
    float | None,
    list[str],
    str | None,
]

def fit_drive(
    source: str,
    model: str,
    path: str | None = None,
    log: Log | None = None,
    time_col: str | None = None,
    track_col: str | None = None,
    bias_col: str | None = None,
    bias_unit: str | None = None,
    track_unit: str | None = None,
    delimiter: str | None = None,
    deadband: float | None = None,
    velocity_col: str | None = None,
    rank_tolerance: float | None = None,
    grid: int | None = None,
    refine: int | None = None,
    threads: int | None = None,
    keep_model: bool = False,
) -> tuple[_Row, str | None]: ...
def fleet_outliers(
    csv: str, threshold: float = 4.0, name: str = "<fits>"
) -> list[tuple[str, str, float, float, float, float, str]]: ...
def fits_csv(rows: list[_Row]) -> str: ...

_Screen = tuple[
    str,
    str | None,
    list[str],
    list[bool],
    list[float],
    list[float],
    list[float],
    int,
    list[float],
    list[str | None],
    list[list[str]],
]

def screen_drive(
    source: str,
    model: str,
    path: str | None = None,
    log: Log | None = None,
    seed: int = 1,
    alpha: float = 0.01,
    permutations: int = 199,
    folds: int = 5,
    time_col: str | None = None,
    track_col: str | None = None,
    bias_col: str | None = None,
    bias_unit: str | None = None,
    track_unit: str | None = None,
    delimiter: str | None = None,
    deadband: float | None = None,
    velocity_col: str | None = None,
    threads: int | None = None,
) -> _Screen: ...

_Refit = tuple[
    str,
    str,
    str | None,
    tuple[int, float, float, float, float, float, float, float],
    tuple[bool, str, str, str],
]

def verify_drive(
    source: str,
    model: str,
    terms: list[str],
    path: str | None = None,
    log: Log | None = None,
    verify_folds: int = 3,
    time_col: str | None = None,
    track_col: str | None = None,
    bias_col: str | None = None,
    bias_unit: str | None = None,
    track_unit: str | None = None,
    delimiter: str | None = None,
    deadband: float | None = None,
    velocity_col: str | None = None,
    threads: int | None = None,
) -> list[_Refit]: ...
def pool_screens(
    screens: list[_Screen],
    seed: int = 1,
    alpha: float = 0.01,
    permutations: int = 199,
    folds: int = 5,
    verify_folds: int = 3,
    refits: list[_Refit] | None = None,
) -> str: ...
