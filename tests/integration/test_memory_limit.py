"""A job whose scene and film need more memory than its worker may use fails with that message,
and the worker lives on (issue 18). The worker estimates the job's memory before allocating it
(the film's sums, then each mesh, grid, image and file the loaders read: core/base/
memory_budget.h) against `worker --max-memory`; over it, the lease fails with the estimate and
the limit, and since every worker the server knows failed it, the job FAILS with that error.
The same worker then renders a job that fits, to an image equal to `render`'s."""

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

        small = c.api.submit(scene, algorithm="pt", iterations=4, resolution=(32, 32), seed=2,
                             name="fits")
        c.api.wait_job(small.id, timeout=60, procs=[c.server, worker])
        out = c.api.fetch_to(small.id, c.path("fits.exr"))
        self.assertImagesMatch(out, cluster.render_reference(scene, "pt", 4, (32, 32), 2))


if __name__ == "__main__":
    cluster.main()
