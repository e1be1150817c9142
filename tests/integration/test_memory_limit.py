"""A job whose scene and film need more memory than its worker may use fails with that message,
and the worker lives on (docs/guide/reliability.md, "The memory budget"). The worker estimates the job's memory before allocating it
(the film's sums, then each mesh, grid, image and file the loaders read: core/base/
memory_budget.h) against `worker --max-memory`; over it, the lease fails with the estimate and
the limit. The same holds for the algorithm's own working memory per iteration (light
vertices, merging grids: core/render/iteration_memory.h), charged once the job's settings are
known and before the first iteration. `render --max-memory` refuses what the worker refuses.

A refusal for memory is not a failure of the job (it counted toward the poison rule before, so
small workers failed jobs a larger worker could render): the job is not offered to that worker
again and waits for a worker with more memory (Job.waiting, the dashboard and
render_job_waiting_for_memory_bytes say so); it FAILS with the refusal's message only once
every live worker refused it (or is known to have less memory than it needs) for
`server --memory-wait` seconds. Tested both ways: two 4 MiB workers and --memory-wait 2 fail
the jobs, and the same workers then render a job that fits, to an image equal to `render`'s; a
4 MiB worker refuses a vcm job, which waits, and a larger worker started later renders it to an
image equal to `render`'s."""

import json
import os
import subprocess
import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402


class MemoryLimit(cluster.ClusterTestCase):
    def test_job_over_the_workers_memory_fails_and_the_worker_lives(self):
        P = cluster.pb()
        c = self.new_cluster(heartbeat=0.5, server_args=["--memory-wait", "2"])
        c.start_server()
        # 4 MiB: a 32x32 film's sums (5 x 24 B x 1024 = 120 KiB) and the Cornell box's meshes
        # fit; a 512x512 film (30 MiB) does not. Two such workers: the jobs fail once both
        # refused them and no larger worker joined within --memory-wait 2 s.
        worker = c.start_worker(threads=1, extra=["--max-memory", "4M"])
        other = c.start_worker(threads=1, extra=["--max-memory", "4M"])
        c.wait_workers_registered(2)
        scene = cluster.cornell_box()

        big = c.api.submit(scene, algorithm="pt", iterations=4, resolution=(512, 512), seed=2,
                           name="too-big")
        failed = c.api.wait_job(big.id, states={P.JOB_STATE_FAILED}, timeout=60,
                                procs=[c.server, worker, other])
        print(f"job error: {failed.error}")
        self.assertIn("no worker has the memory for this job: refused for memory by 2 workers",
                      failed.error)
        self.assertIn("(server --memory-wait)", failed.error)
        self.assertIn("the film (512 x 512)", failed.error)
        self.assertIn("more than the 4.0 MiB limit (worker --max-memory 4.0 MiB)", failed.error)
        self.assertTrue(worker.alive() and other.alive(), "a worker died")

        # A 64x64 film (480 KiB) fits, but vcm's light vertices do not: 4096 light paths x up to
        # 9 stored vertices (the scene's max_depth 65 bounded by rr_depth 5 + 4) x 188 B (a
        # 128-B light vertex and its 60-B merge index), 6.6 MiB.
        light_paths = c.api.submit(scene, algorithm="vcm", iterations=4, resolution=(64, 64),
                                   seed=2, name="vcm-too-big")
        failed = c.api.wait_job(light_paths.id, states={P.JOB_STATE_FAILED}, timeout=60,
                                procs=[c.server, worker, other])
        print(f"job error: {failed.error}")
        self.assertIn("vcm's working memory per iteration (estimated ", failed.error)
        self.assertIn("4096 light paths x up to 9 stored vertices x 188 B", failed.error)
        self.assertIn("more than the 4.0 MiB limit (worker --max-memory 4.0 MiB)", failed.error)
        self.assertTrue(worker.alive(), "the worker died")

        small = c.api.submit(scene, algorithm="pt", iterations=4, resolution=(32, 32), seed=2,
                             name="fits")
        c.api.wait_job(small.id, timeout=60, procs=[c.server, worker, other])
        out = c.api.fetch_to(small.id, c.path("fits.exr"))
        self.assertImagesMatch(out, cluster.render_reference(scene, "pt", 4, (32, 32), 2))

    def test_job_refused_for_memory_waits_for_a_larger_worker(self):
        P = cluster.pb()
        c = self.new_cluster(heartbeat=0.5, server_args=["--memory-wait", "600",
                                                         "--metrics", "127.0.0.1:0",
                                                         "--http", "127.0.0.1:0"])
        c.start_server()
        small = c.start_worker(threads=1, extra=["--max-memory", "4M"])
        c.wait_workers_registered(1)
        scene = cluster.cornell_box()
        # vcm's light vertices at 64x64 need about 9 MiB (see above): the small worker refuses.
        job = c.api.submit(scene, algorithm="vcm", iterations=4, resolution=(64, 64), seed=2,
                           name="vcm-waits")

        def waiting():
            j = c.api.get_job(job.id)
            self.assertNotEqual(j.state, P.JOB_STATE_FAILED, j.error)
            return j if j.waiting else None
        j = cluster.wait_until(waiting, timeout=60, what="the job waiting for memory")
        print(f"job waiting: {j.waiting}")
        self.assertIn("waiting for a worker with more than 4.0 MiB of memory: the job needs at "
                      "least ", j.waiting)
        self.assertIn("refused for memory by 1 worker;", j.waiting)
        self.assertEqual(j.frames[0].iterations_done, 0)
        _, _, body = cluster.http_get(c.http_addresses["metrics"], "/metrics")
        metrics = cluster.parse_metrics(body.decode())
        self.assertEqual(metrics["render_leases_refused_memory_total"], 1)
        self.assertEqual(metrics["render_leases_failed_total"], 0)
        self.assertGreater(metrics[f'render_job_waiting_for_memory_bytes{{job="{job.id}"}}'],
                           4 << 20)
        # Leased once (refused), no lease held: shown as WAITING, not RUNNING, everywhere.
        self.assertEqual(j.state, P.JOB_STATE_WAITING)
        self.assertEqual((metrics['render_jobs{state="waiting"}'],
                          metrics['render_jobs{state="running"}']), (1, 0))
        status = c.api.cluster_status()
        self.assertEqual((status.waiting_jobs, status.running_jobs, status.queued_jobs),
                         (1, 0, 0))
        listed = subprocess.run([cluster.binary("client"), "--server", c.address, "list"],
                                capture_output=True, text=True, timeout=60)
        self.assertEqual(listed.returncode, 0, listed.stderr)
        row = next(line for line in listed.stdout.splitlines() if line.startswith(job.id))
        self.assertIn(" WAITING ", row, listed.stdout)
        shown = subprocess.run([cluster.binary("client"), "--server", c.address, "status"],
                               capture_output=True, text=True, timeout=60)
        self.assertIn("0 queued, 0 running, 1 waiting for memory job(s)", shown.stdout)
        _, _, body = cluster.http_get(c.http_addresses["http"], "/api/jobs")
        api_jobs = json.loads(body.decode())
        api_job = next(x for x in api_jobs["jobs"] if x["id"] == job.id)
        self.assertEqual(api_job["state"], "JOB_STATE_WAITING")  # the dashboard's source

        # A worker with enough memory joins and renders it; the small one was not offered the
        # job again (one refusal in the log).
        large = c.start_worker(threads=1, extra=["--max-memory", "1G"])
        done = c.api.wait_job(job.id, timeout=180, procs=[c.server, small, large])
        self.assertEqual(done.waiting, "")
        self.assertEqual(c.server.log_tail(2000).count("event=lease_refused_memory"), 1)
        out = c.api.fetch_to(job.id, c.path("vcm.exr"))
        self.assertImagesMatch(out, cluster.render_reference(scene, "vcm", 4, (64, 64), 2))
        self.assertTrue(small.alive(), "the small worker died")

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
