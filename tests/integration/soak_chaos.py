"""Chaos soak (docs/results/reliability-probes.md): three jobs (pt, vcm, volpt on small images) on 3 workers while a driver
SIGKILLs a random worker every 2-4 s (starting a replacement at once) and SIGKILLs the server
three times, restarting it on the same store and port.

What must hold:
* every job ends DONE with all its iterations, and its image equals `render`'s in one process
  (tolerance below);
* no range is merged twice: within each server life the merged ranges of a frame (the server's
  `event=merged` log lines) are disjoint, and the final count equals the target (a range merged
  twice across lives would add its light twice and break the image equality);
* progress never goes backwards while a server lives; across a server SIGKILL it returns to at
  least the count of the frame's last checkpoint logged before the kill (merges after that
  checkpoint are by design re-leased: docs/guide/service.md);
* nothing is left RUNNING: every job final, no worker holding a lease at the end.

Tolerance: each image must equal `render`'s to a relative 1e-6 per value (plus 1e-9 absolute).
The iteration contract makes every iteration's contribution the same wherever it is rendered;
only the order in which the server adds ranges differs from `render`'s, and the float64 sums are
rounded to float32 in the EXR, so equality is expected up to that rounding (the test prints the
largest difference seen; it has been 0 so far).

Run alone with `ctest -L soak` (it takes 2-4 minutes). RENDER_SOAK_SEED changes the kill schedule.
"""

import collections
import os
import random
import re
import time

import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

SEED = int(os.environ.get("RENDER_SOAK_SEED", "18"))
RESOLUTION = (24, 24)
# (algorithm, scene, iterations): about 20 s of one worker thread each on this machine (2 shared
# cores), so that the three server kills land while the jobs run.
JOBS = [
    ("pt", ("bitterli", "cornell-box", "scene_v3.xml"), 6000),
    ("vcm", ("bitterli", "cornell-box", "scene_v3.xml"), 2500),
    ("volpt", ("tests", "fog-box.xml"), 4000),
]
WORKERS = 3
SERVER_KILLS_AT = (0.2, 0.45, 0.7)  # fractions of all iterations merged
WORKER_KILL_EVERY = (2.0, 4.0)  # seconds, uniform
DEADLINE = 240  # seconds for the chaos phase

MERGED = re.compile(rb"event=merged .*?job=(\S+) frame=(\d+) first=(\d+) end=(\d+)")
CHECKPOINT = re.compile(rb"event=checkpoint job=(\S+) frame=(\d+) .*?iterations=(\d+)")


def merged_ranges(log_path):
    """{(job, frame): [(first, end), ...]} of one server life's log."""
    out = collections.defaultdict(list)
    with open(log_path, "rb") as f:
        for m in MERGED.finditer(f.read()):
            out[(m.group(1).decode(), int(m.group(2)))].append((int(m.group(3)), int(m.group(4))))
    return out


def last_checkpoints(log_path):
    """{(job, frame): iterations} of the last checkpoint of each frame in one server life."""
    out = {}
    with open(log_path, "rb") as f:
        for m in CHECKPOINT.finditer(f.read()):
            out[(m.group(1).decode(), int(m.group(2)))] = int(m.group(3))
    return out


LEASE = re.compile(rb"event=lease lease=\S+ worker=\S+ job=(\S+) frame=(\d+) first=(\d+) end=(\d+)")


def leased_iterations(log_paths, job_id, frame=0):
    """How many distinct iterations of a frame the servers of `log_paths` ever leased."""
    leased = set()
    for path in log_paths:
        with open(path, "rb") as f:
            for m in LEASE.finditer(f.read()):
                if m.group(1).decode() == job_id and int(m.group(2)) == frame:
                    leased.update(range(int(m.group(3)), int(m.group(4))))
    return len(leased)


class ChaosSoak(cluster.ClusterTestCase):
    def test_jobs_survive_worker_and_server_kills(self):
        P = cluster.pb()
        rng = random.Random(SEED)
        c = self.new_cluster(lease_timeout=3, heartbeat=0.5,
                             server_args=["--checkpoint-seconds", "1"])
        port = c.start_server()
        c.start_workers(WORKERS, threads=1)
        c.wait_workers_registered(WORKERS)
        jobs = []
        for algo, scene_parts, iterations in JOBS:
            scene = cluster.scene_path(*scene_parts)
            job = c.api.submit(scene, algorithm=algo, iterations=iterations,
                               resolution=RESOLUTION, seed=SEED, name=f"soak-{algo}")
            jobs.append((job.id, algo, scene, iterations))
        total = sum(j[3] for j in jobs)

        life = [c.server.log_path]  # one log per server life
        progress = {job_id: 0 for job_id, *_ in jobs}  # last seen in this server life
        worker_kills = server_kills = 0
        backwards = []
        next_worker_kill = time.monotonic() + rng.uniform(*WORKER_KILL_EVERY)
        start = time.monotonic()
        states = {}
        while time.monotonic() - start < DEADLINE:
            # Observe: progress per job, monotonic within this server life.
            for job_id, *_ in jobs:
                try:
                    j = c.api.get_job(job_id)
                except Exception as e:  # the server is restarting
                    print(f"get_job: {e!r}")
                    continue
                states[job_id] = j.state
                done = j.frames[0].iterations_done if j.frames else 0
                if done < progress[job_id]:
                    backwards.append((job_id, progress[job_id], done, len(life)))
                progress[job_id] = done
            if all(s in (P.JOB_STATE_DONE, P.JOB_STATE_FAILED, P.JOB_STATE_CANCELLED)
                   for s in states.values()) and len(states) == len(jobs):
                break
            merged_fraction = sum(progress.values()) / total

            # Kill the server at the next fraction of the work, restart it on the same store.
            if server_kills < len(SERVER_KILLS_AT) and \
                    merged_fraction >= SERVER_KILLS_AT[server_kills]:
                server_kills += 1
                c.kill_server()
                checkpoints = last_checkpoints(life[-1])
                print(f"t={time.monotonic() - start:.1f}s server kill {server_kills} at "
                      f"{merged_fraction:.0%} merged; last checkpoints {checkpoints}")
                port = c.restart_server(port, workers=WORKERS)
                life.append(c.server.log_path)
                # Progress restarts from the store: at least each frame's last checkpoint.
                for job_id, *_ in jobs:
                    j = c.api.get_job(job_id)
                    done = j.frames[0].iterations_done if j.frames else 0
                    floor = checkpoints.get((job_id, 0), 0)
                    self.assertGreaterEqual(done, floor,
                                            f"job {job_id} restored {done} iterations, fewer "
                                            f"than its last checkpoint ({floor})")
                    # ... and no more than was ever leased. (Not "than the last poll or logged
                    # checkpoint": the server saves a checkpoint, then logs it, and a SIGKILL
                    # between the two restores a count no log line shows.)
                    leased = leased_iterations(life, job_id)
                    self.assertLessEqual(done, leased,
                                         f"job {job_id} restored {done} iterations, more than "
                                         f"were ever leased ({leased})")
                    progress[job_id] = done

            # Kill a random worker every few seconds and start a replacement.
            if time.monotonic() >= next_worker_kill:
                live = c.live_workers()
                if live:
                    victim = rng.choice(live)
                    victim.kill()
                    worker_kills += 1
                    c.start_worker(threads=1)
                next_worker_kill = time.monotonic() + rng.uniform(*WORKER_KILL_EVERY)
            self.assertTrue(c.server.alive(), f"the server died:\n{c.server.log_tail()}")
            time.sleep(0.2)
        elapsed = time.monotonic() - start
        print(f"chaos phase: {elapsed:.1f} s, {worker_kills} worker kills, {server_kills} server "
              f"kills, {len(c.workers)} workers started in all")

        self.assertEqual(server_kills, len(SERVER_KILLS_AT),
                         "the jobs finished before the three server kills; make them longer")
        self.assertEqual(backwards, [], "progress went backwards within a server life "
                                        "(job, before, after, server life)")
        # Every job final and DONE, nothing leased any more.
        for job_id, algo, scene, iterations in jobs:
            j = c.api.wait_job(job_id, timeout=30, procs=[c.server])
            self.assertEqual(j.frames[0].iterations_done, iterations, str(j))
        cluster.wait_until(lambda: not any(w.lease_id for w in c.api.cluster_status().workers),
                           timeout=15, what="no worker to hold a lease")

        # No range merged twice within a server life; ranges cover the job at most once each.
        for n, log in enumerate(life, 1):
            lives_ranges = merged_ranges(log)
            count = sum(len(r) for r in lives_ranges.values())
            print(f"server life {n}: {count} ranges merged")
            if n < len(life):  # every life but the last one merged work before its kill
                self.assertGreater(count, 0, f"no merged range found in {log}")
            for (job_id, frame), ranges in lives_ranges.items():
                ranges.sort()
                for (a0, a1), (b0, b1) in zip(ranges, ranges[1:]):
                    self.assertLessEqual(a1, b0, f"server life {n}: job {job_id} frame {frame} "
                                                 f"merged [{a0},{a1}) and [{b0},{b1})")

        # Images equal `render`'s.
        for job_id, algo, scene, iterations in jobs:
            out = c.api.fetch_to(job_id, c.path(f"{algo}.exr"))
            ref = cluster.render_reference(scene, algo, iterations, RESOLUTION, SEED)
            a, b = cluster.read_exr(out), cluster.read_exr(ref)
            differing = int((a != b).sum())
            print(f"{algo}: {differing} of {a.size} values differ from render's; "
                  + self.assertImagesMatch(out, ref, rel=1e-6, abs_=1e-9))
        self.assertTrue(c.server.alive(), "the server died")


if __name__ == "__main__":
    cluster.main()
