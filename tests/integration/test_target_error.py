"""Integration test: --target-error (RenderSettings.target_error, `render --target-error`).

A job with a target relative error far below its iteration cap stops once the merged frame's
odd/even estimate reaches it: it ends DONE with fewer iterations than the cap, its error at or
below the target, the EXR records both (render:target_error, render:relative_error_estimate),
and, because a frame stops after the iterations already handed out ([1, n) merged), the image
equals `render` over the same n iterations. `render --target-error` stops the same way. Bad
targets are refused."""

import math
import subprocess

import grpc

import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

SEED = 13
ALGO = "pt"
CAP = 200000
TARGET = 0.04
RESOLUTION = (16, 16)


def exr_attributes(path):
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(path)
    try:
        spec = inp.spec()
        return {a.name: a.value for a in spec.extra_attribs}
    finally:
        inp.close()


class TargetError(cluster.ClusterTestCase):
    def test_job_stops_at_target(self):
        P = cluster.pb()
        # Short leases: the target is checked at each merge.
        c = self.new_cluster(heartbeat=0.5, server_args=["--lease-seconds", "0.2"])
        c.start_server()
        c.start_worker(threads=1)
        c.wait_workers_registered(1)
        scene = cluster.cornell_box()
        for bad in (-0.1, float("nan"), 11.0):
            self.assertStatus(grpc.StatusCode.INVALID_ARGUMENT, c.api.submit, scene,
                              iterations=16, resolution=RESOLUTION, target_error=bad,
                              what=f"target_error {bad}")
        job = c.api.submit(scene, algorithm=ALGO, iterations=CAP, resolution=RESOLUTION,
                           seed=SEED, target_error=TARGET, name="target")
        self.assertEqual(job.settings.target_error, TARGET)
        done = c.api.wait_job(job.id, timeout=120, procs=[c.server] + c.live_workers())
        frame = done.frames[0]
        n = frame.iterations_done
        print(f"stopped after {n} of {CAP} iterations at estimated error "
              f"{frame.relative_error:.4f} (target {TARGET})")
        self.assertLess(n, CAP)
        self.assertGreaterEqual(n, 4)
        self.assertLessEqual(frame.relative_error, TARGET)
        out = c.api.fetch_to(job.id, c.path("target.exr"))
        attrs = exr_attributes(out)
        self.assertAlmostEqual(float(attrs["render:target_error"]), TARGET, places=9)
        self.assertLessEqual(float(attrs["render:relative_error_estimate"]), TARGET)
        self.assertEqual(int(attrs["render:iterations"]), n)
        ref = cluster.render_reference(scene, ALGO, n, RESOLUTION, SEED)
        print(self.assertImagesMatch(out, ref))

    def test_render_cli_stops_at_target(self):
        out = cluster.tempfile.mktemp(suffix=".exr", prefix="render-it-target-")
        try:
            args = [cluster.binary("render"), cluster.cornell_box(), "--algo", ALGO,
                    "--iterations", str(CAP), "--resolution", "16x16", "--seed", str(SEED),
                    "--threads", "1", "--target-error", str(TARGET), "--out", out]
            r = subprocess.run(args, capture_output=True, text=True, timeout=300)
            self.assertEqual(r.returncode, 0, r.stderr)
            attrs = exr_attributes(out)
            n = int(attrs["render:iterations"])
            err = float(attrs["render:relative_error_estimate"])
            print(f"render stopped after {n} iterations at {err:.4f}")
            self.assertLess(n, CAP)
            self.assertGreaterEqual(n, 4)
            self.assertLessEqual(err, TARGET)
            self.assertTrue(math.isclose(float(attrs["render:target_error"]), TARGET))
            for bad in ("0", "-1", "nan", "11"):
                r = subprocess.run(args[:-4] + ["--target-error", bad, "--out", out],
                                   capture_output=True, text=True, timeout=60)
                self.assertEqual(r.returncode, 2, f"--target-error {bad}: {r.stderr}")
        finally:
            if cluster.os.path.exists(out):
                cluster.os.remove(out)


if __name__ == "__main__":
    cluster.main()
