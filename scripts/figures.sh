#!/usr/bin/env bash
# Redraws the README's figures (docs/figures/*.svg) from the built-in drive, seed 1: the demo's
# report, then `biasctl plot` for each figure. The list of figures and their commands lives in
# one place, the test that keeps them current (tests/it/report.rs, readme_figures_are_current);
# this runs it in update mode. Deterministic: the same build gives byte-identical SVGs.
set -euo pipefail
cd "$(dirname "$0")/.."
BIASCTL_UPDATE_FIGURES=1 cargo test --quiet --test it readme_figures_are_current
git status --short docs/figures
