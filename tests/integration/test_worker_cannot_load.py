"""A job that loads on the server but not on its workers fails, with the workers' error.

The realistic case: workers deployed without the image plugin (librender_image_oiio.so, which
reads PNG textures; docs/guide/deploy.md says it must sit next to the worker). The server, which has
it, validates the scene at submit; every worker then fails to load the scene's PNG texture. Each
worker reports its failed lease in a heartbeat (HeartbeatRequest.failed_leases) instead of
letting it expire, and once every worker the server knows (two here, fewer than three) failed
the job, it FAILS with the workers' error message, visible through GetJob. The range never
merges, so nothing of it reaches an image. Then the broken workers are replaced by one with the
plugin, which renders a new job of the same scene: the failure was the deployment's, not the
scene's."""

import os

import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

SCENE = """<scene version="3.0.0">
    <sensor type="perspective">
        <float name="fov" value="45"/>
        <transform name="to_world">
            <lookat origin="0, 1, 6.8" target="0, 1, 0" up="0, 1, 0"/>
        </transform>
        <film type="hdrfilm">
            <integer name="width" value="16"/>
            <integer name="height" value="16"/>
        </film>
    </sensor>
    <shape type="rectangle">
        <transform name="to_world"><scale value="3"/></transform>
        <bsdf type="diffuse">
            <texture type="bitmap" name="reflectance">
                <string name="filename" value="checker.png"/>
            </texture>
        </bsdf>
    </shape>
    <shape type="sphere">
        <point name="center" x="0" y="1.9" z="2"/>
        <float name="radius" value="0.3"/>
        <emitter type="area"><rgb name="radiance" value="10"/></emitter>
    </shape>
</scene>
"""


def write_scene(folder):
    import numpy as np
    import OpenImageIO as oiio

    os.makedirs(folder, exist_ok=True)
    pixels = np.zeros((8, 8, 3), dtype=np.uint8)
    pixels[::2, ::2] = 200
    pixels[1::2, 1::2] = 200
    out = oiio.ImageOutput.create("png")
    path = os.path.join(folder, "checker.png")
    assert out.open(path, oiio.ImageSpec(8, 8, 3, oiio.UINT8)), oiio.geterror()
    out.write_image(pixels)
    out.close()
    scene = os.path.join(folder, "scene.xml")
    with open(scene, "w") as f:
        f.write(SCENE)
    return scene


class WorkerCannotLoad(cluster.ClusterTestCase):
    def test_job_fails_with_the_workers_error(self):
        P = cluster.pb()
        c = self.new_cluster(heartbeat=0.5)
        c.start_server()
        # Workers that cannot load the plugin: RENDER_IMAGE_PLUGIN names the only place tried.
        broken = {"RENDER_IMAGE_PLUGIN": c.path("missing/librender_image_oiio.so")}
        for _ in range(2):
            c.start_worker(threads=1, env=broken)
        c.wait_workers_registered(2)
        scene = write_scene(c.path("scene"))
        job = c.api.submit(scene, algorithm="pt", iterations=64, resolution=(16, 16), seed=3,
                           name="no-plugin")  # the server validates it: it has the plugin
        failed = c.api.wait_job(job.id, states={P.JOB_STATE_FAILED}, timeout=60,
                                procs=[c.server])
        print(f"job error: {failed.error}")
        self.assertIn("failed on 2 workers", failed.error)
        self.assertIn("image plugin", failed.error)  # the workers' own message
        # Files named as in the bundle, not by the worker's cache folder.
        self.assertIn("scene.xml:16", failed.error)
        self.assertIn("read checker.png", failed.error)
        self.assertNotIn("cache-", failed.error)
        self.assertEqual(sum(f.iterations_done for f in failed.frames), 0)
        # Both workers are still alive and idle: a failed lease is not a crash.
        self.assertEqual(len(c.live_workers()), 2, c.logs())

        # The deployment is fixed: the broken workers go, one with the plugin comes, and it
        # renders the same scene. (Left running, the broken ones would fail the new job too:
        # two workers failing it is enough.)
        for w in c.live_workers():
            w.stop()
        c.start_worker(threads=1)
        again = c.api.submit(scene, algorithm="pt", iterations=8, resolution=(16, 16), seed=3,
                             name="with-plugin")
        done = c.api.wait_job(again.id, timeout=120, procs=[c.server])
        self.assertEqual(done.frames[0].iterations_done, 8)


if __name__ == "__main__":
    cluster.main()
