"""Integration test 3: the server killed with SIGKILL mid-job and restarted on the same store
(and the same port, so that the running workers reconnect by themselves; if the port cannot be
taken again, a new port and new workers). The job resumes and completes with the same image as
`render` in one process. The image equality shows that no range was merged twice (a range
merged twice would add its iterations' light twice) and none was lost. The server checkpoints
every second (`--checkpoint-seconds 1`, default 30), so that the kill lands after some
checkpoints, with ranges merged since the last one: those are leased again after the
restart."""

import time

import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

SEED = 5
ALGO = "vcm"
ITERATIONS = 1000  # ~4 s for 2 workers x 1 thread at 32x32
RESOLUTION = (32, 32)


class ServerRestart(cluster.ClusterTestCase):
    def test_sigkill_server_mid_job(self):
        P = cluster.pb()
        c = self.new_cluster(lease_timeout=3, heartbeat=0.5,
                             server_args=["--checkpoint-seconds", "1"])
        port = c.start_server()
        c.start_workers(2, threads=1)
        c.wait_workers_registered(2)
        scene = cluster.cornell_box()
        job = c.api.submit(scene, algorithm=ALGO, iterations=ITERATIONS, resolution=RESOLUTION,
                           seed=SEED, name="server-restart")

        # Kill the server once part of the job is merged (or, at the latest, 6 s after the
        # workers started rendering it).
        state = {}

        def checkpointed():
            with open(c.server.log_path, "rb") as f:
                return b"event=checkpoint " in f.read()

        def progressed():
            j = c.api.get_job(job.id)
            st = c.api.cluster_status()
            state["job"] = j
            done = j.frames[0].iterations_done if j.frames else 0
            leased = any(w.lease_id for w in st.workers)
            if leased and "leased_at" not in state:
                state["leased_at"] = time.monotonic()
            if j.state == P.JOB_STATE_DONE:
                return True
            # More than the first (calibration) iteration of each worker merged, a checkpoint
            # written (every second), and the workers in the middle of their next ranges.
            if 2 < done < ITERATIONS and checkpointed():
                return True
            return "leased_at" in state and time.monotonic() - state["leased_at"] > 6
        cluster.wait_until(progressed, timeout=40, poll=0.05, what="the job to make progress")
        before = state["job"]
        self.assertNotEqual(before.state, P.JOB_STATE_DONE,
                            "the job finished before the server could be killed; make it longer")
        c.kill_server()
        print(f"killed the server at {before.frames[0].iterations_done if before.frames else 0}"
              f"/{ITERATIONS} iterations")

        c.restart_server(port, workers=2)

        # The job survived the restart.
        again = c.api.get_job(job.id)
        self.assertEqual(again.id, job.id)
        self.assertIn(again.state, (P.JOB_STATE_QUEUED, P.JOB_STATE_RUNNING, P.JOB_STATE_DONE),
                      str(again))
        if before.frames and again.frames:
            # Work merged and checkpointed before the kill may be partly lost, never more than
            # the target, and the count never exceeds what was merged.
            self.assertLessEqual(again.frames[0].iterations_done, ITERATIONS)
            print(f"restored {again.frames[0].iterations_done} iterations from the checkpoint")

        done = c.api.wait_job(job.id, timeout=120, procs=[c.server])
        self.assertEqual(done.frames[0].iterations_done, ITERATIONS, str(done))
        out = c.api.fetch_to(job.id, c.path("restart.exr"))
        ref = cluster.render_reference(scene, ALGO, ITERATIONS, RESOLUTION, SEED)
        print(self.assertImagesMatch(out, ref))

        # The queue still works after the restart.
        small = c.api.submit(scene, algorithm="pt", iterations=8, resolution=RESOLUTION,
                             seed=SEED, name="after-restart")
        c.api.wait_job(small.id, timeout=60, procs=[c.server])
        out2 = c.api.fetch_to(small.id, c.path("after.exr"))
        self.assertImagesMatch(out2, cluster.render_reference(scene, "pt", 8, RESOLUTION, SEED))


if __name__ == "__main__":
    cluster.main()
