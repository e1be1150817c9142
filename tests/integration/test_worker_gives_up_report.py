"""A worker that gives up on a report tells the server at once (docs/guide/service.md,
"Workers").

A report the worker cannot deliver (the server answers it with an error that retrying will not
change, or the lease's patience runs out) is given up. Before, the lease then lived on at the
server while the worker heartbeated its next lease (a heartbeat extends all of a worker's
leases), so the range waited for the lease timeout. The worker now says so in a heartbeat's
`failed_leases` (a lease failure naming the report's error), and the server queues the range
again at once (`ManagerTest.AReportGivenUpIsLeasedAgainAtOnce`).

Here a real `worker` talks to a fake server written with Python gRPC on 127.0.0.1: it grants
one lease, rejects its report with INVALID_ARGUMENT, and grants the same range again only once
the worker has reported the failure; the worker renders the range again and the fake merges
that second report. Nothing here waits for a lease timeout.
"""

import hashlib
import os
import sys
import threading
import time
from concurrent import futures

import grpc

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

SCENE = b"""<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="60"/>
    <transform name="to_world"><lookat origin="0, 0, 0" target="0, 0, 1" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/></film>
  </sensor>
  <shape type="sphere">
    <float name="radius" value="2"/>
    <boolean name="flip_normals" value="true"/>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>
    <emitter type="area"><rgb name="radiance" value="0.5"/></emitter>
  </shape>
</scene>
"""
SHA = hashlib.sha256(SCENE).hexdigest()
FIRST, END = 1, 3  # the range both leases carry


class FakeJob:
    """What every fake WorkerService of these tests serves of its one job: a pt lease of the
    range [FIRST, END) over SCENE, the scene's bytes and no adaptive mask."""

    @staticmethod
    def granted(lease_id):
        P = cluster.pb()
        settings = P.RenderSettings(algorithm="pt", iterations=END - 1, width=8, height=6,
                                    seed=1)
        bundle = P.SceneBundle(scene_path="scene.xml", files=[
            P.BundleFile(path="scene.xml", sha256=SHA, size=len(SCENE))])
        return P.LeaseReply(granted=True, lease=P.Lease(
            lease_id=lease_id, job_id="job-fake", frame=0, first_iteration=FIRST,
            end_iteration=END, settings=settings, bundle=bundle, expires_in_seconds=600))

    def FetchAsset(self, request, context):
        if request.sha256 != SHA:
            context.abort(grpc.StatusCode.NOT_FOUND, "no such asset")
        yield cluster.pb().AssetChunk(sha256=SHA, size=len(SCENE), data=SCENE)

    def FetchMask(self, request, context):
        # The fake job is not adaptive: its leases carry no mask to fetch.
        context.abort(grpc.StatusCode.NOT_FOUND, "the fake job has no adaptive mask")
        yield cluster.pb().MaskChunk()


class FakeServer(FakeJob):
    """WorkerService: one job of one range; the report of the first lease is rejected."""

    def __init__(self):
        self.lock = threading.Lock()
        self.events = []        # (what, lease_id, detail) in order
        self.failures = {}      # lease_id -> LeaseFailure.error
        self.undelivered = {}   # lease_id -> LeaseFailure.report_undelivered
        self.leases = []        # granted lease ids
        self.merged = []        # (lease_id, count) of accepted reports
        self.changed = threading.Condition(self.lock)

    def note(self, *event):
        with self.lock:
            self.events.append(event)
            self.changed.notify_all()

    # -- WorkerService

    def RegisterWorker(self, request, context):
        return cluster.pb().RegisterWorkerReply(worker_id="w-fake", heartbeat_seconds=0.5)

    def Lease(self, request, context):
        P = cluster.pb()
        with self.lock:
            if self.merged:
                return P.LeaseReply(granted=False)
            # The first lease, then the same range again only once the first was given up.
            if self.leases and self.leases[-1] not in self.failures:
                return P.LeaseReply(granted=False)
            lease_id = f"L-{len(self.leases) + 1}"
            self.leases.append(lease_id)
            self.events.append(("lease", lease_id, ""))
            self.changed.notify_all()
        return self.granted(lease_id)

    def Heartbeat(self, request, context):
        for f in request.failed_leases:
            with self.lock:
                self.failures[f.lease_id] = f.error
                self.undelivered[f.lease_id] = f.report_undelivered
            self.note("failure", f.lease_id, f.error)
        return cluster.pb().HeartbeatReply()

    def Report(self, request_iterator, context):
        header = None
        values = 0
        for chunk in request_iterator:
            if chunk.HasField("header"):
                header = chunk.header
            else:
                values += len(chunk.values)
        lease_id = header.lease_id if header else ""
        self.note("report", lease_id, f"{values} bytes")
        if lease_id == "L-1":
            context.abort(grpc.StatusCode.INVALID_ARGUMENT,
                          "the fake server rejects this report")
        with self.lock:
            self.merged.append((lease_id, header.count))
            self.changed.notify_all()
        return cluster.pb().ReportReply(merged=True)


class WorkerGivesUpReport(cluster.ClusterTestCase):
    def test_rejected_report_is_told_to_the_server_and_the_range_leased_again(self):
        s = cluster.stubs()
        fake = FakeServer()
        server = grpc.server(futures.ThreadPoolExecutor(max_workers=8))
        s["rpc"].add_WorkerServiceServicer_to_server(fake, server)
        port = server.add_insecure_port(f"{cluster.LOCALHOST}:0")
        server.start()
        c = self.new_cluster()
        c.address = f"{cluster.LOCALHOST}:{port}"
        try:
            worker = c.start_worker(threads=1)
            with fake.lock:
                ok = fake.changed.wait_for(lambda: bool(fake.merged) or not worker.alive(),
                                           timeout=120)
            self.assertTrue(ok, f"no report merged within 120 s; events: {fake.events}")
            self.assertTrue(worker.alive(), worker.log_tail())
            kinds = [(what, lease) for what, lease, _ in fake.events]
            print("events:", fake.events)
            # The order: lease 1, its report (rejected), its failure told, lease 2 (the same
            # range), its report (merged).
            self.assertEqual(kinds, [("lease", "L-1"), ("report", "L-1"), ("failure", "L-1"),
                                     ("lease", "L-2"), ("report", "L-2")])
            self.assertIn("the worker could not deliver its report", fake.failures["L-1"])
            self.assertIn("the fake server rejects this report", fake.failures["L-1"])
            # Marked as a delivery fault, which the server does not count as the job's failure.
            self.assertTrue(fake.undelivered["L-1"])
            self.assertEqual(fake.merged, [("L-2", END - FIRST)])
            worker.wait_for_log("event=report_failed lease=L-1")
        finally:
            server.stop(0)


if __name__ == "__main__":
    cluster.main()
