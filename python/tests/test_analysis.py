"""Diagnose, discover, ladder and settle: each equal to the `biasctl` binary's JSON."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import biasctl


@pytest.fixture(scope="module")
def logs(data):
    return biasctl.read_log(data / "train.csv"), biasctl.read_log(data / "test.csv")


@pytest.mark.parametrize("verify", [True, False])
def test_diagnose_equals_cli_diagnose_json(data, cli, model_file, logs, verify):
    args = ["diagnose", "--model", model_file, "--data", data / "test.csv", "--json"]
    want = cli.json(*args, *([] if verify else ["--no-verify"]))
    d = biasctl.Model.load(model_file).diagnose(logs[1], verify=verify)
    assert d.to_dict() == want
    feats = d.features
    assert isinstance(feats, pd.DataFrame)
    assert list(feats.name) == [f["name"] for f in want["features"]]
    assert d.summary == want["summary"]
    if verify:
        v = want["verification"]
        best = v["edits"][0] if v["edits"] and v["edits"][0]["verified"] else None
        assert d.best_edit == (best["terms"] if best else None)
    else:
        assert d.best_edit is None


def test_diagnose_settings_match_the_cli_flags(data, cli, model_file, logs):
    want = cli.json("diagnose", "--model", model_file, "--data", data / "test.csv", "--json",
                    "--seed", "7", "--alpha", "0.05", "--permutations", "99", "--folds", "4",
                    "--verify-folds", "4")
    d = biasctl.Model.load(model_file).diagnose(
        logs[1], seed=7, alpha=0.05, permutations=99, folds=4, verify_folds=4)
    assert d.to_dict() == want


def test_best_edit_refits_and_lowers_the_error(model_file, logs):
    train, test = logs
    m = biasctl.Model.load(model_file)
    d = m.diagnose(test)
    assert d.best_edit is not None, d.summary
    better = biasctl.fit(train, d.best_edit)
    assert better.score(test)["std"] < m.score(test)["std"]


def test_plot_and_html(model_file, logs):
    import matplotlib

    matplotlib.use("Agg")
    d = biasctl.Model.load(model_file).diagnose(logs[1], verify=False)
    ax = d.plot()
    lead = d.to_dict()["features"][0]["name"]
    assert ax.get_xlabel() == lead
    x, r = ax.collections[0].get_offsets().T
    assert len(x) > 100 and np.isfinite(r).all()
    html = d._repr_html_()
    assert "<svg" in html and "<table>" in html and lead in html


def test_bad_diagnose_settings(model_file, logs):
    m = biasctl.Model.load(model_file)
    with pytest.raises(biasctl.BiasctlError, match="alpha"):
        m.diagnose(logs[1], alpha=2.0)
    with pytest.raises(biasctl.BiasctlError, match="olds"):
        m.diagnose(logs[1], folds=1)


def test_discover_equals_cli_discover_json(data, cli, logs):
    want = cli.json("discover", "--data", data / "train.csv", "--test", data / "test.csv",
                    "--max-steps", "2", "--json")
    d = biasctl.discover(logs[0], test=logs[1], max_steps=2)
    assert d.to_dict() == want
    assert d.model.terms[: len(want["final_terms"])] == want["final_terms"] or \
        d.model.spec == ",".join(want["final_terms"])
    assert str(d).strip()


def test_discover_from_a_model_file_and_a_preset(data, cli, model_file, logs):
    want = cli.json("discover", "--data", data / "train.csv", "--start", model_file,
                    "--max-steps", "1", "--json")
    assert biasctl.discover(logs[0], start=model_file, max_steps=1).to_dict() == want
    assert biasctl.discover(logs[0], start=biasctl.Model.load(model_file), max_steps=1).to_dict() == want


def test_ladder_equals_cli_ladder_json(data, cli, logs):
    want = cli.json("ladder", "--data", data / "train.csv", "--test", data / "test.csv",
                    "--terms", "poly2,direction,dahl:4", "--json")
    df = biasctl.ladder(logs[0], logs[1], ["poly2", "direction", "dahl:4"])
    assert biasctl.ladder_json(logs[0], logs[1], "poly2,direction,dahl:4") == want
    assert df.to_dict("records") == want["steps"]


@pytest.mark.parametrize(
    "kwargs, flags",
    [
        ({}, []),
        ({"preset": "modern"}, ["--preset", "modern"]),
        ({"step_um": 30.0, "window_um": 0.4, "bias": 5, "bias_uncertainty": 2, "horizon": 200,
          "hold": 3},
         ["--step-um", "30", "--window-um", "0.4", "--bias", "5", "--bias-uncertainty", "2",
          "--horizon", "200", "--hold", "3"]),
    ],
)
def test_settle_equals_cli_settle_json(cli, kwargs, flags):
    assert biasctl.settle(**kwargs) == cli.json("settle", "--json", *flags)


def test_settle_plant_file(cli):
    from conftest import REPO

    plant = REPO / "data" / "plant_modern.toml"
    assert biasctl.settle(plant=plant) == cli.json("settle", "--json", "--plant", plant)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"preset": "nope"}, "nope"),
        ({"window_um": -1.0}, "window_um"),
        ({"horizon": 0}, "horizon"),
        ({"stepum": 3}, "stepum"),
        ({"step_um": "far"}, "far"),
        ({"plant": "/nonexistent/plant.toml"}, "plant.toml"),
    ],
)
def test_settle_errors_name_the_setting(kwargs, match):
    with pytest.raises(biasctl.SettleError, match=match):
        biasctl.settle(**kwargs)


def test_discovery_model_is_the_cli_fit_of_the_final_terms(data, cli, logs, tmp_path):
    """Discovery.model: the model `biasctl fit` writes for discover's final term list."""
    d = biasctl.discover(logs[0], test=logs[1], max_steps=2)
    out = tmp_path / "final.json"
    cli.run("fit", "--data", data / "train.csv", "--terms", ",".join(d.final_terms), "--out", out)
    assert d.model.to_json() == out.read_text()
