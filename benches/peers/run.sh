#!/usr/bin/env bash
# The peer harness of issue #16, one command: makes its own venv (pip only) with numpy, numba,
# polars and pandas, builds biasctl, runs biasctl's criterion benches and the peers in the same
# run, checks every peer against biasctl's output on a small input, and prints the ratio table
# of README's Benchmarks section. Optional; not part of `cargo test`. Takes ~10 min (more on a
# loaded machine). Criterion measures thread CPU time (BIASCTL_BENCH_CPU=1; the fit bench process
# CPU time, since its solve also runs on rayon's pool) in the benches built with `bench_main!`, and peers.py times their peers by CPU time too (see its docstring).
#   benches/peers/run.sh [--only dahl,handoff,read,fit,write]   (PEERS_VENV=dir: the venv elsewhere)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
venv=${PEERS_VENV:-$root/target/peers-venv}
work=$root/target/peers-work
cd "$root"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
"$venv/bin/pip" install -q -r "$here/requirements.txt"
cargo build --release --quiet
export BIASCTL_BENCH_CPU=1
crit=(-- --warm-up-time 1 --measurement-time 3 --sample-size 10)
cargo bench --quiet --features bench --bench dahl "${crit[@]}" 'dahl/(predictor|step_many)_1M_seeks'
cargo bench --quiet --features bench --bench handoff "${crit[@]}" 'handoff/(solve|bounds_into)/64$'
cargo bench --quiet --features bench --bench read "${crit[@]}" 'read/check_summarise_1M_rows'
# the fit factorises row chunks on rayon's pool too: count every thread's CPU time
BIASCTL_BENCH_CPU=process cargo bench --quiet --features bench --bench fit "${crit[@]}"
cargo bench --quiet --features bench --bench predict "${crit[@]}" 'predict/replay_and_write_1M_rows'
"$venv/bin/python" "$here/peers.py" --root "$root" --exe "$root/target/release/biasctl" --work "$work" "$@"
