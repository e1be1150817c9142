"""A worker sends a finished lease's report in the background while it renders its next lease
(worker/background_report.h; docs/results/performance-notes.md, "Reports in the background"). The server's test option --report-delay holds every
report after its values arrive, so that a report stays in flight long enough to be seen; the
order of the processes' own log lines shows the overlap (nothing is timed):

* the server grants the worker its next lease while the previous report is held (`lease`
  between `report_delayed` and `merged` of the previous lease), and the worker finishes
  rendering that next lease before the held report is answered (`rendered` of the next lease
  before `reported` of the previous one, in the worker's log);
* a worker SIGKILLed with a report in flight and its next lease loses exactly those: the
  held report is cancelled, both leases expire and are leased again, the job's progress never
  goes backwards, and the final image equals `render`'s."""

import re
import sys
import time

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

SEED = 11
ALGO = "vcm"
RESOLUTION = (32, 32)
EVENT = re.compile(rb"event=(\S+)")
KEY = re.compile(rb"\b(lease|worker)=(\S+)")


def events(path):
    """The log's (event, {lease, worker}) in order."""
    out = []
    with open(path, "rb") as f:
        for line in f:
            m = EVENT.search(line)
            if m:
                out.append((m.group(1).decode(),
                            {k.decode(): v.decode() for k, v in KEY.findall(line)}))
    return out


def worker_id(worker):
    # The server may count the worker as registered before its log line is written.
    worker.wait_for_log("event=registered")
    for event, kv in events(worker.log_path):
        if event == "registered":
            return kv["worker"]
    raise AssertionError(f"{worker.name} did not register:\n{worker.log_tail()}")


class ReportInFlight(cluster.ClusterTestCase):
    def test_the_next_lease_renders_while_a_report_is_in_flight(self):
        c = self.new_cluster(heartbeat=0.5,
                             server_args=["--report-delay", "1", "--lease-seconds", "0.2"])
        c.start_server()
        worker = c.start_worker(threads=1)
        c.wait_workers_registered(1)
        scene = cluster.cornell_box()
        iterations = 60  # leases of >= 0.2 s, each report held 1 s: >= 3 reports
        job = c.api.submit(scene, algorithm=ALGO, iterations=iterations, resolution=RESOLUTION,
                           seed=SEED, name="report-in-flight")
        done = c.api.wait_job(job.id, timeout=300, procs=[c.server, worker])
        self.assertEqual(done.frames[0].iterations_done, iterations, str(done))
        me = worker_id(worker)

        # Server: leases granted to the worker while an earlier lease of it was not merged yet
        # (its report was on the way or held), which a worker that waits for its report's
        # reply before it asks for the next lease never gets.
        unmerged, granted_while_held = set(), 0
        for event, kv in events(c.server.log_path):
            if event == "lease" and kv.get("worker") == me:
                if unmerged:
                    granted_while_held += 1
                unmerged.add(kv["lease"])
            elif event == "merged":
                unmerged.discard(kv.get("lease"))
        # Worker: leases rendered to the end while the previous lease's report was unanswered.
        unanswered, rendered_while_in_flight, reports = set(), 0, 0
        for event, kv in events(worker.log_path):
            if event == "report_queued":
                unanswered.add(kv["lease"])
                reports += 1
            elif event in ("reported", "report_dropped", "report_failed"):
                unanswered.discard(kv["lease"])
            elif event == "rendered" and unanswered - {kv["lease"]}:
                rendered_while_in_flight += 1
        print(f"{reports} reports; {granted_while_held} leases granted and "
              f"{rendered_while_in_flight} rendered while a report was in flight")
        self.assertGreaterEqual(reports, 3, "too few leases to show an overlap")
        self.assertGreaterEqual(granted_while_held, 1,
                                "no lease was granted while the worker's report was held")
        self.assertGreaterEqual(rendered_while_in_flight, 1,
                                "no lease was rendered while the previous report was in flight")
        out = c.api.fetch_to(job.id, c.path("in-flight.exr"))
        print(self.assertImagesMatch(
            out, cluster.render_reference(scene, ALGO, iterations, RESOLUTION, SEED)))

    def test_a_worker_killed_with_a_report_in_flight_loses_nothing(self):
        P = cluster.pb()
        lease_timeout = 2
        c = self.new_cluster(lease_timeout=lease_timeout, heartbeat=0.5,
                             server_args=["--report-delay", "5"])
        c.start_server()
        victim = c.start_worker(threads=1)
        c.wait_workers_registered(1)
        scene = cluster.cornell_box()
        iterations = 300
        job = c.api.submit(scene, algorithm=ALGO, iterations=iterations, resolution=RESOLUTION,
                           seed=SEED, name="killed-in-flight")
        victim_id = worker_id(victim)

        # The victim's first report is held; kill it once the server has granted it the next
        # lease (its render threads are on that one now; the lease may be granted before the
        # report's values arrive).
        def in_flight_and_leased():
            held, granted = None, []
            for event, kv in events(c.server.log_path):
                if event == "report_delayed" and held is None:
                    held = kv["lease"]
                elif event == "lease" and kv.get("worker") == victim_id:
                    granted.append(kv["lease"])
                elif event in ("merged", "report_cancelled") and held and kv.get("lease") == held:
                    raise AssertionError(f"the held report ended ({event}) before the kill")
            if held is None or held not in granted or granted[-1] == held:
                return None
            return held, granted[granted.index(held) + 1]
        held, next_lease = cluster.wait_until(in_flight_and_leased, timeout=60, poll=0.02,
                                              what="a report in flight and the next lease")
        victim.kill()
        print(f"killed {victim.name}: report of {held} in flight, rendering {next_lease}")

        def logged(event_name, lease):
            return any(e == event_name and kv.get("lease") == lease
                       for e, kv in events(c.server.log_path))
        cluster.wait_until(lambda: logged("report_cancelled", held), timeout=30,
                           what="the server to cancel the held report")
        cluster.wait_until(lambda: logged("lease_lost", held) and logged("lease_lost", next_lease),
                           timeout=30, what="both of the victim's leases to expire")

        c.start_worker(threads=1)
        progress = []
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline:
            j = c.api.get_job(job.id)
            progress.append(j.frames[0].iterations_done if j.frames else 0)
            if j.state == P.JOB_STATE_DONE:
                break
            for p in [c.server] + c.live_workers():
                self.assertTrue(p.alive(), f"{p.name} died:\n{p.log_tail()}")
            time.sleep(0.1)
        self.assertEqual(j.state, P.JOB_STATE_DONE, str(j))
        self.assertEqual(progress, sorted(progress), "the job's progress went backwards")
        self.assertEqual(j.frames[0].iterations_done, iterations, str(j))
        # The lost ranges were rendered again by the new worker: merged once each, under new
        # leases (the lost leases themselves never merged).
        self.assertFalse(logged("merged", held), "the cancelled report was merged")
        self.assertFalse(logged("merged", next_lease), "the dead worker's lease was merged")
        out = c.api.fetch_to(job.id, c.path("killed-in-flight.exr"))
        print(self.assertImagesMatch(
            out, cluster.render_reference(scene, ALGO, iterations, RESOLUTION, SEED)))


if __name__ == "__main__":
    cluster.main()
