"""A renderer that throws during a lease fails the lease, never the worker.

Workers whose renderer throws (the worker's test-only flag --test-render-fault stands for
whatever the renderer cannot handle: the real causes are refused at load,
docs/guide/reliability.md) report
the lease as failed with the exception's message and stay alive; once both workers the server
knows failed it, the job FAILS with that message. An exception that is not a std::exception
fails the lease the same way. Then a healthy worker renders the next job on the same farm."""

import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402



def scene():
    return cluster.scene_path("smallvcm", "1-glm_c.xml")


class WorkerRenderThrows(cluster.ClusterTestCase):
    def fail_with(self, c, hook, expected):
        P = cluster.pb()
        for _ in range(2):
            c.start_worker(threads=1, extra=["--test-render-fault", hook])
        c.wait_workers_registered(2)
        job = c.api.submit(scene(), algorithm="pt", iterations=8, resolution=(16, 16), seed=3,
                           name=f"throws-{hook}")
        failed = c.api.wait_job(job.id, states={P.JOB_STATE_FAILED}, timeout=60,
                                procs=[c.server])
        print(f"job error: {failed.error}")
        self.assertIn("failed on 2 workers", failed.error)
        self.assertIn(expected, failed.error)
        self.assertEqual(sum(f.iterations_done for f in failed.frames), 0)
        # Both workers are still alive: a failed lease is not a crash.
        self.assertEqual(len(c.live_workers()), 2, c.logs())
        for w in c.live_workers():
            w.stop()

    def test_a_throwing_renderer_fails_the_job_and_no_worker(self):
        P = cluster.pb()
        c = self.new_cluster(heartbeat=0.5)
        c.start_server()
        self.fail_with(c, "throw:the renderer met something it cannot render",
                       "the renderer met something it cannot render")
        self.fail_with(c, "non-std", "not a std::exception")
        c.start_worker(threads=1)
        again = c.api.submit(scene(), algorithm="pt", iterations=4, resolution=(16, 16), seed=3,
                             name="healthy")
        done = c.api.wait_job(again.id, timeout=120, procs=[c.server])
        self.assertEqual(done.state, P.JOB_STATE_DONE)
        self.assertEqual(done.frames[0].iterations_done, 4)


if __name__ == "__main__":
    cluster.main()
