"""Integration test 1: a job rendered by 2 workers (1 thread each) equals `render` of the same
scene and settings in one process, up to floating-point summation order:
|a-b| <= 1e-5 * max(|a|,|b|) + 1e-7 for every pixel and channel. Also for scenes with
participating media: a homogeneous one (vcm, volpt) and a heterogeneous grid (volpt), whose
volume file travels with the job, as a .vol and as a .vdb (which the workers read through the
volume plugin librender_volume_vdb.so beside them, docs/guide/deploy.md)."""

import os
import subprocess
import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

SEED = 7
ITERATIONS = 16
RESOLUTION = (32, 32)


class TwoWorkersMatchRender(cluster.ClusterTestCase):
    def test_vcm_and_pt(self):
        c = self.new_cluster()
        c.start_server()
        c.start_workers(2, threads=1)
        c.wait_workers_registered(2)
        scene = cluster.cornell_box()
        # Both jobs are queued at once, so that the two workers share the work.
        jobs = {algo: c.api.submit(scene, algorithm=algo, iterations=ITERATIONS,
                                   resolution=RESOLUTION, seed=SEED, name=f"two-workers-{algo}")
                for algo in ("vcm", "pt")}
        for algo, job in jobs.items():
            self.assertTrue(job.id, "SubmitJob returned a job without id")
            done = c.api.wait_job(job.id, timeout=90, procs=[c.server] + c.workers)
            frame = done.frames[0]
            self.assertEqual(frame.iterations_done, ITERATIONS, str(done))
            self.assertTrue(frame.done, str(done))
            out = c.api.fetch_to(job.id, c.path(f"{algo}.exr"))
            ref = cluster.render_reference(scene, algo, ITERATIONS, RESOLUTION, SEED)
            with self.subTest(algorithm=algo):
                msg = self.assertImagesMatch(out, ref)
                print(f"{algo}: {msg}")


    def test_media_scenes(self):
        c = self.new_cluster()
        c.start_server()
        c.start_workers(2, threads=1)
        c.wait_workers_registered(2)
        # The smoke again with its grid as OpenVDB: the same density (make_smoke's arguments
        # of scenes/smoke/README.md), written next to a copy of the scene that names it.
        vdb_scene = c.path("smoke-vdb/scene.xml")
        os.makedirs(os.path.dirname(vdb_scene), exist_ok=True)
        subprocess.run([cluster.binary("make_smoke"), "--resolution", "48", "--seed", "1",
                        "--out", c.path("smoke-vdb/smoke.vdb")], check=True,
                       stdout=subprocess.DEVNULL)
        with open(cluster.scene_path("smoke", "scene.xml")) as f:
            text = f.read()
        self.assertIn('value="smoke.vol"', text)
        with open(vdb_scene, "w") as f:
            f.write(text.replace('value="smoke.vol"', 'value="smoke.vdb"'))
        cases = [(cluster.scene_path("smallupbp", "isosph.xml"), "vcm"),
                 (cluster.scene_path("smallupbp", "isosph.xml"), "volpt"),
                 (cluster.scene_path("smoke", "scene.xml"), "volpt"),
                 (vdb_scene, "volpt")]
        jobs = [(scene, algo, c.api.submit(scene, algorithm=algo, iterations=8,
                                           resolution=RESOLUTION, seed=SEED,
                                           name=f"media-{algo}"))
                for scene, algo in cases]
        for i, (scene, algo, job) in enumerate(jobs):
            done = c.api.wait_job(job.id, timeout=120, procs=[c.server] + c.workers)
            self.assertTrue(done.frames[0].done, str(done))
            out = c.api.fetch_to(job.id, c.path(f"media-{i}.exr"))
            ref = cluster.render_reference(scene, algo, 8, RESOLUTION, SEED)
            with self.subTest(scene=scene, algorithm=algo):
                msg = self.assertImagesMatch(out, ref)
                print(f"{scene} {algo}: {msg}")


if __name__ == "__main__":
    cluster.main()
