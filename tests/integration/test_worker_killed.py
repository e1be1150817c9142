"""Integration test 2: a worker killed with SIGKILL in the middle of a job. Its lease expires
(server --lease-timeout 2), the range goes back to the queue, another worker renders it, and
the job completes with the same image as `render` in one process."""

import time

import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

SEED = 11
ALGO = "vcm"
ITERATIONS = 1000  # ~8 s of one thread at 32x32: long enough to kill a worker mid-job
RESOLUTION = (32, 32)
LEASE_TIMEOUT = 2


class WorkerKilled(cluster.ClusterTestCase):
    def test_sigkill_worker_mid_job(self):
        P = cluster.pb()
        c = self.new_cluster(lease_timeout=LEASE_TIMEOUT, heartbeat=0.5)
        c.start_server()
        victim = c.start_worker(threads=1)
        c.wait_workers_registered(1)
        scene = cluster.cornell_box()
        job = c.api.submit(scene, algorithm=ALGO, iterations=ITERATIONS, resolution=RESOLUTION,
                           seed=SEED, name="worker-killed")

        # Wait until the only worker holds a lease of the job, then kill it mid-range.
        def leased():
            st = c.api.cluster_status()
            return any(w.lease_id for w in st.workers)
        cluster.wait_until(leased, timeout=30, what="the worker to hold a lease")
        time.sleep(0.5)  # let it render part of the range
        before = c.api.get_job(job.id)
        self.assertNotEqual(before.state, P.JOB_STATE_DONE,
                            "the job finished before the worker could be killed; make it longer")
        victim.kill()
        print(f"killed {victim.name} at {before.frames[0].iterations_done if before.frames else 0}"
              f"/{ITERATIONS} iterations")

        # A fresh worker finishes the job once the dead worker's lease has expired.
        c.start_worker(threads=1)
        done = c.api.wait_job(job.id, timeout=90, procs=[c.server] + c.live_workers())
        self.assertEqual(done.frames[0].iterations_done, ITERATIONS, str(done))
        out = c.api.fetch_to(job.id, c.path("killed.exr"))
        ref = cluster.render_reference(scene, ALGO, ITERATIONS, RESOLUTION, SEED)
        print(self.assertImagesMatch(out, ref))
        self.assertTrue(c.server.alive(), "the server died")


    def test_job_fails_once_three_workers_die_on_it(self):
        """A poison job (one that kills every worker that renders it) must not take the farm
        down for ever: each dead worker's lease expires, and after three distinct workers lost
        it with no merged report in between, the job FAILS with a message saying so."""
        P = cluster.pb()
        c = self.new_cluster(lease_timeout=LEASE_TIMEOUT, heartbeat=0.5)
        c.start_server()
        scene = cluster.cornell_box()
        # 512x512 vcm: a first lease takes about a second, so each worker is killed before it
        # can report (a merged report would clear the count).
        job = c.api.submit(scene, algorithm=ALGO, iterations=ITERATIONS, resolution=(512, 512),
                           seed=SEED, name="poison")
        for victim_number in range(3):
            victim = c.start_worker(threads=1)

            def holds_lease():
                st = c.api.cluster_status()
                return any(w.lease_id for w in st.workers if w.worker_id and w.lease_id)
            cluster.wait_until(holds_lease, timeout=30, what=f"worker {victim_number} to lease")
            victim.kill()
            state = c.api.get_job(job.id)
            self.assertEqual(state.frames[0].iterations_done if state.frames else 0, 0,
                             "a report was merged before the kill; make the range slower")
            if victim_number < 2:
                # Its lease expires; the job waits for the next worker.
                time.sleep(LEASE_TIMEOUT + 1.5)
                self.assertEqual(c.api.get_job(job.id).state, P.JOB_STATE_RUNNING)
        done = c.api.wait_job(job.id, states={P.JOB_STATE_FAILED}, timeout=30,
                              procs=[c.server])
        self.assertEqual(done.state, P.JOB_STATE_FAILED, str(done))
        self.assertIn("failed on 3 workers (3 lost the lease", done.error)
        self.assertTrue(c.server.alive(), "the server died")


if __name__ == "__main__":
    cluster.main()
