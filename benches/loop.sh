#!/usr/bin/env bash
# The loop's commands timed against the comparisons of the speed goals, in one run: on a family
# drive's log (6,000 seeks by default, with a lagged-temperature effect and three decoy columns;
# `examples/family_log.rs`), for `calibration` and the rich model: `fit`, `diagnose --no-verify`
# (the screen) and `diagnose` (verified, the default), and the ratio
# verified / (screen + fit) (goal ≤ 3); and `fit` of the rich model against
# `fit --terms poly2,direction` (goal ≤ 25). Each figure is the best of REPS runs, in wall time
# and in CPU time (user + system, every thread: on a shared machine the wait for a core is
# not the command's).
#   benches/loop.sh [SEEKS] [REPS]        (BIASCTL=path: an already built binary)
# Prints the table and writes it to target/loop-bench.md. Not part of `cargo test`.
set -euo pipefail
seeks=${1:-6000}
reps=${2:-3}
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
# shellcheck source=benches/common/family_log.sh
source "$root/benches/common/family_log.sh" loop-bench
# NUM / DEN to one decimal ("n/a" where DEN is 0).
ratio() {
    if [ "$(echo "$2 > 0" | bc -l)" = 1 ]; then printf '%.1f' "$(echo "$1 / $2" | bc -l)"; else echo n/a; fi
}

out=$root/target/loop-bench.md
{
    echo "| model | fit | diagnose --no-verify | diagnose | diagnose / (screen + fit) |"
    echo "|---|---|---|---|---|"
} >"$out"
declare -A fitw fitc
for m in "poly2,direction" calibration "table,direction,seek,memory,drift,dahl:4,memsum,play:8"; do
    if [[ "$m" == *,* ]]; then sel=(--terms "$m"); else sel=(--model "$m"); fi
    model=$work/model_$(echo "$m" | tr ',:' '__').json
    "$BIASCTL" fit --data "$log" "${sel[@]}" --out "$model" >/dev/null 2>&1
    read -r fw fc <<<"$(best "$BIASCTL" fit --data "$log" "${sel[@]}" --out "$work/refit.json")"
    fitw[$m]=$fw
    fitc[$m]=$fc
    [ "$m" = "poly2,direction" ] && continue
    read -r sw sc <<<"$(best "$BIASCTL" diagnose --model "$model" --data "$log" --no-verify --json)"
    read -r dw dc <<<"$(best "$BIASCTL" diagnose --model "$model" --data "$log" --json)"
    printf '| `%s` | %s s wall, %s s CPU | %s / %s | %s / %s | **%s× wall, %s× CPU** |\n' \
        "$m" "$fw" "$fc" "$sw" "$sc" "$dw" "$dc" \
        "$(ratio "$dw" "$sw + $fw")" "$(ratio "$dc" "$sc + $fc")" >>"$out"
done
rich="table,direction,seek,memory,drift,dahl:4,memsum,play:8"
base="poly2,direction"
printf '\n`fit` of the rich model / `fit --terms poly2,direction` (%s s wall, %s s CPU): **%s× wall, %s× CPU** (goal ≤ 25×)\n' \
    "${fitw[$base]}" "${fitc[$base]}" "$(ratio "${fitw[$rich]}" "${fitw[$base]}")" \
    "$(ratio "${fitc[$rich]}" "${fitc[$base]}")" >>"$out"
echo "($seeks seeks, best of $reps runs each; CPU = user + system of every thread; $(nproc) cores, load $(cut -d' ' -f1 /proc/loadavg))" >>"$out"
cat "$out"
