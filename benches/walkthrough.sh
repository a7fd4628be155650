#!/usr/bin/env bash
# The README's first walk-through timed step by step on a family drive's log (6,000 seeks by
# default; `examples/family_log.rs`, the log `benches/loop.sh` times): `check`, `fit --model
# position-direction`, `score`, `diagnose` (verified, the default), `discover --start
# position-direction` and `report` of the model discover ends with. Each figure is the best of
# REPS runs, in wall time and in CPU time (user + system, every thread).
#   benches/walkthrough.sh [SEEKS] [REPS]        (BIASCTL=path: an already built binary)
# Prints the table and writes it to target/walkthrough-bench.md. Not part of `cargo test`.
set -euo pipefail
seeks=${1:-6000}
reps=${2:-3}
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
# shellcheck source=benches/common/family_log.sh
source "$root/benches/common/family_log.sh" walkthrough-bench

out=$root/target/walkthrough-bench.md
{
    echo "| step | command | wall | CPU |"
    echo "|---|---|---|---|"
} >"$out"
row() {
    local step=$1 name=$2
    shift 2
    read -r w c <<<"$(best "$@")"
    printf '| %s | `%s` | %s s | %s s |\n' "$step" "$name" "$w" "$c" >>"$out"
}
pd=$work/pd.json
"$BIASCTL" fit --data "$log" --model position-direction --out "$pd" >/dev/null 2>&1
"$BIASCTL" discover --data "$log" --start position-direction --out "$work/disc" >/dev/null 2>&1
row 1 check "$BIASCTL" check --data "$log"
row 2 "fit --model position-direction" "$BIASCTL" fit --data "$log" --model position-direction --out "$pd"
row 2 score "$BIASCTL" score --model "$pd" --data "$log"
row 3 diagnose "$BIASCTL" diagnose --model "$pd" --data "$log"
row 4 "discover --start position-direction" "$BIASCTL" discover --data "$log" \
    --start position-direction --out "$work/disc"
row 5 report "$BIASCTL" report --data "$log" --model "$work/disc/model.json" --out "$work/out"
echo "($seeks seeks, best of $reps runs each; CPU = user + system of every thread; $(nproc) cores, load $(cut -d' ' -f1 /proc/loadavg))" >>"$out"
cat "$out"
