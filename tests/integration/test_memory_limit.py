"""A job whose scene and film need more memory than its worker may use fails with that message,
and the worker lives on (issue 18). The worker estimates the job's memory before allocating it
(the film's sums, then each mesh, grid, image and file the loaders read: core/base/
memory_budget.h) against `worker --max-memory`; over it, the lease fails with the estimate and
the limit, and since every worker the server knows failed it, the job FAILS with that error.
The same holds for the algorithm's own working memory per iteration (light vertices, merging
grids: core/render/iteration_memory.h), charged once the job's settings are known and before
the first iteration. The same worker then renders a job that fits, to an image equal to
`render`'s; `render --max-memory` refuses what the worker refuses."""

import os
import subprocess
import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402


class MemoryLimit(cluster.ClusterTestCase):
    def test_job_over_the_workers_memory_fails_and_the_worker_lives(self):
        P = cluster.pb()
        c = self.new_cluster(heartbeat=0.5)
        c.start_server()
        # 4 MiB: a 32x32 film's sums (5 x 24 B x 1024 = 120 KiB) and the Cornell box's meshes
        # fit; a 512x512 film (30 MiB) does not.
        worker = c.start_worker(threads=1, extra=["--max-memory", "4M"])
        c.wait_workers_registered(1)
        scene = cluster.cornell_box()

        big = c.api.submit(scene, algorithm="pt", iterations=4, resolution=(512, 512), seed=2,
                           name="too-big")
        failed = c.api.wait_job(big.id, states={P.JOB_STATE_FAILED}, timeout=60,
                                procs=[c.server, worker])
        print(f"job error: {failed.error}")
        self.assertIn("the film (512 x 512)", failed.error)
        self.assertIn("more than the 4.0 MiB limit (worker --max-memory 4.0 MiB)", failed.error)
        self.assertTrue(worker.alive(), "the worker died")

        # A 64x64 film (480 KiB) fits, but vcm's light vertices do not: 4096 light paths x up to
        # 9 stored vertices (the scene's max_depth 65 bounded by rr_depth 5 + 4) x 288 B, 10 MiB.
        light_paths = c.api.submit(scene, algorithm="vcm", iterations=4, resolution=(64, 64),
                                   seed=2, name="vcm-too-big")
        failed = c.api.wait_job(light_paths.id, states={P.JOB_STATE_FAILED}, timeout=60,
                                procs=[c.server, worker])
        print(f"job error: {failed.error}")
        self.assertIn("vcm's working memory per iteration (estimated ", failed.error)
        self.assertIn("4096 light paths x up to 9 stored vertices x 288 B", failed.error)
        self.assertIn("more than the 4.0 MiB limit (worker --max-memory 4.0 MiB)", failed.error)
        self.assertTrue(worker.alive(), "the worker died")

        small = c.api.submit(scene, algorithm="pt", iterations=4, resolution=(32, 32), seed=2,
                             name="fits")
        c.api.wait_job(small.id, timeout=60, procs=[c.server, worker])
        out = c.api.fetch_to(small.id, c.path("fits.exr"))
        self.assertImagesMatch(out, cluster.render_reference(scene, "pt", 4, (32, 32), 2))

    def test_render_max_memory_refuses_before_rendering(self):
        scene = cluster.cornell_box()
        out = self.new_cluster().path("vcm.exr")
        args = [cluster.binary("render"), scene, "--algo", "vcm", "--iterations", "1",
                "--resolution", "64x64", "--threads", "1", "--out", out]
        refused = subprocess.run(args + ["--max-memory", "4M"], capture_output=True, text=True,
                                 timeout=120)
        print(refused.stderr)
        self.assertEqual(refused.returncode, 1)
        self.assertIn("vcm's working memory per iteration (estimated ", refused.stderr)
        self.assertIn("more than the 4.0 MiB limit (render --max-memory 4.0 MiB)", refused.stderr)
        self.assertFalse(os.path.exists(out), "an image was written")
        # The same render within a limit that holds the estimate renders.
        fits = subprocess.run(args + ["--max-memory", "64M"], capture_output=True, text=True,
                              timeout=300)
        self.assertEqual(fits.returncode, 0, fits.stderr)
        self.assertTrue(os.path.exists(out))


if __name__ == "__main__":
    cluster.main()
