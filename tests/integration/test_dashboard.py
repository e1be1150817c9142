"""Integration test: the web dashboard (`server --http HOST:PORT`) in a real browser.

Headless Chromium (Debian `chromium`, `chromium-driver`, `python3-selenium`) opens the page of a
local cluster whose server has a token, enters the token, waits until the first job (adaptive)
shows 100 %, and checks that the live preview the page shows is not blank and equals the
fetched EXR's tone-mapped PNG: the test tone-maps the EXR from FetchResult itself (clamp to
[0, 1], sRGB curve, 8 bits, as core/image/exr_io.cpp's write_png_preview) and compares it with
the pixels the browser decoded (read back through a canvas); tolerance: 1 of 255 per channel
(one rounding step), every pixel. Beside the preview, the sample-count map equals the EXR's
samples layer through the maps' ramp (2 of 255), and the variance map of the finished frame
(no variance layer) is hidden with its reason; a running job's variance map shows. It cancels a second job with its Cancel button and checks its
state through the gRPC API, raises a third job's priority with its + button (checked through
gRPC too), and saves a screenshot (into the test's folder; to docs/img/dashboard.png with
DASHBOARD_SCREENSHOT=docs/img/dashboard.png).

Without the browser the browser case is skipped with a message (CTest runs it as a test of its
own, integration.test_dashboard.browser, reported as Skipped: tests/CMakeLists.txt); the HTTP
API's token rule and the static files' path handling are checked over plain HTTP either way."""

import http.client
import os
import shutil
import sys
import tempfile
import time

import numpy as np

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

TOKEN = "dashboard-secret-token"
CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
RESOLUTION = (32, 32)


def browser_missing():
    if not (os.access(CHROMIUM, os.X_OK) and os.access(CHROMEDRIVER, os.X_OK)):
        return f"{CHROMIUM} or {CHROMEDRIVER} not found (Debian chromium, chromium-driver)"
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "python3-selenium is not installed"
    return None


def raw_get(address, path):
    """GET with the path sent exactly as given (no client-side normalisation of '..')."""
    host, port = address.rsplit(":", 1)
    conn = http.client.HTTPConnection(host, int(port), timeout=10)
    try:
        conn.request("GET", path)
        r = conn.getresponse()
        return r.status, r.read()
    finally:
        conn.close()


def tone_map(rgb):
    """write_png_preview's curve: clamp to [0, 1], sRGB, 8 bits."""
    v = np.clip(rgb, 0.0, 1.0).astype(np.float32)
    v = np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1 / 2.4) - 0.055)
    return np.rint(v * 255.0).astype(np.int32)


# The maps' colour ramp (core/render/adaptive_maps.cpp), sRGB-encoded stops, and its grey for
# unknown values.
RAMP = np.array([[13, 8, 64], [84, 20, 140], [190, 45, 95], [245, 130, 40], [252, 232, 130]],
                dtype=np.float64)
GREY = 128


def ramp_colours(t):
    """The 8-bit colours of ramp positions t (clamped to [0, 1]), as the server's PNG has them:
    interpolated between the stops, linearised and encoded again (a rounding step each way)."""
    t = np.clip(np.asarray(t, dtype=np.float64), 0.0, 1.0) * (len(RAMP) - 1)
    i = np.minimum(np.floor(t).astype(int), len(RAMP) - 2)
    f = (t - i)[..., None]
    return np.rint(RAMP[i] + f * (RAMP[i + 1] - RAMP[i])).astype(np.int32)


def expected_map(values, log_scale):
    """heat_map's image of per-pixel values (NaN: unknown), with its low and high ends."""
    finite = values[np.isfinite(values) & ((values > 0) if log_scale else True)]
    x = np.log10(finite) if log_scale else finite
    x = np.sort(x)
    last = len(x) - 1
    lo = x[int(np.floor(0.01 * last))] if log_scale else x[0]
    hi = x[int(np.ceil(0.99 * last))] if log_scale else x[last]
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.log10(np.where(values > 0, values, np.nan)) if log_scale else values
        t = (v - lo) / (hi - lo) if hi > lo else np.full(values.shape, 0.5)
    t = np.where(log_scale & ~(values > 0) & np.isfinite(values), 0.0, t)
    colours = ramp_colours(np.nan_to_num(t))
    colours[~np.isfinite(values)] = GREY
    return colours, (10 ** lo if log_scale else lo), (10 ** hi if log_scale else hi)


def decode_png(data):
    from PIL import Image
    import io
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"), dtype=np.int32)


def start_browser(tmp):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic",
                 "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--disable-dev-shm-usage",
                 "--window-size=1280,1000", "--force-color-profile=srgb",
                 f"--user-data-dir={tmp}"):
        options.add_argument(flag)
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)


class Dashboard(cluster.ClusterTestCase):
    def test_http_api_token_and_paths(self):
        P = cluster.pb()
        c = self.new_cluster(token=TOKEN, server_args=["--http", "127.0.0.1:0"])
        c.start_server()
        addr = c.http_addresses["http"]
        job = c.api.submit(cluster.cornell_box(), iterations=4, resolution=RESOLUTION, seed=2)
        # /api/ follows the gRPC token rule; the page and /metrics need none.
        for token in (None, "wrong-token"):
            status, _, body = cluster.http_get(addr, "/api/jobs", token=token)
            self.assertEqual(status, 401, body)
            status, _, body = cluster.http_get(addr, f"/api/jobs/{job.id}/cancel", token=token,
                                               method="POST")
            self.assertEqual(status, 401, body)
        # A page of another origin cannot post, even with the token.
        status, _, body = cluster.http_get(addr, f"/api/jobs/{job.id}/cancel", token=TOKEN,
                                           method="POST",
                                           headers={"Origin": "http://elsewhere.example"})
        self.assertEqual(status, 403, body)
        self.assertIn(b"PERMISSION_DENIED", body)
        self.assertNotEqual(c.api.get_job(job.id).state, P.JOB_STATE_CANCELLED)
        status, ctype, body = cluster.http_get(addr, "/api/jobs", token=TOKEN)
        self.assertEqual(status, 200)
        self.assertTrue(ctype.startswith("application/json"), ctype)
        self.assertIn(job.id.encode(), body)
        status, _, _ = cluster.http_get(addr, "/api/jobs/job-000099-nosuch", token=TOKEN)
        self.assertEqual(status, 404)
        status, _, _ = cluster.http_get(addr, f"/api/jobs/{job.id}/priority?value=x",
                                        token=TOKEN, method="POST")
        self.assertEqual(status, 400)
        status, _, body = cluster.http_get(addr, f"/api/jobs/{job.id}/priority?value=7",
                                           token=TOKEN, method="POST")
        self.assertEqual(status, 200, body)
        self.assertEqual(c.api.get_job(job.id).priority, 7)
        for path in ("/", "/index.html", "/app.js", "/style.css", "/metrics"):
            status, _, body = cluster.http_get(addr, path)
            self.assertEqual(status, 200, path)
            self.assertGreater(len(body), 0, path)
        # Only the embedded files answer: nothing reaches the file system.
        for path in ("/../../../../etc/passwd", "/..%2f..%2fetc%2fpasswd", "/etc/passwd",
                     "/%2e%2e/%2e%2e/etc/passwd", "/CMakeLists.txt", "/server", "/.."):
            status, body = raw_get(addr, path)
            self.assertIn(status, (400, 404), f"{path}: {status} {body[:80]!r}")
            self.assertNotIn(b"root:", body, path)

    def test_maps_over_http(self):
        """The maps beside the preview (core/render/adaptive_maps.h) over plain HTTP: the token
        rule; an adaptive job's sample counts and a job's variance layer, each against the
        fetched EXR's layer drawn through the same ramp (legend headers to 6 digits, pixels to 2
        of 255: a rounding step in linearising and one in encoding); a finished frame without a
        variance layer says so; a running frame's variance from its odd/even halves."""
        c = self.new_cluster(token=TOKEN, heartbeat=0.5,
                             server_args=["--http", "127.0.0.1:0", "--lease-seconds", "0.1"])
        c.start_server()
        c.start_worker(threads=1)
        c.wait_workers_registered(1)
        addr = c.http_addresses["http"]
        scene = cluster.cornell_box()
        adaptive = c.api.submit(scene, algorithm="pt", iterations=96, resolution=RESOLUTION,
                                seed=7, name="adaptive", priority=2,
                                options={"adaptive": "0.08", "adaptive_min_iterations": "8",
                                         "adaptive_round": "4"})
        layered = c.api.submit(scene, algorithm="pt", iterations=24, resolution=RESOLUTION,
                               seed=8, name="variance", priority=1,
                               options={"layers": "variance"})
        running = c.api.submit(scene, algorithm="pt", iterations=200000, resolution=RESOLUTION,
                               seed=9, name="running", priority=0)
        for path in ("variance.png", "samples.png"):
            status, _, body = cluster.http_get(addr, f"/api/jobs/{adaptive.id}/{path}")
            self.assertEqual(status, 401, body)
        for job in (adaptive, layered):
            done = c.api.wait_job(job.id, timeout=120, procs=[c.server] + c.workers)
            self.assertTrue(done.frames[0].done, str(done))

        def get_map(job_id, kind):
            import urllib.request
            req = urllib.request.Request(f"http://{addr}/api/jobs/{job_id}/{kind}.png")
            req.add_header("Authorization", f"Bearer {TOKEN}")
            opener = urllib.request.build_opener(urllib.request.ProxyHandler({}))
            try:
                with opener.open(req, timeout=10) as r:
                    return r.status, dict(r.headers), r.read()
            except urllib.error.HTTPError as e:
                return e.code, dict(e.headers), e.read()
        import urllib.error

        def check(job_id, kind, values, log_scale):
            status, headers, body = get_map(job_id, kind)
            self.assertEqual(status, 200, body[:200])
            self.assertEqual(headers.get("X-Map-Scale"), "log" if log_scale else "linear")
            expected, lo, hi = expected_map(values, log_scale)
            self.assertAlmostEqual(float(headers["X-Map-Low"]) / lo, 1.0, delta=1e-5)
            self.assertAlmostEqual(float(headers["X-Map-High"]) / hi, 1.0, delta=1e-5)
            shown = decode_png(body)
            self.assertEqual(shown.shape[:2], values.shape)
            diff = np.abs(shown - expected)
            print(f"{kind} map of {job_id}: {lo:.4g} to {hi:.4g}, max |diff| {diff.max()} of 255")
            self.assertLessEqual(int(diff.max()), 2, f"the {kind} map differs from the EXR's")
            return headers

        # The adaptive job: its samples layer, not uniform; no variance once it is done.
        pixels, names, _ = cluster.read_exr_channels(c.api.fetch_to(adaptive.id,
                                                                    c.path("a.exr")))
        samples = pixels[:, :, names.index("samples.R")].astype(np.float64)
        self.assertGreater(samples.max(), samples.min(), "the mask stopped no pixel")
        check(adaptive.id, "samples", samples, False)
        status, _, body = get_map(adaptive.id, "variance")
        self.assertEqual(status, 409, body)
        self.assertIn(b"variance layer", body)
        # The variance-layer job: the variance layer's mean over R, G, B, on the log scale;
        # its samples uniform.
        pixels, names, _ = cluster.read_exr_channels(c.api.fetch_to(layered.id,
                                                                    c.path("v.exr")))
        variance = np.mean([pixels[:, :, names.index(f"variance.{k}")].astype(np.float64)
                            for k in "RGB"], axis=0)
        headers = check(layered.id, "variance", variance, True)
        self.assertEqual(headers.get("X-Map-Source"), "variance layer")
        check(layered.id, "samples", np.full(variance.shape, 24.0), False)
        # A running frame: the odd/even halves of its merged sums.
        cluster.wait_until(
            lambda: int(c.api.get_job(running.id).frames[0].iterations_done) >= 4, timeout=60,
            what="the running job to merge 4 iterations")
        status, headers, body = get_map(running.id, "variance")
        self.assertEqual(status, 200, body[:200])
        self.assertEqual(headers.get("X-Map-Source"), "odd/even halves")
        self.assertLess(float(headers["X-Map-Low"]), float(headers["X-Map-High"]))

    def test_dashboard_in_chromium(self):
        missing = browser_missing()
        if missing:
            self.skipTest(f"no headless browser: {missing}")
        from selenium.webdriver.common.by import By
        from selenium.common.exceptions import (NoSuchElementException,
                                                StaleElementReferenceException)
        from selenium.webdriver.common.keys import Keys
        P = cluster.pb()
        # Short leases: the finished job's error plot has a point per merged report.
        c = self.new_cluster(token=TOKEN, heartbeat=0.5,
                             server_args=["--http", "127.0.0.1:0", "--lease-seconds", "0.1"])
        c.start_server()
        c.start_worker(threads=1)
        c.wait_workers_registered(1)
        scene = cluster.cornell_box()
        # A short job first (higher priority), then one far too long to finish: it is cancelled.
        # Adaptive: the samples map beside its preview is not flat.
        short = c.api.submit(scene, algorithm="pt", iterations=256, resolution=RESOLUTION,
                             seed=7, name="short", priority=1,
                             options={"adaptive": "0.08", "adaptive_min_iterations": "8",
                                      "adaptive_round": "4"})
        long = c.api.submit(scene, algorithm="pt", iterations=200000, resolution=RESOLUTION,
                            seed=8, name="long", priority=0)
        # A third that keeps rendering while the screenshot is taken (adaptive with a small
        # threshold: its maps show the variance and the counts of a frame in progress).
        running = c.api.submit(scene, algorithm="pt", iterations=200000, resolution=RESOLUTION,
                               seed=9, name="running", priority=0,
                               options={"adaptive": "0.002", "adaptive_min_iterations": "8",
                                        "adaptive_round": "8"})
        tmp = tempfile.mkdtemp(prefix="render-it-chromium-")
        driver = start_browser(tmp)
        try:
            driver.set_page_load_timeout(20)
            driver.get(f"http://{c.http_addresses['http']}/")
            token = driver.find_element(By.ID, "token")
            token.send_keys(TOKEN)
            token.send_keys(Keys.TAB)  # the change event stores it and refreshes

            # The page redraws its tables every second: read them in one script each time,
            # and retry a click that lands on a row just replaced.
            def row_state(job_id):
                return driver.execute_script("""
                    const r = document.querySelector(`tr[data-job="${arguments[0]}"]`);
                    const img = document.getElementById('preview');
                    return r && {state: r.dataset.state,
                                 percent: r.querySelector('.percent').textContent,
                                 preview_job: img.dataset.job, preview_done: img.dataset.done};
                """, job_id)

            def click(selector):
                for _ in range(50):
                    try:
                        driver.find_element(By.CSS_SELECTOR, selector).click()
                        return
                    except (StaleElementReferenceException, NoSuchElementException):
                        time.sleep(0.1)
                raise AssertionError(f"cannot click {selector}")

            def short_done():
                r = row_state(short.id)
                return (r and r["percent"] == "100 %" and r["preview_job"] == short.id
                        and r["preview_done"] == "true")
            cluster.wait_until(short_done, timeout=40, poll=0.25,
                               what="the short job at 100 % with its final preview")
            self.assertEqual(row_state(short.id)["state"], "DONE")

            # The pixels the browser shows, read back through a canvas.
            pixels = driver.execute_script("""
                const img = document.getElementById('preview');
                const c = document.createElement('canvas');
                c.width = img.naturalWidth; c.height = img.naturalHeight;
                const g = c.getContext('2d');
                g.drawImage(img, 0, 0);
                return [c.width, c.height, Array.from(g.getImageData(0, 0, c.width, c.height).data)];
            """)
            w, h, rgba = pixels
            self.assertEqual((w, h), RESOLUTION)
            shown = np.array(rgba, dtype=np.int32).reshape(h, w, 4)[:, :, :3]
            self.assertGreater(shown.max(), 0, "the preview is black")
            self.assertGreater(shown.std(), 1.0, "the preview is one flat colour")
            exr = c.api.fetch_to(short.id, c.path("short.exr"))
            expected = tone_map(cluster.read_exr(exr))
            diff = np.abs(shown - expected)
            print(f"preview vs tone-mapped EXR: max |diff| {diff.max()} of 255, "
                  f"mean {diff.mean():.4f}; preview mean {shown.mean():.2f}")
            self.assertLessEqual(int(diff.max()), 1, "the preview differs from the EXR's "
                                 "tone-mapped PNG by more than one 8-bit step")

            # Beside it, the samples map: the EXR's samples layer through the ramp (2 of 255:
            # a rounding step each way through linear), and its range in the caption; the
            # variance map hidden, its caption saying why (a finished frame without the
            # variance layer).
            maps = driver.execute_script("""
                const out = {};
                for (const kind of ['samples', 'variance']) {
                  const img = document.getElementById(kind + '-map');
                  const o = {hidden: img.hidden, job: img.dataset.job,
                             caption: document.getElementById(kind + '-caption').textContent};
                  if (!img.hidden) {
                    const c = document.createElement('canvas');
                    c.width = img.naturalWidth; c.height = img.naturalHeight;
                    const g = c.getContext('2d');
                    g.drawImage(img, 0, 0);
                    o.size = [c.width, c.height];
                    o.rgba = Array.from(g.getImageData(0, 0, c.width, c.height).data);
                  }
                  out[kind] = o;
                }
                return out;
            """)
            pixels, names, _ = cluster.read_exr_channels(exr)
            samples = pixels[:, :, names.index("samples.R")].astype(np.float64)
            self.assertGreater(samples.max(), samples.min(), "the mask stopped no pixel")
            m = maps["samples"]
            self.assertFalse(m["hidden"], m["caption"])
            self.assertEqual(m["job"], short.id)
            self.assertEqual(tuple(m["size"]), RESOLUTION)
            shown = np.array(m["rgba"], dtype=np.int32).reshape(h, w, 4)[:, :, :3]
            expected, lo, hi = expected_map(samples, False)
            diff = np.abs(shown - expected)
            print(f"samples map vs the EXR's samples layer: max |diff| {diff.max()} of 255; "
                  f"caption {m['caption']!r}")
            self.assertLessEqual(int(diff.max()), 2, "the samples map differs from the EXR's")
            self.assertIn(f"{lo:g} to {hi:g}", m["caption"])
            v = maps["variance"]
            self.assertTrue(v["hidden"], "a finished frame without a variance layer has no map")
            self.assertIn("variance layer", v["caption"])

            # Cancel the long job with its button; the gRPC API sees it cancelled.
            self.assertNotEqual(c.api.get_job(long.id).state, P.JOB_STATE_CANCELLED)
            click(f'tr[data-job="{long.id}"] button.cancel')
            done = c.api.wait_job(long.id, states=[P.JOB_STATE_CANCELLED], timeout=20)
            self.assertEqual(done.state, P.JOB_STATE_CANCELLED)
            cluster.wait_until(lambda: (row_state(long.id) or {}).get("state") == "CANCELLED",
                               timeout=10, what="the page to show the job cancelled")

            # Its priority goes up with the + button; the gRPC API sees it.
            click(f'tr[data-job="{running.id}"] button.priority-up')
            cluster.wait_until(lambda: c.api.get_job(running.id).priority == 1, timeout=10,
                               what="the + button to raise the priority to 1")

            # The screenshot of docs/guide/service.md: the running job selected, its preview, its
            # maps (the variance from its odd/even halves) and its plot.
            click(f'tr[data-job="{running.id}"] td.id')

            def running_maps():
                return driver.execute_script("""
                    const v = document.getElementById('variance-map');
                    const s = document.getElementById('samples-map');
                    return !v.hidden && v.dataset.job === arguments[0] &&
                           s.dataset.job === arguments[0] &&
                           document.getElementById('variance-caption').textContent;
                """, running.id)
            cluster.wait_until(running_maps, timeout=20, poll=0.25,
                               what="the running job's variance and samples maps")
            self.assertIn("odd/even halves", running_maps())
            time.sleep(1.5)  # one refresh: preview and plot of the selected job
            # Into the test's own folder, so that a test run leaves the checkout clean;
            # DASHBOARD_SCREENSHOT=docs/img/dashboard.png refreshes the one docs/guide/service.md shows.
            out = os.environ.get("DASHBOARD_SCREENSHOT") or c.path("dashboard.png")
            os.makedirs(os.path.dirname(out), exist_ok=True)
            self.assertTrue(driver.save_screenshot(out), "no screenshot")
            print(f"screenshot: {out}")
        finally:
            driver.quit()
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    cluster.main()
