#!/usr/bin/env bash
# `reducem view` driven headless (Chromium through selenium): for each image size, full frames
# per second while the page orbits the model (each full frame's arrival moves the camera, so the
# figure includes the coarse frame a move renders first when full frames are slow), and the
# median latency from a camera change to its first frame (coarse, or full when it came without
# one), with the page's medians of when a move's frames were taken up, decoded
# (createImageBitmap) and drawn; then the time from starting the viewer on a model with a cold
# page cache to the page's first frame. Primary shading (configs/scenes/primary.toml).
# VIEW_LOG=FILE keeps the viewer's standard error there; with REDUCEM_VIEW_STAGES=1 it has the
# server's stages of every frame (docs/VIEWER.md, "Frames").
# As a reference for the load of a shared machine, the same run also times `reducem query` on the
# camera rays of a 512² view (the first camera, in the renderer's 8×8-tile order), THREADS threads,
# median of 3.
#
#   scripts/bench_view.sh MODEL [THREADS] [SECONDS]
#   scripts/bench_view.sh /tmp/scan10m.rdm 2 10
#
# Needs chromium, chromium-driver and python3 with selenium (pip install selenium).
# REDUCEM_BIN=DIR runs DIR/reducem (and the reducem-view beside it) instead of building
# target/release, so that two builds can be run alternately.
#
# With --first-picture, the first picture instead: `reducem render` of each shipped scene with its
# automatic camera and the file's stored up axis, at SIZE² (default 512), and for each the fill
# (the fraction of pixels not of the background colour) and the 10th, 50th and 90th percentiles
# of the model's pixels' luminance (Rec. 709 weights on the 8-bit sRGB codes). Needs numpy.
#
#   scripts/bench_view.sh --first-picture MODEL [SIZE]
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "${1:-}" = --first-picture ]; then
    model=$2
    size=${3:-512}
    cargo build --release --quiet -p reducem --bin reducem
    images=$(mktemp -d)
    trap 'rm -rf "$images"' EXIT
    for scene in primary occlusion shadows; do
        target/release/reducem render "$model" --scene "configs/scenes/$scene.toml" \
            --width "$size" --height "$size" -o "$images/$scene.pfm" >/dev/null
    done
    "${PYTHON:-python3}" - "$images"/*.pfm <<'EOF'
import os, sys
import numpy as np

def linear_rgb(path):
    with open(path, "rb") as f:
        assert f.readline().strip() == b"PF"
        width, height = map(int, f.readline().split())
        scale = float(f.readline())
        pixels = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4")
    return pixels.reshape(height * width, 3)

for path in sys.argv[1:]:
    pixels = linear_rgb(path)
    values, counts = np.unique(pixels, axis=0, return_counts=True)
    model = np.any(pixels != values[counts.argmax()], axis=1)
    x = np.clip(np.nan_to_num(pixels[model]), 0, 1)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    luminance = np.floor(srgb * 255 + 0.5) @ np.array([0.2126, 0.7152, 0.0722])
    p10, p50, p90 = np.percentile(luminance, [10, 50, 90])
    scene = os.path.basename(path).removesuffix(".pfm")
    print(f"{scene}.toml: fill {model.mean():.3f}, luminance p10 {p10:.0f} p50 {p50:.0f} p90 {p90:.0f}")
EOF
    exit 0
fi
model=$1
threads=${2:-2}
seconds=${3:-10}
bin=${REDUCEM_BIN:-target/release}
[ -n "${REDUCEM_BIN:-}" ] || cargo build --release --quiet -p reducem -p reducem-view --bins
python3 -c "import os,sys; fd=os.open(sys.argv[1], os.O_RDONLY); os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED); os.close(fd)" "$model"
exec "${PYTHON:-python3}" - "$model" "$threads" "$seconds" "$bin/reducem" <<'EOF'
import json, math, os, statistics, struct, subprocess, sys, tempfile, time
from selenium import webdriver
from selenium.webdriver.chrome.service import Service

model, threads, seconds, reducem = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4]

def camera_rays(camera, side):
    """The primary rays of a side² view of `camera`, 8x8 tiles in 4x2 packet blocks."""
    sub = lambda a, b: [x - y for x, y in zip(a, b)]
    cross = lambda a, b: [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    unit = lambda a: [x / math.sqrt(sum(c * c for c in a)) for x in a]
    forward = unit(sub(camera["look_at"], camera["position"]))
    right = unit(cross(forward, camera["up"]))
    up = cross(right, forward)
    half = math.tan(math.radians(camera["fov"]) / 2)
    rays = bytearray()
    for tile_y in range(0, side, 8):
        for tile_x in range(0, side, 8):
            for block_y in range(tile_y, tile_y + 8, 2):
                for block_x in range(tile_x, tile_x + 8, 4):
                    for y in range(block_y, block_y + 2):
                        for x in range(block_x, block_x + 4):
                            sx, sy = (2 * (x + 0.5) / side - 1) * half, (1 - 2 * (y + 0.5) / side) * half
                            direction = unit([f + r * sx + u * sy for f, r, u in zip(forward, right, up)])
                            rays += struct.pack("<8f", *camera["position"], *direction, 0.0, math.inf)
    return rays

def reference_rate(camera, side):
    """`reducem query` Mrays/s on the camera rays of a side² view, median of 3."""
    with tempfile.TemporaryDirectory() as directory:
        rays, hits = os.path.join(directory, "camera.rays"), os.path.join(directory, "camera.hits")
        with open(rays, "wb") as f:
            f.write(camera_rays(camera, side))
        environment = dict(os.environ, RAYON_NUM_THREADS=threads)
        runs = []
        for _ in range(3):
            began = time.monotonic()
            subprocess.run([reducem, "query", model, "--rays", rays, "-o", hits],
                           check=True, env=environment, stderr=subprocess.DEVNULL)
            runs.append(time.monotonic() - began)
    rate = side * side / statistics.median(runs) / 1e6
    return (f"reference: reducem query, {side}x{side} camera rays, {threads} threads: {rate:.1f} Mrays/s "
            f"(whole process, median of 3), load average {os.getloadavg()[0]:.1f}")
started = time.monotonic()
log = open(os.environ["VIEW_LOG"], "w") if os.environ.get("VIEW_LOG") else subprocess.DEVNULL
viewer = subprocess.Popen([reducem, "view", model, "--up", "z", "--threads", threads],
                          stdout=subprocess.PIPE, stderr=log, text=True)
url = viewer.stdout.readline().strip()
options = webdriver.ChromeOptions()
for argument in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1200,1200"):
    options.add_argument(argument)
driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)
frames = lambda: int(driver.execute_script("return document.documentElement.dataset.frame") or 0)
try:
    driver.get(url)
    while frames() == 0:
        time.sleep(0.01)
    print(f"first frame, cold page cache: {time.monotonic() - started:.2f} s after starting reducem view")
    # Each full frame moves the camera; the first coarse frame after a move gives its latency.
    orbit = """
        const [side, seconds, done] = arguments;
        const canvas = document.getElementById("view");
        canvas.style.width = canvas.style.height = side + "px";
        const original = drawFrame, decode = window.createImageBitmap;
        let fullFrames = 0, movedAt = null, movedFrom = 0, latencies = [], start = null;
        let decoded = null, stages = [];
        window.createImageBitmap = async (...image) => {
            const bitmap = await decode(...image);
            decoded = performance.now();
            return bitmap;
        };
        const move = () => { movedAt = performance.now(); movedFrom = lastHeader.generation; orbit(4, 0); };
        window.drawFrame = async buffer => {
            // A frame is taken up as it arrives unless the page is still drawing the one before.
            const arrival = performance.now();
            await original(buffer);
            const now = performance.now();
            if (movedAt !== null && lastHeader.generation > movedFrom) {
                latencies.push(now - movedAt);
                stages.push({ moved: movedAt, arrival, decoded, drawn: now, full: lastHeader.spp >= 1 });
                movedAt = null;
            } else if (stages.length) {
                Object.assign(stages[stages.length - 1], { fullArrival: arrival, fullDecoded: decoded, fullDrawn: now });
            }
            if (lastHeader.spp >= 1 && lastHeader.width === side) {
                if (start === null) start = now; else fullFrames += 1;
                if (now - start < seconds * 1000) move();
                else {
                    window.drawFrame = original;
                    window.createImageBitmap = decode;
                    done({ fullFrames, elapsed: now - start, latencies, stages });
                }
            }
        };
        move();
    """
    driver.set_script_timeout(seconds + 120)
    def median_ms(pairs):
        """The median of `later - earlier` over the pairs both of whose times the page took."""
        values = [later - earlier for later, earlier in pairs if later is not None and earlier is not None]
        return f"{statistics.median(values):.1f}" if values else "-"
    for side in (512, 1024):
        result = driver.execute_async_script(orbit, side, seconds)
        fps = result["fullFrames"] / (result["elapsed"] / 1000)
        latency = statistics.median(result["latencies"])
        print(f"{side}x{side}: {fps:.1f} full frames/s over {result['elapsed'] / 1000:.1f} s, "
              f"camera change to first frame median {latency:.0f} ms ({len(result['latencies'])} moves), "
              f"{threads} threads")
        # A move's frames on the page: its first (coarse, unless skipped) and the full one after it.
        stages = result["stages"]
        first = [s for s in stages if not s["full"] and "fullDrawn" in s]
        print(f"  page, medians in ms after the camera was sent ({len(stages)} moves, "
              f"{len(stages) - len(first)} without a coarse frame): "
              f"coarse taken up {median_ms([(s['arrival'], s['moved']) for s in first])}, "
              f"decoded {median_ms([(s['decoded'], s['moved']) for s in first])}, "
              f"drawn {median_ms([(s['drawn'], s['moved']) for s in first])}; "
              f"full taken up {median_ms([(s.get('fullArrival', s['arrival']), s['moved']) for s in stages])}, "
              f"decoded {median_ms([(s.get('fullDecoded', s['decoded']), s['moved']) for s in stages])}, "
              f"drawn {median_ms([(s.get('fullDrawn', s['drawn']), s['moved']) for s in stages])}")
    camera = json.loads(driver.execute_script("return document.documentElement.dataset.camera"))
    print(reference_rate(camera, 512))
finally:
    driver.quit()
    viewer.terminate()
    viewer.wait()
EOF
