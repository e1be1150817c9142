"""Early-iteration bias of the merging estimators on the water caustic
(`scripts/bench --only merging-bias`).

Photon mapping's estimate at iteration i has an expected value that depends on the merging
radius r_i alone (docs/reference/algorithms.md, "Merging radius"), not on the resolution or the
light-path count: so the bias of the image mean after n iterations can be measured on a small
image (the image mean does not depend on the resolution). For each merging algorithm and each
n, `render --iterations n` runs with several seeds; the mean of the runs' image means is compared
with the converged mean, that of docs/references/water-caustic.exr. The table gives the relative
difference and its standard error (over the seeds): beyond about 2 standard errors it is bias,
not noise.

Every pixel is clipped at CLIP (10) first, in the runs and in the reference. The scene's
estimators are heavy-tailed (caustic paths through the water that connections find with a tiny
density): the reference holds one such pixel, (20, 127), of about 1.2e4, which alone doubles its
image mean (0.255 unclipped, 0.1367 clipped, 0.1366 without that pixel), and a vcm render of our
own of 1024 iterations at 64x64 had an unclipped mean of 0.39 +- 0.17 over two seeds for the
same reason. Clipping makes the means measurable; what it removes from the runs (their rare
pixels above 10) is a loss that shrinks as n grows, so the differences at small n are the
merging kernel's bias plus that clipping loss, an upper bound on the loss of energy due to
merging alone. The reference's own remaining bias (a converged vcm render) is not known and
not included.

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
REFERENCE = "docs/references/water-caustic.exr"
CLIP = 10.0
QUICK = {"iterations": [1, 4], "seeds": 2}


def image_mean(binary, algo, iterations, seed, work):
    out = work / f"{algo}-{iterations}-{seed}.exr"
    cmd = common.render_command(binary, SCENE, out, algo=algo, iterations=iterations,
                                seed=seed, resolution=RESOLUTION, threads=2)
    run = common.run_render(cmd)
    pixels, _ = common.read_exr(out)
    out.unlink()
    # Mean of the three channels (the bias is a loss of energy in every channel), clipped.
    return clipped_mean(pixels), run


def clipped_mean(pixels):
    return float(pixels.clip(max=CLIP).mean())


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
        reference_pixels, _ = common.read_exr(common.REPO_ROOT / REFERENCE)
        ref_mean = clipped_mean(reference_pixels)
        print(f"merging-bias: {REFERENCE}: clipped mean {ref_mean:.6g} (unclipped "
              f"{float(reference_pixels.mean()):.6g})", flush=True)
        rows = []
        for algo in ALGORITHMS:
            for n in iterations:
                means = [image_mean(binary, algo, n, 1 + s, work)[0] for s in range(seeds)]
                m, se = mean_and_se(means)
                rel = m / ref_mean - 1
                rel_se = se / ref_mean
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
                   "seeds": seeds, "reference": REFERENCE, "clip": CLIP,
                   "reference_mean": ref_mean,
                   "reference_mean_unclipped": float(reference_pixels.mean()),
                   "example_command": " ".join(example),
                   "minutes": round((time.monotonic() - t0) / 60, 1)},
        "tables": {"bias": {
            "columns": ["algorithm", "iterations n", "image mean", "SE (seeds)",
                        "relative to converged", "SE", "beyond 2 SE"],
            "formats": [None, None, ".5g", ".2g", "+.4f", ".4f", None],
            "rows": rows}}})
    print(f"merging-bias: wrote {path}", flush=True)
    pages.write(["performance"], Path(docs_dir))
