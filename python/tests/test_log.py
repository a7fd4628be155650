"""Logs: the CLI's reader, logs built from pandas and numpy (read by the same reader), their
columns, units, round trips and every bad input."""

from __future__ import annotations

import pickle

import numpy as np
import pandas as pd
import pytest

import biasctl


def _cells(path):
    """The numeric rows of a CSV log as the file holds them (reference: the text itself)."""
    rows = [l for l in open(path).read().splitlines() if l and not l.startswith("#")]
    header = rows[0].split(",")
    values = [[float(c) if c else np.nan for c in r.split(",")] for r in rows[1:]]
    return header, np.array(values)


def test_read_log_holds_the_file_values(data):
    log = biasctl.read_log(data / "train.csv")
    header, values = _cells(data / "train.csv")
    assert log.columns == header == ["time_s", "track", "bias"]
    assert len(log) == values.shape[0] == 600
    df = log.to_pandas()
    assert list(df.columns) == header
    np.testing.assert_array_equal(df.to_numpy(), values)
    assert log.units == {"bias": "counts", "position": "tracks"}
    assert log.has_bias and log.file.endswith("train.csv")


def test_unit_and_column_arguments(data, tmp_path):
    text = (data / "train.csv").read_text().replace("time_s,track,bias", "t;pos;force")
    text = "\n".join(l.replace(",", ";") for l in text.splitlines() if not l.startswith("#"))
    p = tmp_path / "renamed.csv"
    p.write_text(text + "\n")
    log = biasctl.read_log(
        p, time_col="t", track_col="pos", bias_col="force", bias_unit="N", track_unit="mm",
        delimiter=";",
    )
    assert log.columns == ["t", "pos", "force"]
    assert log.units == {"bias": "N", "position": "mm"}
    ref = biasctl.read_log(data / "train.csv").to_pandas().to_numpy()
    np.testing.assert_array_equal(log.to_pandas().to_numpy(), ref)


def test_from_pandas_and_from_arrays_equal_the_file(data):
    ref = biasctl.read_log(data / "train.csv")
    df = ref.to_pandas()
    a = biasctl.Log.from_pandas(df)
    b = biasctl.Log.from_arrays(df.time_s, df.track.to_numpy(), df.bias.tolist())
    for log in (a, b):
        assert log.columns == ref.columns
        np.testing.assert_array_equal(log.to_pandas().to_numpy(), df.to_numpy())
    # Same model either way (reference: the fit on the file).
    m = biasctl.fit(ref, "poly2,direction")
    assert biasctl.fit(a, "poly2,direction").params.equals(m.params)


def test_covariates_nan_bias_and_plans():
    t = np.arange(6, dtype=float)
    track = np.array([10.0, 50, 20, 80, 30, 60])
    bias = np.array([1.0, np.nan, 2.0, 3.0, np.nan, 4.0])
    log = biasctl.Log.from_arrays(t, track, bias, temp_c=np.linspace(20, 25, 6))
    assert log.columns == ["time_s", "track", "bias", "temp_c"]
    assert log.covariates == ["temp_c"]
    got = log.to_pandas()
    np.testing.assert_array_equal(got.bias.to_numpy(), bias)  # NaN = moved, not measured
    plan = biasctl.Log.from_arrays(t, track)
    assert not plan.has_bias and plan.columns == ["time_s", "track"]
    df = pd.DataFrame({"time_s": t, "track": track, "bias": bias, "note": list("abcdef"),
                       "flag": [True] * 6, "load": np.arange(6)})
    log = biasctl.Log.from_pandas(df)
    assert log.columns == ["time_s", "track", "bias", "load"]  # text and bool columns left out


def test_pickle_round_trips_a_log(data):
    log = biasctl.read_log(data / "train.csv")
    back = pickle.loads(pickle.dumps(log))
    assert back.columns == log.columns and back.units == log.units
    np.testing.assert_array_equal(back.to_pandas().to_numpy(), log.to_pandas().to_numpy())
    plan = biasctl.Log.from_arrays([0.0, 1.0], [1.0, 2.0], [np.nan, 1.5], temp_c=[20.0, 21.0])
    back = pickle.loads(pickle.dumps(plan))
    assert back.columns == plan.columns
    np.testing.assert_array_equal(back.to_pandas().to_numpy(), plan.to_pandas().to_numpy())


def test_a_plan_file_reads_and_fit_refuses_it(data):
    plan = biasctl.read_log(data / "plan.csv")
    assert not plan.has_bias
    with pytest.raises(biasctl.LogError, match="bias"):
        biasctl.fit(plan, "poly2")


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: biasctl.Log.from_arrays([0.0, np.nan], [1.0, 2.0], [1.0, 2.0]), "line 3"),
        (lambda: biasctl.Log.from_arrays([0.0, 1.0], [1.0, np.inf], [1.0, 2.0]), "line 3"),
        (lambda: biasctl.Log.from_arrays([1.0, 0.0], [1.0, 2.0], [1.0, 2.0]), "time"),
        (lambda: biasctl.Log.from_arrays([0.0, 1.0], [1.0, 2.0, 3.0]), "track"),
        (lambda: biasctl.Log.from_arrays(["a", "b"], [1.0, 2.0]), "not numeric"),
        (lambda: biasctl.Log.from_arrays(np.zeros((2, 2)), [1.0, 2.0]), "one-dimensional"),
        (lambda: biasctl.Log.from_arrays([], [], []), "no rows"),
        (lambda: biasctl.Log.from_pandas(pd.DataFrame()), "time_s"),
        (lambda: biasctl.Log.from_pandas(pd.DataFrame({"time_s": [], "track": [], "bias": []})),
         "no rows"),
        (lambda: biasctl.Log.from_pandas({"time_s": [0.0]}), "DataFrame"),
        (lambda: biasctl.read_log("/nonexistent/log.csv"), "log.csv"),
        (lambda: biasctl.read_log("x.csv", delimiter="|"), "delimiter"),
    ],
)
def test_bad_input_raises_a_log_error(make, match):
    with pytest.raises(biasctl.LogError, match=match) as e:
        make()
    assert isinstance(e.value, biasctl.BiasctlError) and isinstance(e.value, ValueError)


def test_non_contiguous_and_other_dtypes_are_read_by_value():
    base = np.arange(20, dtype=np.float64)
    t, track = base[::2], (base * 3)[::2]  # strided views
    bias = np.arange(10, dtype=np.int32)
    log = biasctl.Log.from_arrays(t, track, bias)
    df = log.to_pandas()
    np.testing.assert_array_equal(df.time_s, t)
    np.testing.assert_array_equal(df.track, track)
    np.testing.assert_array_equal(df.bias, bias.astype(float))
    f32 = biasctl.Log.from_arrays(t.astype(np.float32), track.astype(np.float32))
    np.testing.assert_array_equal(f32.to_pandas().track, track)


def test_read_log_messages_name_the_file_line_and_column(data, tmp_path, cli):
    p = tmp_path / "bad.csv"
    p.write_text("time_s,track,bias\n0,1,2\n1,abc,3\n")
    with pytest.raises(biasctl.LogError) as e:
        biasctl.read_log(p)
    cli_err = cli.run("fit", "--data", p, "--terms", "poly2", "--out", tmp_path / "m.json", ok=False)
    assert cli_err.returncode == 2
    # The library's message, as the CLI prints it after `error: `.
    assert str(e.value) in cli_err.stderr
    assert "bad.csv" in str(e.value) and "line 3" in str(e.value)


@pytest.mark.parametrize(
    "kwargs, flags",
    [
        ({"n": 300, "seed": 5}, ["--sequence", "random", "--n", "300", "--seed", "5"]),
        ({"sequence": "table2", "seed": 2, "disable": ["drift", "scatter"]},
         ["--sequence", "table2", "--seed", "2", "--disable", "drift,scatter"]),
        ({"n": 200, "span": 40.0, "center": 900.0, "dwell_min": 0.1, "dwell_max": 0.2},
         ["--sequence", "random", "--n", "200", "--span", "40", "--center", "900",
          "--dwell-min", "0.1", "--dwell-max", "0.2"]),
    ],
)
def test_simulate_equals_cli_simulate(cli, tmp_path, kwargs, flags):
    out = tmp_path / "sim.csv"
    cli.run("simulate", *flags, "--out", out)
    want = biasctl.read_log(out)
    got = biasctl.simulate(**kwargs)
    assert got.columns == want.columns and got.units == want.units
    np.testing.assert_array_equal(got.to_pandas().to_numpy(), want.to_pandas().to_numpy())


def test_simulate_a_drive_file_with_a_covariate(cli, tmp_path):
    from conftest import REPO

    drive = REPO / "data" / "drive_temperature.toml"
    out = tmp_path / "sim.csv"
    cli.run("simulate", "--sequence", "random", "--n", "200", "--drive", drive, "--out", out)
    got = biasctl.simulate(n=200, drive=drive)
    assert got.covariates == ["temp_c"]
    np.testing.assert_array_equal(
        got.to_pandas().to_numpy(), biasctl.read_log(out).to_pandas().to_numpy())
    with pytest.raises(biasctl.BiasctlError, match="sequence|nope"):
        biasctl.simulate("nope")


def test_a_nan_covariate_is_a_missing_value_as_an_empty_cell(cli, tmp_path):
    t = np.arange(5, dtype=float)
    track = np.array([10.0, 50, 20, 80, 30])
    bias = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    temp = np.array([20.0, np.nan, 21.0, 22.0, 23.0])
    log = biasctl.Log.from_arrays(t, track, bias, temp_c=temp)
    # Reference: the reader on the file pandas writes for the same frame (NaN: an empty cell).
    p = tmp_path / "gap.csv"
    pd.DataFrame({"time_s": t, "track": track, "bias": bias, "temp_c": temp}).to_csv(p, index=False)
    ref = biasctl.read_log(p)
    assert log.columns == ref.columns and log.notes == [n.replace(str(p), "<arrays>") for n in ref.notes]
    np.testing.assert_array_equal(log.to_pandas().to_numpy(), ref.to_pandas().to_numpy())


def test_messages_name_settings_by_the_keyword_that_sets_them(tmp_path, cli):
    # A rig's log: the CLI's hint names the flags, the package's the keywords, for the same
    # columns; the call the hint gives reads the log.
    p = tmp_path / "rig.csv"
    p.write_text("time_s,position_m,force_N\n0,1,2\n1,2,3\n2,3,4\n")
    with pytest.raises(biasctl.LogError) as e:
        biasctl.read_log(p)
    msg = str(e.value)
    assert 'track_col="position_m"' in msg and 'bias_col="force_N"' in msg, msg
    assert "ColumnMap::" not in msg, msg
    cli_err = cli.run("check", "--data", p, ok=False)
    assert cli_err.returncode == 2
    assert "--track-col position_m" in cli_err.stderr, cli_err.stderr
    log = biasctl.read_log(p, track_col="position_m", bias_col="force_N")
    assert len(log) == 3
    # A setting out of range: its keyword, not the library's field.
    with pytest.raises(biasctl.FitError) as e:
        biasctl.fit(log, "poly2", grid=2)
    assert "grid: 2 is not in" in str(e.value) and "FitOptions::" not in str(e.value), str(e.value)
    with pytest.raises(biasctl.SettleError) as e:
        biasctl.settle(window_um=-1.0)
    assert "window_um" in str(e.value) and "SettleSpec::" not in str(e.value), str(e.value)
