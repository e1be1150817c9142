"""A report that fails half-way changes nothing: it is merged whole or not at all.

The server receives a report's values in chunks and checks each value as it arrives
(server/worker_service.cpp): a non-finite value ends the report with INVALID_ARGUMENT, and a
stream that ends before the last value is refused after it ends. Neither may leave part of its
values in the frame's sums. The test acts as a worker through the raw WorkerService stubs and
sends, for one lease, in small chunks (so that the failures come after many chunks were read):
  1. the right sum, then an odd sum with a NaN half-way through it: refused;
  2. the right sum and half of the odd sum, then the stream ends: refused;
  3. the right report: merged.
A real worker renders the rest. The job's image must equal `render`'s: any part of reports 1
or 2 in the sums would add their range a second time (or a NaN) and show.

Twice: with the reports held in memory (the server's default for reports this small) and
spooled to a file in the store while they arrive (`--spool-reports-above 0`,
server/report_values.h). The chunks are 2045 bytes, so values are split between chunks (the
spool checks a value when its last byte arrives). Spooled, no file may be left in the store's
spool folder (the files are unlinked: they must not even have a name)."""

import os
import sys

import grpc
import numpy as np

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402
from test_duplicate_report import FakeWorker, W, H, SEED, ALGO, odd_count, range_sum  # noqa: E402

ITERATIONS = 8
SMALL_CHUNK = 2045  # bytes: ~12 chunks per 32x32 float64 RGB buffer, splitting values


def report_chunks(lease_id, first, end, values):
    """The header and `values` (bytes) in SMALL_CHUNK pieces; the header claims a full report."""
    P = cluster.pb()
    count = end - first
    header = P.ReportHeader(lease_id=lease_id, count=count, odd_count=odd_count(first, end),
                            width=W, height=H, samples=W * H * count, rays=0, non_finite=0,
                            render_seconds=0.1)
    yield P.ReportChunk(header=header)
    for i in range(0, len(values), SMALL_CHUNK):
        yield P.ReportChunk(values=values[i:i + SMALL_CHUNK])


class ReportRejectedWhole(cluster.ClusterTestCase):
    def refused(self, api, chunks, what):
        with self.assertRaises(grpc.RpcError, msg=f"{what} was accepted") as caught:
            api.call(api.workers.Report, chunks)
        self.assertEqual(caught.exception.code(), grpc.StatusCode.INVALID_ARGUMENT,
                         f"{what}: {caught.exception.details()!r}")
        print(f"{what}: {caught.exception.details()}")

    def test_a_report_that_fails_half_way_changes_nothing(self):
        self.check_whole_or_nothing(server_args=())

    def test_a_spooled_report_that_fails_half_way_changes_nothing(self):
        c = self.check_whole_or_nothing(server_args=("--spool-reports-above", "0"))
        with open(c.server.log_path, "rb") as f:
            received = [line for line in f if b"event=report_received" in line]
        self.assertTrue(received, "the server logged no merged report")
        self.assertTrue(all(b"spooled=1" in line for line in received),
                        "a report was not spooled with --spool-reports-above 0")

    def spool_files(self, c):
        folder = os.path.join(c.store, "spool")
        return os.listdir(folder) if os.path.isdir(folder) else []

    def check_whole_or_nothing(self, server_args):
        c = self.new_cluster(server_args=server_args)
        c.start_server()
        scene = cluster.cornell_box()
        fake = FakeWorker(c.api)
        job = c.api.submit(scene, algorithm=ALGO, iterations=ITERATIONS, resolution=(W, H),
                           seed=SEED, name="half-way")
        lease = fake.lease()
        a, b = lease.first_iteration, lease.end_iteration
        print(f"fake worker leased [{a}, {b})")
        sum_, odd = range_sum(scene, a, b)
        sum_bytes = np.ascontiguousarray(sum_, dtype="<f8").tobytes()
        odd_values = np.ascontiguousarray(odd, dtype="<f8").copy()
        with_nan = odd_values.copy()
        with_nan[len(with_nan) // 2] = np.nan
        self.refused(c.api, report_chunks(lease.lease_id, a, b, sum_bytes + with_nan.tobytes()),
                     "a report with a NaN half-way through its odd sum")
        half = odd_values[:len(odd_values) // 2].tobytes()
        self.refused(c.api, report_chunks(lease.lease_id, a, b, sum_bytes + half),
                     "a report whose stream ends half-way through its odd sum")
        self.assertEqual(self.spool_files(c), [], "a refused report left a file behind")
        fake.heartbeat([lease.lease_id])
        self.assertTrue(fake.report(lease.lease_id, a, b, sum_, odd),
                        "the whole report was not merged after the refused ones")
        worker = c.start_worker(threads=1)
        c.api.wait_job(job.id, timeout=120, procs=[c.server, worker])
        out = c.api.fetch_to(job.id, c.path("out.exr"))
        ref = cluster.render_reference(scene, ALGO, ITERATIONS, (W, H), SEED)
        print("image:", self.assertImagesMatch(out, ref))
        self.assertEqual(self.spool_files(c), [], "a merged report left a file behind")
        return c


if __name__ == "__main__":
    cluster.main()
