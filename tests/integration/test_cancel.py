"""Integration test 7: cancel a running long job. Within a heartbeat or two the workers stop
rendering it: ClusterStatus shows their leases cleared, their processes stop using CPU, and the
job's merged iteration count stops growing. Then the queue moves on: a next job completes with
the same image as `render`."""

import time

import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

HEARTBEAT = 0.5
SEED = 13
RES = (32, 32)
LONG_ITERATIONS = 20000  # minutes of work for 2 workers x 1 thread: it is cancelled long before


class Cancel(cluster.ClusterTestCase):
    def test_cancel_running_job(self):
        P = cluster.pb()
        c = self.new_cluster(heartbeat=HEARTBEAT, lease_timeout=5)
        c.start_server()
        workers = c.start_workers(2, threads=1)
        c.wait_workers_registered(2)
        scene = cluster.cornell_box()
        job = c.api.submit(scene, algorithm="vcm", iterations=LONG_ITERATIONS, resolution=RES,
                           seed=SEED, name="to-cancel")

        # Both workers render it (at least one within bounds), and some of it is merged.
        def busy():
            st = c.api.cluster_status()
            return sum(1 for w in st.workers if w.lease_id) >= 2
        try:
            cluster.wait_until(busy, timeout=20, what="both workers to hold leases")
        except AssertionError:
            cluster.wait_until(lambda: any(w.lease_id for w in c.api.cluster_status().workers),
                               timeout=10, what="a worker to hold a lease")
        time.sleep(1.0)
        running = c.api.get_job(job.id)
        self.assertEqual(running.state, P.JOB_STATE_RUNNING, str(running))

        cancelled = c.api.call(c.api.jobs.CancelJob, P.CancelJobRequest(job_id=job.id))
        t_cancel = time.monotonic()
        self.assertEqual(cancelled.state, P.JOB_STATE_CANCELLED, str(cancelled))

        # Leases cleared within two heartbeats (plus slack for process scheduling).
        bound = 2 * HEARTBEAT + 1.0

        def idle():
            st = c.api.cluster_status()
            return all(not w.lease_id for w in st.workers) and len(st.workers) >= 2
        cluster.wait_until(idle, timeout=bound, poll=0.05,
                           what=f"the workers' leases to clear within {bound} s of the cancel")
        print(f"leases cleared {time.monotonic() - t_cancel:.2f} s after CancelJob")

        # The worker processes really stopped rendering: almost no CPU over the next 1.5 s.
        time.sleep(0.3)
        cpu0 = [w.cpu_seconds() for w in workers]
        done0 = c.api.get_job(job.id)
        time.sleep(1.5)
        cpu1 = [w.cpu_seconds() for w in workers]
        for w, a, b in zip(workers, cpu0, cpu1):
            self.assertTrue(w.alive(), f"{w.name} died:\n{w.log_tail()}")
            self.assertLess(b - a, 0.5, f"{w.name} used {b - a:.2f} s of CPU in 1.5 s after "
                                        f"the cancel: it is still rendering")
        after = c.api.get_job(job.id)
        self.assertEqual(after.state, P.JOB_STATE_CANCELLED)
        self.assertEqual(after.frames[0].iterations_done, done0.frames[0].iterations_done,
                         "iterations were merged into a cancelled job")
        self.assertLess(after.frames[0].iterations_done, LONG_ITERATIONS)

        # The queue moves on.
        nxt = c.api.submit(scene, algorithm="vcm", iterations=16, resolution=RES, seed=SEED,
                           name="after-cancel")
        c.api.wait_job(nxt.id, timeout=60, procs=[c.server] + workers)
        out = c.api.fetch_to(nxt.id, c.path("next.exr"))
        print(self.assertImagesMatch(out, cluster.render_reference(scene, "vcm", 16, RES, SEED)))
        self.assertEqual(c.api.get_job(job.id).state, P.JOB_STATE_CANCELLED)

        # Cancelling a queued job (no worker free: none started for it) works too.
        for w in workers:
            w.kill()
        queued = c.api.submit(scene, algorithm="pt", iterations=8, resolution=RES, seed=SEED,
                              name="queued-cancel")
        got = c.api.call(c.api.jobs.CancelJob, P.CancelJobRequest(job_id=queued.id))
        self.assertEqual(got.state, P.JOB_STATE_CANCELLED)


if __name__ == "__main__":
    cluster.main()
