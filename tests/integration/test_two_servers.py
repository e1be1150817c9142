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
  other server and sees the job end. No lease stays lost for longer than its timeout (from the
  servers' logs: an expired lease's range is queued again at its expiry, a killed server's
  when another server takes its job over, within the lease timeout of the kill), and each is
  leased again in the queue's order.
* Forwarding: a report sent to the server that did not grant its lease (a worker that failed
  over while the holder lives) is forwarded to the holder and merged there once; a second copy
  is dropped; the job ends with `render`'s image."""

import datetime
import json
import re
import subprocess
import sys
import time

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402
import numpy as np  # noqa: E402
from postgres_instance import PostgresClusterTestCase  # noqa: E402

SEED = 7
RESOLUTION = (24, 24)
HOLD_SECONDS = 2  # a dead server's jobs are taken over ~2 s after its last renewal
LEASE_TIMEOUT = 3
TICK_SECONDS = 0.25  # the server's housekeeping (and the sync's check) runs this often
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


TS = re.compile(rb"ts=(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3})Z")
LEASE = re.compile(rb"event=lease .*?lease=(\S+) .*?job=(\S+) frame=(\d+) first=(\d+) "
                   rb"end=(\d+)")
MERGED_LEASE = re.compile(rb"event=merged .*?lease=(\S+)")
LEASE_LOST = re.compile(rb"event=lease_lost .*?lease=(\S+)")


def log_seconds(line):
    """A log line's time stamp (ts=...Z, UTC) in seconds since the epoch."""
    m = TS.search(line)
    return datetime.datetime.strptime(m.group(1).decode(), "%Y-%m-%dT%H:%M:%S.%f").replace(
        tzinfo=datetime.timezone.utc).timestamp()


TAKEN_AT = re.compile(rb"event=job_taken .*?job=(\S+)")
REGISTERED = re.compile(rb"event=worker_registered ")


def lost_leases(log_paths, killed_at):
    """Every lease granted and never merged (by any server), with how it was lost and when its
    range was queued again (docs/design/job-store.md, "What each server does"):

    * "expired": its worker went silent for the lease timeout; queued again at the expiry
      itself (event=lease_lost). An expiry followed by its server's kill before anyone leased
      the range again counts as "server killed", from the kill.
    * "server killed": its server died (`killed_at[log_path]`); queued again when a server
      takes the job over (the first event=job_taken of its job after the kill). `ready` is when
      a server could first take it: the dead server's hold had run out (HOLD_SECONDS after the
      kill at the latest) and the taker had a worker (a server takes jobs only for its
      workers: it had one at the kill, or from its first event=worker_registered after it).

    Returns dicts (lease, job, frame, first, end, how, lost_at, queued_at, ready, leased_at:
    the next grant of an overlapping range by any server, or None; overtaken: grants of the
    same frame entirely after the range, made between its queueing and its grant) and the
    leases unmerged for another reason (neither killed nor expired)."""
    grants, merged, expired, taken, registered, started = [], set(), {}, [], {}, {}
    for path in log_paths:
        for line in read(path, "rb").splitlines():
            if b"ts=" not in line:
                continue
            t = log_seconds(line)
            started.setdefault(path, t)
            if m := LEASE.search(line):
                grants.append((t, path, m.group(1), m.group(2), int(m.group(3)),
                               int(m.group(4)), int(m.group(5))))
            elif m := MERGED_LEASE.search(line):
                merged.add(m.group(1))
            elif m := LEASE_LOST.search(line):
                expired[m.group(1)] = t
            elif m := TAKEN_AT.search(line):
                taken.append((t, path, m.group(1)))
            elif REGISTERED.search(line):
                registered.setdefault(path, []).append(t)
    grants.sort()
    taken.sort()
    out, other = [], []
    for t, path, lease, job, frame, first, end in grants:
        if lease in merged:
            continue
        again = [g for g in grants if g[0] > t and g[3] == job and g[4] == frame
                 and g[5] < end and first < g[6]]
        kill = killed_at.get(path)
        if lease in expired:
            lost_at, how = expired[lease], "expired"
            if kill is not None and lost_at <= kill and (not again or kill < again[0][0]):
                lost_at, how = kill, "server killed"
        elif kill is not None and kill >= t:
            lost_at, how = kill, "server killed"
        else:
            other.append(lease)
            continue
        queued_at, ready = lost_at, None
        if how == "server killed":
            # The first take-over of the job by another server after the grant (the killed
            # server may have lost the job before it died: then before the kill).
            take = next((x for x in taken if x[0] > t and x[1] != path and x[2] == job), None)
            queued_at = take[0] if take else None
            if take:
                had = started[take[1]] <= lost_at and any(
                    r <= lost_at for r in registered.get(take[1], []))
                first_worker = lost_at if had else min(
                    (r for r in registered.get(take[1], []) if r > lost_at), default=None)
                ready = max(lost_at + HOLD_SECONDS, first_worker or queued_at)
        leased = again[0] if again else None
        overtaken = [g[2] for g in grants if queued_at is not None and g[0] >= queued_at
                     and (leased is None or g[0] < leased[0]) and g[3] == job
                     and g[4] == frame and g[5] >= end]
        out.append({"lease": lease.decode(), "job": job.decode(), "frame": frame, "first": first,
                    "end": end, "how": how, "lost_at": lost_at, "queued_at": queued_at,
                    "ready": ready, "leased_at": leased[0] if leased else None,
                    "overtaken": overtaken})
    return out, other


def metric(metrics, name, **labels):
    """One sample of parse_metrics' output by its name and labels (None when absent)."""
    if labels:
        name += "{" + ",".join(f'{k}="{v}"' for k, v in sorted(labels.items())) + "}"
    return metrics.get(name)


def jobs_taken(log_path):
    """How many jobs the server of this log took a hold of (event=job_taken)."""
    return len(re.findall(rb"event=job_taken ", read(log_path, "rb")))


FORWARDED = re.compile(rb"event=report_forwarded .*?result=(\S+)")


class TwoServers(PostgresClusterTestCase):
    def start_pair(self, extra=(), lease_timeout=LEASE_TIMEOUT):
        """Servers A and B on one database and one data folder; returns both clusters (each
        holds one server; workers are started through `a`)."""
        a = self.new_cluster(lease_timeout=lease_timeout, heartbeat=0.5)
        b = self.new_cluster(lease_timeout=lease_timeout, heartbeat=0.5)
        data = a.store  # the shared folder: assets, checkpoints, results
        for c in (a, b):
            c.store = self.pg.url()
            c.server_args = ["--data", data, "--checkpoint-seconds", "1",
                             "--hold-seconds", str(HOLD_SECONDS), *extra]
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

        killed_at = {}  # a killed server's log: when it was killed

        def kill_when(victim, survivor, fraction):
            cluster.wait_until(lambda: (progress(survivor.api) or 0) >= fraction, timeout=180,
                               poll=0.1, what=f"{fraction:.0%} of the iterations merged")
            at = progress(survivor.api)
            print(f"SIGKILL server {victim.address} at {at:.0%} of all iterations merged")
            port = victim.port
            victim.kill_server()
            killed_at[victim.server.log_path] = time.time()
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
        # No lease lost for longer than its timeout: every lost lease's range is queued again
        # within it (lost_leases: when and how). An expired lease's range is queued at the
        # expiry itself. A killed server's leases are void, and their ranges queued again when
        # another server takes the job over: the dead server's hold runs out at most
        # HOLD_SECONDS after the kill (it renews at most up to the kill), and a server that
        # has a worker takes every job it may at its next sync, at most a quarter of the hold
        # and one tick (TICK_SECONDS) later. So the configuration below keeps
        # HOLD_SECONDS * 1.25 + TICK_SECONDS within LEASE_TIMEOUT, and a dead server's leases
        # are queued again no later than a dead worker's are. Before a server with a worker
        # exists nobody can lease the range anyway: the bound counts from `ready`.
        # Queued again, a range is leased again in the queue's order: none of its frame's
        # ranges after it is handed out before it, and it is handed out.
        self.assertLessEqual(HOLD_SECONDS * 1.25 + TICK_SECONDS, LEASE_TIMEOUT)
        lost, other = lost_leases([p.log_path for p in servers], killed_at)
        kinds = {how: sum(x["how"] == how for x in lost) for how in ("expired", "server killed")}
        print(f"leases lost: {len(lost)} {kinds}; unmerged otherwise: {len(other)}")
        for x in lost:
            queued = x["queued_at"] - x["lost_at"] if x["queued_at"] is not None else None
            leased = (x["leased_at"] - x["queued_at"]) if x["leased_at"] is not None else None
            print(f"  {x['lease']} ({x['how']}): queued again after "
                  f"{'never' if queued is None else f'{queued:.2f} s'}"
                  + (f" (a server could take it after {x['ready'] - x['lost_at']:.2f} s)"
                     if x["ready"] is not None else "")
                  + f", leased again {'never' if leased is None else f'{leased:.2f} s'} later")
        self.assertGreater(len(lost), 0, "no lease was lost: the kills hit no lease")
        for x in lost:
            what = f"lease {x['lease']} ({x['how']}, iterations {x['first']}..{x['end']})"
            self.assertIsNotNone(x["queued_at"], f"{what} was never queued again")
            if x["how"] == "server killed":
                self.assertLessEqual(x["queued_at"] - (x["ready"] - HOLD_SECONDS),
                                     LEASE_TIMEOUT, f"{what} stayed lost too long: {x}")
            self.assertIsNotNone(x["leased_at"], f"{what} was never leased again")
            self.assertEqual(x["overtaken"], [], f"{what}: later ranges leased before it")

    def test_a_report_to_the_server_that_did_not_grant_its_lease_is_forwarded(self):
        from test_duplicate_report import ALGO, ITERATIONS, SEED as FAKE_SEED, W, H
        from test_duplicate_report import FakeWorker, range_sum
        # A long lease timeout: the fake worker does not heartbeat while `render` computes the
        # range's sums (a lease that expired is no longer outstanding and is not forwarded).
        a, b = self.start_pair(extra=["--metrics", "127.0.0.1:0", "--http", "127.0.0.1:0"],
                               lease_timeout=60)
        scene = cluster.cornell_box()
        # Registered with A only: A has a live worker and takes the job, B has none and never
        # holds it.
        fake = FakeWorker(a.api)
        job = a.api.submit(scene, algorithm=ALGO, iterations=ITERATIONS, resolution=(W, H),
                           seed=FAKE_SEED, name="forwarded")
        lease = fake.lease()
        self.assertEqual(lease.job_id, job.id)
        first, end = lease.first_iteration, lease.end_iteration
        print(f"leased [{first}, {end}) from A")
        sum_, odd = range_sum(scene, first, end)
        # The same worker, failed over to B: B did not grant the lease and forwards it.
        to_b = FakeWorker.__new__(FakeWorker)
        to_b.api, to_b.worker_id = b.api, fake.worker_id
        merged = to_b.report(lease.lease_id, first, end, sum_, odd)
        self.assertTrue(merged, "a report sent to the server that did not grant its lease was "
                        "not merged by the holder")
        # A second copy: the lease is no longer outstanding (A deletes the rows of the leases
        # it merged at its next tick, docs/design/job-store.md, "Connections"), so B drops it
        # without forwarding. (Sent before that tick, B would forward it and A drop it as a
        # duplicate: merged once either way.)
        lease_rows = f"SELECT count(*) FROM leases WHERE lease_id = '{lease.lease_id}'"
        cluster.wait_until(lambda: self.pg.psql(lease_rows) == ["0"], timeout=30,
                           what="A to delete the merged lease's row")
        garbage = np.full(W * H * 3, 1000.0)
        self.assertFalse(to_b.report(lease.lease_id, first, end, garbage, garbage),
                         "a second copy of a forwarded report was merged")
        self.assertEqual([m for m in FORWARDED.findall(read(b.server.log_path, "rb"))],
                         [b"merged"])
        metrics = cluster.parse_metrics(
            cluster.http_get(b.http_addresses["metrics"], "/metrics")[2].decode())
        forwarded = {k: v for k, v in metrics.items()
                     if k.startswith("render_reports_forwarded_total")}
        print(f"B's forwarded reports: {forwarded}")
        self.assertEqual(metric(metrics, "render_reports_forwarded_total", result="merged"), 1)
        self.assertEqual(metric(metrics, "render_reports_forwarded_total", result="not_merged"),
                         0)
        # The shared queue's figures, as B reads them from the store: A holds the job.
        self.assertEqual(metric(metrics, "render_farm_jobs_held", server=a.address), 1)
        self.assertEqual(metric(metrics, "render_farm_jobs_unheld"), 0)
        # The dashboard's view of the farm, from B: A holding the job, B nothing.
        status, _, body = cluster.http_get(b.http_addresses["http"], "/api/farm")
        self.assertEqual(status, 200)
        farm = json.loads(body)
        print(f"B's /api/farm: {farm}")
        self.assertTrue(farm["shared"])
        self.assertEqual(farm["self"], b.address)
        self.assertEqual({s["address"]: s["jobs_held"] for s in farm["servers"]},
                         {a.address: 1, b.address: 0})
        self.assertEqual(farm["jobs_unheld"], 0)
        # The farm's workers, from B: A's worker as A recorded it in the store at its sync
        # (B reads the store at its own; a few syncs at most, each a quarter of the hold).
        def a_workers_seen_by_b():
            farm = json.loads(cluster.http_get(b.http_addresses["http"], "/api/farm")[2])
            return [w for w in farm["workers"]
                    if w["worker_id"] == fake.worker_id and w["server"] == a.address]
        seen = []
        for _ in range(40):
            seen = a_workers_seen_by_b()
            if seen:
                break
            time.sleep(0.25)
        self.assertEqual(len(seen), 1, "B's /api/farm does not list A's worker")
        self.assertFalse(seen[0]["self"])
        merged_at_a = [m for m in MERGED.findall(read(a.server.log_path, "rb"))
                       if int(m[2]) == first and int(m[3]) == end]
        self.assertEqual(len(merged_at_a), 1, "the forwarded report was not merged at A once")
        # A real worker on A renders the rest: the forwarded sums are in the image.
        a.start_worker(threads=1)
        b.api.wait_job(job.id, timeout=60, procs=[a.server, b.server])  # as B reads the store
        self.assertEqual(b.api.get_job(job.id).frames[0].iterations_done, ITERATIONS)
        ref = cluster.render_reference(scene, ALGO, ITERATIONS, (W, H), FAKE_SEED)
        print("forwarded:", self.assertImagesMatch(b.api.fetch_to(job.id, b.path("f.exr")), ref))
        self.assertEqual(merged_twice_within_a_hold(a.server.log_path), [])


if __name__ == "__main__":
    cluster.main()
