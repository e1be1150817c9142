"""Integration test: the per-pixel error layers (`layers` = `variance`,
docs/reference/variance-layers.md) of a service job equal `render --layers variance`'s for the
same iterations, bit for bit in every channel (image, variance, odd_half, even_half):
  * one worker, the job submitted through the API (`RenderSettings.options`);
  * two workers with short leases (many ranges merged in arrival order), the job submitted with
    `client submit --layers variance`;
  * two workers, the server killed with SIGKILL mid-job and restarted: the sums of squares come
    back from the checkpoint.
The design allows sums to differ in the order doubles were added (docs/design/design.md); the
float layers are compared exactly because that order changes a double in its last bits, far
below a float's resolution, so a difference would be a real error (a range merged twice or
lost, a layer not merged or not checkpointed)."""

import os
import subprocess
import sys
import time

sys.dont_write_bytecode = True  # keep the source tree clean
import numpy as np  # noqa: E402

import cluster  # noqa: E402

SEED = 11
RES = (32, 32)
LAYERS = ["variance", "odd_half", "even_half"]


class VarianceLayers(cluster.ClusterTestCase):
    def render(self, c, scene, algorithm, iterations, out):
        args = [cluster.binary("render"), scene, "--algo", algorithm, "--iterations",
                str(iterations), "--resolution", f"{RES[0]}x{RES[1]}", "--seed", str(SEED),
                "--threads", "2", "--layers", "variance", "--out", out]
        r = subprocess.run(args, capture_output=True, text=True, timeout=300,
                           start_new_session=True)
        self.assertEqual(r.returncode, 0, f"{' '.join(args)}:\n{r.stderr}")

    def assertLayersEqual(self, service, local):
        a, a_channels, _ = cluster.read_exr_channels(local)
        b, b_channels, _ = cluster.read_exr_channels(service)
        for name in LAYERS:
            for ch in "RGB":
                self.assertIn(f"{name}.{ch}", a_channels)
        self.assertEqual(a_channels, b_channels, "the same channels")
        self.assertTrue(np.all(np.isfinite(a)), "render wrote a non-finite value")
        variance = a[:, :, [a_channels.index(f"variance.{ch}") for ch in "RGB"]]
        self.assertGreater(float(variance.max()), 0.0, "a zero variance layer proves nothing")
        differ = int(np.sum(a != b))
        msg = f"{differ} of {a.size} values differ"
        if differ:
            y, x, k = np.argwhere(a != b)[0]
            msg += f"; first at ({x},{y}) {a_channels[k]}: {a[y, x, k]!r} vs {b[y, x, k]!r}"
        self.assertEqual(differ, 0, msg)
        return msg

    def test_one_worker_through_the_api(self):
        c = self.new_cluster()
        c.start_server()
        c.start_workers(1, threads=1)
        c.wait_workers_registered(1)
        scene = cluster.cornell_box()
        job = c.api.submit(scene, algorithm="pt", iterations=32, resolution=RES, seed=SEED,
                           name="variance-1", options={"layers": "variance"})
        done = c.api.wait_job(job.id, timeout=120, procs=[c.server] + c.workers)
        self.assertTrue(done.frames[0].done, str(done))
        out = c.api.fetch_to(job.id, c.path("service.exr"))
        ref = c.path("render.exr")
        self.render(c, scene, "pt", 32, ref)
        print("one worker:", self.assertLayersEqual(out, ref))

    def test_two_workers_through_client_submit(self):
        # Short leases: the job is cut into many ranges shared by both workers.
        c = self.new_cluster(server_args=["--lease-seconds", "0.05", "--max-lease-seconds",
                                          "0.2"])
        c.start_server()
        c.start_workers(2, threads=1)
        c.wait_workers_registered(2)
        scene = cluster.cornell_box()
        out = c.path("service.exr")
        args = [cluster.binary("client"), "--server", c.address, "submit", scene, "--algo",
                "pt", "--iterations", "200", "--resolution", f"{RES[0]}x{RES[1]}", "--seed",
                str(SEED), "--layers", "variance", "--out", out]
        env = {k: v for k, v in os.environ.items() if k not in ("RENDER_TOKEN", "RENDER_SERVER")}
        r = subprocess.run(args, capture_output=True, text=True, timeout=300, env=env,
                           stdin=subprocess.DEVNULL, start_new_session=True)
        self.assertEqual(r.returncode, 0, f"{' '.join(args)}:\n{r.stdout}\n{r.stderr}")
        reports = [w.log_text().count("event=reported ") for w in c.workers]
        self.assertTrue(all(n > 0 for n in reports), f"a worker merged nothing: {reports}")
        ref = c.path("render.exr")
        self.render(c, scene, "pt", 200, ref)
        print(f"two workers (reports merged per worker {reports}):",
              self.assertLayersEqual(out, ref))

    def test_server_restarted_mid_job(self):
        P = cluster.pb()
        c = self.new_cluster(lease_timeout=3, heartbeat=0.5,
                             server_args=["--checkpoint-seconds", "1"])
        port = c.start_server()
        c.start_workers(2, threads=1)
        c.wait_workers_registered(2)
        scene = cluster.cornell_box()
        # Long enough that a checkpoint (every second) comes before the end on a fast machine.
        iterations = 4000
        job = c.api.submit(scene, algorithm="pt", iterations=iterations, resolution=RES,
                           seed=SEED, name="variance-restart", options={"layers": "variance"})

        def checkpointed():
            with open(c.server.log_path, "rb") as f:
                return b"event=checkpoint " in f.read()

        state = {}

        def progressed():
            j = c.api.get_job(job.id)
            state["job"] = j
            done = j.frames[0].iterations_done if j.frames else 0
            return j.state == P.JOB_STATE_DONE or (2 < done < iterations and checkpointed())
        cluster.wait_until(progressed, timeout=60, poll=0.05, what="the job to make progress")
        before = state["job"]
        self.assertNotEqual(before.state, P.JOB_STATE_DONE,
                            "the job finished before the server could be killed; make it longer")
        c.kill_server()
        time.sleep(0.2)
        c.restart_server(port, workers=2)
        again = c.api.get_job(job.id)
        print(f"killed at {before.frames[0].iterations_done}, restored "
              f"{again.frames[0].iterations_done if again.frames else 0} of {iterations}")
        done = c.api.wait_job(job.id, timeout=180, procs=[c.server])
        self.assertEqual(done.frames[0].iterations_done, iterations, str(done))
        out = c.api.fetch_to(job.id, c.path("service.exr"))
        ref = c.path("render.exr")
        self.render(c, scene, "pt", iterations, ref)
        print("server restarted:", self.assertLayersEqual(out, ref))


if __name__ == "__main__":
    cluster.main()
