#!/usr/bin/env bash
# The workspace on aarch64, cross-built on x86-64 and run under qemu-aarch64 (no ARM machine
# needed): the reducem-core tests, then a generated mesh converted and queried by the ARM
# binaries, every output compared byte for byte with the x86-64 binaries' own.
#
# Needs the Debian packages gcc-aarch64-linux-gnu, g++-aarch64-linux-gnu (meshopt is C++),
# libc6-dev-arm64-cross and qemu-user, and
# `rustup target add aarch64-unknown-linux-gnu` (.ci/run installs them). The linker and runner
# are set here, in the environment, rather than in a .cargo/config.toml that every build of
# the repository would pick up.
#
#   scripts/aarch64.sh              # tests and byte comparison
#   TRIANGLES=200000 scripts/aarch64.sh
set -euo pipefail
cd "$(dirname "$0")/.."
target=aarch64-unknown-linux-gnu
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUNNER="qemu-aarch64 -L /usr/aarch64-linux-gnu"
export CC_aarch64_unknown_linux_gnu=aarch64-linux-gnu-gcc
export CXX_aarch64_unknown_linux_gnu=aarch64-linux-gnu-g++
arm() { qemu-aarch64 -L /usr/aarch64-linux-gnu "$@"; }

# Code for other architectures is compiled out on x86-64, so its warnings show only here: they
# fail the run.
RUSTFLAGS="-D warnings" cargo check -p reducem-core --target "$target" --all-targets

# The truncated-mapping test runs itself again as a child process, which qemu-user cannot start
# without binfmt_misc (a machine-wide setting); x86-64 runs it.
cargo test -p reducem-core --target "$target" -- \
  --skip a_read_beyond_a_truncated_mapping_exits_74_naming_the_file

cargo build -p reducem -p pipeline --bins
cargo build -p reducem -p pipeline --bins --target "$target"
target_dir=${CARGO_TARGET_DIR:-target}
x86_dir=$target_dir/debug
arm_dir=$target_dir/$target/debug

dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
"$x86_dir/pipeline" gen scan --triangles "${TRIANGLES:-50000}" -o "$dir/x86.ply"
arm "$arm_dir/pipeline" gen scan --triangles "${TRIANGLES:-50000}" -o "$dir/arm.ply"
cmp "$dir/x86.ply" "$dir/arm.ply"

# Rays from outside the mesh's bounds towards points inside them, and from inside in every
# direction (some with a finite tmax), so that there are hits, misses, and occluded and
# unoccluded rays; a fixed generator, so both sides trace the same file.
python3 - "$dir/x86.ply" "$dir/rays" <<'EOF'
import struct, sys
data = open(sys.argv[1], "rb").read()
header_end = data.index(b"end_header\n") + len(b"end_header\n")
vertices = int(data.split(b"element vertex ")[1].split(b"\n")[0])
points = struct.unpack_from("<%df" % (3 * vertices), data, header_end)
low = [min(points[a::3]) for a in range(3)]
high = [max(points[a::3]) for a in range(3)]
state = 12345
def uniform():
    global state
    state = (state * 6364136223846793005 + 1442695040888963407) % 2**64
    return (state >> 11) / 2**53
def inside():
    return [lo + (hi - lo) * uniform() for lo, hi in zip(low, high)]
rays = []
for k in range(20000):
    target = inside()
    if k % 2 == 0:
        origin = [c + 3.0 * (hi - lo) * (uniform() - 0.5) for c, lo, hi in zip(target, low, high)]
        origin = [o if k % 4 else 2 * hi - lo for o, lo, hi in zip(origin, low, high)]
        direction = [t - o for t, o in zip(target, origin)]
        tmax = float("inf")
    else:
        origin = target
        direction = [uniform() - 0.5 for _ in range(3)]
        tmax = float("inf") if k % 3 else 0.05 * (high[0] - low[0])
    if not any(direction):
        direction = [1.0, 0.0, 0.0]
    rays.append(struct.pack("<8f", *origin, *direction, 0.0, tmax))
open(sys.argv[2], "wb").write(b"".join(rays))
EOF

for encoding in f32 grid; do
    "$x86_dir/pipeline" convert "$dir/x86.ply" --encoding "$encoding" -o "$dir/x86-$encoding.rdm"
    arm "$arm_dir/pipeline" convert "$dir/x86.ply" --encoding "$encoding" \
        -o "$dir/arm-$encoding.rdm"
    cmp "$dir/x86-$encoding.rdm" "$dir/arm-$encoding.rdm"
    for query in "--format full" --occluded; do
        # shellcheck disable=SC2086 # the query's flags are words
        "$x86_dir/reducem" query "$dir/x86-$encoding.rdm" --rays "$dir/rays" $query \
            -o "$dir/x86.answers"
        # shellcheck disable=SC2086
        arm "$arm_dir/reducem" query "$dir/x86-$encoding.rdm" --rays "$dir/rays" $query \
            -o "$dir/arm.answers"
        cmp "$dir/x86.answers" "$dir/arm.answers"
        echo "aarch64: $encoding file and query $query byte-identical to x86-64's"
    done
done
