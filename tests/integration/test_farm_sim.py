"""Integration test: `farm_sim` (tools/farm_sim.cpp), simulated workers against a real server.

A few simulated workers render two jobs of made-up but exactly known sums through the real
worker protocol (register, lease, heartbeat, report), with every third report sent twice.
Correctness only, never timing:
* every job ends DONE with all its iterations;
* every lease granted was reported and merged; every duplicate report was dropped (and the
  server's metrics count exactly those merges and drops);
* the merged ranges of each frame tile [1, iterations] with no gap and no overlap;
* each finished image equals the mean of the made-up iteration values (iteration i gives value
  k the value 1 + ((i + k) mod 8) / 8), to float32 rounding: a range merged twice or lost would
  move some pixel by at least 1/(8 * iterations), far beyond that.
"""

import json
import os
import subprocess

import numpy as np

import cluster

WORKERS = 6
JOBS = 2
ITERATIONS = 240
WIDTH, HEIGHT = 16, 12


def expected_image(iterations, width, height):
    """The mean over iterations 1..N of the values farm_sim reports, as (height, width, 3)."""
    k = np.arange(width * height * 3)
    total = np.zeros(k.shape)
    for i in range(1, iterations + 1):
        total += 1.0 + ((i + k) % 8) / 8.0
    return (total / iterations).reshape(height, width, 3)


class FarmSimTest(cluster.ClusterTestCase):
    def test_simulated_workers_merge_every_range_once(self):
        # Short leases (0.05 s of simulated work: 10 iterations of 5 ms) make many leases.
        c = self.new_cluster(server_args=["--metrics", "127.0.0.1:0", "--lease-seconds", "0.05"])
        c.start_server()
        out = c.path("farm_sim.json")
        args = [cluster.binary("farm_sim"), "--server", c.address, "--workers", str(WORKERS),
                "--jobs", str(JOBS), "--iterations", str(ITERATIONS), "--iteration-ms", "5",
                "--resolution", f"{WIDTH}x{HEIGHT}", "--until-done", "--duplicate-every", "3",
                "--seconds", "120", "--server-pid", str(c.server.pid), "--json", out]
        run = subprocess.run(args, capture_output=True, text=True, timeout=300)
        self.assertEqual(run.returncode, 0, f"farm_sim failed:\n{run.stdout}\n{run.stderr}")
        with open(out) as f:
            r = json.load(f)
        print({k: r[k] for k in ("total_leases", "total_merged", "duplicates_sent",
                                 "duplicates_merged", "errors")})

        self.assertEqual(r["errors"], 0, r["first_errors"])
        self.assertEqual(len(r["jobs"]), JOBS)
        self.assertGreater(r["total_leases"], 2 * JOBS, "too few leases to test anything")
        self.assertEqual(r["total_merged"], r["total_leases"], "a lease was not merged")
        self.assertEqual(r["total_not_merged"], 0)
        self.assertEqual(r["cancelled"] + r["abandoned"], 0)
        self.assertGreater(r["duplicates_sent"], 0)
        self.assertEqual(r["duplicates_merged"], 0, "a duplicate report was merged")

        # The merged ranges of every frame tile [1, ITERATIONS + 1).
        self.assertEqual(sorted(r["merged_ranges"]), sorted(f"{j}/0" for j in r["jobs"]))
        for key, ranges in r["merged_ranges"].items():
            at = 1
            for first, end in ranges:
                self.assertEqual(first, at, f"{key}: gap or overlap at {first} ({ranges})")
                self.assertGreater(end, first)
                at = end
            self.assertEqual(at, ITERATIONS + 1, f"{key}: ranges end at {at}")

        # The server agrees: jobs DONE, and it merged and dropped exactly those reports.
        for job_id in r["jobs"]:
            job = c.api.get_job(job_id)
            self.assertEqual(job.state, cluster.pb().JOB_STATE_DONE)
            self.assertEqual(job.frames[0].iterations_done, ITERATIONS)
        status, _, body = cluster.http_get(c.http_addresses["metrics"], "/metrics")
        self.assertEqual(status, 200)
        m = cluster.parse_metrics(body.decode())
        self.assertEqual(m["render_reports_merged_total"], r["total_merged"])
        self.assertEqual(m["render_leases_granted_total"], r["total_leases"])
        dropped = sum(v for k, v in m.items() if k.startswith("render_reports_dropped_total"))
        self.assertEqual(dropped, r["duplicates_sent"])

        # Each image is the exact mean of the reported values (float32 in the EXR).
        want = expected_image(ITERATIONS, WIDTH, HEIGHT)
        for job_id in r["jobs"]:
            got = cluster.read_exr(c.api.fetch_to(job_id, c.path(f"{job_id}.exr")))
            ok, msg = cluster.compare_images(got, want, rel=1e-6, abs_=0)
            self.assertTrue(ok, f"{job_id}: {msg}")


if __name__ == "__main__":
    cluster.main()
