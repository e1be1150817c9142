"""Deleting a job frees its assets (docs/guide/service.md, "Deleting jobs").

The server never deleted an asset: the store only grew until --max-store-size refused uploads.
`client delete JOB` (DeleteJob) now deletes a finished, failed or cancelled job: its rows, scene
folder, checkpoints and results, and the assets of its bundle that no other job references; the
store's size (render_asset_store_bytes, what --max-store-size counts) goes down by theirs. A
queued or running job is refused (cancel it first). Shared (content-addressed) assets stay
while a job references them: a second job sharing the scene file, submitted before the first
is deleted, still renders to an image equal to `render`'s. After a restart on the same store,
nothing of the deleted jobs comes back. Real server and worker, Python gRPC and the client CLI.
"""

import hashlib
import os
import subprocess
import sys

import grpc

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

W, H = 32, 32


def store_bytes(c):
    _, _, body = cluster.http_get(c.http_addresses["metrics"], "/metrics")
    return cluster.parse_metrics(body.decode())["render_asset_store_bytes"]


class DeleteJob(cluster.ClusterTestCase):
    def submit(self, c, scene_bytes, extra_name, extra, seed):
        P = cluster.pb()
        bundle = c.api.upload_bundle({"scene_v3.xml": scene_bytes, extra_name: extra},
                                     "scene_v3.xml")
        return c.api.call(c.api.jobs.SubmitJob, P.SubmitJobRequest(
            name=extra_name, bundle=bundle,
            settings=P.RenderSettings(algorithm="pt", iterations=4, width=W, height=H,
                                      seed=seed)))

    def test_delete_frees_unshared_assets_and_keeps_shared_ones(self):
        P = cluster.pb()
        # --fixed-stream-window: the option's end-to-end run (reports, uploads and fetches
        # through fixed 64 KiB windows; images equal to render's). Its memory figures:
        # docs/guide/service.md.
        c = self.new_cluster(heartbeat=0.5, server_args=["--metrics", "127.0.0.1:0",
                                                         "--fixed-stream-window"])
        c.start_server()
        assets = os.path.join(c.store, "assets")
        with open(cluster.cornell_box(), "rb") as f:
            scene = f.read()
        a_only, b_only = b"a" * 5000, b"b" * 7000  # one asset each job alone references
        sha = {name: hashlib.sha256(data).hexdigest()
               for name, data in (("scene", scene), ("a", a_only), ("b", b_only))}

        job_a = self.submit(c, scene, "a.bin", a_only, seed=2)
        worker = c.start_worker(threads=1)
        c.api.wait_job(job_a.id, timeout=120, procs=[c.server, worker])
        worker.kill()
        job_b = self.submit(c, scene, "b.bin", b_only, seed=3)  # queued: no worker now
        self.assertEqual(store_bytes(c), len(scene) + len(a_only) + len(b_only))
        for folder in ("jobs", "results"):
            self.assertTrue(os.path.isdir(os.path.join(c.store, folder, job_a.id)), folder)

        # A queued job is not deleted.
        with self.assertRaises(grpc.RpcError) as queued:
            c.api.call(c.api.jobs.DeleteJob, P.DeleteJobRequest(job_id=job_b.id))
        self.assertEqual(queued.exception.code(), grpc.StatusCode.FAILED_PRECONDITION)
        self.assertIn("cancel it first", queued.exception.details())

        # Deleting A (with the CLI) removes its own asset only; the shared scene file stays.
        out = subprocess.run([cluster.binary("client"), "--server", c.address, "delete",
                              job_a.id], capture_output=True, text=True, timeout=60)
        print(out.stdout, out.stderr)
        self.assertEqual(out.returncode, 0, out.stderr)
        self.assertIn(f"job {job_a.id} deleted: 1 asset(s) no other job uses removed, "
                      f"4.9 KiB freed", out.stdout)
        self.assertFalse(os.path.exists(os.path.join(assets, sha["a"])))
        self.assertTrue(os.path.exists(os.path.join(assets, sha["scene"])))
        self.assertTrue(os.path.exists(os.path.join(assets, sha["b"])))
        for folder in ("jobs", "results", "checkpoints"):
            self.assertFalse(os.path.exists(os.path.join(c.store, folder, job_a.id)), folder)
        self.assertEqual(store_bytes(c), len(scene) + len(b_only))
        with self.assertRaises(grpc.RpcError) as gone:
            c.api.get_job(job_a.id)
        self.assertEqual(gone.exception.code(), grpc.StatusCode.NOT_FOUND)

        # B, which shares the scene file, renders.
        worker = c.start_worker(threads=1)
        c.api.wait_job(job_b.id, timeout=120, procs=[c.server, worker])
        got = c.api.fetch_to(job_b.id, c.path("b.exr"))
        print("job B:", self.assertImagesMatch(
            got, cluster.render_reference(cluster.cornell_box(), "pt", 4, (W, H), 3)))

        # Deleting B empties the store.
        reply = c.api.call(c.api.jobs.DeleteJob, P.DeleteJobRequest(job_id=job_b.id))
        self.assertEqual((reply.assets_removed, reply.bytes_freed), (2, len(scene) + len(b_only)))
        self.assertEqual(os.listdir(assets), [])
        self.assertEqual(store_bytes(c), 0)

        # A restart on the same store knows neither job and counts no assets.
        c.kill_server()
        c.start_server()
        self.assertEqual(len(c.api.call(c.api.jobs.ListJobs, P.ListJobsRequest()).jobs), 0)
        self.assertEqual(store_bytes(c), 0)


if __name__ == "__main__":
    cluster.main()
