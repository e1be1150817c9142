"""The worker's asset cache stays within `worker --cache-max-size` (docs/guide/service.md "Workers").

The cache used to grow forever: every job's assets and folder stayed. Now, before a worker
fetches a job's missing assets, it removes the least recently used job folders and the assets
no job folder links until they fit; never the job it prepares, and never while another worker
sharing the cache prepares a job or loads its scene. Real server, two real workers sharing one
cache folder (as systemd instances share /var/cache/render-worker), three jobs whose assets do
not fit together: the cache never holds more than the bound after a job, the oldest job's folder
and own asset go, the jobs' images equal `render`'s, and a job submitted again with the removed
asset fetches it again and renders.
"""

import hashlib
import os
import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

W, H = 24, 24
OWN = 300 * 1024  # each job's own asset
BOUND = 700 * 1024  # two jobs' assets fit, three do not


def worker_logs(workers):
    text = ""
    for w in workers:
        with open(w.log_path) as f:
            text += f.read()
    return text


def cache_bytes(folder):
    """The bytes the cache's files take, each inode once (hard links)."""
    seen, total = set(), 0
    for root, _, files in os.walk(folder):
        for name in files:
            st = os.lstat(os.path.join(root, name))
            if (st.st_dev, st.st_ino) not in seen:
                seen.add((st.st_dev, st.st_ino))
                total += st.st_size
    return total


class WorkerCacheBound(cluster.ClusterTestCase):
    def submit(self, c, scene, name, own, seed):
        P = cluster.pb()
        bundle = c.api.upload_bundle({"scene_v3.xml": scene, name: own}, "scene_v3.xml")
        return c.api.call(c.api.jobs.SubmitJob, P.SubmitJobRequest(
            name=name, bundle=bundle,
            settings=P.RenderSettings(algorithm="pt", iterations=4, width=W, height=H,
                                      seed=seed)))

    def test_cache_stays_within_its_bound_and_removes_the_oldest_job_first(self):
        c = self.new_cluster(heartbeat=0.5)
        c.start_server()
        cache = c.path("shared-cache")
        os.makedirs(cache)
        workers = [c.start_worker(threads=1, extra=["--cache", cache, "--cache-max-size",
                                                    f"{BOUND // 1024}K"]) for _ in range(2)]
        with open(cluster.cornell_box(), "rb") as f:
            scene = f.read()
        own = {name: os.urandom(OWN) for name in ("a", "b", "c")}
        sha = {name: hashlib.sha256(data).hexdigest() for name, data in own.items()}
        self.assertLess(2 * OWN + len(scene), BOUND)
        self.assertGreater(3 * OWN + len(scene), BOUND)

        jobs = {}
        for seed, name in enumerate(("a", "b", "c"), start=2):
            jobs[name] = self.submit(c, scene, f"{name}.bin", own[name], seed)
            c.api.wait_job(jobs[name].id, timeout=120, procs=[c.server, *workers])
            size = cache_bytes(cache)
            print(f"after job {name}: cache holds {size} B (bound {BOUND} B)")
            self.assertLessEqual(size, BOUND)
            got = c.api.fetch_to(jobs[name].id, c.path(f"{name}.exr"))
            print(f"job {name}:", self.assertImagesMatch(
                got, cluster.render_reference(cluster.cornell_box(), "pt", 4, (W, H), seed)))

        # The oldest job's folder and its own asset went to make room for the third job's.
        job_folders = os.listdir(os.path.join(cache, "jobs"))
        self.assertNotIn(jobs["a"].id, job_folders)
        self.assertIn(jobs["c"].id, job_folders)
        self.assertFalse(os.path.exists(os.path.join(cache, "assets", sha["a"])))
        self.assertTrue(os.path.exists(os.path.join(cache, "assets", sha["c"])))
        logs = worker_logs(workers)
        self.assertIn("event=cache_pruned", logs)

        # A's asset again, in a new job: fetched again, rendered, and still within the bound.
        fetched_a = logs.count(f"event=asset_fetched sha256={sha['a']}")
        again = self.submit(c, scene, "a.bin", own["a"], 5)
        c.api.wait_job(again.id, timeout=120, procs=[c.server, *workers])
        self.assertLessEqual(cache_bytes(cache), BOUND)
        logs = worker_logs(workers)
        self.assertGreater(logs.count(f"event=asset_fetched sha256={sha['a']}"), fetched_a)
        got = c.api.fetch_to(again.id, c.path("again.exr"))
        print("job a again:", self.assertImagesMatch(
            got, cluster.render_reference(cluster.cornell_box(), "pt", 4, (W, H), 5)))


if __name__ == "__main__":
    cluster.main()
