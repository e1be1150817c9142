"""A worker's Report stream that goes silent is cancelled, and its lease goes to another worker
(docs/guide/reliability.md, "Streams and the asset store").

The workers' Report stream had no idle timeout: a worker that opened it, sent its header and
part of its values and then stalled held a server thread and its lease's range for as long as
it liked (with a long --lease-timeout, for ever, since the lease stays active while its report
is being received). Now the stream is cancelled after --stream-idle-timeout seconds without a
chunk, like UploadAsset/FetchResult/FetchAsset, and the lease is voided at once: its range is
queued again, a real worker renders it, and a later report of the voided lease is dropped. The
job's image equals `render`'s (nothing lost, nothing merged twice: a merged garbage report would
show). A stream that never sends its header is cancelled as well.

The test acts as the stalled worker through the raw WorkerService stubs (Python gRPC); the
server's --lease-timeout is 600 s, so without the voiding the job could not finish within the
test's bound."""

import sys
import threading

import grpc
import numpy as np

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402
from test_duplicate_report import FakeWorker, W, H, SEED, ALGO, odd_count  # noqa: E402

IDLE_SECONDS = 3
ITERATIONS = 8


class ReportStreamIdle(cluster.ClusterTestCase):
    def test_silent_report_stream_is_cancelled_and_its_lease_rendered_elsewhere(self):
        P = cluster.pb()
        c = self.new_cluster(lease_timeout=600, heartbeat=0.5,
                             server_args=["--stream-idle-timeout", str(IDLE_SECONDS)])
        c.start_server()
        scene = cluster.cornell_box()
        job = c.api.submit(scene, algorithm=ALGO, iterations=ITERATIONS, resolution=(W, H),
                           seed=SEED, name="report-idle")
        fake = FakeWorker(c.api)
        lease = fake.lease()
        self.assertEqual(lease.job_id, job.id)
        a, b = lease.first_iteration, lease.end_iteration
        print(f"fake worker leased [{a}, {b}) and stalls mid-report")
        garbage = np.full(W * H * 3, 1000.0)

        release = threading.Event()

        def stalled_report():
            yield P.ReportChunk(header=P.ReportHeader(
                lease_id=lease.lease_id, count=b - a, odd_count=odd_count(a, b), width=W,
                height=H, samples=W * H * (b - a), render_seconds=0.1))
            yield P.ReportChunk(values=garbage.astype("<f8").tobytes()[:4096])
            release.wait()

        def no_header():
            release.wait()
            yield P.ReportChunk()

        try:
            stalled = c.api.workers.Report.future(stalled_report(), metadata=c.api.metadata(),
                                                  timeout=120)
            silent = c.api.workers.Report.future(no_header(), metadata=c.api.metadata(),
                                                 timeout=120)
            for name, f in (("mid-report", stalled), ("before its header", silent)):
                # A bound for the test, not a measurement: the server cancels after 3 s.
                error = f.exception(timeout=60)
                self.assertIsNotNone(error, f"a Report stream idle {name} was not ended")
                print(f"Report stream idle {name} ended: {error.code()} {error.details()}")
                self.assertIn(error.code(), (grpc.StatusCode.CANCELLED,
                                             grpc.StatusCode.DEADLINE_EXCEEDED))
        finally:
            release.set()
        # The server logs the cancel just after it ends the stream: wait for the line.
        log = c.server.wait_for_log(f"event=report_stream_idle lease={lease.lease_id}")
        self.assertIn("rpc=Report", log)

        # The voided range goes to a real worker (the lease would otherwise hold it for 600 s).
        worker = c.start_worker(threads=1)
        done = c.api.wait_job(job.id, timeout=120, procs=[c.server, worker])
        self.assertEqual(done.frames[0].iterations_done, ITERATIONS, str(done))
        # The stalled worker's report of its voided lease, complete this time, is dropped.
        try:
            self.assertFalse(fake.report(lease.lease_id, a, b, garbage, garbage),
                             "a report of a voided lease was merged")
        except grpc.RpcError as e:
            self.assertIn(e.code(), {grpc.StatusCode.NOT_FOUND,
                                     grpc.StatusCode.FAILED_PRECONDITION}, str(e))
        out = c.api.fetch_to(job.id, c.path("idle.exr"))
        ref = cluster.render_reference(scene, ALGO, ITERATIONS, (W, H), SEED)
        print("image:", self.assertImagesMatch(out, ref))
        self.assertTrue(c.server.alive())


if __name__ == "__main__":
    cluster.main()
