"""Many-light rendering at equal time: all VPLs (uniform), importance-driven VPLs and importance
caching (`scripts/bench --only many-lights`, writes docs/results/many-lights.md and
docs/img/many-lights/).

The four many-light arms are the same estimator in expectation: `vpl` with a fixed clamp (d_min = 1 % of
the scene radius, so the variance is finite) connects every shading point to every VPL;
`--vpl-distribution importance` is Russian roulette on those VPLs; `ic` draws 16 of them per
shading point from the importance caches and weights them by MIS; `power` (`ic
--ic-distributions power`) draws 16 in proportion to their power, the baseline of the
importance-caching paper, so ic against power is the comparison at equal sample count. `bpt`
and `bpt-ic` (`bpt --connections ic`: each eye vertex connects to light vertices drawn from the
importance caches over the first 64 light paths instead of to its own light path) are a second
pair, unclamped, with the same expectation as each other (the block tests
`Convergence.ImportanceDrivenVplsMatchUniformVpls`, `ImportanceCachingMatchesAllVpls` and
`ImportanceCachedConnectionsMatchBpt` check that each pair agrees). Their mean squared error is therefore their variance, and for an unbiased
estimator whose iterations are independent the error after T seconds is

    relMSE(T) = v * t / T,   v = relative variance of one iteration, t = seconds per iteration,

so the equal-time ratio of two arms is (v_a t_a) / (v_b t_b) at every T. The two factors are
measured apart, each where it can be measured well:

- v: RUNS independent `render --iterations N` runs per arm (own seeds); the per-pixel sample
  variance over the runs (ddof 1) times N estimates one iteration's variance, reported as
  mean over pixels and channels of  variance / (r^2 + 0.01)  (the relative-MSE definition of
  docs/results/speed-vs-error.md; r, which only scales the pixels, is a long run of the uniform arm).
  VPL errors are heavy-tailed (a VPL near a wall lights a small spot brightly; the brightest
  1 % of pixels carry about half of the total), so many runs are needed; the uncertainty
  shown is the standard error over GROUPS disjoint groups of runs.
- t: the median over TIMING_REPEATS runs of `render`'s own wall time (rendering only) per
  iteration.

(An earlier version compared single `--time T` runs with a reference image directly: with three
runs per point its ratios moved by a factor of two from point to point, and the reference's
own noise set a floor.) Scenes: two-rooms (the light in the next room, the case the
importance-driven distribution was made for), the Cornell box (every VPL matters: the
control) and many-emitters (36 small lights in four bays joined by gaps). `render` runs with all cores.
"""

import math
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from resultslib import pages  # scripts/ is on sys.path (scripts/bench)

from . import common

CLAMP = ["--vpl-clamp", "0.01", "--vpl-clamp-schedule", "fixed"]
ARMS = {
    "uniform": ["--algo", "vpl"] + CLAMP,
    "importance": ["--algo", "vpl"] + CLAMP + ["--vpl-distribution", "importance"],
    "ic": ["--algo", "ic"] + CLAMP,
    "power": ["--algo", "ic", "--ic-distributions", "power"] + CLAMP,
    # Importance-cached connections in bpt against plain bpt (no clamp: their own pair).
    "bpt": ["--algo", "bpt"],
    "bpt-ic": ["--algo", "bpt", "--connections", "ic"],
}
SCENES = {
    "two-rooms": common.REPO_ROOT / "scenes" / "tests" / "two-rooms.xml",
    "cornell-box": common.REPO_ROOT / "scenes" / "bitterli" / "cornell-box" / "scene_v3.xml",
    # 36 small lights in four bays: many emitters, each seen from part of the room.
    "many-emitters": common.REPO_ROOT / "scenes" / "tests" / "many-emitters.xml",
}
OCCLUDED_SCENE = "two-rooms"  # where the paper's claim is checked
CONTROL_SCENE = "cornell-box"
WIDTH = 128  # 256 (ALGORITHMS-NEXT.md 1.7 b) takes about four times as long
RUNS = 24  # independent runs per arm for the variance
ITERATIONS = 8  # iterations per variance run
GROUPS = 4  # disjoint groups of runs: the spread of their estimates gives the uncertainty
TIMING_REPEATS = 3
TIMING_SECONDS = 4.0  # each timing run renders about this long
TIMES = (4.0, 8.0, 16.0)  # equal-time errors are shown at these times
REFERENCE_SECONDS = 60.0
PICTURE_TIME = 4.0  # the pictures in docs/img/many-lights/ are `--time 4` runs
QUICK = {"width": 64, "runs": 4, "iterations": 2, "groups": 2, "timing_repeats": 1,
         "timing_seconds": 0.3, "reference_seconds": 1.0, "picture_time": 0.3}
CLAIM_ACCEPTANCE = 1 / 3  # the "well under a third of the candidates"
CLAIM_RATIO = 5.0  # and ">= 5x lower equal-time error" (the paper: more than 10x)
CONTROL_RATIO = 1.15  # ALGORITHMS-NEXT.md 1.7 (b): DIV must not lose more where all VPLs matter
IC_CLAIM_RATIO = 10.0  # ALGORITHMS-NEXT.md 2.10 (b): IC vs power sampling at equal m, occluded


def acceptance(stdout: str):
    """The acceptance percentage render prints for importance-driven VPLs, or None."""
    for line in stdout.splitlines():
        if line.startswith("VPLs:") and "accepted" in line:
            return float(line.split(",")[1].split("%")[0])
    return None


def render(binary, scene, out, arm, seed, resolution, threads, *, seconds=None, iterations=None,
           png=None, realtime=False):
    algo, *flags = ARMS[arm][1:]
    cmd = common.render_command(binary, scene, out, algo=algo, seconds=seconds,
                                iterations=iterations, seed=seed, resolution=resolution,
                                threads=threads, extra=flags, png=png)
    if realtime:
        cmd = [*common.realtime_prefix(), *cmd]
    proc = subprocess.run(cmd, cwd=common.REPO_ROOT, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"render failed: {' '.join(cmd)}\n{proc.stderr[-2000:]}")
    image, header = common.read_exr(out)
    out.unlink()
    return image, header, acceptance(proc.stdout), cmd


def relative_variance(images, reference, iterations) -> float:
    """One iteration's relative variance from independent runs of `iterations` each."""
    variance = np.stack(images).var(axis=0, ddof=1) * iterations
    return float((variance / (reference * reference + common.RELATIVE_MSE_EPSILON)).mean())


def geometric_mean(values):
    return math.exp(sum(map(math.log, values)) / len(values)) if values else float("nan")


def measure_arm(binary, scene, name, arm, reference, resolution, threads, workdir, cfg):
    """v (with its standard error over groups of runs), t and the acceptance of one arm."""
    kept = []

    def render_arm(tag, seed, iterations, realtime):
        image, header, accepted, _ = render(binary, scene, workdir / f"{name}-{arm}-{tag}.exr",
                                            arm, seed, resolution, threads,
                                            iterations=iterations, realtime=realtime)
        if not realtime:
            kept.append(accepted if accepted is not None else 100.0)
        return image, header

    m = common.variance_and_time(
        render_arm, lambda images, n: relative_variance(images, reference, n), cfg)
    return {"v": m["v"], "v_se": m["v_se"], "t": m["t"], "kept": sum(kept) / len(kept),
            "timing_iterations": m["timing_iterations"]}


def run(build_dir: Path, docs_dir: Path, quick: bool = False, threads=None):
    binary = common.render_binary(build_dir)
    workdir = Path(tempfile.mkdtemp(prefix="bench-many-lights-"))
    cfg = dict(QUICK) if quick else {
        "width": WIDTH, "runs": RUNS, "iterations": ITERATIONS, "groups": GROUPS,
        "timing_repeats": TIMING_REPEATS, "timing_seconds": TIMING_SECONDS,
        "reference_seconds": REFERENCE_SECONDS, "picture_time": PICTURE_TIME}
    img_dir = docs_dir / "img" / "many-lights"
    img_dir.mkdir(parents=True, exist_ok=True)
    lines = ["# Many-light rendering: uniform against importance-driven VPLs", "",
             "Written by `scripts/bench --only many-lights` (scripts/benchlib/many_lights.py); "
             "do not edit by hand.", "", __doc__.strip(), ""]
    machine = common.machine_info()
    lines += [f"Machine: {machine.get('cpu_model')}, {machine.get('cores')} cores, "
              f"{machine.get('date_utc')}; revision {machine.get('source_revision', '?')}; "
              f"load average before {(machine.get('load_average') or ['?'])[0]}. "
              f"{cfg['runs']} variance runs of {cfg['iterations']} iterations per arm, "
              f"{cfg['groups']} groups; {cfg['timing_repeats']} timing runs of about "
              f"{cfg['timing_seconds']:g} s"
              + (" under SCHED_FIFO (`chrt -f 10`)" if common.realtime_prefix() else
                 " at normal priority (real-time scheduling not permitted here)")
              + f"{' (quick mode)' if quick else ''}.", ""]
    verdicts = {}
    for name, scene in SCENES.items():
        resolution = common.resolution_for_width(scene, cfg["width"])
        reference, ref_header, _, ref_cmd = render(
            binary, scene, workdir / f"{name}-reference.exr", "uniform", 1_000_000, resolution,
            threads, seconds=cfg["reference_seconds"], png=img_dir / f"{name}-reference.png")
        arms = {arm: measure_arm(binary, scene, name, arm, reference, resolution, threads,
                                 workdir, cfg) for arm in ARMS}
        for arm in ARMS:
            render(binary, scene, workdir / f"{name}-{arm}-picture.exr", arm, 30_000, resolution,
                   threads, seconds=cfg["picture_time"],
                   png=img_dir / f"{name}-{arm}-{cfg['picture_time']:g}s.png")
        u, i, c, pw = arms["uniform"], arms["importance"], arms["ic"], arms["power"]

        def gain(a, b):
            """Equal-time relMSE(a) / relMSE(b), with first-order propagation of the two
            variance estimates' standard errors."""
            r = (a["v"] * a["t"]) / (b["v"] * b["t"])
            return r, r * math.hypot(a["v_se"] / a["v"], b["v_se"] / b["v"])

        ratio, ratio_se = gain(u, i)
        ic_ratio, ic_ratio_se = gain(u, c)
        # At equal sample count (16 VPLs per shading point in both): the variance ratio alone.
        m_ratio = pw["v"] / c["v"]
        m_ratio_se = m_ratio * math.hypot(pw["v_se"] / pw["v"], c["v_se"] / c["v"])
        t_ratio, t_ratio_se = gain(pw, c)
        b, bi = arms["bpt"], arms["bpt-ic"]
        bpt_ratio, bpt_ratio_se = gain(b, bi)
        verdicts[name] = (ratio, ratio_se, i["kept"] / 100, ic_ratio, ic_ratio_se, m_ratio,
                          m_ratio_se, t_ratio, t_ratio_se, bpt_ratio, bpt_ratio_se,
                          b["v"] / bi["v"], bi["t"] / b["t"])
        lines += [f"## {name} ({resolution[0]}x{resolution[1]})", "",
                  f"Scale image r: `{' '.join(ref_cmd)}` — "
                  f"{ref_header.get('render:iterations')} iterations.", "",
                  "| arm | VPLs kept | relative variance of one iteration v (± SE) | seconds "
                  "per iteration t | v·t | " + " | ".join(f"relMSE at {t:g} s" for t in TIMES)
                  + " |",
                  "| --- | --- | --- | --- | --- |" + " --- |" * len(TIMES)]
        for arm, m in arms.items():
            lines.append(f"| {arm} | {m['kept']:.1f} % | {m['v']:.4g} ± {m['v_se']:.2g} | "
                         f"{m['t']:.3f} | {m['v'] * m['t']:.4g} | "
                         + " | ".join(f"{m['v'] * m['t'] / t:.3g}" for t in TIMES) + " |")
            print(f"  {name:12s} {arm:10s} v {m['v']:.4g} ± {m['v_se']:.2g}  t {m['t']:.3f} s"
                  f"  kept {m['kept']:.1f} %", flush=True)
        pictures = " ".join(f"![{name} {arm}](../img/many-lights/{name}-{arm}-"
                            f"{cfg['picture_time']:g}s.png)" for arm in ARMS)
        lines += ["", f"Equal-time relMSE(uniform) / relMSE(importance) = (v·t)_uniform / "
                  f"(v·t)_importance = **{ratio:.2f} ± {ratio_se:.2f}** (at every time: all "
                  f"errors fall like 1/T). Per iteration the importance arm costs "
                  f"{u['t'] / i['t']:.2f}× less and has {i['v'] / u['v']:.2f}× the variance.", "",
                  f"Equal-time relMSE(uniform) / relMSE(ic) = **{ic_ratio:.2f} ± "
                  f"{ic_ratio_se:.2f}**: per iteration ic costs {u['t'] / c['t']:.2f}× less "
                  f"and has {c['v'] / u['v']:.2f}× the variance.", "",
                  f"Importance caching against power-proportional VPL sampling (both 16 VPLs "
                  f"per shading point): **{m_ratio:.2f} ± {m_ratio_se:.2f}×** lower variance "
                  f"per iteration; at equal time {t_ratio:.2f} ± {t_ratio_se:.2f}× (an ic "
                  f"iteration, with its records and tables, costs {c['t'] / pw['t']:.2f}× a "
                  f"power-sampling one).", "",
                  f"Importance-cached connections in bpt: **{bpt_ratio:.2f} ± "
                  f"{bpt_ratio_se:.2g}×** lower relative MSE than plain bpt at equal time; "
                  f"{b['v'] / bi['v']:.2f}× lower variance per iteration, at "
                  f"{bi['t'] / b['t']:.2f}× the cost.", "",
                  f"Pictures (`--time {cfg['picture_time']:g}`; tone-mapped by `render --png`): "
                  f"{', '.join(ARMS)}, and the scale image.", "",
                  f"{pictures} ![{name} reference](../img/many-lights/{name}-reference.png)", ""]
    lines += ["## The claims", ""]
    if OCCLUDED_SCENE in verdicts:
        ratio, ratio_se, kept = verdicts[OCCLUDED_SCENE][:3]
        held = kept < CLAIM_ACCEPTANCE and ratio >= CLAIM_RATIO
        lines.append(f"- {OCCLUDED_SCENE}: importance keeps {100 * kept:.1f} % of the candidates "
                     f"(claim: well under {100 * CLAIM_ACCEPTANCE:.0f} %) and lowers the "
                     f"equal-time relative MSE {ratio:.2f} ± {ratio_se:.2f}× (claim: ≥ "
                     f"{CLAIM_RATIO:g}×; the paper: more than 10× at 7 % kept): "
                     f"**{'held' if held else 'not held'}**. Russian roulette cannot lower the "
                     "variance of one iteration, so the gain is at most the cost ratio, about "
                     "1 / (share kept) when the VPL connections dominate the cost.")
    if CONTROL_SCENE in verdicts:
        ratio, ratio_se, kept = verdicts[CONTROL_SCENE][:3]
        lines.append(f"- {CONTROL_SCENE} (control): importance keeps {100 * kept:.1f} %; "
                     f"relMSE(importance) / relMSE(uniform) = {1 / ratio:.2f} (bar: ≤ "
                     f"{CONTROL_RATIO:g}): **{'held' if 1 / ratio <= CONTROL_RATIO else 'not held'}**.")
    for name, v in verdicts.items():
        ic_ratio, ic_ratio_se, m_ratio, m_ratio_se, t_ratio, t_ratio_se = v[3:9]
        claim = ""
        if name == OCCLUDED_SCENE:
            claim = (f" Claim (ALGORITHMS-NEXT.md 2.10 b): ≥ {IC_CLAIM_RATIO:g}× lower variance "
                     f"at equal sample count in the occluded scene: **"
                     f"{'held' if m_ratio >= IC_CLAIM_RATIO else 'not held'}**.")
        elif name == CONTROL_SCENE:
            claim = (" Control: a gain (ratio ≥ 1) expected: **"
                     f"{'held' if m_ratio >= 1 else 'not held'}**.")
        lines.append(f"- {name}, importance caching: {m_ratio:.2f} ± {m_ratio_se:.2f}× lower "
                     f"variance than power-proportional sampling at equal sample count, "
                     f"{t_ratio:.2f} ± {t_ratio_se:.2f}× lower relative MSE at equal time; "
                     f"{ic_ratio:.2f} ± {ic_ratio_se:.2f}× lower relative MSE than all VPLs at "
                     f"equal time.{claim}")
    for name, v in verdicts.items():
        bpt_ratio, bpt_ratio_se, v_ratio, t_ratio = v[9:]
        lines.append(f"- {name}, importance-cached connections: {bpt_ratio:.2f} ± "
                     f"{bpt_ratio_se:.2g}× lower relative MSE than bpt at equal time "
                     f"({v_ratio:.2f}× lower variance per iteration, {t_ratio:.2f}× the cost).")
    # The page is generated from its template and this data file (docs/guide/results.md).
    out_doc = pages.publish_blocks(docs_dir, "many-lights", lines,
                                   "scripts/bench --only many-lights" + (" --quick" if quick else ""),
                                   load_before=pages.load_text(machine.get("load_average")))
    print(f"bench: wrote {out_doc}")
