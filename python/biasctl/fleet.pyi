from os import PathLike
from typing import Any, Sequence

import pandas as pd

from . import Log

def fit_many(
    logs: Sequence[str | PathLike[str] | Log],
    model: str | Sequence[str],
    *,
    client: Any = None,
    batch: int = 64,
    workers: int | None = None,
    time_col: str | None = ...,
    track_col: str | None = ...,
    bias_col: str | None = ...,
    bias_unit: str | None = ...,
    track_unit: str | None = ...,
    delimiter: str | None = ...,
    deadband: float | None = ...,
    velocity_col: str | None = ...,
    rank_tolerance: float | None = ...,
    grid: int | None = ...,
    refine: int | None = ...,
) -> pd.DataFrame: ...
def to_csv(fits: pd.DataFrame, path: str | PathLike[str] | None = None) -> str | None: ...
def outliers(fits: pd.DataFrame | str | PathLike[str], *, threshold: float = 4.0) -> pd.DataFrame: ...

class FleetDiagnosis:
    def to_json(self) -> str: ...
    def to_dict(self) -> dict[str, Any]: ...
    @property
    def summary(self) -> str: ...
    @property
    def failed(self) -> list[tuple[str, str]]: ...
    @property
    def features(self) -> pd.DataFrame: ...
    @property
    def flagged(self) -> list[str]: ...
    @property
    def best_edit(self) -> str | None: ...
    @property
    def verification(self) -> dict[str, Any]: ...

def diagnose_many(
    logs: Sequence[str | PathLike[str] | Log],
    model: str | Sequence[str],
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
) -> FleetDiagnosis: ...
def score_many(
    fits: pd.DataFrame,
    logs: dict[str, str | PathLike[str] | Log] | Sequence[str | PathLike[str] | Log],
    *,
    client: Any = None,
    batch: int = 64,
    workers: int | None = None,
    feedback_every: int = 0,
    **read_options: Any,
) -> pd.DataFrame: ...
