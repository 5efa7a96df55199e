#!/usr/bin/env bash
# Open time against model size: for each model, the median time to open it and trace one ray in
# a fresh process (examples/open_time.rs), hot (5 runs after a warm-up) and cold (3 runs, the
# model's pages dropped with posix_fadvise(DONTNEED) before each; nothing else is dropped), with
# lazy validation and, for comparison, full validation at open.
#
#   scripts/bench_open.sh RAYS MODEL...
#   scripts/bench_open.sh /work/big/one.rays /work/big/scan{1m,10m,30m,100m,300m}.rdm
set -euo pipefail
cd "$(dirname "$0")/.."
rays=$1
shift
cargo build --release --quiet --example open_time
bin=target/release/examples/open_time

drop_pages() {
    python3 -c "import os,sys; fd=os.open(sys.argv[1], os.O_RDONLY); os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED); os.close(fd)" "$1"
}
median() { sort -g | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'; }

printf "%-16s %9s %-5s | %12s %12s | %12s %12s\n" model GiB open "hot open ms" "hot trace ms" \
    "cold open ms" "cold trace ms"
for model in "$@"; do
    gib=$(awk -v b="$(stat -c %s "$model")" 'BEGIN { printf "%.2f", b / 2^30 }')
    for mode in lazy full; do
        flag=()
        [ "$mode" = full ] && flag=(--full)
        "$bin" "$model" --rays "$rays" "${flag[@]}" > /dev/null
        hot=$(for _ in 1 2 3 4 5; do "$bin" "$model" --rays "$rays" "${flag[@]}"; done)
        cold=$(for _ in 1 2 3; do drop_pages "$model"; "$bin" "$model" --rays "$rays" "${flag[@]}"; done)
        printf "%-16s %9s %-5s | %12s %12s | %12s %12s\n" "$(basename "$model")" "$gib" "$mode" \
            "$(cut -d' ' -f1 <<< "$hot" | median)" "$(cut -d' ' -f2 <<< "$hot" | median)" \
            "$(cut -d' ' -f1 <<< "$cold" | median)" "$(cut -d' ' -f2 <<< "$cold" | median)"
    done
done
