"""Integration test: the server's Prometheus metrics (`server --metrics HOST:PORT`).

1. A real job on a real worker: scrapes before, during and after it; the counters move (leases
   granted, reports merged, bytes received, histogram counts), the worker's rates and the job's
   iterations/s show up while it runs, a SIGKILLed worker's lease shows up as expired and
   requeued, and the finished job is counted as done.
2. A fake worker over the raw WorkerService: the rates it sends with a heartbeat are exported
   as its per-worker gauges exactly, a lease it reports as failed counts as failed and
   requeued (and fails the job: one known worker), and a report of an unknown lease counts as
   dropped.
3. The exposition of a fresh server, of one running a job (per-worker and per-job series) and
   of one whose job was cancelled passes `promtool check metrics` (Debian `prometheus`, which
   scripts/setup installs). Without promtool this case is skipped, never passed: CTest runs it
   as its own test, integration.test_metrics.promtool (tests/CMakeLists.txt)."""

import shutil
import subprocess
import time

import numpy as np

import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

SEED = 5
ALGO = "vcm"
ITERATIONS = 1000  # several seconds of one thread at 32x32: time to scrape and kill mid-job
RESOLUTION = (32, 32)
LEASE_TIMEOUT = 2


def scrape(c):
    status, ctype, body = cluster.http_get(c.http_addresses["metrics"], "/metrics")
    assert status == 200, f"/metrics answered {status}: {body[:200]!r}"
    assert ctype.startswith("text/plain"), ctype
    text = body.decode()
    return text, cluster.parse_metrics(text)


def check_with_promtool(test, promtool, text, what):
    r = subprocess.run([promtool, "check", "metrics"], input=text, capture_output=True,
                       text=True, timeout=60)
    test.assertEqual(r.returncode, 0,
                     f"promtool check metrics ({what}):\n{r.stdout}\n{r.stderr}\n{text}")
    print(f"promtool check metrics ({what}): ok")


class Metrics(cluster.ClusterTestCase):
    def test_counters_move_and_killed_worker_expires(self):
        P = cluster.pb()
        c = self.new_cluster(lease_timeout=LEASE_TIMEOUT, heartbeat=0.5,
                             server_args=["--metrics", "127.0.0.1:0"])
        c.start_server()
        _, m0 = scrape(c)
        for name in ("render_leases_granted_total", "render_leases_expired_total",
                     "render_leases_requeued_total", "render_leases_failed_total",
                     "render_reports_merged_total", "render_workers_connected",
                     "render_queue_iterations", "render_merge_seconds_count",
                     "render_store_seconds_count", "render_report_bytes_count",
                     'render_jobs{state="done"}', 'render_reports_dropped_total{reason="duplicate"}',
                     'render_received_bytes_total{kind="report"}'):
            self.assertIn(name, m0, f"{name} missing from a fresh server's metrics")
            self.assertEqual(m0[name], 0, name)

        victim = c.start_worker(threads=1)
        c.wait_workers_registered(1)
        job = c.api.submit(cluster.cornell_box(), algorithm=ALGO, iterations=ITERATIONS,
                           resolution=RESOLUTION, seed=SEED, name="metrics")
        # The job is queued: its iterations count in the queue until leased.
        _, m = scrape(c)
        self.assertEqual(m['render_jobs{state="queued"}'] + m['render_jobs{state="running"}'], 1)
        self.assertGreater(m['render_received_bytes_total{kind="asset"}'], 0)

        # While it runs: leases granted, reports merged, rates, bytes, histograms.
        def merged_twice():
            _, m = scrape(c)
            return m if m["render_reports_merged_total"] >= 2 else None
        m1 = cluster.wait_until(merged_twice, timeout=60, poll=0.2, what="two merged reports")
        self.assertGreaterEqual(m1["render_leases_granted_total"], 2)
        self.assertEqual(m1["render_workers_connected"], 1)
        self.assertEqual(m1["render_merge_seconds_count"], m1["render_reports_merged_total"])
        self.assertEqual(m1["render_store_seconds_count"], m1["render_reports_merged_total"])
        self.assertGreaterEqual(m1["render_report_bytes_count"], m1["render_reports_merged_total"])
        # A report holds sum and odd sum, 32 x 32 x 3 float64 each; a one-iteration report (the
        # worker's first) sum alone (ReportHeader.odd_sum_omitted).
        min_report = RESOLUTION[0] * RESOLUTION[1] * 3 * 8
        self.assertGreaterEqual(m1['render_received_bytes_total{kind="report"}'],
                                m1["render_reports_merged_total"] * min_report)
        self.assertEqual(m1['render_received_bytes_total{kind="report"}'],
                         m1["render_report_bytes_sum"])
        rates = {k: v for k, v in m1.items()
                 if k.startswith("render_worker_iterations_per_second{")}
        self.assertEqual(len(rates), 1, str(rates))
        self.assertGreater(next(iter(rates.values())), 0)
        rays = [v for k, v in m1.items() if k.startswith("render_worker_rays_per_second{")]
        self.assertTrue(rays and rays[0] > 0, f"no positive ray rate: {rays}")
        job_rate = m1.get(f'render_job_iterations_per_second{{job="{job.id}"}}')
        self.assertIsNotNone(job_rate, "the running job has no iterations/s gauge")
        self.assertGreater(job_rate, 0)
        self.assertLess(m1[f'render_job_relative_error{{job="{job.id}"}}'], 1)
        self.assertEqual(m1["render_leases_expired_total"], 0)

        # SIGKILL the worker while it holds a lease: the lease expires and is requeued.
        def leased():
            st = c.api.cluster_status()
            return any(w.lease_id for w in st.workers)
        cluster.wait_until(leased, timeout=30, what="the worker to hold a lease")
        self.assertNotEqual(c.api.get_job(job.id).state, P.JOB_STATE_DONE,
                            "the job finished before the worker could be killed; make it longer")
        victim.kill()

        # It may hold two leases (the one it renders and one whose report is in flight,
        # docs/guide/service.md); one granted after its last heartbeat expires later: wait for both.
        def expired():
            _, m = scrape(c)
            return m if m["render_leases_expired_total"] >= 1 and \
                m["render_leases_active"] == 0 else None
        m2 = cluster.wait_until(expired, timeout=LEASE_TIMEOUT + 20, poll=0.25,
                                what="the killed worker's leases to expire")
        self.assertGreaterEqual(m2["render_leases_requeued_total"], 1)
        self.assertGreater(m2["render_queue_iterations"], 0)
        self.assertEqual(m2["render_leases_active"], 0)

        # A new worker finishes the job.
        c.start_worker(threads=1)
        c.api.wait_job(job.id, timeout=120, procs=[c.server] + c.live_workers())
        _, m3 = scrape(c)
        self.assertEqual(m3['render_jobs{state="done"}'], 1)
        self.assertEqual(m3['render_jobs{state="running"}'], 0)
        self.assertEqual(m3["render_queue_iterations"], 0)
        self.assertNotIn(f'render_job_iterations_per_second{{job="{job.id}"}}', m3,
                         "a finished job keeps its per-job gauge")
        for name in ("render_leases_granted_total", "render_reports_merged_total",
                     'render_received_bytes_total{kind="report"}'):
            self.assertGreater(m3[name], m1[name], f"{name} did not move")
        self.assertGreaterEqual(m3["render_leases_expired_total"], 1)
        print(f"merged {m3['render_reports_merged_total']:.0f} reports in "
              f"{m3['render_leases_granted_total']:.0f} leases, "
              f"{m3['render_leases_expired_total']:.0f} expired")

    def test_heartbeat_rates_failures_and_drops(self):
        P = cluster.pb()
        c = self.new_cluster(server_args=["--metrics", "127.0.0.1:0"])
        c.start_server()
        api = c.api
        worker_id = api.call(api.workers.RegisterWorker,
                             P.RegisterWorkerRequest(host="fake-host", threads=3,
                                                     version="fake")).worker_id
        job = api.submit(cluster.cornell_box(), algorithm="pt", iterations=64,
                         resolution=(16, 16), seed=SEED, name="fake")

        def lease():
            r = api.call(api.workers.Lease, P.LeaseRequest(worker_id=worker_id))
            return r.lease if r.granted else None
        first = cluster.wait_until(lease, timeout=20, what="a lease")
        rates = P.WorkerRates(iterations_per_second=12.5, samples_per_second=3200.0,
                              rays_per_second=25600.0)
        api.call(api.workers.Heartbeat,
                 P.HeartbeatRequest(worker_id=worker_id, lease_ids=[first.lease_id],
                                    rates=rates))
        _, m = scrape(c)
        labels = f'{{host="fake-host",worker="{worker_id}"}}'
        self.assertEqual(m["render_worker_iterations_per_second" + labels], 12.5)
        self.assertEqual(m["render_worker_samples_per_second" + labels], 3200.0)
        self.assertEqual(m["render_worker_rays_per_second" + labels], 25600.0)
        self.assertEqual(m["render_worker_leases" + labels], 1)
        self.assertEqual(m["render_leases_active"], 1)
        # ClusterStatus carries the same rates.
        st = api.cluster_status()
        w = [w for w in st.workers if w.worker_id == worker_id][0]
        self.assertEqual(w.rates.rays_per_second, 25600.0)
        self.assertEqual(w.active_leases, 1)

        # The worker gives the lease up: failed and requeued, not expired. It is the only
        # worker the server knows, so the job FAILS (server/failure_policy.h, the poison rule).
        api.call(api.workers.Heartbeat,
                 P.HeartbeatRequest(worker_id=worker_id, failed_leases=[
                     P.LeaseFailure(lease_id=first.lease_id, error="planted failure")]))
        _, m = scrape(c)
        self.assertEqual(m["render_leases_failed_total"], 1)
        self.assertEqual(m["render_leases_requeued_total"], 1)
        self.assertEqual(m["render_leases_expired_total"], 0)
        self.assertEqual(m["render_leases_active"], 0)
        self.assertEqual(m['render_jobs{state="failed"}'], 1)
        self.assertEqual(m["render_queue_iterations"], 0)
        self.assertNotIn(f'render_job_iterations_per_second{{job="{job.id}"}}', m)

        # A report of a lease the server never granted is dropped and counted.
        n = 16 * 16 * 3
        header = P.ReportHeader(lease_id="no-such-lease", count=1, odd_count=1, width=16,
                                height=16, render_seconds=0.1)
        values = np.zeros(2 * n, dtype="<f8").tobytes()
        reply = api.call(api.workers.Report,
                         iter([P.ReportChunk(header=header), P.ReportChunk(values=values)]))
        self.assertFalse(reply.merged)
        _, m = scrape(c)
        self.assertEqual(m['render_reports_dropped_total{reason="unknown_lease"}'], 1)
        self.assertEqual(m["render_reports_merged_total"], 0)
        self.assertEqual(m['render_received_bytes_total{kind="report"}'],
                         header.ByteSize() + len(values))

    def test_exposition_passes_promtool(self):
        promtool = shutil.which("promtool")
        if not promtool:
            self.skipTest("promtool not found (Debian package `prometheus`; scripts/setup "
                          "installs it)")
        P = cluster.pb()
        c = self.new_cluster(heartbeat=0.5, server_args=["--metrics", "127.0.0.1:0"])
        c.start_server()
        check_with_promtool(self, promtool, scrape(c)[0], "a fresh server")
        c.start_worker(threads=1)
        c.wait_workers_registered(1)
        job = c.api.submit(cluster.cornell_box(), algorithm=ALGO, iterations=ITERATIONS,
                           resolution=RESOLUTION, seed=SEED, name="promtool")

        def running():
            text, m = scrape(c)
            return text if m["render_reports_merged_total"] >= 1 and \
                f'render_job_iterations_per_second{{job="{job.id}"}}' in m else None
        text = cluster.wait_until(running, timeout=60, poll=0.2, what="a merged report")
        check_with_promtool(self, promtool, text, "a job running")
        cancelled = c.api.call(c.api.jobs.CancelJob, P.CancelJobRequest(job_id=job.id))
        self.assertEqual(cancelled.state, P.JOB_STATE_CANCELLED, str(cancelled))
        check_with_promtool(self, promtool, scrape(c)[0], "the job cancelled")


if __name__ == "__main__":
    cluster.main()
