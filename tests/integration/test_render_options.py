"""Integration test: every render option works through the service with the meaning it has in
`render`. The options are not listed here: the test walks the tables that `render
--describe-options` prints (core/render/render_options.cpp, core/render/algorithms.cpp). For each
option (and each negated flag such as --no-equiangular) it picks a value other than the default
and an algorithm that reads the option, then
  * renders locally with `render ... --FLAG VALUE`,
  * submits the same through `client submit ... --FLAG VALUE --out` to a local cluster of two
    workers (one thread each),
and requires: the two images equal up to floating-point summation order (every channel,
including technique layers: |a-b| <= 1e-5 max(|a|,|b|) + 1e-7); the image differs from the one
rendered with the default value (so the option was not ignored on both sides); and both EXR
headers record every option the algorithm reads under the same render:NAME key with the same
value."""

import json
import os
import subprocess
import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import numpy as np  # noqa: E402

import cluster  # noqa: E402

SEED = 5
ITERATIONS = 4
RES = (24, 16)


def describe():
    r = subprocess.run([cluster.binary("render"), "--describe-options"], capture_output=True,
                       text=True, timeout=60, check=True)
    return json.loads(r.stdout)


def other_value(option):
    """A valid value that differs from the option's default."""
    kind, default = option["type"], option["default"]
    if kind == "choice":
        return next(c for c in option["choices"] if c != default)
    if kind == "unsigned":
        return "99"
    if kind == "integer":
        # max_depth 2: direct light; light_paths 3; ic_samples (default 4) 3
        value = int(option["min"]) + 3
        return str(value if str(value) != default else value - 1)
    # real: three times the default when that is in range, else the middle of the range
    try:
        value = float(default) * 3
    except ValueError:
        value = None
    if value is None or not option["min"] < value <= option["max"]:
        value = (option["min"] + option["max"]) / 2
    return repr(value)


def pick_algorithm(option, tables):
    """The algorithm the option is named after, if it reads it; otherwise the reader of
    `option` that reads the most options (the one most exposed to a
    mix-up; the last in table order among equals, which for the bidirectional family is VCM,
    where every option matters), and a scene on which the option matters: with media (isosph,
    which has surfaces and an area light too) for every reader of homogeneous media, so that
    options of media such as --jis change the image."""
    readers = [(len(a["options"]), i, a) for i, a in enumerate(tables["algorithms"])
               if a["name"] in option["read_by"]]
    # An option named after one of its readers (ic_heuristic, vpl_clamp) is that algorithm's
    # own and matters there by itself; another reader may use it only in a mode (bpt reads the
    # ic_* options with --connections ic), so the owner is taken.
    owners = [r for r in readers if option["name"].startswith(r[2]["name"] + "_")]
    algorithm = max(owners or readers, key=lambda r: r[:2])[2]
    media = algorithm["homogeneous_media"]
    scene = (cluster.scene_path("smallupbp", "isosph.xml") if media
             else cluster.scene_path("smallvcm", "1-glm_c.xml"))
    return algorithm, scene


def read_exr(path):
    """All channels as float64 (height, width, channels), the channel names, the render:*
    attributes."""
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise AssertionError(f"cannot open {path}: {oiio.geterror()}")
    try:
        spec = inp.spec()
        pixels = np.asarray(inp.read_image(0, 0, 0, spec.nchannels, "float"), dtype=np.float64)
        pixels = pixels.reshape(spec.height, spec.width, spec.nchannels)
        header = {a.name: str(a.value) for a in spec.extra_attribs
                  if a.name.startswith("render:")}
        return pixels, list(spec.channelnames), header
    finally:
        inp.close()


class RenderOptionsThroughTheService(cluster.ClusterTestCase):
    def render(self, c, scene, algorithm, out, extra):
        args = [cluster.binary("render"), scene, "--algo", algorithm, "--iterations",
                str(ITERATIONS), "--resolution", f"{RES[0]}x{RES[1]}", "--seed", str(SEED),
                "--threads", "2", "--out", out] + extra
        r = subprocess.run(args, capture_output=True, text=True, timeout=300,
                           start_new_session=True)
        self.assertEqual(r.returncode, 0, f"{' '.join(args)}:\n{r.stderr}")

    def submit(self, c, scene, algorithm, out, extra):
        args = [cluster.binary("client"), "--server", c.address, "submit", scene, "--algo",
                algorithm, "--iterations", str(ITERATIONS), "--resolution",
                f"{RES[0]}x{RES[1]}", "--seed", str(SEED), "--out", out] + extra
        env = {k: v for k, v in os.environ.items() if k not in ("RENDER_TOKEN", "RENDER_SERVER")}
        r = subprocess.run(args, capture_output=True, text=True, timeout=300, env=env,
                           stdin=subprocess.DEVNULL, start_new_session=True)
        self.assertEqual(r.returncode, 0, f"{' '.join(args)}:\n{r.stdout}\n{r.stderr}")

    def test_every_option(self):
        tables = describe()
        self.assertGreaterEqual(len(tables["options"]), 1)
        c = self.new_cluster()
        c.start_server()
        c.start_workers(2, threads=1)
        c.wait_workers_registered(2)

        cases = []
        # Adaptive sampling's options change an image only after more rounds than this test's
        # few iterations: tests/integration/test_adaptive.py compares them, render against the
        # service (docs/reference/adaptive-sampling.md, "The service").
        render_only = {o["name"] for o in tables["options"] if o["name"].startswith("adaptive")}
        for option in tables["options"]:
            if option["name"] in render_only:
                continue
            algorithm, scene = pick_algorithm(option, tables)
            value = other_value(option)
            # --seed is also given by the harness; the later flag wins in both programs.
            # Options that matter only together with another (the clamp schedule needs a clamp)
            # get that one too, in both renders and in the default render.
            needs = []
            for other, needed in option["effective_with"]:
                flag = next(o["flag"] for o in tables["options"] if o["name"] == other)
                needs += [flag, needed]
            cases.append((option["name"], algorithm, scene, needs + [option["flag"], value],
                          value, needs))
            if option["negated_flag"]:
                cases.append((option["name"], algorithm, scene, needs + [option["negated_flag"]],
                              None, needs))
        # Every option of the tables is exercised.
        self.assertEqual({name for name, *_ in cases},
                         {o["name"] for o in tables["options"]} - render_only)

        for i, (name, algorithm, scene, extra, value, needs) in enumerate(cases):
            with self.subTest(option=name, flags=" ".join(extra), algorithm=algorithm["name"]):
                local = c.path(f"render-{i}.exr")
                default = c.path(f"default-{i}.exr")
                service = c.path(f"service-{i}.exr")
                self.render(c, scene, algorithm["name"], local, extra)
                self.render(c, scene, algorithm["name"], default, needs)
                self.submit(c, scene, algorithm["name"], service, extra)
                a, a_channels, a_header = read_exr(local)
                b, b_channels, b_header = read_exr(service)
                d, _, _ = read_exr(default)
                self.assertEqual(a_channels, b_channels, "the same channels (layers)")
                self.assertGreater(float(np.abs(a).max()), 0.0, "a black image proves nothing")
                ok, msg = cluster.compare_images(a, b)
                self.assertTrue(ok, f"render vs service: {msg}")
                self.assertFalse(a.shape == d.shape and np.array_equal(a, d),
                                 f"{' '.join(extra)} did not change the image")
                for option_name in algorithm["options"]:
                    key = "render:" + option_name
                    self.assertIn(key, a_header, f"render's header lacks {key}")
                    self.assertEqual(a_header.get(key), b_header.get(key),
                                     f"{key}: render {a_header.get(key)!r}, service "
                                     f"{b_header.get(key)!r}")
                if value is not None:
                    option = next(o for o in tables["options"] if o["name"] == name)
                    if option["type"] != "real":  # reals are recorded in canonical form
                        self.assertEqual(a_header["render:" + name], value)
                self.assertEqual(a_header["render:algorithm"], b_header["render:algorithm"])
                # Statistics the algorithm reports (the VPL acceptance) travel with the reports.
                for key in ("render:vpl_acceptance", "render:vpl_candidates_per_iteration"):
                    self.assertEqual(a_header.get(key), b_header.get(key), key)
                print(f"{' '.join(extra)} ({algorithm['name']}): {msg}")


if __name__ == "__main__":
    cluster.main()
