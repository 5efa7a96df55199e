"""`reducem view` end to end in headless Chromium, driven by selenium.

The first frame arrives; a drag changes data-camera and the image; a click reports in #pick the
face id `reducem query --format full` gives for the same pixel's ray; the image "save image"
downloads equals `reducem render` with the same camera, byte for byte; the AO switch brings an
image of 16 samples per pixel; "copy scene" shows the scene; a page that leaves
mid-frame does not stop the server; SIGTERM ends it with 0.

Run: python3 view/tests/browser.py, with REDUCEM_BIN and PIPELINE_BIN naming the binaries
(default target/debug/; reducem-view must sit beside reducem). Without Chromium it skips with a
message, unless VIEW_TEST_REQUIRED=1 (CI), where a missing browser fails.
"""

import json
import os
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
REDUCEM = os.environ.get("REDUCEM_BIN", str(ROOT / "target/debug/reducem"))
PIPELINE = os.environ.get("PIPELINE_BIN", str(ROOT / "target/debug/pipeline"))
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")
WIDTH, HEIGHT = 480, 360


def wait_for(condition, what, timeout=60.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def convert_model(directory):
    """A generated scan with face ids, converted: the model the page shows."""
    ply, model = directory / "scan.ply", directory / "scan.rdm"
    run = lambda *args: subprocess.run(args, check=True, stdout=subprocess.DEVNULL)
    run(PIPELINE, "gen", "scan", "--triangles", "50000", "-o", str(ply))
    run(PIPELINE, "convert", str(ply), "-o", str(model), "--face-ids")
    ply.unlink()
    return model


def start_viewer(model):
    viewer = subprocess.Popen(
        [REDUCEM, "view", str(model), "--up", "z", "--threads", "2"],
        stdout=subprocess.PIPE,
        text=True,
    )
    url = viewer.stdout.readline().strip()
    assert url.startswith("http://127.0.0.1:") and "/?token=" in url, url
    return viewer, url


def browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for argument in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                     f"--window-size={WIDTH},{HEIGHT}"):
        options.add_argument(argument)
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)


def frames(driver):
    return int(driver.execute_script("return document.documentElement.dataset.frame") or 0)


def camera(driver):
    return driver.execute_script("return document.documentElement.dataset.camera")


def canvas_pixels(driver):
    return driver.execute_script("return document.getElementById('view').toDataURL()")


def settled(driver):
    """Waits until the frames stop coming (the latest view is fully drawn)."""
    last = -1
    while True:
        count = frames(driver)
        if count == last:
            return count
        last = count
        time.sleep(1.0)


def click_on_model(driver, canvas):
    """Clicks points around the canvas centre until one is on the model (the scan is a torus,
    its centre may be the hole); the pick reported there."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    pick_box = driver.find_element(By.ID, "pick")
    for dx, dy in [(0, 0), (0, 60), (60, 0), (0, -60), (-60, 0), (0, 100), (100, 0)]:
        previous = pick_box.get_attribute("data-pick")
        ActionChains(driver).move_to_element_with_offset(canvas, dx, dy).click().perform()
        wait_for(lambda: pick_box.get_attribute("data-pick") != previous, "the pick")
        pick = json.loads(pick_box.get_attribute("data-pick"))
        if pick and pick["hit"]:
            return pick
    raise AssertionError("no click hit the model")


def query_face_id(model, directory, pick):
    """The face id and distance `reducem query --format full` gives for the pick's ray."""
    rays, hits = directory / "ray.bin", directory / "hit.bin"
    ray = struct.pack("<8f", *pick["ray_origin"], *pick["ray_direction"], 0.0, float("inf"))
    rays.write_bytes(ray)
    subprocess.run([REDUCEM, "query", str(model), "--rays", str(rays), "-o", str(hits),
                    "--format", "full"], check=True, stderr=subprocess.DEVNULL)
    record = hits.read_bytes()
    (t,) = struct.unpack_from("<f", record, 0)
    (face_id,) = struct.unpack_from("<I", record, 12)
    return face_id, t


def as_f32(value):
    return struct.unpack("<f", struct.pack("<f", value))[0]


def rendered_png(model, directory, view_camera, width, height):
    """What `reducem render` writes with the page's camera (its f32 values) and size."""
    point = lambda key: ",".join(repr(as_f32(v)) for v in view_camera[key])
    out = directory / "render.png"
    subprocess.run([REDUCEM, "render", str(model), "--scene", str(ROOT / "configs/scenes/primary.toml"),
                    "--up", "z", "-o", str(out), "--width", str(width), "--height", str(height),
                    "--camera-position", point("position"), "--look-at", point("look_at"),
                    "--camera-up", point("up"), "--fov", repr(as_f32(view_camera["fov"]))],
                   check=True, stdout=subprocess.DEVNULL)
    return out.read_bytes()


def main():
    if not (CHROMIUM and CHROMEDRIVER):
        message = "view/tests/browser.py: chromium and chromium-driver are not installed"
        if os.environ.get("VIEW_TEST_REQUIRED") == "1":
            sys.exit(message)
        print(message + ": skipped (apt-get install chromium chromium-driver)")
        return
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select

    directory = Path(tempfile.mkdtemp(prefix="reducem-view-browser-"))
    viewer = driver = None
    try:
        model = convert_model(directory)
        viewer, url = start_viewer(model)
        driver = browser()
        driver.get(url)
        wait_for(lambda: frames(driver) > 0, "the first frame")
        print("first frame arrived")
        settled(driver)
        before_camera, before_image, before_frames = camera(driver), canvas_pixels(driver), frames(driver)
        canvas = driver.find_element(By.ID, "view")
        ActionChains(driver).move_to_element(canvas).click_and_hold().move_by_offset(60, 25).release().perform()
        wait_for(lambda: camera(driver) != before_camera, "the camera to change after a drag")
        wait_for(lambda: frames(driver) > before_frames, "a frame of the new camera")
        settled(driver)
        assert canvas_pixels(driver) != before_image, "the image did not change after the drag"
        print("a drag changed data-camera and the image")

        pick = click_on_model(driver, canvas)
        pick_box = driver.find_element(By.ID, "pick")
        face_id, t = query_face_id(model, directory, pick)
        assert pick["face_id"] == face_id, (pick, face_id)
        assert struct.pack("<f", pick["distance"]) == struct.pack("<f", t), (pick, t)
        assert f"face id {face_id}" in pick_box.text, pick_box.text
        print(f"the pick reports face {face_id}, as reducem query does")

        image_url = driver.execute_script("return imageUrl()")
        view = driver.execute_script("return currentView()")
        saved = urllib.request.urlopen(url.split("/?")[0] + image_url).read()
        expected = rendered_png(model, directory, view["camera"], view["width"], view["height"])
        assert saved == expected, "the saved image differs from reducem render's"
        print(f"the saved {view['width']}x{view['height']} image equals reducem render's")

        driver.find_element(By.ID, "ambient_occlusion").click()
        spp = lambda: driver.execute_script("return document.documentElement.dataset.spp")
        wait_for(lambda: spp() == "16", "the AO image (16 samples per pixel)")
        driver.find_element(By.ID, "copy").click()
        scene_box = driver.find_element(By.ID, "scene")
        wait_for(lambda: "[ambient_occlusion]" in scene_box.get_attribute("value"), "the scene text")
        print("the AO switch brought 16 samples per pixel, and copy scene shows the scene")

        # Clicked by script: the scene text shown above may cover the switch in a narrow window.
        switch = driver.find_element(By.ID, "normals_view")
        driver.execute_script("arguments[0].click()", switch)
        wait_for(lambda: spp() == "1", "the normals view (no AO samples)")
        driver.find_element(By.ID, "copy").click()
        wait_for(lambda: 'mode = "normals"' in scene_box.get_attribute("value"), "the normals scene")
        driver.execute_script("arguments[0].click()", switch)
        wait_for(lambda: spp() == "16", "the lit AO image again")
        print("the normal colours switch shows the normals view, without AO samples")

        Select(driver.find_element(By.ID, "up")).select_by_value("y")
        wait_for(lambda: json.loads(camera(driver))["up"] == [0, 1, 0], "the y-up camera")
        wait_for(lambda: "#up=y&camera=" in driver.current_url, "the camera in the URL fragment")
        print("the up-axis switch reframes for y up, and the URL fragment follows")

        driver.execute_script("document.getElementById('scale').value = '1'")
        driver.execute_script("orbit(40, 0)")
        driver.get("about:blank")
        driver.get(url)
        wait_for(lambda: frames(driver) > 0, "a frame after a page left mid-frame")
        print("a page that left mid-frame did not stop the server")
    finally:
        if driver:
            driver.quit()
        if viewer:
            viewer.send_signal(signal.SIGTERM)
            code = viewer.wait(timeout=30)
            assert code == 0, f"reducem view exited with {code} on SIGTERM"
        shutil.rmtree(directory)
    print("reducem view exited with 0 on SIGTERM")


if __name__ == "__main__":
    main()
