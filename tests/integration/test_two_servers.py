"""Two servers on one PostgreSQL queue and one shared data folder (docs/design/job-store.md,
"Several servers, one farm"), against a PostgreSQL of the test's own (postgres_instance.py; the
test skips, with the reason, where PostgreSQL is not installed).

* Jobs submitted to one server are watched and fetched through the other, with workers
  attached to both (`worker --server A,B` and `--server B,A`); every image equals `render`'s
  bit for bit.
* Chaos: a VCM and a volpt job with workers and a watching `client --server A,B watch` attached;
  server A is killed with SIGKILL, restarted, then server B is killed with SIGKILL and
  restarted. Every job finishes with `render`'s image bit for bit (a range merged twice, or
  lost, would change it), and its iteration count is the target. The watcher moves to the
  other server and sees the job end."""

import os
import re
import subprocess
import sys
import time

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402
from postgres_instance import PostgresClusterTestCase  # noqa: E402

SEED = 7
RESOLUTION = (24, 24)
HOLD_SECONDS = 2  # a dead server's jobs are taken over ~2 s after its last renewal
# (algorithm, scene, iterations): a few seconds each on 4 one-thread workers
SHARED_JOBS = [
    ("vcm", ("bitterli", "cornell-box", "scene_v3.xml"), 300),
    ("volpt", ("tests", "fog-box.xml"), 500),
]
# Long enough for two kills and takeovers to land while they render.
CHAOS_JOBS = [
    ("vcm", ("bitterli", "cornell-box", "scene_v3.xml"), 1500),
    ("volpt", ("tests", "fog-box.xml"), 2500),
]


def read(path, mode="r"):
    with open(path, mode) as f:
        return f.read()


MERGED = re.compile(rb"event=merged .*?job=(\S+) frame=(\d+) first=(\d+) end=(\d+)")
TAKEN = re.compile(rb"event=job_taken .*?job=(\S+)")


def merged_twice_within_a_hold(log_path):
    """The ranges a server's log shows merged twice within one hold of a job (a new hold
    starts from a checkpoint and may merge again what the previous one merged after it)."""
    ranges, twice = {}, []
    for line in read(log_path, "rb").splitlines():
        if m := TAKEN.search(line):
            for key in [k for k in ranges if k[0] == m.group(1)]:
                del ranges[key]
        elif m := MERGED.search(line):
            key = (m.group(1), int(m.group(2)))
            first, end = int(m.group(3)), int(m.group(4))
            held = ranges.setdefault(key, [])
            twice += [(key, (first, end)) for f, e in held if f < end and first < e]
            held.append((first, end))
    return twice


def jobs_taken(log_path):
    """How many jobs the server of this log took a hold of (event=job_taken)."""
    return len(re.findall(rb"event=job_taken ", read(log_path, "rb")))


class TwoServers(PostgresClusterTestCase):
    def start_pair(self):
        """Servers A and B on one database and one data folder; returns both clusters (each
        holds one server; workers are started through `a`)."""
        a = self.new_cluster(lease_timeout=3, heartbeat=0.5)
        b = self.new_cluster(lease_timeout=3, heartbeat=0.5)
        data = a.store  # the shared folder: assets, checkpoints, results
        for c in (a, b):
            c.store = self.pg.url()
            c.server_args = ["--data", data, "--checkpoint-seconds", "1",
                             "--hold-seconds", str(HOLD_SECONDS)]
            c.start_server()
        return a, b

    def start_workers(self, a, b, n_each):
        """n_each workers preferring A and n_each preferring B (each fails over to the other)."""
        for first, second in ((a, b), (b, a)):
            for _ in range(n_each):
                a.start_worker(threads=1,
                               extra=["--server", f"{first.address},{second.address}"])

    def submit(self, api, jobs):
        out = []
        for algorithm, scene_parts, iterations in jobs:
            scene = cluster.scene_path(*scene_parts)
            job = api.submit(scene, algorithm=algorithm, iterations=iterations,
                             resolution=RESOLUTION, seed=SEED, name=f"two-servers-{algorithm}")
            out.append((job.id, scene, algorithm, iterations))
        return out

    def check_result(self, api, job_id, scene, algorithm, iterations, path):
        done = api.get_job(job_id)
        self.assertEqual(done.frames[0].iterations_done, iterations, str(done))
        out = api.fetch_to(job_id, path)
        ref = cluster.render_reference(scene, algorithm, iterations, RESOLUTION, SEED)
        print(f"{algorithm}: {self.assertImagesMatch(out, ref, rel=0, abs_=0)}")

    def test_jobs_submitted_to_one_server_are_watched_and_fetched_from_the_other(self):
        a, b = self.start_pair()
        self.start_workers(a, b, n_each=2)
        a.wait_workers_registered(1)
        b.wait_workers_registered(1)
        jobs = self.submit(a.api, SHARED_JOBS[:1]) + self.submit(b.api, SHARED_JOBS[1:])
        # Each job watched through the server it was not submitted to.
        for (job_id, scene, algorithm, iterations), other in zip(jobs, (b, a)):
            other.api.wait_job(job_id, timeout=180, procs=[a.server, b.server])
        for (job_id, scene, algorithm, iterations), other in zip(jobs, (b, a)):
            self.check_result(other.api, job_id, scene, algorithm, iterations,
                              other.path(f"{algorithm}.exr"))
        # Both servers took part: each held a job (their workers rendered it).
        for c in (a, b):
            self.assertEqual(merged_twice_within_a_hold(c.server.log_path), [])
        taken = [jobs_taken(c.server.log_path) for c in (a, b)]
        print(f"jobs taken: A {taken[0]}, B {taken[1]}")
        self.assertEqual(sum(taken), len(jobs))

    def test_chaos_each_server_killed_in_turn(self):
        P = cluster.pb()
        a, b = self.start_pair()
        self.start_workers(a, b, n_each=2)
        a.wait_workers_registered(1)
        b.wait_workers_registered(1)
        jobs = self.submit(a.api, CHAOS_JOBS)
        watcher_log = a.path("watch.log")
        with open(watcher_log, "wb") as log:
            watcher = subprocess.Popen(
                [cluster.binary("client"), "--server", f"{a.address},{b.address}", "watch",
                 jobs[0][0]], stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        self.addCleanup(lambda: watcher.poll() is None and watcher.kill())
        total = sum(j[3] for j in jobs)

        def progress(api):
            done = 0
            for job_id, *_ in jobs:
                try:
                    j = api.get_job(job_id)
                except Exception:  # the server being killed or restarted: ask again
                    return None
                done += j.frames[0].iterations_done if j.frames else 0
            return done / total

        def kill_when(victim, survivor, fraction):
            cluster.wait_until(lambda: (progress(survivor.api) or 0) >= fraction, timeout=180,
                               poll=0.1, what=f"{fraction:.0%} of the iterations merged")
            at = progress(survivor.api)
            print(f"SIGKILL server {victim.address} at {at:.0%} of all iterations merged")
            port = victim.port
            victim.kill_server()
            return port, at

        port_a, at_a = kill_when(a, b, 0.15)
        # B takes A's jobs over once their holds run out; then A comes back (same port: the
        # workers' and the watcher's lists still name it).
        time.sleep(HOLD_SECONDS + 1)
        a.start_server(port=port_a)
        port_b, at_b = kill_when(b, a, max(0.5, at_a + 0.2))
        time.sleep(1)
        b.start_server(port=port_b)
        self.assertLess(at_b, 1.0, "the jobs finished before the second kill; make them longer")

        for job_id, *_ in jobs:
            a.api.wait_job(job_id, timeout=240, procs=[a.server, b.server])
        for job_id, scene, algorithm, iterations in jobs:
            self.check_result(a.api, job_id, scene, algorithm, iterations,
                              a.path(f"chaos-{algorithm}.exr"))
            self.assertEqual(b.api.get_job(job_id).state, P.JOB_STATE_DONE)
        self.assertEqual(watcher.wait(timeout=60), 0, read(watcher_log))
        watched = read(watcher_log)
        self.assertIn("DONE", watched)
        print(f"the watcher: {watched.strip().splitlines()[-1]}")
        servers = [p for c in (a, b) for p in c.procs if p.name.startswith("server")]
        for p in servers:
            self.assertEqual(merged_twice_within_a_hold(p.log_path), [], p.name)
        taken = sum(jobs_taken(p.log_path) for p in servers)
        print(f"jobs taken over in all: {taken}")
        self.assertGreaterEqual(taken, len(jobs) + 1, "no job changed hands")


if __name__ == "__main__":
    cluster.main()
