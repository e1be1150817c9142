"""Integration test: adaptive sampling in the service (docs/reference/adaptive-sampling.md,
"The service"). A job with `adaptive` > 0 is rendered in rounds: the server leases only within
the current round, takes the next round's mask from the merged exact sums with the function
`render` uses, and the workers render only the mask's pixels. The cluster's EXR (the image and
its `samples` layer) must equal `render --adaptive`'s bit for bit, with its iteration count:
  * with 1, 2 and 3 workers (short leases: each round is split among them), submitted through
    the API (options map) and with `client submit --adaptive ...`; and bpt (the bidirectional
    family) with 2 workers;
  * with a worker killed with SIGKILL while it holds a lease of a round after the first: its
    range is leased again, with the same mask, once the lease expires;
  * with the server killed with SIGKILL after a checkpoint in a round after the first and
    restarted: the round's mask comes back from the checkpoint (the log says which round).
The design allows the image's double sums to differ in the order they were added
(docs/design/design.md); the float channels are compared exactly because that order changes a
double in its last bits, far below a float's resolution, so a difference would be a real error
(a pixel given another count, a round with another mask, a range merged twice or lost).
Each case also checks that adaptive sampling did something: some pixels stopped early (the
samples layer is not uniform) after several rounds."""

import os
import re
import subprocess
import sys
import time

sys.dont_write_bytecode = True  # keep the source tree clean
import numpy as np  # noqa: E402

import cluster  # noqa: E402

SEED = 7
RES = (32, 32)
# A threshold that stops part of the Cornell box after a few rounds and leaves the rest to the
# iteration cap (render: about 18 of 160 iterations per pixel on average)...
OPTIONS = {"adaptive": "0.08", "adaptive_min_iterations": "8", "adaptive_round": "4"}
ITERATIONS = 160
# ...and one that stops every pixel long before the cap (render: after 60 of 400 iterations),
# so that the job ends because no pixel is left.
CONVERGING = {"adaptive": "0.5", "adaptive_min_iterations": "8", "adaptive_round": "4"}
CONVERGING_ITERATIONS = 400
# bpt: a threshold that stops part of the box after a few rounds.
BPT_OPTIONS = {"adaptive": "0.08", "adaptive_min_iterations": "8", "adaptive_round": "4"}


def option_flags(options):
    flags = []
    for name, value in options.items():
        flags += ["--" + name.replace("_", "-"), value]
    return flags


class Adaptive(cluster.ClusterTestCase):
    def render(self, c, scene, out, iterations=ITERATIONS, res=RES, options=OPTIONS,
               algorithm="pt"):
        args = [cluster.binary("render"), scene, "--algo", algorithm, "--iterations",
                str(iterations), "--resolution", f"{res[0]}x{res[1]}", "--seed", str(SEED),
                "--threads", "2", "--out", out] + option_flags(options)
        r = subprocess.run(args, capture_output=True, text=True, timeout=300,
                           start_new_session=True)
        self.assertEqual(r.returncode, 0, f"{' '.join(args)}:\n{r.stderr}")
        return r.stderr

    def assertSameExr(self, service, local, c):
        a, a_channels, a_header = cluster.read_exr_channels(local)
        b, b_channels, b_header = cluster.read_exr_channels(service)
        self.assertIn("samples.R", a_channels)
        self.assertEqual(a_channels, b_channels, "the same channels")
        self.assertTrue(np.all(np.isfinite(a)), "render wrote a non-finite value")
        samples = a[:, :, a_channels.index("samples.R")]
        # Adaptive sampling did something: some pixels stopped before others, after rounds.
        self.assertGreater(float(samples.max()), float(samples.min()),
                           "every pixel took every iteration: the mask did nothing")
        self.assertGreater(len(set(samples.ravel().tolist())), 2,
                           "fewer than two rounds after the first decided anything")
        self.assertEqual(a_header.get("render:iterations"), b_header.get("render:iterations"),
                         "the iteration count (the render stops when no pixel is left)")
        for key in ("render:adaptive", "render:adaptive_min_iterations",
                    "render:adaptive_round"):
            self.assertEqual(a_header.get(key), b_header.get(key), key)
        differ = int(np.sum(a != b))
        msg = (f"{differ} of {a.size} values differ; samples per pixel {samples.min():g}.."
               f"{samples.max():g} (mean {samples.mean():.2f}), "
               f"{a_header.get('render:iterations')} iterations")
        if differ:
            y, x, k = np.argwhere(a != b)[0]
            msg += f"; first at ({x},{y}) {a_channels[k]}: {a[y, x, k]!r} vs {b[y, x, k]!r}"
        self.assertEqual(differ, 0, msg)
        rounds = c.server.log_text().count("event=adaptive_round ") if c.server else 0
        return msg + f", {rounds} rounds taken by the server"

    def run_workers(self, workers, through_client, options=OPTIONS, iterations=ITERATIONS,
                    algorithm="pt"):
        # Short leases: every round is cut into ranges shared by the workers.
        c = self.new_cluster(server_args=["--lease-seconds", "0.02", "--max-lease-seconds",
                                          "0.05"])
        c.start_server()
        c.start_workers(workers, threads=1)
        c.wait_workers_registered(workers)
        scene = cluster.cornell_box()
        out = c.path("service.exr")
        if through_client:
            args = [cluster.binary("client"), "--server", c.address, "submit", scene, "--algo",
                    algorithm, "--iterations", str(iterations), "--resolution", f"{RES[0]}x{RES[1]}",
                    "--seed", str(SEED), "--out", out] + option_flags(options)
            env = {k: v for k, v in os.environ.items()
                   if k not in ("RENDER_TOKEN", "RENDER_SERVER")}
            r = subprocess.run(args, capture_output=True, text=True, timeout=300, env=env,
                               stdin=subprocess.DEVNULL, start_new_session=True)
            self.assertEqual(r.returncode, 0, f"{' '.join(args)}:\n{r.stdout}\n{r.stderr}")
        else:
            job = c.api.submit(scene, algorithm=algorithm, iterations=iterations,
                               resolution=RES, seed=SEED, name=f"adaptive-{workers}",
                               options=options)
            done = c.api.wait_job(job.id, timeout=180, procs=[c.server] + c.workers)
            self.assertTrue(done.frames[0].done, str(done))
            c.api.fetch_to(job.id, out)
        reports = [w.log_text().count("event=reported ") for w in c.workers]
        masks = [w.log_text().count("event=mask_fetched ") for w in c.workers]
        self.assertTrue(all(n > 0 for n in reports), f"a worker merged nothing: {reports}")
        self.assertGreater(sum(masks), 0, "no worker fetched a round's mask")
        ref = c.path("render.exr")
        self.render(c, scene, ref, iterations, RES, options, algorithm)
        print(f"{algorithm}, {workers} worker(s) (reports {reports}, masks fetched {masks}):",
              self.assertSameExr(out, ref, c))
        return cluster.read_exr_channels(out)[2]

    def test_one_worker_through_the_api(self):
        self.run_workers(1, through_client=False)

    def test_two_workers_through_client_submit(self):
        self.run_workers(2, through_client=True)

    def test_three_workers_until_no_pixel_is_left(self):
        header = self.run_workers(3, through_client=False, options=CONVERGING,
                                  iterations=CONVERGING_ITERATIONS)
        self.assertLess(int(header["render:iterations"]), CONVERGING_ITERATIONS,
                        "the job was to stop when no pixel was left, before the cap")

    def test_bpt_two_workers_through_the_api(self):
        # The bidirectional family: eye subpaths from the round's active pixels, the light pass
        # whole, its splats into inactive pixels dropped (docs/reference/adaptive-sampling.md,
        # "The bidirectional family"); the same image as render's.
        self.run_workers(2, through_client=False, options=BPT_OPTIONS, algorithm="bpt")

    def long_job(self, c, name):
        """A job of many rounds of long leases (128 x 128 pixels), submitted through the API."""
        scene = cluster.cornell_box()
        job = c.api.submit(scene, algorithm="pt", iterations=LONG_ITERATIONS, resolution=LONG_RES,
                           seed=SEED, name=name, options=LONG_OPTIONS)
        return scene, job

    def test_worker_killed_in_a_later_round(self):
        P = cluster.pb()
        c = self.new_cluster(lease_timeout=2, heartbeat=0.5,
                             server_args=["--lease-seconds", "5"])
        c.start_server()
        workers = c.start_workers(2, threads=1)
        c.wait_workers_registered(2)
        scene, job = self.long_job(c, "adaptive-killed")
        ids = {}

        def victim_leases_a_later_round():
            # A round after the first has begun, and a worker holds one of its leases.
            if c.server.log_text().count("event=adaptive_round ") < 1:
                return False
            for w in workers:
                m = re.findall(r"event=lease lease=(\S+) .*first=(\d+)", w.log_text())
                if m and int(m[-1][1]) > int(LONG_OPTIONS["adaptive_min_iterations"]):
                    st = c.api.cluster_status()
                    if any(s.lease_id == m[-1][0] for s in st.workers):
                        ids["victim"] = w
                        ids["lease"] = m[-1][0]
                        return True
            return c.api.get_job(job.id).state == P.JOB_STATE_DONE
        cluster.wait_until(victim_leases_a_later_round, timeout=120, poll=0.05,
                           what="a worker to hold a lease after the first round")
        self.assertIn("victim", ids, "the job finished before a worker could be killed")
        ids["victim"].kill()
        before = c.api.get_job(job.id).frames[0].iterations_done
        done = c.api.wait_job(job.id, timeout=300, procs=[c.server] + c.live_workers())
        self.assertTrue(done.frames[0].done, str(done))
        self.assertIn(f"event=lease_lost lease={ids['lease']}", c.server.log_text(),
                      "the killed worker's lease did not expire")
        out = c.api.fetch_to(job.id, c.path("service.exr"))
        ref = c.path("render.exr")
        self.render(c, scene, ref, LONG_ITERATIONS, LONG_RES, LONG_OPTIONS)
        print(f"worker killed holding {ids['lease']} at {before} iterations:",
              self.assertSameExr(out, ref, c))

    def test_server_restarted_in_a_later_round(self):
        P = cluster.pb()
        # Short leases: a round is merged range by range, so checkpoints fall inside rounds.
        c = self.new_cluster(lease_timeout=3, heartbeat=0.5,
                             server_args=["--checkpoint-seconds", "0.2", "--lease-seconds",
                                          "0.05", "--max-lease-seconds", "0.1"])
        port = c.start_server()
        c.start_workers(2, threads=1)
        c.wait_workers_registered(2)
        scene, job = self.long_job(c, "adaptive-restart")

        first_round_end = int(LONG_OPTIONS["adaptive_min_iterations"])
        length = int(LONG_OPTIONS["adaptive_round"])
        started = time.monotonic()

        def checkpointed_in_a_later_round():
            # A checkpoint of a round after the first: preferably in the middle of the round
            # (part of its ranges merged), else, after 20 s, at its start.
            if c.api.get_job(job.id).state == P.JOB_STATE_DONE:
                return True
            text = c.server.log_text()
            at = text.find("event=adaptive_round ")
            if at < 0:
                return False
            counts = [int(n) for n in
                      re.findall(r"event=checkpoint .*?iterations=(\d+)", text[at:])]
            mid = [n for n in counts if n > first_round_end and (n - first_round_end) % length]
            return bool(mid) or bool(counts and time.monotonic() - started > 20)
        cluster.wait_until(checkpointed_in_a_later_round, timeout=180, poll=0.05,
                           what="a checkpoint after the first round")
        before = c.api.get_job(job.id)
        self.assertNotEqual(before.state, P.JOB_STATE_DONE,
                            "the job finished before the server could be killed")
        c.kill_server()
        time.sleep(0.2)
        c.restart_server(port, workers=2)
        restored = re.findall(r"event=adaptive_round_restored .*?round=(\d+)",
                              c.server.log_text())
        restored_at = re.findall(r"event=adaptive_round_restored .*?iterations=(\d+)",
                                 c.server.log_text())
        self.assertTrue(restored and int(restored[0]) >= 1,
                        f"the checkpoint did not bring back a round after the first: {restored}")
        done = c.api.wait_job(job.id, timeout=300, procs=[c.server])
        self.assertTrue(done.frames[0].done, str(done))
        out = c.api.fetch_to(job.id, c.path("service.exr"))
        ref = c.path("render.exr")
        self.render(c, scene, ref, LONG_ITERATIONS, LONG_RES, LONG_OPTIONS)
        print(f"server killed at {before.frames[0].iterations_done} iterations, restored in "
              f"round {restored[0]} with {restored_at[0]} iterations:",
              self.assertSameExr(out, ref, c))

    def test_refused_where_render_refuses_it(self):
        c = self.new_cluster()
        c.start_server()
        scene = cluster.cornell_box()
        import grpc
        for algorithm, options, expected in (
                ("eyelight", {"adaptive": "0.05"}, "not read by algorithm eyelight (read by pt"),
                ("pt", {"adaptive": "0.05", "layers": "variance"}, "--layers is not supported"),
                ("pt", {"adaptive": "0.05", "adaptive_min_iterations": "1"},
                 "adaptive_min_iterations")):
            with self.subTest(algorithm=algorithm, options=options):
                with self.assertRaises(grpc.RpcError) as e:
                    c.api.submit(scene, algorithm=algorithm, iterations=16, resolution=RES,
                                 options=options)
                self.assertEqual(e.exception.code(), grpc.StatusCode.INVALID_ARGUMENT)
                self.assertIn(expected, e.exception.details())


# The long jobs: 128 x 128 pixels, rounds of 8 iterations (a lease of a later round takes a tenth
# of a second or more of one thread), a threshold that leaves pixels active for many rounds
# (render: about 100 of 160 iterations per pixel on average).
LONG_RES = (128, 128)
LONG_OPTIONS = {"adaptive": "0.005", "adaptive_min_iterations": "8", "adaptive_round": "8"}
LONG_ITERATIONS = 160


if __name__ == "__main__":
    cluster.main()
