#!/usr/bin/env bash
# Regenerates the README's figures (docs/figures/*.svg) from the built-in drive, seed 1:
# `biasctl report` simulates and fits exactly what `demo` does, then `biasctl plot` draws each
# figure from the files it wrote. Deterministic: the same build gives byte-identical SVGs.
#   scripts/figures.sh            # from anywhere in the repository
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
cargo build --release --quiet
B="$root/target/release/biasctl"
out="$root/docs/figures"
mkdir -p "$out"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work" # figure titles name the files relative to here
"$B" report --out . --seed 1 >/dev/null
"$B" plot position --data table1.csv --model model_position-direction.json --out "$out/fig03_table1.svg"
"$B" plot time --data dwell.csv --out "$out/fig04_time_at_track.svg"
"$B" plot seek --data table3.csv --out "$out/fig06_table3.svg"
"$B" plot errors --data random.csv --model model_position-direction.json,model_calibration.json \
    --out "$out/fig10_11_errors.svg"
"$B" plot loop --data table2.csv --model model_dahl.json --out "$out/fig13_14_dahl_loop.svg"
"$B" plot ladder --data calibration.csv --test random.csv --terms poly2,direction,seek,memory,drift \
    --out "$out/ladder.svg"
"$B" plot bounds --preset paper1997 --bias-uncertainty 8 --out "$out/fig15_bounds.svg"
"$B" plot responses --preset paper1997 --bias-uncertainty 8 --out "$out/fig16_responses.svg"
