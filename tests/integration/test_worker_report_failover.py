"""A worker's report outlives the server that granted its lease (docs/design/job-store.md, "How
long a lease stays lost"; docs/guide/service.md, "Several servers").

Real `worker` processes against fake servers written with Python gRPC on 127.0.0.1:

* The server that granted a lease cannot be reached for its report: the worker sends the report
  to the other server of its `--server` list at once (which forwards it to the job's holder or
  says nobody will merge it), where it used to retry the dead server for ten seconds with its
  next lease waiting behind that report.
* A finished lease waits for the report before it: the worker heartbeats it meanwhile, so that
  a slow report cannot make the next lease expire (three such losses failed a job as poison in
  the two-server chaos test).

Nothing here waits for a timeout: each case waits for events in order.
"""

import sys
import threading
from concurrent import futures

import grpc

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402
from test_worker_gives_up_report import FakeJob  # noqa: E402

class FakeServer(FakeJob):
    """WorkerService granting the leases named in `grants`, one per Lease call, in order."""

    def __init__(self, name, grants, report):
        self.name = name
        self.grants = list(grants)
        self.report = report  # (server, lease_id, context) -> ReportReply; may block
        self.lock = threading.Lock()
        self.changed = threading.Condition(self.lock)
        self.events = []  # (what, lease_id) in order

    def note(self, *event):
        with self.lock:
            self.events.append(event)
            self.changed.notify_all()

    def wait_for(self, predicate, timeout=120):
        with self.lock:
            return self.changed.wait_for(lambda: predicate(self.events), timeout=timeout)

    def RegisterWorker(self, request, context):
        return cluster.pb().RegisterWorkerReply(worker_id=f"w-{self.name}", heartbeat_seconds=0.5)

    def Lease(self, request, context):
        P = cluster.pb()
        with self.lock:
            if not self.grants:
                return P.LeaseReply(granted=False)
            lease_id = self.grants.pop(0)
            self.events.append(("lease", lease_id))
            self.changed.notify_all()
        return self.granted(lease_id)

    def Heartbeat(self, request, context):
        for lease_id in request.lease_ids:
            self.note("heartbeat", lease_id)
        for f in request.failed_leases:
            self.note("failure", f.lease_id)
        return cluster.pb().HeartbeatReply()

    def Report(self, request_iterator, context):
        header = None
        for chunk in request_iterator:
            if chunk.HasField("header"):
                header = chunk.header
        lease_id = header.lease_id if header else ""
        self.note("report", lease_id)
        return self.report(self, lease_id, context)


def serve(fake):
    server = grpc.server(futures.ThreadPoolExecutor(max_workers=8))
    cluster.stubs()["rpc"].add_WorkerServiceServicer_to_server(fake, server)
    port = server.add_insecure_port(f"{cluster.LOCALHOST}:0")
    server.start()
    return server, f"{cluster.LOCALHOST}:{port}"


class WorkerReportFailover(cluster.ClusterTestCase):
    def start(self, *fakes):
        servers = [serve(f) for f in fakes]
        for server, _ in servers:
            self.addCleanup(server.stop, 0)
        c = self.new_cluster()
        c.address = servers[0][1]
        worker = c.start_worker(threads=1, extra=["--server", ",".join(a for _, a in servers)])
        return worker

    def test_a_report_its_server_cannot_take_goes_to_the_other_server(self):
        def gone(server, lease_id, context):
            context.abort(grpc.StatusCode.UNAVAILABLE, "the fake server is going away")

        def forwarded(server, lease_id, context):
            return cluster.pb().ReportReply(merged=True)  # as the holder's answer, forwarded

        a = FakeServer("a", ["L-1"], gone)
        b = FakeServer("b", [], forwarded)
        worker = self.start(a, b)
        self.assertTrue(b.wait_for(lambda ev: ("report", "L-1") in ev),
                        f"the report never reached B; A saw {a.events}, B {b.events}\n"
                        f"{worker.log_tail()}")
        # A first (it granted the lease), then B, before the worker's patience ran out: the
        # lease was not given up.
        self.assertIn(("report", "L-1"), a.events)
        self.assertNotIn(("failure", "L-1"), a.events)
        worker.wait_for_log("event=reported lease=L-1 merged=true through=")
        print("A:", a.events, "B:", b.events)

    def test_a_finished_lease_is_heartbeaten_while_the_report_before_it_is_sent(self):
        release = threading.Event()

        def slow_first(server, lease_id, context):
            if lease_id == "L-1":
                # Held open until L-2 has been rendered and heartbeaten behind it.
                release.wait(timeout=120)
            return cluster.pb().ReportReply(merged=True)

        a = FakeServer("a", ["L-1", "L-2"], slow_first)
        worker = self.start(a)
        try:
            # L-2 is granted after L-1's report started (one report in flight), renders in
            # milliseconds and then waits for L-1's report: its heartbeats go on meanwhile.
            worker.wait_for_log("event=rendered lease=L-2", timeout=120)
            with a.lock:
                before = a.events.count(("heartbeat", "L-2"))
            self.assertTrue(a.wait_for(lambda ev: ev.count(("heartbeat", "L-2")) >= before + 2,
                                       timeout=60),
                            f"L-2 not heartbeaten while L-1's report was held: {a.events}\n"
                            f"{worker.log_tail()}")
            self.assertNotIn(("report", "L-2"), a.events)  # still behind L-1's report
        finally:
            release.set()
        self.assertTrue(a.wait_for(lambda ev: ("report", "L-2") in ev),
                        f"L-2 never reported: {a.events}")
        print("A:", a.events[:6], "...", a.events[-3:])


if __name__ == "__main__":
    cluster.main()
