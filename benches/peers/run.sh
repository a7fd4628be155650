#!/usr/bin/env bash
# The peer harness, one command: makes its own venv (pip only) with numpy, numba,
# polars and pandas, builds biasctl, runs biasctl's criterion benches and the peers in the same
# run, checks every peer against biasctl's output on a small input, and prints the ratio table
# of README's Benchmarks section. Optional; not part of `cargo test`. Takes ~10 min (more on a
# loaded machine). Criterion measures thread CPU time (BIASCTL_BENCH_CPU=1; the fit and predict benches
# process CPU time, since fit's solve also runs on rayon's pool and predict formats on a second thread) in the benches built with `bench_main!`, and peers.py times their peers by CPU time too (see its docstring).
#   benches/peers/run.sh [--only dahl,handoff,read,fit,write]   (PEERS_VENV=dir: the venv elsewhere)
# `--only` selects the sections: only their criterion benches run, then only their peers.
set -euo pipefail
sections=dahl,handoff,read,fit,write
only=$sections
args=("$@")
while [ $# -gt 0 ]; do
    case $1 in
        --only) only=${2:?--only needs a list, e.g. --only read,fit}; shift 2 ;;
        --only=*) only=${1#--only=}; shift ;;
        *) shift ;;
    esac
done
IFS=, read -r -a picked <<<"$only"
for s in "${picked[@]}"; do
    case ",$sections," in
        *",$s,"*) ;;
        *) echo "run.sh: --only: unknown section \`$s\` (sections: $sections)" >&2; exit 2 ;;
    esac
done
# Whether section $1 was picked.
picked() { case ",$only," in *",$1,"*) return 0 ;; *) return 1 ;; esac; }
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
if picked dahl; then
    cargo bench --quiet --features bench --bench dahl "${crit[@]}" 'dahl/(predictor|step_many)_1M_seeks'
fi
if picked handoff; then
    cargo bench --quiet --features bench --bench handoff "${crit[@]}" 'handoff/(solve|bounds_into)/64$'
fi
if picked read; then
    cargo bench --quiet --features bench --bench read "${crit[@]}" 'read/check_summarise_1M_rows'
fi
if picked fit; then
    # the fit factorises row chunks on rayon's pool too: count every thread's CPU time
    BIASCTL_BENCH_CPU=process cargo bench --quiet --features bench --bench fit "${crit[@]}"
fi
if picked write; then
    # predict formats its rows on a second thread: count every thread's CPU time
    BIASCTL_BENCH_CPU=process cargo bench --quiet --features bench --bench predict "${crit[@]}" 'predict/replay_and_write_1M_rows'
fi
"$venv/bin/python" "$here/peers.py" --root "$root" --exe "$root/target/release/biasctl" --work "$work" "${args[@]}"
