"""Integration test 4: duplicate, unknown and late reports are dropped.

The test acts as a worker itself through the raw WorkerService stubs: it leases a range, computes
the range's sum with the local `render` binary (sum over [1, b) = b-1 times the average image),
reports it (merged), reports the same lease again with garbage values (must be dropped:
merged=false), reports an unknown lease (merged=false or an error status). A second job checks a
late report: the fake worker leases a range and goes silent, the lease expires, a real worker
renders the range, and the stale lease's garbage report afterwards is dropped. Both jobs must
end with the same image as `render` in one process: a merged garbage report would be visible."""

import hashlib

import grpc
import numpy as np

import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

SEED = 3
ALGO = "pt"
ITERATIONS = 16
W, H = 32, 32
LEASE_TIMEOUT = 3


def odd_count(a, b):
    """Odd iteration indices in [a, b)."""
    return sum(1 for i in range(a, b) if i % 2 == 1)


class FakeWorker:
    def __init__(self, api):
        self.api = api
        P = cluster.pb()
        reply = api.call(api.workers.RegisterWorker,
                         P.RegisterWorkerRequest(host="integration-test", threads=1,
                                                 version="fake"))
        assert reply.worker_id, "RegisterWorker returned no worker_id"
        self.worker_id = reply.worker_id

    def lease(self, timeout=20):
        P = cluster.pb()

        def get():
            r = self.api.call(self.api.workers.Lease, P.LeaseRequest(worker_id=self.worker_id))
            # LeaseReply.granted (named has_lease in early versions of the proto).
            fields = P.LeaseReply.DESCRIPTOR.fields_by_name
            granted = r.granted if "granted" in fields else r.has_lease
            return r.lease if granted else None
        return cluster.wait_until(get, timeout=timeout, poll=0.1, what="a lease")

    def heartbeat(self, lease_ids):
        P = cluster.pb()
        return self.api.call(self.api.workers.Heartbeat,
                             P.HeartbeatRequest(worker_id=self.worker_id, lease_ids=lease_ids))

    def report(self, lease_id, first, end, sum_, odd_sum):
        """Streams a report; returns ReportReply.merged."""
        P = cluster.pb()
        count = end - first
        header = P.ReportHeader(lease_id=lease_id, count=count, odd_count=odd_count(first, end),
                                width=W, height=H, samples=W * H * count, rays=0,
                                non_finite=0, render_seconds=0.1)
        payload = [np.ascontiguousarray(sum_, dtype="<f8").tobytes(),
                   np.ascontiguousarray(odd_sum, dtype="<f8").tobytes()]

        def chunks():
            yield P.ReportChunk(header=header)
            for data in payload:
                for i in range(0, len(data), cluster.CHUNK):
                    yield P.ReportChunk(values=data[i:i + cluster.CHUNK])
        return self.api.call(self.api.workers.Report, chunks()).merged


def range_sum(scene, first, end):
    """The sum of the iteration images over [first, end), from `render` averages."""
    def total(n):
        if n == 0:
            return np.zeros((H, W, 3))
        ref = cluster.render_reference(scene, ALGO, n, (W, H), SEED)
        return cluster.read_exr(ref) * n
    s = total(end - 1) - total(first - 1)
    odd = s * (odd_count(first, end) / max(1, end - first))  # only used for error estimates
    return s.reshape(-1), odd.reshape(-1)


class DuplicateReport(cluster.ClusterTestCase):
    def test_duplicate_unknown_and_late_reports(self):
        P = cluster.pb()
        c = self.new_cluster(lease_timeout=LEASE_TIMEOUT, heartbeat=0.5)
        c.start_server()
        scene = cluster.cornell_box()
        fake = FakeWorker(c.api)
        garbage = np.full(W * H * 3, 1000.0)

        # Job A: duplicate and unknown reports.
        job_a = c.api.submit(scene, algorithm=ALGO, iterations=ITERATIONS, resolution=(W, H),
                             seed=SEED, name="duplicate")
        lease = fake.lease()
        self.assertEqual(lease.job_id, job_a.id)
        a, b = lease.first_iteration, lease.end_iteration
        self.assertTrue(1 <= a < b <= ITERATIONS + 1, f"bad lease range [{a}, {b})")
        print(f"fake worker leased [{a}, {b}) of job A")
        sum_, odd = range_sum(scene, a, b)
        fake.heartbeat([lease.lease_id])
        self.assertTrue(fake.report(lease.lease_id, a, b, sum_, odd),
                        "the first report of a lease was not merged")
        self.assertFalse(fake.report(lease.lease_id, a, b, garbage, garbage),
                         "a second report of the same lease was merged")
        unknown = "no-such-lease-" + hashlib.sha256(b"unknown").hexdigest()[:12]
        try:
            merged = fake.report(unknown, a, b, garbage, garbage)
            self.assertFalse(merged, "a report of an unknown lease was merged")
        except grpc.RpcError as e:
            # An error status is as good as merged=false, if it is the right family.
            self.assertIn(e.code(), {grpc.StatusCode.NOT_FOUND,
                                     grpc.StatusCode.FAILED_PRECONDITION,
                                     grpc.StatusCode.INVALID_ARGUMENT},
                          f"unknown lease: {e.code()} {e.details()!r}")

        worker = c.start_worker(threads=1)  # renders what is left of job A
        c.api.wait_job(job_a.id, timeout=60, procs=[c.server, worker])
        # The duplicate again, after the job is done.
        self.assertFalse(fake.report(lease.lease_id, a, b, garbage, garbage))
        out_a = c.api.fetch_to(job_a.id, c.path("a.exr"))
        ref = cluster.render_reference(scene, ALGO, ITERATIONS, (W, H), SEED)
        print("job A:", self.assertImagesMatch(out_a, ref))
        worker.kill()

        # Job B: a late report of an expired lease whose range another worker rendered.
        job_b = c.api.submit(scene, algorithm=ALGO, iterations=ITERATIONS, resolution=(W, H),
                             seed=SEED, name="late")
        stale = fake.lease()
        self.assertEqual(stale.job_id, job_b.id)
        sa, sb = stale.first_iteration, stale.end_iteration
        print(f"fake worker leased [{sa}, {sb}) of job B and goes silent")
        worker2 = c.start_worker(threads=1)
        c.api.wait_job(job_b.id, timeout=60, procs=[c.server, worker2])
        # A lease that expired may have been forgotten by the server: an error status of the
        # "unknown lease" family is as good as merged=false.
        try:
            self.assertFalse(fake.report(stale.lease_id, sa, sb, garbage, garbage),
                             "a late report of an expired lease was merged")
        except grpc.RpcError as e:
            self.assertIn(e.code(), {grpc.StatusCode.NOT_FOUND,
                                     grpc.StatusCode.FAILED_PRECONDITION},
                          f"late report: {e.code()} {e.details()!r}")
        done_b = c.api.get_job(job_b.id)
        self.assertEqual(done_b.state, P.JOB_STATE_DONE)
        self.assertEqual(done_b.frames[0].iterations_done, ITERATIONS, str(done_b))
        out_b = c.api.fetch_to(job_b.id, c.path("b.exr"))
        print("job B:", self.assertImagesMatch(out_b, ref))
        # And job A's result is unchanged by all of this.
        self.assertImagesMatch(c.api.fetch_to(job_a.id, c.path("a2.exr")), ref)


if __name__ == "__main__":
    cluster.main()
