#!/usr/bin/env bash
# `reducem view` driven headless (Chromium through selenium): for each image size, full frames
# per second while the page orbits the model (each full frame's arrival moves the camera, so the
# figure includes the coarse frame every move renders first), and the median latency from a
# camera change to its first coarse frame; then the time from starting the viewer on a model
# with a cold page cache to the page's first frame. Primary shading (configs/scenes/primary.toml).
#
#   scripts/bench_view.sh MODEL [THREADS] [SECONDS]
#   scripts/bench_view.sh /tmp/scan10m.rdm 2 10
#
# Needs chromium, chromium-driver and python3 with selenium (pip install selenium).
set -euo pipefail
cd "$(dirname "$0")/.."
model=$1
threads=${2:-2}
seconds=${3:-10}
cargo build --release --quiet -p reducem -p reducem-view --bins
python3 -c "import os,sys; fd=os.open(sys.argv[1], os.O_RDONLY); os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED); os.close(fd)" "$model"
exec "${PYTHON:-python3}" - "$model" "$threads" "$seconds" <<'EOF'
import statistics, subprocess, sys, time
from selenium import webdriver
from selenium.webdriver.chrome.service import Service

model, threads, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
started = time.monotonic()
viewer = subprocess.Popen(["target/release/reducem", "view", model, "--up", "z", "--threads", threads],
                          stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
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
        const original = drawFrame;
        let fullFrames = 0, movedAt = null, latencies = [], start = null;
        const move = () => { movedAt = performance.now(); orbit(4, 0); };
        window.drawFrame = async buffer => {
            await original(buffer);
            const now = performance.now();
            if (lastHeader.spp < 1 && movedAt !== null) { latencies.push(now - movedAt); movedAt = null; }
            if (lastHeader.spp >= 1 && lastHeader.width === side) {
                if (start === null) start = now; else fullFrames += 1;
                if (now - start < seconds * 1000) move();
                else { window.drawFrame = original; done({ fullFrames, elapsed: now - start, latencies }); }
            }
        };
        move();
    """
    driver.set_script_timeout(seconds + 120)
    for side in (512, 1024):
        result = driver.execute_async_script(orbit, side, seconds)
        fps = result["fullFrames"] / (result["elapsed"] / 1000)
        latency = statistics.median(result["latencies"])
        print(f"{side}x{side}: {fps:.1f} full frames/s over {result['elapsed'] / 1000:.1f} s, "
              f"camera change to coarse frame median {latency:.0f} ms ({len(result['latencies'])} moves), "
              f"{threads} threads")
finally:
    driver.quit()
    viewer.terminate()
    viewer.wait()
EOF
