"""A poison job on a farm of supervised workers, end to end (docs/guide/reliability.md, "A lease
the renderer cannot render").

A real server and three real workers, started as deploy/local-cluster starts them, each kept
running by a supervisor that restarts it when it exits (as systemd's Restart=always or a
Kubernetes Deployment would; deploy/local-cluster itself restarts nothing). The workers carry
the test-only flag --test-render-fault for one scene file, poison.xml (a copy of a shipped
scene): their renderer fails every lease of that scene and no other, standing for the scenes the
renderer cannot render (the real ones found so far are refused at load).

- The renderer throws: every failing lease is reported to the server with the message, no
  worker process dies (the supervisor restarts none), and the job FAILS by the poison rule with
  that message. A healthy job submitted next renders on the same workers to `render`'s image.
- The renderer aborts (as Embree's assertion on an invalid ray did): each worker that leases the
  job dies and is restarted; the job FAILS once three distinct workers lost it, within a bounded
  number of deaths, and the farm then settles (no more deaths) and renders a healthy job to
  `render`'s image on the restarted workers.
"""

import os
import re
import shutil
import sys
import threading
import time

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

WORKERS = 3
LEASE_TIMEOUT = 2
SEED = 5
RESOLUTION = (24, 24)
MESSAGE = "the renderer cannot render this scene (a test fault)"
# The poison rule (server/failure_policy.h): reported failures on 2 distinct workers fail a
# job; with lost leases (dead workers) 3 are needed. The three workers lease the job at once
# and die; their leases expire LEASE_TIMEOUT later (plus the server's check and a heartbeat),
# and the job fails then, within about 3 s of the first deaths. A slot is restarted RESTART_DELAY
# after each death (a supervisor's back-off), so each dies at most 1 + 3 / RESTART_DELAY times
# before the verdict: deaths are bounded by 4 per slot.
REPORTING_WORKERS = 2
LOST_WORKERS = 3
RESTART_DELAY = 1.0
MAX_DEATHS = 4 * WORKERS


class Supervisor:
    """Keeps `n` workers running: a worker that exits is started again with the same
    arguments after `delay` seconds (systemd's RestartSec), and its death recorded."""

    def __init__(self, c, n, extra, delay=RESTART_DELAY):
        self.c, self.extra, self.delay = c, list(extra), delay
        self.slots = [c.start_worker(threads=1, extra=self.extra) for _ in range(n)]
        self.deaths = []  # (slot, exit status) per worker that exited
        self.lock = threading.Lock()
        self.stopping = threading.Event()
        self.thread = threading.Thread(target=self._watch, daemon=True)
        self.thread.start()

    def _watch(self):
        restart_at = {}  # slot -> when its dead worker is started again
        while not self.stopping.wait(0.05):
            now = time.monotonic()
            for k, proc in enumerate(self.slots):
                if k in restart_at:
                    if now >= restart_at[k]:
                        del restart_at[k]
                        self.slots[k] = self.c.start_worker(threads=1, extra=self.extra)
                elif not proc.alive():
                    with self.lock:
                        self.deaths.append((k, proc.popen.returncode))
                    restart_at[k] = now + self.delay

    def death_count(self):
        with self.lock:
            return len(self.deaths)

    def stop(self):
        self.stopping.set()
        self.thread.join(timeout=10)


def poison_scene(c):
    """A copy of scenes/smallvcm (its includes and meshes) with 1-glm_c.xml as poison.xml."""
    folder = c.path("scenes")
    shutil.copytree(cluster.scene_path("smallvcm"), folder)
    shutil.copy(os.path.join(folder, "1-glm_c.xml"), os.path.join(folder, "poison.xml"))
    return os.path.join(folder, "poison.xml")


def healthy_scene():
    return cluster.scene_path("smallvcm", "1-glm_c.xml")


def lease_failures(text):
    """{lease id: line} of the lease_failed lines of a log."""
    out = {}
    for line in text.splitlines():
        if "event=lease_failed" in line:
            m = re.search(r"\blease=(\S+)", line)
            if m:
                out[m.group(1)] = line
    return out


class PoisonJobSupervised(cluster.ClusterTestCase):
    def farm(self, fault):
        c = self.new_cluster(lease_timeout=LEASE_TIMEOUT, heartbeat=0.5)
        c.start_server()
        supervisor = Supervisor(c, WORKERS, ["--test-render-fault", fault,
                                             "--test-render-fault-scene", "poison.xml"])
        self.addCleanup(supervisor.stop)
        c.wait_workers_registered(WORKERS)
        return c, supervisor

    def submit_poison(self, c):
        # Many short leases: every worker gets one of the job.
        return c.api.submit(poison_scene(c), algorithm="pt", iterations=64,
                            resolution=RESOLUTION, seed=SEED, name="poison")

    def assert_healthy_job_renders(self, c, supervisor):
        P = cluster.pb()
        job = c.api.submit(healthy_scene(), algorithm="pt", iterations=8, resolution=RESOLUTION,
                           seed=SEED, name="healthy")
        done = c.api.wait_job(job.id, timeout=120, procs=[c.server])
        self.assertEqual(done.state, P.JOB_STATE_DONE, done.error)
        self.assertEqual(done.frames[0].iterations_done, 8)
        out = c.api.fetch_to(job.id, c.path("healthy.exr"))
        reference = cluster.render_reference(healthy_scene(), "pt", 8, RESOLUTION, SEED)
        print("healthy job vs render:", self.assertImagesMatch(out, reference))

    def test_a_throwing_renderer_fails_the_job_by_the_poison_rule_and_no_worker(self):
        P = cluster.pb()
        c, supervisor = self.farm("throw:" + MESSAGE)
        first_workers = list(supervisor.slots)
        job = self.submit_poison(c)
        failed = c.api.wait_job(job.id, states={P.JOB_STATE_FAILED}, timeout=60,
                                procs=[c.server])
        print(f"job error: {failed.error}")
        self.assertIn(f"failed on {REPORTING_WORKERS} workers", failed.error)
        self.assertNotIn("lost the lease", failed.error)
        self.assertIn(MESSAGE, failed.error)
        self.assertEqual(sum(f.iterations_done for f in failed.frames), 0)

        # No worker died: the same processes run, the supervisor restarted none.
        self.assertEqual(supervisor.death_count(), 0, supervisor.deaths)
        self.assertEqual(supervisor.slots, first_workers)
        self.assertTrue(all(w.alive() for w in first_workers))

        # Each lease a worker failed was reported with the message (the report was delivered:
        # no failure_report_failed), and every failure the server counted is one of them, with
        # the message. (A failure reported after the job FAILED may find its lease gone and
        # is not logged by the server: only those before the verdict must be there.)
        server_failed = lease_failures(c.server.wait_for_log("event=lease_failed",
                                                             count=REPORTING_WORKERS))
        worker_failed = {}
        for w in first_workers:
            text = w.log_text()
            self.assertNotIn("failure_report_failed", text)
            worker_failed.update(lease_failures(text))
        self.assertGreaterEqual(len(worker_failed), REPORTING_WORKERS)
        for lease, line in worker_failed.items():
            self.assertIn(MESSAGE, line)
        self.assertGreaterEqual(len(server_failed), REPORTING_WORKERS)
        for lease, line in server_failed.items():
            self.assertIn(lease, worker_failed, f"the server counted a failure no worker "
                                                f"logged: {line}")
            self.assertIn(MESSAGE, line)
            self.assertIn(f"job={job.id}", line)

        # The same workers render the next job.
        self.assert_healthy_job_renders(c, supervisor)
        self.assertEqual(supervisor.death_count(), 0, supervisor.deaths)

    def test_an_aborting_renderer_fails_the_job_within_bounded_deaths(self):
        P = cluster.pb()
        c, supervisor = self.farm("abort")
        job = self.submit_poison(c)
        failed = c.api.wait_job(job.id, states={P.JOB_STATE_FAILED}, timeout=90,
                                procs=[c.server])
        deaths = supervisor.death_count()
        print(f"job error: {failed.error}; worker deaths: {deaths}")
        m = re.search(r"failed on (\d+) workers \((\d+) lost the lease", failed.error)
        self.assertIsNotNone(m, failed.error)
        self.assertGreaterEqual(int(m.group(2)), LOST_WORKERS)
        self.assertEqual(sum(f.iterations_done for f in failed.frames), 0)
        # Every death was an abort (SIGABRT), never a clean exit; at least one per lost worker,
        # and bounded.
        self.assertTrue(all(status == -6 for _, status in supervisor.deaths), supervisor.deaths)
        self.assertGreaterEqual(deaths, LOST_WORKERS)
        self.assertLessEqual(deaths, MAX_DEATHS)

        # The farm settles: each death is one lease of the job (a worker dies at its first),
        # leases granted just before the verdict included; once the deaths caught up with the
        # leases, the failed job is leased no more and no worker dies any longer.
        def poison_leases():
            return sum(1 for line in c.server.log_text().splitlines()
                       if "event=lease " in line and f"job={job.id} " in line)
        cluster.wait_until(lambda: supervisor.death_count() == poison_leases() and
                           all(w.alive() for w in supervisor.slots), timeout=30,
                           what="every leased worker dead and restarted")
        settled, leases = supervisor.death_count(), poison_leases()
        time.sleep(2 * LEASE_TIMEOUT)
        self.assertEqual(poison_leases(), leases, "the failed job was leased again")
        self.assertEqual(supervisor.death_count(), settled, supervisor.deaths)
        self.assertLessEqual(settled, MAX_DEATHS)
        print(f"leases of the poison job: {leases}; worker deaths: {settled}")

        # The restarted workers render the next job.
        self.assert_healthy_job_renders(c, supervisor)
        self.assertEqual(supervisor.death_count(), settled, supervisor.deaths)


if __name__ == "__main__":
    cluster.main()
