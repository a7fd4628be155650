"""Every CSV biasctl writes loads in pandas and polars with their default type inference, its
number columns as floats (polars guesses a column's type from its first rows: whole numbers
written without a decimal point there make an integer column that fails at the first
fraction)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import polars as pl
import pytest

# Columns that hold counts or indices, not measurements.
INTEGER_COLUMNS = {"k", "count", "bin", "measured"}


def _outputs(data, cli, model_file, tmp):
    out = {}
    out["simulate"] = data / "test.csv"
    out["truth"] = data / "test_truth.csv"
    out["table1"] = data / "table1.csv"
    p = tmp / "pred.csv"
    cli.run("predict", "--model", model_file, "--data", data / "test.csv", "--handoff",
            "paper1997", "--out", p)
    out["predict"] = p
    p = tmp / "plan_pred.csv"
    cli.run("predict", "--model", model_file, "--data", data / "plan.csv", "--out", p)
    out["predict_plan"] = p
    cli.run("settle", "--bounds-out", tmp / "bounds.csv", "--response-out", tmp / "resp.csv")
    out["settle_bounds"] = tmp / "bounds.csv"
    out["settle_responses"] = tmp / "resp.csv"
    cli.run("diagnose", "--model", model_file, "--data", data / "test.csv", "--no-verify",
            "--out", tmp / "diag")
    for f in sorted((tmp / "diag").glob("*.csv")):
        out[f"diagnose_{f.stem}"] = f
    return out


@pytest.fixture(scope="module")
def outputs(data, cli, model_file, tmp_path_factory):
    return _outputs(data, cli, model_file, tmp_path_factory.mktemp("csv"))


def test_there_are_diagnose_csvs(outputs):
    assert any(k.startswith("diagnose_residual_vs_") for k in outputs)


@pytest.mark.parametrize("reader", ["pandas", "polars"])
def test_every_csv_reads_with_float_columns(outputs, reader):
    for name, path in outputs.items():
        if reader == "pandas":
            df = pd.read_csv(path, comment="#")
            kinds = {c: df[c].dtype.kind for c in df.columns}
            values = {c: df[c].to_numpy() for c in df.columns}
        else:
            df = pl.read_csv(path, comment_prefix="#")
            kinds = {c: ("f" if df[c].dtype.is_float() else "i" if df[c].dtype.is_integer()
                         else "O") for c in df.columns}
            values = {c: df[c].to_numpy() for c in df.columns}
        for c, kind in kinds.items():
            if c in INTEGER_COLUMNS:
                assert kind in "iuf", (name, c, kind)
            elif c == "bin":
                continue
            else:
                # An all-empty column (a plan's bias) reads as float in pandas, null in polars.
                empty = reader == "polars" and df[c].null_count() == len(df)
                assert kind == "f" or empty, (name, c, kind)
        assert len(next(iter(values.values()))) > 0, name


def test_the_prediction_csv_reads_equal_in_both(outputs):
    a = pd.read_csv(outputs["predict"], comment="#")
    b = pl.read_csv(outputs["predict"], comment_prefix="#")
    assert list(a.columns) == list(b.columns)
    np.testing.assert_array_equal(a.to_numpy(dtype=float), b.to_numpy().astype(float))
