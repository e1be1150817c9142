"""Integration test (extra): the `client` command line against a local cluster with a token.
`client submit --out` writes the same image as `render`; `submit` prints the job id, which
`fetch`, `list` and `cancel` accept; `status` runs; a wrong token fails with exit status 1; a
smallvcm scene with include files and meshes goes through the bundle packing."""

import os
import re
import subprocess
import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

TOKEN = "cli-token"
SEED = 17
RES = (32, 32)


class CliClient(cluster.ClusterTestCase):
    def client(self, c, *args, token=TOKEN, timeout=90, check=True):
        cmd = [cluster.binary("client"), "--server", c.address]
        if token:
            cmd += ["--token", token]
        cmd += [str(a) for a in args]
        env = dict(os.environ)
        env.pop("RENDER_TOKEN", None)
        env.pop("RENDER_SERVER", None)
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env,
                           stdin=subprocess.DEVNULL, start_new_session=True)
        if check:
            self.assertEqual(r.returncode, 0, f"{' '.join(cmd)} exited {r.returncode}:\n"
                                              f"{r.stdout}\n{r.stderr}")
        return r

    def test_cli(self):
        P = cluster.pb()
        c = self.new_cluster(token=TOKEN, heartbeat=0.5)
        c.start_server()
        workers = c.start_workers(2, threads=1)
        scene = cluster.cornell_box()

        # submit --out: waits, fetches, equals render.
        out = c.path("cli.exr")
        self.client(c, "submit", scene, "--algo", "vcm", "--iterations", 16, "--resolution",
                    f"{RES[0]}x{RES[1]}", "--seed", SEED, "--out", out)
        self.assertTrue(os.path.exists(out))
        print(self.assertImagesMatch(out, cluster.render_reference(scene, "vcm", 16, RES,
                                                                   SEED)))

        # submit prints the job id; fetch, list and status work with it.
        r = self.client(c, "submit", scene, "--algo", "pt", "--iterations", 8, "--resolution",
                        f"{RES[0]}x{RES[1]}", "--seed", SEED, "--wait")
        jobs = c.api.call(c.api.jobs.ListJobs, P.ListJobsRequest()).jobs
        ids = [j.id for j in jobs]
        printed = [i for i in ids if re.search(r"\b" + re.escape(i) + r"\b", r.stdout)]
        self.assertTrue(printed, f"submit did not print a job id of {ids}: {r.stdout!r}")
        job_id = printed[-1]
        c.api.wait_job(job_id, timeout=60, procs=[c.server] + workers)
        out2 = c.path("fetched.exr")
        self.client(c, "fetch", job_id, "--out", out2)
        self.assertImagesMatch(out2, cluster.render_reference(scene, "pt", 8, RES, SEED))
        listing = self.client(c, "list").stdout
        for i in ids:
            self.assertIn(i, listing)
        self.client(c, "status")

        # A scene with include files and meshes (bundle packing).
        smallvcm = cluster.scene_path("smallvcm", "0-gbs_s.xml")
        out3 = c.path("smallvcm.exr")
        self.client(c, "submit", smallvcm, "--algo", "pt", "--iterations", 4, "--resolution",
                    f"{RES[0]}x{RES[1]}", "--seed", SEED, "--out", out3)
        self.assertImagesMatch(out3, cluster.render_reference(smallvcm, "pt", 4, RES, SEED))

        # cancel a long job.
        r = self.client(c, "submit", scene, "--algo", "vcm", "--iterations", 20000,
                        "--resolution", f"{RES[0]}x{RES[1]}", "--seed", SEED)
        new = [j.id for j in c.api.call(c.api.jobs.ListJobs, P.ListJobsRequest()).jobs
               if j.id not in ids and re.search(r"\b" + re.escape(j.id) + r"\b", r.stdout)]
        self.assertTrue(new, f"submit did not print the new job id: {r.stdout!r}")
        self.client(c, "cancel", new[0])
        self.assertEqual(c.api.get_job(new[0]).state, P.JOB_STATE_CANCELLED)

        # A wrong token: exit status 1.
        bad = self.client(c, "list", token="wrong", check=False)
        self.assertEqual(bad.returncode, 1, bad.stdout + bad.stderr)


if __name__ == "__main__":
    cluster.main()
