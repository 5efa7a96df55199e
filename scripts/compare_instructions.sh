#!/usr/bin/env bash
# Whole-process instructions (callgrind, 1 thread) of two `reducem` binaries answering the same
# 100k camera-like and 100k AO-like rays on one model, per kernel: a repeatable comparison of two
# versions of the tracer on a busy machine, where wall-clock times are not.
#
#   scripts/compare_instructions.sh OLD/reducem NEW/reducem MODEL.ply MODEL.rdm [NEW_MODEL.rdm]
#
# MODEL.ply is the mesh MODEL.rdm was converted from (its vertices place the rays). NEW_MODEL.rdm,
# when given, is what the new binary answers on (the same mesh converted by it, e.g. in a newer
# format). The answers of both binaries are compared byte for byte.
#
# The AO-like rays start at random vertices in random directions, spread over the whole model.
# AO_RAYS=FILE takes the first 100k rays of a ray file instead, e.g. scripts/bench_trace.sh's
# rays-scan-N/ao.rays (16 per camera hit, neighbours in origin): the two sets have ranked walk
# variants differently, so a tracer change should be measured on both.
set -euo pipefail
old=$1 new=$2 ply=$3 model=$4 new_model=${5:-$4}
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
python3 - "$ply" "$dir/camera.rays" "$dir/ao.rays" <<'PY'
import math, random, struct, sys
ply, camera_path, ao_path = sys.argv[1:4]
data = open(ply, "rb").read()
end = data.index(b"end_header\n") + len(b"end_header\n")
count = int(data.split(b"element vertex ")[1].split(b"\n")[0])
points = struct.unpack_from("<%df" % (3 * count), data, end)
low = [min(points[a::3]) for a in range(3)]
high = [max(points[a::3]) for a in range(3)]
centre = [(l + h) / 2 for l, h in zip(low, high)]
diagonal = math.dist(low, high)
eye = [centre[0] + diagonal, centre[1] + 0.8 * diagonal, centre[2] + 1.2 * diagonal]
forward = [c - e for c, e in zip(centre, eye)]
with open(camera_path, "wb") as out:
    side = 316
    for y in range(side):
        for x in range(side):
            u, v = (x / side - 0.5) * 0.6, (y / side - 0.5) * 0.6
            direction = [forward[0] + u * diagonal, forward[1] + (0.3 * v - u) * diagonal,
                         forward[2] + v * diagonal]
            out.write(struct.pack("<8f", *eye, *direction, 0.0, float("inf")))
rng = random.Random(7)
with open(ao_path, "wb") as out:
    for _ in range(100000):
        i = rng.randrange(count)
        while True:
            direction = [rng.uniform(-1, 1) for _ in range(3)]
            if 0 < sum(d * d for d in direction) <= 1:
                break
        out.write(struct.pack("<8f", *points[3 * i:3 * i + 3], *direction,
                              1e-4 * diagonal, 0.05 * diagonal))
PY
if [[ -n ${AO_RAYS-} ]]; then
    head -c $((100000 * 32)) "$AO_RAYS" > "$dir/ao.rays"
fi
instructions() {
    local binary=$1 model=$2 kernel=$3 rays=$4 answers=$5
    shift 5
    REDUCEM_KERNEL=$kernel RAYON_NUM_THREADS=1 valgrind --tool=callgrind \
        --callgrind-out-file=/dev/null "$binary" query "$model" --rays "$dir/$rays.rays" \
        -o "$answers" "$@" 2>&1 | sed -n 's/.*Collected : \([0-9]*\).*/\1/p'
}
echo "kernel rays old new change"
for kernel in avx2 sse2; do
    for rays in camera ao; do
        flag=()
        [[ $rays == ao ]] && flag=(--occluded)
        a=$(instructions "$old" "$model" "$kernel" "$rays" "$dir/old.out" "${flag[@]}")
        b=$(instructions "$new" "$new_model" "$kernel" "$rays" "$dir/new.out" "${flag[@]}")
        cmp -s "$dir/old.out" "$dir/new.out" || { echo "answers differ ($kernel, $rays)" >&2; exit 1; }
        awk -v k="$kernel" -v r="$rays" -v a="$a" -v b="$b" \
            'BEGIN { printf "%s %s %d %d %+.1f%%\n", k, r, a, b, 100 * (b - a) / a }'
    done
done
