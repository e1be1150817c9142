"""The server on PostgreSQL (`server --store postgresql://... --data DIR`), against a
PostgreSQL of the test's own (postgres_instance.py; the test skips, with the reason, where
PostgreSQL is not installed). A job renders to the same image as `render` in one process, the
server is killed with SIGKILL mid-job and restarted on the same database, and the job resumes
and completes with that image: no range lost or merged twice across the restart. The jobs live
in the database, not in a SQLite file in the data folder."""

import os
import sys
import time

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402
from postgres_instance import PostgresClusterTestCase  # noqa: E402

SEED = 5
ALGO = "vcm"
ITERATIONS = 1000  # ~4 s for 2 workers x 1 thread at 32x32
RESOLUTION = (32, 32)


class PostgresStore(PostgresClusterTestCase):
    def test_renders_as_render_and_resumes_after_a_restart(self):
        P = cluster.pb()
        c = self.new_cluster(lease_timeout=3, heartbeat=0.5)
        data = c.store  # the cluster's store folder holds the files; the queue is in PostgreSQL
        c.store = self.pg.url()
        c.server_args = ["--data", data, "--checkpoint-seconds", "1"]
        port = c.start_server()
        c.start_workers(2, threads=1)
        c.wait_workers_registered(2)
        scene = cluster.cornell_box()
        job = c.api.submit(scene, algorithm=ALGO, iterations=ITERATIONS, resolution=RESOLUTION,
                           seed=SEED, name="postgres-restart")
        self.assertEqual(self.pg.psql(f"SELECT name FROM jobs WHERE id = '{job.id}'"),
                         ["postgres-restart"])

        # Kill the server once part of the job is merged and checkpointed (or, at the latest,
        # 6 s after the workers started rendering it).
        state = {}

        def checkpointed():
            with open(c.server.log_path, "rb") as f:
                return b"event=checkpoint " in f.read()

        def progressed():
            j = c.api.get_job(job.id)
            st = c.api.cluster_status()
            state["job"] = j
            done = j.frames[0].iterations_done if j.frames else 0
            if any(w.lease_id for w in st.workers) and "leased_at" not in state:
                state["leased_at"] = time.monotonic()
            if j.state == P.JOB_STATE_DONE:
                return True
            if 2 < done < ITERATIONS and checkpointed():
                return True
            return "leased_at" in state and time.monotonic() - state["leased_at"] > 6
        cluster.wait_until(progressed, timeout=40, poll=0.05, what="the job to make progress")
        before = state["job"]
        self.assertNotEqual(before.state, P.JOB_STATE_DONE,
                            "the job finished before the server could be killed; make it longer")
        # The checkpoint's ranges are recorded in the database.
        merged = self.pg.psql(f"SELECT count(*) FROM merged_ranges WHERE job_id = '{job.id}'")
        print(f"killed the server at {before.frames[0].iterations_done}/{ITERATIONS} "
              f"iterations, {merged[0]} merged ranges recorded in PostgreSQL")
        c.kill_server()

        c.restart_server(port, workers=2)

        again = c.api.get_job(job.id)
        self.assertEqual(again.id, job.id)
        self.assertIn(again.state, (P.JOB_STATE_QUEUED, P.JOB_STATE_RUNNING, P.JOB_STATE_DONE),
                      str(again))
        print(f"restored {again.frames[0].iterations_done} iterations from the checkpoint")
        self.assertLessEqual(again.frames[0].iterations_done, ITERATIONS)

        done = c.api.wait_job(job.id, timeout=120, procs=[c.server])
        self.assertEqual(done.frames[0].iterations_done, ITERATIONS, str(done))
        out = c.api.fetch_to(job.id, c.path("postgres.exr"))
        ref = cluster.render_reference(scene, ALGO, ITERATIONS, RESOLUTION, SEED)
        print(self.assertImagesMatch(out, ref))

        # The finished job's state and its frame are in the database; no SQLite store was made.
        self.assertEqual(self.pg.psql(f"SELECT state FROM jobs WHERE id = '{job.id}'"),
                         [str(P.JOB_STATE_DONE)])
        self.assertEqual(self.pg.psql(f"SELECT done FROM frames WHERE job_id = '{job.id}'"),
                         ["1"])
        self.assertFalse(os.path.exists(os.path.join(data, "render.db")))


if __name__ == "__main__":
    cluster.main()
