"""UPBP's robustness claim at equal time: `bpt`, `vcm` and `upbp` over a sweep of medium density
(`scripts/bench --only upbp`, writes docs/results/upbp.md; the estimators: docs/design/media.md, "Points,
beams and paths").

The claim to check (ALGORITHMS-NEXT.md 4.6 b): over isosph with sigma_t x 0.1, x 1, x 10 (the
scene's `density` define) and glasssph, `upbp` with every estimator is never the worst arm and
within 2x of the best at every density, and which single estimator wins changes with density.
The arms: `bpt`, `vcm` (connections, surface merges, photon points), `upbp` with connections
and query beams only (P-B2D), `upbp` with connections and photon beams only (B-B1D, short
beams, eta_1 = r/2), and `upbp` with everything (connections, surface merges, photon points,
query beams, photon beams).

Measured per arm, as in docs/results/joint-sampling.md, on the image without the emitter seen
directly (every arm samples that alike): v, one iteration's variance (the per-pixel
variance over RUNS independent runs of ITERATIONS iterations, times ITERATIONS; mean over pixels
and channels; its standard error over GROUPS disjoint groups of runs), and t, render's own
seconds per iteration (median of TIMING_REPEATS runs of about TIMING_SECONDS, under SCHED_FIFO
where permitted). The variance part of the relative MSE after T seconds is v t / (T m^2), m the
image mean; the table gives v t / m^2 ("relative variance x seconds": lower is better, the
equal-time RMSE ratio of two arms is the square root of its ratio). The merging arms are
biased by their kernels (fixed radius here, alpha = 1 for the volume estimators): the table
also gives each arm's image-mean difference from bpt over all runs, with its standard error,
as a check that the bias is small next to the noise; a per-pixel bias is not measured.
"""

import math
import tempfile
from pathlib import Path

import numpy as np

from resultslib import pages  # scripts/ is on sys.path (scripts/bench)

from . import common

ISOSPH = common.REPO_ROOT / "scenes" / "smallupbp" / "isosph.xml"
GLASSSPH = common.REPO_ROOT / "scenes" / "smallupbp" / "glasssph.xml"
SCENES = {"isosph, sigma_t x 0.1": (ISOSPH, ["-D", "density=0.1"]),
          "isosph, sigma_t x 1": (ISOSPH, ["-D", "density=1"]),
          "isosph, sigma_t x 10": (ISOSPH, ["-D", "density=10"]),
          "glasssph": (GLASSSPH, [])}
# One merging radius for every merging arm: 1 % of the scene radius, about a pixel at 64 px
# wide (the default 0.3 % suits 256 px and more light paths; at 64 px it leaves the merges
# almost no weight, and vcm and upbp would render bpt's image with its noise).
RADIUS = ["--radius-factor", "0.01"]
ARMS = {"bpt": ("bpt", []),
        "vcm": ("vcm", RADIUS),
        "upbp: connections + query beams": ("upbp", [*RADIUS, "--surface-merging", "off",
                                                     "--photon-points", "off",
                                                     "--photon-beams", "off"]),
        "upbp: connections + photon beams": ("upbp", [*RADIUS, "--surface-merging", "off",
                                                      "--photon-points", "off",
                                                      "--query-beams", "off"]),
        "upbp: all": ("upbp", RADIUS)}
WIDTH = 64
RUNS = 8
ITERATIONS = 8
GROUPS = 4
TIMING_REPEATS = 3
TIMING_SECONDS = 2.0
QUICK = {"width": 24, "runs": 4, "iterations": 2, "groups": 2, "timing_repeats": 1,
         "timing_seconds": 0.3}
CLAIM_FACTOR = 2.0


def indirect_image(path: Path):
    """The image without the emitter seen directly (the s0_t2 layer of `--layers st`): every
    arm samples those paths alike (pixel jitter over the lamp's edges), and their variance would
    hide the differences in the medium."""
    layers, attributes = common.read_exr_layers(path)
    return layers[""] - layers["s0_t2"], attributes


def variance(images, iterations) -> float:
    return float((np.stack(images).var(axis=0, ddof=1) * iterations).mean())


def measure_arm(binary, scene, algo, flags, resolution, threads, workdir, cfg):
    commands = []

    def render_arm(tag, seed, iterations, realtime):
        out = workdir / f"{tag}.exr"
        cmd = common.render_command(binary, scene, out, algo=algo, iterations=iterations,
                                    seed=seed, resolution=resolution, threads=threads,
                                    extra=[*flags, "--layers", "st"])
        if realtime:
            cmd = [*common.realtime_prefix(), *cmd]
        common.run_render(cmd)
        image, header = indirect_image(out)
        out.unlink()
        commands.append(cmd)
        return image, header

    m = common.variance_and_time(render_arm, variance, cfg)
    run_means = [float(img.mean()) for img in m["images"]]
    return {"v": m["v"], "v_se": m["v_se"], "t": m["t"], "run_means": run_means,
            "mean": float(np.mean(run_means)), "command": commands[-1]}


def plot(path: Path, table):
    """Equal-time RMSE relative to the best arm, per scene (grouped bars)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(table)
    arms = list(ARMS)
    fig, ax = plt.subplots(figsize=(8, 3.6))
    width = 0.8 / len(arms)
    for k, arm in enumerate(arms):
        ax.bar([i + (k - (len(arms) - 1) / 2) * width for i in range(len(scenes))],
               [table[sc][arm] for sc in scenes], width, label=arm)
    ax.axhline(1.0, color="black", linewidth=0.6)
    ax.set_xticks(range(len(scenes)), scenes)
    ax.set_ylabel("equal-time RMSE / best arm")
    ax.set_ylim(bottom=0.8)
    ax.legend(fontsize=8, ncol=2)
    ax.set_title("bpt, vcm, upbp over a density sweep (lower is better)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(build_dir: Path, docs_dir: Path, quick: bool = False, threads=None):
    binary = common.render_binary(build_dir)
    workdir = Path(tempfile.mkdtemp(prefix="bench-upbp-"))
    cfg = dict(QUICK) if quick else {
        "width": WIDTH, "runs": RUNS, "iterations": ITERATIONS, "groups": GROUPS,
        "timing_repeats": TIMING_REPEATS, "timing_seconds": TIMING_SECONDS}
    machine = common.machine_info()
    lines = ["# UPBP at equal time over a density sweep", "",
             "Written by `scripts/bench --only upbp` (scripts/benchlib/upbp.py); do not edit by "
             "hand.", "", __doc__.strip(), "",
             f"Machine: {machine.get('cpu_model')}, {machine.get('cores')} cores, "
             f"{machine.get('date_utc')}; revision {machine.get('source_revision', '?')}; load "
             f"average before {(machine.get('load_average') or ['?'])[0]}. "
             f"{cfg['width']} px wide, {threads or 'all'} threads, {cfg['runs']} variance runs "
             f"of {cfg['iterations']} iterations per arm, {cfg['groups']} groups; "
             f"{cfg['timing_repeats']} timing runs of about {cfg['timing_seconds']:g} s"
             + (" under SCHED_FIFO (`chrt -f 10`)" if common.realtime_prefix() else
                " at normal priority") + f"{' (quick mode)' if quick else ''}. Merging arms: "
             f"`{' '.join(RADIUS)}` (surfaces, photon points, query beams and photon beams "
             "alike, alpha 0.75, each reduced by its kernel's dimension).", ""]
    verdicts = []
    relative = {}
    for title, (scene, defines) in SCENES.items():
        resolution = common.resolution_for_width(scene, cfg["width"])
        arms = {}
        for arm, (algo, flags) in ARMS.items():
            arms[arm] = measure_arm(binary, scene, algo, [*defines, *flags], resolution,
                                    threads, workdir, cfg)
            m = arms[arm]
            print(f"  {title:24s} {arm:34s} v {m['v']:.4g} ± {m['v_se']:.2g}  "
                  f"t {m['t']:.4f} s", flush=True)
        ref = arms["bpt"]
        m2 = ref["mean"] ** 2
        lines += [f"## {title}", "",
                  f"Timing command (upbp: all): `{' '.join(arms['upbp: all']['command'])}`", "",
                  "| arm | image mean | mean − bpt (± SE) | v (± SE) | s per iteration t | "
                  "v·t / m² | equal-time RMSE / best |", "| --- | --- | --- | --- | --- | --- | --- |"]
        score = {a: m["v"] * m["t"] / m2 for a, m in arms.items()}
        best = min(score.values())
        for arm, m in arms.items():
            se = math.hypot(np.std(m["run_means"], ddof=1) / math.sqrt(len(m["run_means"])),
                            np.std(ref["run_means"], ddof=1) / math.sqrt(len(ref["run_means"])))
            diff = "–" if arm == "bpt" else f"{m['mean'] - ref['mean']:+.3g} ± {se:.2g}"
            lines.append(f"| {arm} | {m['mean']:.4g} | {diff} | {m['v']:.4g} ± {m['v_se']:.2g} | "
                         f"{m['t']:.4f} | {score[arm]:.4g} | "
                         f"{math.sqrt(score[arm] / best):.2f} |")
        relative[title] = {a: math.sqrt(score[a] / best) for a in score}
        worst = max(score, key=score.get)
        winner = min(score, key=score.get)
        ratio = math.sqrt(score["upbp: all"] / best)
        verdicts.append((title, winner, worst, ratio))
        lines += ["", f"Best: {winner}; worst: {worst}; upbp (all) has {ratio:.2f}× the best "
                  "arm's equal-time RMSE.", ""]
    plot(docs_dir / "img" / "upbp" / "density-sweep.png", relative)
    lines += ["## The claim", "", "![equal-time RMSE per arm](../img/upbp/density-sweep.png)", ""]
    held = all(worst != "upbp: all" and ratio <= CLAIM_FACTOR for _, _, worst, ratio in verdicts)
    for title, winner, worst, ratio in verdicts:
        lines.append(f"- {title}: best {winner}, worst {worst}; upbp (all) {ratio:.2f}× the "
                     "best.")
    lines += ["", f"upbp with every estimator it has is never the worst and within "
              f"{CLAIM_FACTOR:g}× of the best at every density: **{'held' if held else 'not held'}**"
              ".", ""]
    # The page is generated from its template and this data file (docs/guide/results.md).
    out_doc = pages.publish_blocks(docs_dir, "upbp", lines,
                                   "scripts/bench --only upbp" + (" --quick" if quick else ""),
                                   load_before=pages.load_text(machine.get("load_average")))
    print(f"bench: wrote {out_doc}")
