"""Fit, the model file, predict, score, the online predictor and the C export, each against
the `biasctl` binary's output on the same files."""

from __future__ import annotations

import json
import pickle

import numpy as np
import pandas as pd
import pytest

import biasctl


def _assert_frames_close(got: pd.DataFrame, want: pd.DataFrame, rtol=1e-12):
    assert list(got.columns) == list(want.columns)
    assert len(got) == len(want)
    for c in want.columns:
        a = got[c].to_numpy(dtype=float)
        b = want[c].to_numpy(dtype=float)
        np.testing.assert_array_equal(np.isnan(a), np.isnan(b), err_msg=c)
        np.testing.assert_allclose(a, b, rtol=rtol, atol=0, equal_nan=True, err_msg=c)


@pytest.mark.parametrize("terms", ["poly2,direction", "calibration", ["poly2", "dahl:4"]])
def test_fit_writes_the_cli_model_file_byte_for_byte(data, cli, tmp_path, terms):
    out = tmp_path / "m.json"
    flag = ["--model", terms] if terms == "calibration" else [
        "--terms", terms if isinstance(terms, str) else ",".join(terms)]
    cli.run("fit", "--data", data / "train.csv", *flag, "--out", out)
    m = biasctl.fit(biasctl.read_log(data / "train.csv"), terms)
    assert m.to_json() == out.read_text()


def test_fit_options_match_the_cli_flags(data, cli, tmp_path):
    out = tmp_path / "m.json"
    cli.run("fit", "--data", data / "train.csv", "--terms", "poly2,direction", "--deadband", "2",
            "--out", out)
    m = biasctl.fit(biasctl.read_log(data / "train.csv"), "poly2,direction", deadband=2.0)
    assert m.to_json() == out.read_text()


def test_json_and_pickle_round_trip_bit_for_bit(data):
    m = biasctl.fit(biasctl.read_log(data / "train.csv"), "poly2,direction,dahl:4")
    text = m.to_json()
    again = biasctl.Model.from_json(text)
    assert again.to_json() == text
    p = pickle.loads(pickle.dumps(m))
    assert p.to_json() == text and p == m
    test = biasctl.read_log(data / "test.csv")
    _assert_frames_close(p.predict(test), m.predict(test), rtol=0)


def test_terms_params_and_warnings(data, model_file):
    m = biasctl.Model.load(model_file)
    assert m.terms == ["poly2", "direction"]
    p = m.params
    assert list(p.columns) == ["term", "name", "value", "std_error", "identifiable"]
    ref = json.loads(model_file.read_text())
    want = [(t["term"], q["name"], q["value"]) for t in ref["terms"] for q in t["params"]]
    assert list(zip(p.term, p.name, p.value)) == want
    assert p.identifiable.dtype == bool
    assert isinstance(m.warnings, list)


@pytest.mark.parametrize("which", ["test.csv", "plan.csv"])
def test_predict_equals_cli_predict_out(data, cli, model_file, tmp_path, which):
    out = tmp_path / "pred.csv"
    cli.run("predict", "--model", model_file, "--data", data / which, "--out", out)
    want = pd.read_csv(out, comment="#")
    got = biasctl.Model.load(model_file).predict(biasctl.read_log(data / which))
    _assert_frames_close(got, want)


def test_predict_handoff_adds_the_integrator_start(data, cli, model_file, tmp_path):
    out = tmp_path / "pred.csv"
    cli.run("predict", "--model", model_file, "--data", data / "test.csv", "--handoff",
            "paper1997", "--out", out)
    want = pd.read_csv(out, comment="#")
    m = biasctl.Model.load(model_file)
    got = m.predict(biasctl.read_log(data / "test.csv"), handoff=True)
    assert "integrator_start" in got.columns
    _assert_frames_close(got, want)
    cli.run("predict", "--model", model_file, "--data", data / "test.csv", "--handoff",
            "modern", "--bias-uncertainty", "3", "--out", out)
    got = m.predict(biasctl.read_log(data / "test.csv"), handoff="modern", bias_uncertainty=3)
    _assert_frames_close(got, pd.read_csv(out, comment="#"))


def test_score_equals_cli_score_json(data, cli, model_file):
    want = cli.json("score", "--model", model_file, "--data", data / "test.csv", "--json")
    got = biasctl.Model.load(model_file).score(biasctl.read_log(data / "test.csv"))
    assert got == want


def test_score_of_an_adaptive_model_with_feedback(data, cli, tmp_path):
    mf = tmp_path / "drift.json"
    cli.run("fit", "--data", data / "train.csv", "--terms", "poly2,direction,drift", "--out", mf)
    want = cli.json("score", "--model", mf, "--data", data / "test.csv", "--json",
                    "--feedback-every", "5")
    got = biasctl.Model.load(mf).score(biasctl.read_log(data / "test.csv"), feedback_every=5)
    assert got == want


def test_predictor_steps_equal_the_replay(data, model_file):
    m = biasctl.Model.load(model_file)
    log = biasctl.read_log(data / "test.csv")
    pred = m.predict(log)
    p = m.predictor()
    df = log.to_pandas()
    got = []
    for t, x, b in zip(df.time_s, df.track, df.bias):
        peek = p.peek(x, t)
        got.append(p.step(x, t, None if np.isnan(b) else b))
        assert peek == got[-1]
    np.testing.assert_array_equal(np.array(got), pred.predicted.to_numpy())


@pytest.mark.parametrize(
    "kwargs, flags",
    [({"float32": True}, ["--float32"]), ({"handoff": "paper1997"}, ["--handoff", "paper1997"])],
)
def test_export_c_writes_the_cli_files(model_file, cli, tmp_path, kwargs, flags):
    a, b = tmp_path / "py", tmp_path / "cli"
    files = biasctl.Model.load(model_file).export_c(a, **kwargs)
    cli.run("export", "c", "--model", model_file, "--out", b, *flags)
    assert sorted(p.rsplit("/", 1)[-1] for p in files) == ["bias_model.c", "bias_model.h", "replay.c"]
    for name in ("bias_model.c", "bias_model.h", "replay.c"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


def test_a_model_from_another_log_is_refused(tmp_path):
    t = np.arange(40, dtype=float)
    track = (np.arange(40) * 37 % 200).astype(float)
    rng = np.random.default_rng(1)
    temp = 20 + rng.random(40)
    bias = 3 + 0.01 * track + 2 * temp + rng.normal(0, 0.1, 40)
    m = biasctl.fit(biasctl.Log.from_arrays(t, track, bias, temp_c=temp), "poly2,col:temp_c")
    other = biasctl.Log.from_arrays(t, track, bias)
    with pytest.raises(biasctl.ModelError, match="temp_c"):
        m.predict(other)
    with pytest.raises(biasctl.ModelError, match="temp_c"):
        m.score(other)
    with pytest.raises(biasctl.ModelError):
        m.predictor().step(1.0, 0.0)  # the covariate is missing


@pytest.mark.parametrize(
    "call, exc, match",
    [
        (lambda log: biasctl.fit(log, "nonsense_term"), biasctl.ModelError, "nonsense_term"),
        (lambda log: biasctl.fit(log, 42), biasctl.ModelError, "term"),
        (lambda log: biasctl.fit(log, "poly2", deadband=-1.0), biasctl.BiasctlError, "eadband"),
        (lambda log: biasctl.fit(log, "poly2", deadband=1.0, velocity_col="v"), biasctl.FitError, "not both"),
        (lambda log: biasctl.fit(log, "poly2", bogus=1), biasctl.FitError, "bogus"),
        (lambda log: biasctl.fit(log, "poly2", threads=0), biasctl.BiasctlError, "thread"),
        (lambda log: biasctl.fit("train.csv", "poly2"), biasctl.LogError, "biasctl.Log"),
        (lambda log: biasctl.Model.from_json("{}"), biasctl.ModelError, "format"),
        (lambda log: biasctl.Model.from_json("not json"), biasctl.ModelError, "<json>"),
        (lambda log: biasctl.fit(log, "poly2").predict(log, handoff="nowhere"), biasctl.SettleError, "nowhere"),
    ],
)
def test_error_paths(data, call, exc, match):
    log = biasctl.read_log(data / "train.csv")
    with pytest.raises(exc, match=match):
        call(log)


def test_a_panic_is_raised_as_biasctl_error():
    from biasctl import _biasctl

    with pytest.raises(biasctl.BiasctlError, match="internal error"):
        _biasctl._panic()


def test_units_for_a_model_as_the_cli_takes_them(data, cli, tmp_path):
    """A model fitted with a bias unit keeps it on a log whose unit came from the column name;
    a unit given that differs from the model's is refused, as the CLI refuses it."""
    src = (data / "train.csv").read_text().splitlines()
    body = [l for l in src if not l.startswith("#")]
    p = tmp_path / "force.csv"
    p.write_text("\n".join(body).replace("time_s,track,bias", "time_s,track,force") + "\n")
    mf = tmp_path / "m.json"
    cli.run("fit", "--data", p, "--bias-col", "force", "--bias-unit", "N", "--terms",
            "poly2,direction", "--out", mf)
    m = biasctl.fit(biasctl.read_log(p, bias_col="force", bias_unit="N"), "poly2,direction")
    assert m.to_json() == mf.read_text()
    log = biasctl.read_log(p, bias_col="force")
    want = cli.json("score", "--model", mf, "--data", p, "--bias-col", "force", "--json")
    got = m.score(log)
    assert got == want and got["units"]["bias"] == "N"
    back = pickle.loads(pickle.dumps(log))
    assert m.score(back) == want
    bad = cli.run("score", "--model", mf, "--data", p, "--bias-col", "force", "--bias-unit",
                  "mA", "--json", ok=False)
    assert bad.returncode == 2
    with pytest.raises(biasctl.ModelError, match="mA"):
        m.score(biasctl.read_log(p, bias_col="force", bias_unit="mA"))
    with pytest.raises(biasctl.ModelError, match="mA"):
        m.predict(biasctl.read_log(p, bias_col="force", bias_unit="mA"))


def test_a_log_written_by_to_csv_fits_in_the_cli_as_in_python(cli, tmp_path):
    """Log.to_csv: the file the CLI reads gives the model Python fits on the log itself."""
    rng = np.random.default_rng(4)
    t = np.arange(300, dtype=float) * 0.5
    track = rng.integers(0, 3000, 300).astype(float)
    temp = 20 + rng.random(300)
    bias = 3 + 0.01 * track + 2 * temp + rng.normal(0, 0.1, 300)
    log = biasctl.Log.from_arrays(t, track, bias, temp_c=temp)
    p = tmp_path / "log.csv"
    log.to_csv(p)
    out = tmp_path / "m.json"
    cli.run("fit", "--data", p, "--terms", "poly2,col:temp_c", "--out", out)
    m = biasctl.fit(log, "poly2,col:temp_c")
    assert m.to_json() == out.read_text()
