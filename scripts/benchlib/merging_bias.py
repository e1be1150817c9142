"""Early-iteration bias of the merging estimators on the water caustic
(`scripts/bench --only merging-bias`).

Photon mapping's estimate at iteration i has an expected value that depends on the merging
radius r_i alone (docs/reference/algorithms.md, "Merging radius"), not on the resolution or the
light-path count: so the bias of the image mean after n iterations can be measured on a small
image (the image mean does not depend on the resolution). For each merging algorithm and each
n, `render --iterations n` runs with several seeds; the mean of the runs' image means is compared
with the converged mean: vcm's image mean after many iterations (REFERENCE_ITERATIONS), rendered
here with REFERENCE_SEEDS seeds of its own. The table gives the relative difference and its
standard error (over the seeds, both sides): beyond about 2 standard errors it is bias, not
noise. The converged render's own remaining bias is that of vcm at its last iterations (radius
about 0.42 of the first at 1024 iterations with alpha 0.75), so the differences are lower
bounds of the bias against the exact mean. docs/references/water-caustic.exr is not used: its
image mean is about twice what today's renderer gives at any iteration count (a change since it
was made, 2026-11-25, not yet explained).

Writes docs/data/performance/merging_bias.json; docs/results/performance.md shows it.
"""

import math
import statistics
import tempfile
import time
from pathlib import Path

from benchlib import common
from resultslib import data as datafile, pages

SCENE = "scenes/bitterli-pbrt/water-caustic/scene-v4.pbrt"
RESOLUTION = (64, 64)
ALGORITHMS = ["ppm", "vcm"]
ITERATIONS = [1, 4, 16, 64]
SEEDS = 8
REFERENCE_ALGORITHM = "vcm"
REFERENCE_ITERATIONS = 1024
REFERENCE_SEEDS = 2
QUICK = {"iterations": [1, 4], "seeds": 2, "reference_iterations": 16}


def image_mean(binary, algo, iterations, seed, work):
    out = work / f"{algo}-{iterations}-{seed}.exr"
    cmd = common.render_command(binary, SCENE, out, algo=algo, iterations=iterations,
                                seed=seed, resolution=RESOLUTION, threads=2)
    run = common.run_render(cmd)
    pixels, _ = common.read_exr(out)
    out.unlink()
    # Luminance-like mean of the three channels: the bias is a loss of energy in every channel.
    return float(pixels.mean()), run


def mean_and_se(values):
    m = statistics.fmean(values)
    se = statistics.stdev(values) / math.sqrt(len(values)) if len(values) > 1 else float("nan")
    return m, se


def run(build_dir: Path, docs_dir: Path, quick: bool) -> None:
    binary = common.render_binary(build_dir)
    iterations = QUICK["iterations"] if quick else ITERATIONS
    seeds = QUICK["seeds"] if quick else SEEDS
    load = pages.load_text(common.load_average())
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="render-merging-bias-") as tmp:
        work = Path(tmp)
        reference_iterations = QUICK["reference_iterations"] if quick else REFERENCE_ITERATIONS
        ref_mean, ref_se = mean_and_se(
            [image_mean(binary, REFERENCE_ALGORITHM, reference_iterations, 1000 + s, work)[0]
             for s in range(REFERENCE_SEEDS)])
        print(f"merging-bias: {REFERENCE_ALGORITHM} x{reference_iterations}: mean "
              f"{ref_mean:.6g} ± {ref_se:.2g}", flush=True)
        rows = []
        for algo in ALGORITHMS:
            for n in iterations:
                means = [image_mean(binary, algo, n, 1 + s, work)[0] for s in range(seeds)]
                m, se = mean_and_se(means)
                rel = m / ref_mean - 1
                rel_se = math.hypot(se / ref_mean, ref_se * m / ref_mean ** 2)
                print(f"merging-bias: {algo} n={n}: mean {m:.6g} ± {se:.2g}, "
                      f"relative {rel:+.4f} ± {rel_se:.4f}", flush=True)
                rows.append([algo, n, m, se, rel, rel_se,
                             abs(rel) > 2 * rel_se])
    command = "scripts/bench --only merging-bias" + (" --quick" if quick else "")
    example = common.render_command(binary, SCENE, Path("OUT.exr"), algo="ppm", iterations=4,
                                    seed=1, resolution=RESOLUTION, threads=2)
    path = Path(docs_dir) / "data" / "performance" / "merging_bias.json"
    datafile.write(path, {
        "stamp": datafile.stamp(command, load_before=load),
        "measured": True,
        "values": {"scene": SCENE, "resolution": f"{RESOLUTION[0]}x{RESOLUTION[1]}",
                   "seeds": seeds, "reference_algorithm": REFERENCE_ALGORITHM,
                   "reference_iterations": reference_iterations,
                   "reference_seeds": REFERENCE_SEEDS, "reference_mean": ref_mean,
                   "reference_se": ref_se,
                   "example_command": " ".join(example),
                   "minutes": round((time.monotonic() - t0) / 60, 1)},
        "tables": {"bias": {
            "columns": ["algorithm", "iterations n", "image mean", "SE (seeds)",
                        "relative to converged", "SE", "beyond 2 SE"],
            "formats": [None, None, ".5g", ".2g", "+.4f", ".4f", None],
            "rows": rows}}})
    print(f"merging-bias: wrote {path}", flush=True)
    pages.write(["performance"], Path(docs_dir))
