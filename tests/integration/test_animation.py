"""Integration test: animations through the `client` command line against a local cluster.
`client submit --frames 1:3 -D power={frame}0 --out DIR` renders one job of three frames
whose light power is 10, 20, 30 and writes DIR/frame_0000.exr ... frame_0002.exr; each equals
`render --frame I` with that frame's defines, and is the frame-I render at power 10 scaled by
power/10 (the define does what it says). `fetch --out DIR` and `fetch --frame F --out FILE.exr`
work, `fetch --out FILE.exr` of an animation is refused, `watch` shows the frame strip. A
frames file whose frame 2 does not load is refused naming frame 2; a malformed frames-file
line names file:line; a bad --frames range says why. A server whose submit-time validation
budget (--submit-validation-seconds) is too small for the frames refuses the animation with
RESOURCE_EXHAUSTED."""

import os
import subprocess
import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

TOKEN = "anim-token"
SEED = 23
RES = (32, 32)
ITERATIONS = 8


def scene():
    return os.path.join(cluster.SOURCE_DIR, "tests", "data", "anim", "plates.xml")


class Animation(cluster.ClusterTestCase):
    def client(self, c, *args, timeout=120, expect=0):
        cmd = [cluster.binary("client"), "--server", c.address, "--token", TOKEN]
        cmd += [str(a) for a in args]
        env = dict(os.environ)
        env.pop("RENDER_TOKEN", None)
        env.pop("RENDER_SERVER", None)
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env,
                           stdin=subprocess.DEVNULL, start_new_session=True)
        if expect is not None:
            self.assertEqual(r.returncode, expect, f"{' '.join(cmd)} exited {r.returncode}:\n"
                                                   f"{r.stdout}\n{r.stderr}")
        return r

    def job_ids(self, c):
        P = cluster.pb()
        return [j.id for j in c.api.call(c.api.jobs.ListJobs, P.ListJobsRequest()).jobs]

    def test_animation(self):
        P = cluster.pb()
        c = self.new_cluster(token=TOKEN, heartbeat=0.5)
        c.start_server()
        workers = c.start_workers(2, threads=1)
        common = ["--algo", "pt", "--iterations", ITERATIONS, "--resolution",
                  f"{RES[0]}x{RES[1]}", "--seed", SEED]

        # Three frames, power 10, 20, 30: submit --out DIR waits and fetches every frame.
        out_dir = c.path("anim")
        r = self.client(c, "submit", scene(), *common, "--frames", "1:3", "-D",
                        "power={frame}0", "--out", out_dir)
        job_id = r.stdout.strip().splitlines()[-1]
        self.assertIn(job_id, self.job_ids(c))
        job = c.api.get_job(job_id)
        self.assertEqual(job.state, P.JOB_STATE_DONE)
        self.assertEqual(len(job.frames), 3)
        self.assertEqual(sorted(os.listdir(out_dir)),
                         ["frame_0000.exr", "frame_0001.exr", "frame_0002.exr"])
        images = []
        for i, power in enumerate((10, 20, 30)):
            path = os.path.join(out_dir, f"frame_{i:04d}.exr")
            # Equal to `render` as frame i with that frame's define.
            print(self.assertImagesMatch(path, cluster.render_reference(
                scene(), "pt", ITERATIONS, RES, SEED, defines={"power": power}, frame=i)))
            # The frame-i render at power 10, scaled by power / 10: the define moved the light.
            base = cluster.read_exr(cluster.render_reference(
                scene(), "pt", ITERATIONS, RES, SEED, defines={"power": 10}, frame=i))
            image = cluster.read_exr(path)
            ok, msg = cluster.compare_images(image, base * (power / 10), rel=1e-4, abs_=1e-6)
            self.assertTrue(ok, f"frame {i} is not power {power} / 10 times power 10: {msg}")
            self.assertGreater(image.mean(), 0)
            images.append(image)
        # The frames differ from each other, brighter with the power (noise is < 10 % here).
        means = [img.mean() for img in images]
        self.assertLess(means[0] * 1.5, means[1], means)
        self.assertLess(means[1] * 1.2, means[2], means)

        # fetch --out DIR again, --frame F --out FILE.exr, and the refused FILE.exr.
        again = c.path("again")
        self.client(c, "fetch", job_id, "--out", again)
        for i in range(3):
            name = f"frame_{i:04d}.exr"
            self.assertImagesMatch(os.path.join(again, name), os.path.join(out_dir, name),
                                   rel=0, abs_=0)
        one = c.path("one.exr")
        self.client(c, "fetch", job_id, "--frame", 1, "--out", one)
        self.assertImagesMatch(one, os.path.join(out_dir, "frame_0001.exr"), rel=0, abs_=0)
        r = self.client(c, "fetch", job_id, "--out", c.path("all.exr"), expect=2)
        self.assertIn("the job has 3 frames", r.stderr)
        self.assertFalse(os.path.exists(c.path("all.exr")))

        # watch: the per-frame strip (not a terminal: plain lines).
        r = self.client(c, "watch", job_id)
        self.assertIn("frames 3/3 done [###]", r.stderr)

        # A frames file whose frame 2 does not load: refused at submit, naming frame 2.
        before = self.job_ids(c)
        frames = c.path("frames.txt")
        with open(frames, "w") as f:
            f.write("# power per frame\npower=10\n\npower=20\npower=abc\n")
        r = self.client(c, "submit", scene(), *common, "--frames-file", frames, expect=1)
        self.assertIn("INVALID_ARGUMENT", r.stderr)
        self.assertRegex(r.stderr, r"frame 2 \(power=abc\): scene error: plates\.xml:\d+: "
                                   r"rgb \"radiance\": \"abc\" is not a number")
        self.assertEqual(self.job_ids(c), before)

        # The same file without the bad frame: a job of two frames.
        with open(frames, "w") as f:
            f.write("# power per frame\npower=10\n\npower=20\n")
        r = self.client(c, "submit", scene(), *common, "--frames-file", frames)
        job2 = r.stdout.strip().splitlines()[-1]
        self.assertEqual(len(c.api.get_job(job2).frames), 2)
        c.api.wait_job(job2, timeout=60, procs=[c.server] + workers)

        # A malformed frames-file line: file:line, nothing submitted.
        before = self.job_ids(c)
        with open(frames, "w") as f:
            f.write("power=10\n# comment\npower 20\n")
        r = self.client(c, "submit", scene(), *common, "--frames-file", frames, expect=2)
        self.assertIn(f"{frames}:3: \"power\" is not name=value", r.stderr)

        # Bad ranges and placeholders: clear usage errors, nothing submitted.
        for args, message in (
                (["--frames", "5:2"], "the last frame 2 comes before the first 5"),
                (["--frames", "0:1000"], "1001 frames exceed the limit of 1000"),
                (["--frames", "24"], "expected FIRST:LAST, both included"),
                (["-D", "power={frame}"], "needs --frames A:B"),
                (["--frames", "0:2", "-D", "power={frame:x}"], "\"{frame:x}\""),
                (["--frames", "0:2", "--frames-file", frames], "not both"),
                (["--frames", "0:2", "--out", c.path("x.exr")], "the job has 3 frames")):
            r = self.client(c, "submit", scene(), *common, *args, expect=2)
            self.assertIn(message, r.stderr, args)
        self.assertEqual(self.job_ids(c), before)

    def test_validation_budget(self):
        # A server whose submit-time validation budget every scene load exceeds: a single
        # frame is still accepted (it is loaded anyway), an animation is refused up front.
        c = self.new_cluster(token=TOKEN, server_args=["--submit-validation-seconds", "1e-9"])
        c.start_server()
        common = ["--algo", "pt", "--iterations", 1, "--resolution", "8x8"]
        r = self.client(c, "submit", scene(), *common, "--frames", "0:2", "-D",
                        "power={frame}", expect=1)
        self.assertIn("RESOURCE_EXHAUSTED", r.stderr)
        self.assertIn("3 distinct frames", r.stderr)
        self.assertIn("--submit-validation-seconds", r.stderr)
        self.assertEqual(self.job_ids(c), [])
        self.client(c, "submit", scene(), *common)
        self.assertEqual(len(self.job_ids(c)), 1)


if __name__ == "__main__":
    cluster.main()
