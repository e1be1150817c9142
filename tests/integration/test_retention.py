"""Retention and the asset sweep (docs/guide/service.md, "Deleting jobs").

`server --retain-finished DURATION` deletes a finished, failed or cancelled job that long after
it finished, through DeleteJob's own code: its rows, folders and the assets no other job
references. Here a short duration (4 s) on a real server: a job rendered by a real worker
disappears by itself (GetJob NOT_FOUND), with its own asset and folders, while the shared scene
file stays for a queued job; `render_jobs_expired_total` counts it and the log says so.

`server --unreferenced-asset-grace DURATION` removes an uploaded asset that no job references
once it was last uploaded (or named in HasAssets) that long ago. Here 4 s: an asset uploaded and
never submitted goes (HasAssets then lists it missing; `render_assets_collected_total`), a
queued job's assets stay, and an upload held open half-way across many sweeps completes and is
stored (the partial upload lives in the store's tmp/ folder, which the sweep never reads).
"""

import threading
import time

import hashlib
import os
import sys

import grpc

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

W, H = 16, 16


def metrics(c):
    _, _, body = cluster.http_get(c.http_addresses["metrics"], "/metrics")
    return cluster.parse_metrics(body.decode())


class Retention(cluster.ClusterTestCase):
    def submit(self, c, scene_bytes, extra_name, extra):
        P = cluster.pb()
        bundle = c.api.upload_bundle({"scene_v3.xml": scene_bytes, extra_name: extra},
                                     "scene_v3.xml")
        return c.api.call(c.api.jobs.SubmitJob, P.SubmitJobRequest(
            name=extra_name, bundle=bundle,
            settings=P.RenderSettings(algorithm="pt", iterations=2, width=W, height=H, seed=1)))

    def test_finished_job_deleted_after_the_retention_time(self):
        P = cluster.pb()
        c = self.new_cluster(heartbeat=0.5, server_args=["--metrics", "127.0.0.1:0",
                                                         "--retain-finished", "4s"])
        c.start_server()
        assets = os.path.join(c.store, "assets")
        with open(cluster.cornell_box(), "rb") as f:
            scene = f.read()
        a_only, b_only = b"a" * 3000, b"b" * 4000
        job_a = self.submit(c, scene, "a.bin", a_only)
        worker = c.start_worker(threads=1)
        done = c.api.wait_job(job_a.id, timeout=120, procs=[c.server, worker])
        self.assertEqual(done.state, P.JOB_STATE_DONE)
        worker.kill()
        job_b = self.submit(c, scene, "b.bin", b_only)  # queued (no worker): never expires

        def gone():
            try:
                c.api.get_job(job_a.id)
                return False
            except grpc.RpcError as e:
                self.assertEqual(e.code(), grpc.StatusCode.NOT_FOUND)
                return True

        cluster.wait_until(gone, timeout=60, what="the finished job deleted by retention")
        self.assertFalse(os.path.exists(os.path.join(assets, hashlib.sha256(a_only).hexdigest())))
        self.assertTrue(os.path.exists(os.path.join(assets, hashlib.sha256(scene).hexdigest())))
        for folder in ("jobs", "results", "checkpoints"):
            self.assertFalse(os.path.exists(os.path.join(c.store, folder, job_a.id)), folder)
        m = metrics(c)
        self.assertEqual(m["render_jobs_expired_total"], 1)
        self.assertEqual(m["render_asset_store_bytes"], len(scene) + len(b_only))
        self.assertEqual(c.api.get_job(job_b.id).state, P.JOB_STATE_QUEUED)
        # Logged when the sweep ends, possibly after the job is gone and counted: waited for.
        c.server.wait_for_log(f"event=job_deleted job={job_a.id} reason=retention")
        c.server.wait_for_log("event=retention jobs_deleted=1 assets_removed=1 bytes_freed=3000")

    def test_never_submitted_asset_removed_after_the_grace_period(self):
        P = cluster.pb()
        c = self.new_cluster(server_args=["--metrics", "127.0.0.1:0",
                                          "--unreferenced-asset-grace", "4"])
        c.start_server()
        assets = os.path.join(c.store, "assets")
        with open(cluster.cornell_box(), "rb") as f:
            scene = f.read()
        job = self.submit(c, scene, "kept.bin", b"k" * 2000)  # queued: its assets stay
        orphan = b"o" * 1500
        orphan_sha = hashlib.sha256(orphan).hexdigest()
        c.api.upload_asset(orphan)

        # An upload held open half-way until the orphan has been swept (several sweeps later).
        slow = b"s" * 3000
        slow_sha = hashlib.sha256(slow).hexdigest()
        swept = threading.Event()

        def chunks():
            yield P.AssetChunk(sha256=slow_sha, size=len(slow), data=slow[:1000])
            swept.wait(60)
            time.sleep(3)  # and more sweeps after that
            yield P.AssetChunk(data=slow[1000:])

        result = {}

        def upload():
            try:
                result["reply"] = c.api.call(c.api.jobs.UploadAsset, chunks(), timeout=90)
            except grpc.RpcError as e:
                result["error"] = e

        uploader = threading.Thread(target=upload)
        uploader.start()
        try:
            cluster.wait_until(
                lambda: not os.path.exists(os.path.join(assets, orphan_sha)), timeout=60,
                what="the never-submitted asset removed")
        finally:
            swept.set()
            uploader.join(90)
        self.assertNotIn("error", result, result.get("error"))
        # HasAssets first: it also touches the held upload's asset, whose grace began when it
        # was stored.
        missing = c.api.call(c.api.jobs.HasAssets,
                             P.HasAssetsRequest(sha256=[orphan_sha, slow_sha])).missing
        self.assertEqual(list(missing), [orphan_sha])
        self.assertTrue(os.path.exists(os.path.join(assets, slow_sha)))
        for data in (scene, b"k" * 2000):
            self.assertTrue(os.path.exists(
                os.path.join(assets, hashlib.sha256(data).hexdigest())))
        self.assertEqual(c.api.get_job(job.id).state, P.JOB_STATE_QUEUED)
        m = metrics(c)
        self.assertEqual(m["render_assets_collected_total"], 1)
        self.assertEqual(m["render_assets_collected_bytes_total"], len(orphan))
        self.assertEqual(m["render_asset_store_bytes"], len(scene) + 2000 + len(slow))
        c.server.wait_for_log(f"event=asset_collected sha256={orphan_sha} bytes=1500")


if __name__ == "__main__":
    cluster.main()
