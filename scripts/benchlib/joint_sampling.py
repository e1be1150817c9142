"""Joint path sampling at equal time: `volpt --jis on` against `--jis off` on the fog box
(`scripts/bench --only joint-sampling`, writes docs/results/joint-sampling.md).

Both arms are the same estimator in expectation (the block test
`Convergence.JointSamplingMatchesVolptWithoutItOnTheFogBox` checks it); joint sampling changes
only the double-scattering paths camera -> c -> b -> light, so the error measured is that of the
`s1_t3` layer (`--layers st`: one light vertex, three eye vertices) with max_depth 3. Its mean
squared error is its variance, and after T seconds

    MSE(T) = v * t / T,   v = variance of one iteration (mean over pixels and channels),
                          t = seconds per iteration,

so the equal-time RMSE ratio of the arms is sqrt((v t)_off / (v t)_on) at every T (the
method of scripts/benchlib/many_lights.py):

- v: RUNS independent `render --iterations N` runs per arm (own seeds); the per-pixel sample
  variance over the runs (ddof 1) times N; the uncertainty is the standard error over GROUPS
  disjoint groups of runs.
- t: the median over TIMING_REPEATS runs of `render`'s own wall time per iteration (under
  SCHED_FIFO where permitted).

Scenes: the isotropic fog box and its g = 0.9 variant. In the anisotropic one both arms are
heavy-tailed (a point light seen through the forward lobe of the phase function, which no
technique samples), so its v, and the ratio, are far less certain than the standard errors say.

bpt's joint (J1) connections (`bpt --joint-connections on` against `off`) are measured the same way on
the isotropic fog box: the double-scattering paths (max_depth 3; the layers with s + t = 4,
summed: bpt samples them with (s, t) = (1, 3), (2, 2) and (3, 1); J1 adds one technique at
the (2, 2) junction and, as equi-angular next-event estimation, one at the (1, 3) junction) and
the whole image with every order (max_depth -1).

vcm's (`vcm --joint-connections on` against `off`) on the whole image only: merges are not in
the (s, t) layers, and J1 moves weight between merges and connections, so a path class of the
layers is not the same estimand in both arms. Both arms use the default merge radius.
"""

import math
import tempfile
from pathlib import Path

import numpy as np

from resultslib import pages  # scripts/ is on sys.path (scripts/bench)

from . import common

SCENE = common.REPO_ROOT / "scenes" / "tests" / "fog-box.xml"
VARIANTS = {"isotropic": ["-D", "g=0"], "g = 0.9": ["-D", "g=0.9"]}
ARMS = {"jis off": ["--jis", "off"], "jis on": ["--jis", "on"]}
LAYER = "s1_t3"  # camera -> c -> b -> light
WIDTH = 64
RUNS = 16
ITERATIONS = 16
GROUPS = 4
TIMING_REPEATS = 3
TIMING_SECONDS = 3.0
QUICK = {"width": 32, "runs": 4, "iterations": 2, "groups": 2, "timing_repeats": 1,
         "timing_seconds": 0.3}
CLAIM_RATIO = 5.0  # ALGORITHMS-NEXT.md 3.8 (b1): >= 5x lower RMSE at equal time


# The pictures of these arms and the convergence slopes come from another benchmark
# (scripts/benchlib/joint_figures.py); this document shows them.
PICTURE_LINES = [
    "## Pictures and convergence slopes", "",
    "Written by `scripts/bench --only joint-figures` into [joint-figures.md](joint-figures.md) "
    "(commands, machine, iteration counts, errors): each arm at equal time beside a reference "
    "and false-colour images of its absolute error, for double scattering alone and the whole "
    "image; and the mean absolute error of the unweighted 0-connection and of unweighted joint "
    "sampling against N.", "",
    "![volpt, isotropic fog box](../img/joint-sampling/fog-box-isotropic-volpt.png)", "",
    "![volpt, fog box with g = 0.9](../img/joint-sampling/fog-box-g09-volpt.png)", "",
    "![bpt with and without J1, isotropic fog box](../img/joint-sampling/fog-box-isotropic-bpt.png)",
    "", "![convergence slopes](../img/joint-sampling/slopes.png)", ""]


def read_layer(path: Path, layer: str):
    """The RGB channels of one EXR layer (float64, H x W x 3) and the file's attributes."""
    layers, attributes = common.read_exr_layers(path)
    return layers[layer or ""], attributes


BPT_ARMS = {"bpt": ["--joint-connections", "off"], "bpt + J1": ["--joint-connections", "on"],
            "bpt + J1 + J2": ["--joint-connections", "all"]}
# What is measured in bpt: paths of 4 vertices (double scattering) or the whole image.
BPT_CASES = {"double scattering (max_depth 3)": (["-D", "max_depth=3"], 4),
             "all orders (max_depth -1)": (["-D", "max_depth=-1"], None)}


def read_path_class(path: Path, vertices):
    """The sum of the (s, t) layers with s + t = vertices, or the image itself (None)."""
    import OpenImageIO as oiio

    if vertices is None:
        return read_layer(path, None)
    inp = oiio.ImageInput.open(str(path))
    names = list(inp.spec().channelnames)
    inp.close()
    layers = sorted({n.split(".")[0] for n in names if n.startswith("s") and "_t" in n})
    total, header = None, None
    for layer in layers:
        s_count, t_count = (int(x) for x in layer[1:].split("_t"))
        if s_count + t_count != vertices:
            continue
        image, header = read_layer(path, layer)
        total = image if total is None else total + image
    return total, header


def render(binary, out, flags, seed, resolution, threads, iterations, realtime=False,
           algo="volpt", vertices=None):
    cmd = common.render_command(binary, SCENE, out, algo=algo, iterations=iterations,
                                seed=seed, resolution=resolution, threads=threads,
                                extra=[*flags, "--layers", "st"])
    if realtime:
        cmd = [*common.realtime_prefix(), *cmd]
    common.run_render(cmd)
    if algo == "volpt":
        image, header = read_layer(out, LAYER)
    else:
        image, header = read_path_class(out, vertices)
    out.unlink()
    return image, header, cmd


def variance(images, iterations) -> float:
    """One iteration's variance (mean over pixels and channels) from independent runs."""
    return float((np.stack(images).var(axis=0, ddof=1) * iterations).mean())


def measure_arm(binary, flags, resolution, threads, workdir, cfg, algo="volpt", vertices=None):
    commands = []

    def render_arm(tag, seed, iterations, realtime):
        image, header, cmd = render(binary, workdir / f"{tag}.exr", flags, seed, resolution,
                                    threads, iterations, realtime=realtime, algo=algo,
                                    vertices=vertices)
        commands.append(cmd)
        return image, header

    m = common.variance_and_time(render_arm, variance, cfg)
    return {"v": m["v"], "v_se": m["v_se"], "t": m["t"],
            "mean": float(np.stack(m["images"]).mean()), "command": commands[-1]}


VCM_ARMS = {"vcm": ["--joint-connections", "off"], "vcm + J1": ["--joint-connections", "on"]}
VCM_CASES = {"all orders (max_depth -1)": (["-D", "max_depth=-1"], None)}


def compare_arms(lines, title, what, arms, off_name, on_name, of_what, technique):
    """Appends a section comparing two measured arms (their table and the equal-time RMSE
    ratio sqrt((v t)_off / (v t)_on)) to `lines`; returns the ratio and its standard error."""
    for arm, m in arms.items():
        print(f"  {title[:60]:60s} {arm:9s} v {m['v']:.4g} ± {m['v_se']:.2g}  "
              f"t {m['t']:.4f} s", flush=True)
    off, on = arms[off_name], arms[on_name]
    ratio = math.sqrt((off["v"] * off["t"]) / (on["v"] * on["t"]))
    ratio_se = 0.5 * ratio * math.hypot(off["v_se"] / off["v"], on["v_se"] / on["v"])
    lines += [f"## {title}", "", f"Timing command ({on_name}): `{' '.join(on['command'])}`", "",
              f"| arm | mean of {what} | variance of one iteration v (± SE) | "
              "seconds per iteration t | v·t |", "| --- | --- | --- | --- | --- |"]
    for arm, m in arms.items():
        lines.append(f"| {arm} | {m['mean']:.4g} | {m['v']:.4g} ± {m['v_se']:.2g} | "
                     f"{m['t']:.4f} | {m['v'] * m['t']:.4g} |")
    lines += ["", f"Equal-time RMSE({off_name}) / RMSE({on_name}){' ' + of_what if of_what else ''}"
              f" = sqrt((v·t)_off / (v·t)_on) = **{ratio:.2f} ± {ratio_se:.2f}**; per "
              f"iteration {technique} costs {on['t'] / off['t']:.2f}× and has "
              f"{on['v'] / off['v']:.3f}× the variance.", ""]
    return ratio, ratio_se


def run(build_dir: Path, docs_dir: Path, quick: bool = False, threads=None):
    binary = common.render_binary(build_dir)
    workdir = Path(tempfile.mkdtemp(prefix="bench-joint-sampling-"))
    cfg = dict(QUICK) if quick else {
        "width": WIDTH, "runs": RUNS, "iterations": ITERATIONS, "groups": GROUPS,
        "timing_repeats": TIMING_REPEATS, "timing_seconds": TIMING_SECONDS}
    resolution = common.resolution_for_width(SCENE, cfg["width"])
    machine = common.machine_info()
    lines = ["# Joint path sampling: volpt with and without it", "",
             "Written by `scripts/bench --only joint-sampling` "
             "(scripts/benchlib/joint_sampling.py); do not edit by hand. The technique: "
             "[media.md](../design/media.md), \"Joint path sampling\".", "", __doc__.strip(), "",
             f"Machine: {machine.get('cpu_model')}, {machine.get('cores')} cores, "
             f"{machine.get('date_utc')}; revision {machine.get('source_revision', '?')}; load "
             f"average before {(machine.get('load_average') or ['?'])[0]}. "
             f"{resolution[0]}x{resolution[1]}, {threads or 'all'} threads, {cfg['runs']} "
             f"variance runs of {cfg['iterations']} iterations per arm, {cfg['groups']} groups; "
             f"{cfg['timing_repeats']} timing runs of about {cfg['timing_seconds']:g} s"
             + (" under SCHED_FIFO (`chrt -f 10`)" if common.realtime_prefix() else
                " at normal priority")
             + f"{' (quick mode)' if quick else ''}.", ""]
    verdicts = {}
    for variant, defines in VARIANTS.items():
        verdicts[variant] = compare_arms(
            lines, f"Fog box, {variant}", f"the {LAYER} layer",
            {arm: measure_arm(binary, [*defines, *flags], resolution, threads, workdir, cfg)
             for arm, flags in ARMS.items()},
            "jis off", "jis on", "of double scattering", "joint sampling")
    bpt_verdicts, bpt_j2_verdicts = {}, {}
    for case, (defines, vertices) in BPT_CASES.items():
        what = "the image" if vertices is None else f"paths of {vertices} vertices"
        arms = {arm: measure_arm(binary, [*defines, *flags], resolution, threads, workdir, cfg,
                                 algo="bpt", vertices=vertices)
                for arm, flags in BPT_ARMS.items()}
        bpt_verdicts[case] = compare_arms(
            lines, f"bpt with and without J1 connections, isotropic fog box, {case}", what,
            {k: arms[k] for k in ("bpt", "bpt + J1")}, "bpt", "bpt + J1", "", "J1")
        # J2 (--joint-connections all) against plain bpt and against bpt + J1.
        bpt_j2_verdicts[case] = (
            compare_arms(lines, f"bpt with and without J1 + J2 connections, {case}", what,
                         {k: arms[k] for k in ("bpt", "bpt + J1 + J2")}, "bpt",
                         "bpt + J1 + J2", "", "J1 + J2"),
            compare_arms(lines, f"bpt + J1 with and without J2, {case}", what,
                         {k: arms[k] for k in ("bpt + J1", "bpt + J1 + J2")}, "bpt + J1",
                         "bpt + J1 + J2", "", "J2"))
    vcm_verdicts = {}
    for case, (defines, vertices) in VCM_CASES.items():
        vcm_verdicts[case] = compare_arms(
            lines, f"vcm with and without J1 connections, isotropic fog box, {case}",
            "the image",
            {arm: measure_arm(binary, [*defines, *flags], resolution, threads, workdir, cfg,
                              algo="vcm", vertices=vertices)
             for arm, flags in VCM_ARMS.items()},
            "vcm", "vcm + J1", "", "J1")
    ratio, ratio_se = verdicts["isotropic"]
    lines += ["## The claim", "",
              f"- Isotropic fog box: {ratio:.2f} ± {ratio_se:.2f}× lower double-scattering RMSE "
              f"at equal time (claim: ≥ {CLAIM_RATIO:g}×; the paper: 5–37×): "
              f"**{'held' if ratio >= CLAIM_RATIO else 'not held'}**.",
              f"- g = 0.9: {verdicts['g = 0.9'][0]:.2f}× (heavy-tailed in both arms, see "
              "above).", ""]
    lines += ["- bpt's J1 connections (the issue asks what they give; no claim of the paper "
              "covers them): " + "; ".join(
                  f"{case}: {r:.2f} ± {se:.2f}× lower RMSE at equal time"
                  for case, (r, se) in bpt_verdicts.items()) + ".",
              "- bpt's J2 connections beside J1 (`--joint-connections all`): " + "; ".join(
                  f"{case}: {a[0]:.2f} ± {a[1]:.2f}× lower RMSE than bpt, {b[0]:.2f} ± "
                  f"{b[1]:.2f}× than bpt + J1, at equal time"
                  for case, (a, b) in bpt_j2_verdicts.items()) + ".",
              "- vcm's J1 connections: " + "; ".join(
                  f"{case}: {r:.2f} ± {se:.2f}× lower RMSE at equal time"
                  for case, (r, se) in vcm_verdicts.items()) + ".", ""]
    lines += PICTURE_LINES
    # The page is generated from its template and this data file (docs/guide/results.md).
    out_doc = pages.publish_blocks(docs_dir, "joint-sampling", lines,
                                   "scripts/bench --only joint-sampling" + (" --quick" if quick else ""),
                                   load_before=pages.load_text(machine.get("load_average")))
    print(f"bench: wrote {out_doc}")
