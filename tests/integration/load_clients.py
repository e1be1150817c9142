"""Load test (docs/results/reliability-probes.md): 100 jobs from 10 concurrent clients on 2 workers, each client on its own
channel doing a mix of what users do: submit and watch (WatchJob) to the end then fetch; submit
and poll (GetJob) then fetch; submit and cancel at once; submit, drop a WatchJob stream after its
first event, then poll; and a FetchResult stream dropped after its first chunk. Each round's
scene file is new to the server and the same for all clients, so that ten clients upload the
same asset at once. The round runs twice.

What must hold:
* no job lost: ListJobs holds every submitted job, and every job ends in a final state (DONE,
  or CANCELLED for the ones cancelled before they finished); every fetched DONE image has the
  job's size; no client call fails;
* the server's open file descriptors (/proc/PID/fd) are back to their value before the round
  once the clients have closed their channels: equal, up to 2 (gRPC may keep a spare pipe or
  epoll descriptor open between rounds);
* the server's memory (VmRSS, /proc/PID/status) does not grow from one round to the next by
  more than 16 MiB (a leak of 160 KiB per job would show; measured: +0.9 MiB from round 1 to
  round 2, about 9 KiB per job, the finished jobs the server keeps on purpose; glibc does not
  always return freed pages either). Its start value is taken after a warm-up round of 10 jobs, which sizes gRPC's
  thread pools and the store's caches.

Run alone with `ctest -L load` (about a minute).
"""

import os
import shutil
import threading
import time

import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

CLIENTS = 10
JOBS_PER_CLIENT = 10
RESOLUTION = (16, 16)
ITERATIONS = 32
FD_TOLERANCE = 2
RSS_GROWTH_LIMIT = 16 << 20


def server_fds(pid):
    return len(os.listdir(f"/proc/{pid}/fd"))


def server_rss(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    raise AssertionError("no VmRSS")


class LoadClients(cluster.ClusterTestCase):
    def run_client(self, c, n, scene, jobs_out, errors, round_no):
        """One client: its own channel, JOBS_PER_CLIENT jobs, one behaviour per job."""
        P = cluster.pb()
        final = {P.JOB_STATE_DONE, P.JOB_STATE_CANCELLED, P.JOB_STATE_FAILED}
        api = cluster.Api(c.address, c.token, timeout=60)
        try:
            for k in range(JOBS_PER_CLIENT):
                kind = (n + k) % 5
                job = api.submit(scene, algorithm="pt", iterations=ITERATIONS,
                                 resolution=RESOLUTION, seed=1 + k,
                                 name=f"load-r{round_no}-c{n}-{k}")
                jobs_out.append((job.id, kind))
                if kind == 0:  # watch to the end, then fetch
                    for event in api.jobs.WatchJob(P.WatchJobRequest(job_id=job.id),
                                                   metadata=api.metadata(), timeout=90):
                        if event.job.state in final:
                            break
                    self.check_image(api, job.id)
                elif kind == 1:  # poll, then fetch
                    api.wait_job(job.id, timeout=90)
                    self.check_image(api, job.id)
                elif kind == 2:  # cancel at once
                    api.call(api.jobs.CancelJob, P.CancelJobRequest(job_id=job.id))
                elif kind == 3:  # a watch dropped after its first event, then poll
                    stream = api.jobs.WatchJob(P.WatchJobRequest(job_id=job.id),
                                               metadata=api.metadata(), timeout=90)
                    next(iter(stream))
                    stream.cancel()
                    api.wait_job(job.id, timeout=90)
                else:  # a fetch dropped after its first chunk, then a whole one
                    api.wait_job(job.id, timeout=90)
                    stream = api.jobs.FetchResult(P.FetchResultRequest(job_id=job.id),
                                                  metadata=api.metadata(), timeout=60)
                    next(iter(stream))
                    stream.cancel()
                    self.check_image(api, job.id)
        except Exception as e:  # recorded: the main thread fails the test with it
            errors.append(f"client {n}: {e!r}")
        finally:
            api.close()

    def check_image(self, api, job_id):
        path = os.path.join(self.tmp, f"{job_id}.exr")
        api.fetch_to(job_id, path)
        image = cluster.read_exr(path)
        assert image.shape == (RESOLUTION[1], RESOLUTION[0], 3), image.shape
        os.remove(path)

    def round(self, c, scene, clients, round_no):
        # A scene file new to the server in each round, the same for every client: the ten
        # clients find it missing (HasAssets) and upload the same asset at the same time.
        with open(scene) as f:
            text = f.read()
        scene = os.path.join(os.path.dirname(scene), f"round-{round_no}.xml")
        with open(scene, "w") as f:
            f.write(text + f"<!-- load test round {round_no} -->\n")
        jobs, errors = [], []
        threads = [threading.Thread(target=self.run_client,
                                    args=(c, n, scene, jobs, errors, round_no))
                   for n in range(clients)]
        t0 = time.monotonic()
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout=300)
        self.assertFalse(any(t.is_alive() for t in threads), "a client hung")
        self.assertEqual(errors, [])
        self.assertEqual(len(jobs), clients * JOBS_PER_CLIENT)
        # Every job known to the server and final.
        P = cluster.pb()
        states = {}
        for job_id, kind in jobs:
            j = c.api.wait_job(job_id, timeout=60, states={P.JOB_STATE_DONE,
                                                             P.JOB_STATE_CANCELLED})
            states[job_id] = j.state
            if kind != 2:
                self.assertEqual(j.state, P.JOB_STATE_DONE, str(j))
        listed = {j.id for j in c.api.call(c.api.jobs.ListJobs, P.ListJobsRequest()).jobs}
        lost = [job_id for job_id, _ in jobs if job_id not in listed]
        self.assertEqual(lost, [], "jobs missing from ListJobs")
        done = sum(1 for s in states.values() if s == P.JOB_STATE_DONE)
        print(f"round {round_no}: {len(jobs)} jobs from {clients} clients in "
              f"{time.monotonic() - t0:.1f} s: {done} DONE, {len(jobs) - done} CANCELLED, "
              f"0 lost, 0 client errors")

    def quiet_values(self, c):
        """fds and RSS once the server is idle: no worker holding a lease, the clients' channels
        closed (gRPC closes them asynchronously: wait for the fd count to settle)."""
        cluster.wait_until(lambda: not any(w.lease_id for w in c.api.cluster_status().workers),
                           timeout=30, what="the workers to be idle")
        pid = c.server.pid
        last = None
        for _ in range(50):
            fds = server_fds(pid)
            if fds == last:
                break
            last = fds
            time.sleep(0.2)
        time.sleep(1.0)
        return server_fds(pid), server_rss(pid)

    def test_hundred_jobs_from_ten_clients(self):
        c = self.new_cluster(heartbeat=0.5)
        self.tmp = c.path("fetched")
        os.makedirs(self.tmp)
        c.start_server()
        c.start_workers(2, threads=1)
        c.wait_workers_registered(2)
        # The Cornell box copied next to its meshes, so that each round can add a scene file.
        box = os.path.dirname(cluster.cornell_box())
        folder = c.path("scene")
        shutil.copytree(box, folder)
        scene = os.path.join(folder, os.path.basename(cluster.cornell_box()))

        self.round(c, scene, 1, 0)  # warm-up: 10 jobs, one client
        fds0, rss0 = self.quiet_values(c)
        print(f"start: {fds0} fds, RSS {rss0 / 2**20:.1f} MiB")
        results = []
        for round_no in (1, 2):
            self.round(c, scene, CLIENTS, round_no)
            fds, rss = self.quiet_values(c)
            results.append((fds, rss))
            print(f"after round {round_no}: {fds} fds, RSS {rss / 2**20:.1f} MiB")
        for fds, _ in results:
            self.assertLessEqual(abs(fds - fds0), FD_TOLERANCE,
                                 f"open fds {fds0} before, {fds} after a round")
        growth = results[1][1] - results[0][1]
        self.assertLessEqual(growth, RSS_GROWTH_LIMIT,
                             f"RSS grew by {growth / 2**20:.1f} MiB from round 1 to round 2")
        self.assertTrue(c.server.alive())

    def test_watch_streams_are_bounded(self):
        """A client cannot open WatchJob streams without end: each holds a server thread (1000
        of them took 1000 threads and made GetJob take 2 s). Past kMaxWatchStreams (256) a
        watch is refused with RESOURCE_EXHAUSTED; a closed one frees its place."""
        import grpc
        P = cluster.pb()
        c = self.new_cluster()
        c.start_server()  # no worker: the job stays queued and its watches open
        job = c.api.submit(cluster.cornell_box(), algorithm="pt", iterations=4,
                           resolution=RESOLUTION, name="watched")
        apis = [cluster.Api(c.address, c.token, timeout=60) for _ in range(4)]
        streams = []
        try:
            def watch(n):
                s = apis[n % len(apis)].jobs.WatchJob(P.WatchJobRequest(job_id=job.id),
                                                      timeout=60)
                next(iter(s))  # the first event: the stream is open on the server
                return s
            for n in range(256):
                streams.append(watch(n))
            with self.assertRaises(grpc.RpcError) as refused:
                watch(256)
            self.assertEqual(refused.exception.code(), grpc.StatusCode.RESOURCE_EXHAUSTED)
            self.assertIn("more than 256 WatchJob streams", refused.exception.details())
            self.assertEqual(c.api.get_job(job.id).id, job.id)  # other calls still served
            streams.pop().cancel()
            streams.append(cluster.wait_until(lambda: self.try_watch(watch), timeout=10,
                                              what="a watch once one was closed"))
        finally:
            for s in streams:
                s.cancel()
            for a in apis:
                a.close()

    @staticmethod
    def try_watch(watch):
        import grpc
        try:
            return watch(0)
        except grpc.RpcError as e:
            if e.code() != grpc.StatusCode.RESOURCE_EXHAUSTED:
                raise
            return None


if __name__ == "__main__":
    cluster.main()
