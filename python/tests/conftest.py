"""Shared fixtures: the `biasctl` binary (the reference every test compares with) and logs it
simulated, made once per session."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _binary() -> str:
    env = os.environ.get("BIASCTL_BIN")
    if env:
        return env
    # The newest build of this checkout (a stale release build must not be the reference).
    built = [REPO / "target" / profile / "biasctl" for profile in ("release", "debug")]
    built = [p for p in built if p.is_file()]
    if built:
        return str(max(built, key=lambda p: p.stat().st_mtime))
    found = shutil.which("biasctl")
    if found:
        return found
    raise RuntimeError(
        "no biasctl binary: set BIASCTL_BIN or run `cargo build` in the repository first"
    )


class Cli:
    """Runs the `biasctl` binary."""

    def __init__(self, path: str) -> None:
        self.path = path

    def run(self, *args: str | os.PathLike, ok: bool = True) -> subprocess.CompletedProcess:
        p = subprocess.run(
            [self.path, *map(str, args)], capture_output=True, text=True, timeout=600
        )
        if ok and p.returncode != 0:
            raise AssertionError(f"biasctl {' '.join(map(str, args))} failed: {p.stderr}")
        return p

    def json(self, *args: str | os.PathLike) -> dict:
        return json.loads(self.run(*args).stdout)


@pytest.fixture(scope="session")
def cli() -> Cli:
    return Cli(_binary())


@pytest.fixture(scope="session")
def data(tmp_path_factory, cli) -> Path:
    """Logs the CLI simulated: train/test random runs (600 seeks, seeds 1 and 2), a test run's
    truth, a calibration run, and a plan (a log without its bias column)."""
    d = tmp_path_factory.mktemp("data")
    cli.run("simulate", "--sequence", "random", "--n", "600", "--seed", "1", "--out", d / "train.csv")
    cli.run(
        "simulate", "--sequence", "random", "--n", "600", "--seed", "2",
        "--out", d / "test.csv", "--truth", d / "test_truth.csv",
    )
    cli.run("simulate", "--sequence", "table1", "--seed", "3", "--out", d / "table1.csv")
    lines = (d / "test.csv").read_text().splitlines()
    plan = []
    for line in lines:
        if line.startswith("#"):
            plan.append(line)
            continue
        cells = line.split(",")
        plan.append(",".join(cells[:2] + cells[3:]))
    (d / "plan.csv").write_text("\n".join(plan) + "\n")
    return d


@pytest.fixture(scope="session")
def model_file(data, cli) -> Path:
    """`poly2,direction` fitted by the CLI on train.csv."""
    p = data / "model.json"
    cli.run("fit", "--data", data / "train.csv", "--terms", "poly2,direction", "--out", p)
    return p
