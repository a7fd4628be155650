# Sourced by benches/loop.sh and benches/walkthrough.sh: builds biasctl and the family-log
# generator (unless BIASCTL names an already built binary), writes a family drive's log of
# $seeks seeks (`examples/family_log.rs`: the `bw-sine-t` member, a lagged-temperature effect,
# three decoy columns) as $log in $work (target/$1), and defines `best`.
# Needs: $root (the repository), $seeks, $reps; the work folder's name as $1.
gen=$root/target/release/examples/family_log
if [ -z "${BIASCTL:-}" ]; then
    cargo build --release --quiet --bin biasctl --example family_log
    BIASCTL=$root/target/release/biasctl
elif [ ! -x "$gen" ]; then
    cargo build --release --quiet --example family_log
fi
work=$root/target/$1
mkdir -p "$work"
log=$work/family_$seeks.csv
"$gen" "$log" "$seeks" 7 lag

# "WALL CPU": the best wall and the best CPU seconds (ms resolution) of $reps runs of the command.
best() {
    local bw="" bc="" w c t
    for _ in $(seq "$reps"); do
        t=$( { TIMEFORMAT='%3R %3U %3S'; time "$@" >/dev/null 2>&1; } 2>&1 ) ||
            { echo "failed: $*" >&2; exit 1; }
        read -r w u s <<<"$t"
        c=$(echo "$u + $s" | bc -l)
        if [ -z "$bw" ] || [ "$(echo "$w < $bw" | bc -l)" = 1 ]; then bw=$w; fi
        if [ -z "$bc" ] || [ "$(echo "$c < $bc" | bc -l)" = 1 ]; then bc=$c; fi
    done
    printf '%.3f %.3f\n' "$bw" "$bc"
}
