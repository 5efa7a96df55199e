#!/usr/bin/env bash
# Peak memory of `reducem render` at the documented largest image (16384 x 16384) on a small
# model: maximum resident set size by /usr/bin/time -v, for PNG (the encoder holds the 8-bit
# image and its compressed copy) and PFM (written band by band as it is rendered), next to a
# 1024 x 1024 render for the part that does not grow with the image.
#
#   scripts/bench_render_memory.sh [WORK_DIR]     (default target/bench-render-memory)
set -euo pipefail
cd "$(dirname "$0")/.."
work=${1:-target/bench-render-memory}
mkdir -p "$work"
cargo build --release -p reducem -p pipeline --bins --quiet
bin=target/release
model=$work/sphere.rdm
if [[ ! -f $model ]]; then
    "$bin/pipeline" gen sphere --triangles 20000 -o "$work/sphere.ply"
    "$bin/pipeline" convert "$work/sphere.ply" -o "$model" --log-format plain 2>/dev/null
fi
scene=$work/scene.toml
printf '[image]\nwidth = 64\nheight = 64\n[camera]\nauto = true\n' > "$scene"

printf "%-12s %-4s %14s %10s %14s\n" size format "peak RSS MiB" seconds "image bytes"
for size in 1024 16384; do
    for format in png pfm; do
        image=$work/image.$format
        report=$( { /usr/bin/time -v "$bin/reducem" render "$model" --scene "$scene" \
            --width "$size" --height "$size" -o "$image" > /dev/null; } 2>&1 )
        kib=$(awk -F': ' '/Maximum resident set size/ { print $2 }' <<< "$report")
        wall=$(awk -F': ' '/Elapsed \(wall clock\)/ { print $2 }' <<< "$report")
        printf "%-12s %-4s %14.1f %10s %14s\n" "${size}x$size" "$format" \
            "$(awk -v k="$kib" 'BEGIN { print k / 1024 }')" "$wall" "$(stat -c %s "$image")"
        rm -f "$image"
    done
done
