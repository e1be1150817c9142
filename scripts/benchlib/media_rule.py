"""Mitsuba's medium rule, per pixel: every algorithm that renders media against a brute-force
volpt reference (`scripts/bench --only media-rule`).

Mitsuba 3's own participating-media test scenes (nested shapes naming only an interior,
emitters inside media, dielectric and thin-dielectric boundaries) are not available here whole
(their meshes and environment map are binary files we do not have), so scenes of the same kinds
were written from Mitsuba's documented semantics (scenes/tests/media-rule/, and
scenes/tests/nested-media.xml; docs/reference/scene-format.md, "Media").

The reference is volpt with distance and light sampling only (`--no-equiangular
--volpt-technique dl`: no equi-angular or joint sampling, no MIS between them), rendered with
REFERENCE_SEEDS seeds of REFERENCE_ITERATIONS iterations each. Each algorithm renders SEEDS seeds
of ITERATIONS iterations. Per pixel and channel: d = mean(algorithm) - mean(reference), and the
expected noise s^2 = var(algorithm) / SEEDS + var(reference) / REFERENCE_SEEDS (sample variances
over the seeds). The figure is sqrt(sum d^2 / sum s^2) over the image: about 1 when the two agree
to noise (the sums pool every pixel, so the estimated variances' own noise hardly moves it);
well above 1 is a difference. The relative difference of the image means is shown beside it.
The merging algorithms (vcm, upbp) are biased at a finite radius: their figure includes that
bias.

Writes docs/data/media-rule/comparison.json; docs/results/media-rule.md shows it.
"""

import math
import tempfile
import time
from pathlib import Path

import numpy as np

from benchlib import common
from resultslib import data as datafile, pages

SCENES = [
    "scenes/tests/nested-media.xml",
    "scenes/tests/media-rule/emitter-inside.xml",
    "scenes/tests/media-rule/dielectric-boundary.xml",
    "scenes/tests/media-rule/thindielectric-nested-emitter.xml",
    # The same with declarations that agree: what is left when light subpaths and camera paths
    # read the rule alike.
    "scenes/tests/media-rule/thindielectric-nested-consistent.xml",
    # An emitting medium in nested interior-only spheres: whether a point emits depends on the
    # path through it.
    "scenes/tests/media-rule/emissive-nested.xml",
]
ALGORITHMS = ["volpt", "lt", "bpt", "vcm", "upbp"]
RESOLUTION = (32, 32)
ITERATIONS = 16
SEEDS = 8
REFERENCE_ITERATIONS = 64
REFERENCE_SEEDS = 16
REFERENCE_EXTRA = ["--no-equiangular", "--volpt-technique", "dl"]
QUICK = {"iterations": 4, "seeds": 3, "reference_iterations": 8, "reference_seeds": 3}


def render_seeds(binary, scene, algo, iterations, seeds, first_seed, extra, work):
    images = []
    for s in range(seeds):
        out = work / f"{algo}-{first_seed + s}.exr"
        cmd = common.render_command(binary, scene, out, algo=algo, iterations=iterations,
                                    seed=first_seed + s, resolution=RESOLUTION, threads=2,
                                    extra=extra)
        common.run_render(cmd)
        pixels, _ = common.read_exr(out)
        images.append(np.asarray(pixels, dtype=np.float64)[..., :3])
        out.unlink()
    return np.stack(images)


def compare(runs, reference):
    """(noise ratio, relative difference of the image means, its standard error)."""
    d = runs.mean(axis=0) - reference.mean(axis=0)
    s2 = runs.var(axis=0, ddof=1) / len(runs) + reference.var(axis=0, ddof=1) / len(reference)
    ratio = math.sqrt(float((d ** 2).sum()) / float(s2.sum())) if s2.sum() > 0 else float("nan")
    run_means = runs.reshape(len(runs), -1).mean(axis=1)
    ref_means = reference.reshape(len(reference), -1).mean(axis=1)
    m, r = run_means.mean(), ref_means.mean()
    se = math.hypot(run_means.std(ddof=1) / math.sqrt(len(runs)),
                    ref_means.std(ddof=1) / math.sqrt(len(reference)))
    return ratio, float(m / r - 1), float(se / r)


def run(build_dir: Path, docs_dir: Path, quick: bool) -> None:
    binary = common.render_binary(build_dir)
    iterations = QUICK["iterations"] if quick else ITERATIONS
    seeds = QUICK["seeds"] if quick else SEEDS
    ref_iterations = QUICK["reference_iterations"] if quick else REFERENCE_ITERATIONS
    ref_seeds = QUICK["reference_seeds"] if quick else REFERENCE_SEEDS
    load = pages.load_text(common.load_average())
    t0 = time.monotonic()
    rows = []
    with tempfile.TemporaryDirectory(prefix="render-media-rule-") as tmp:
        work = Path(tmp)
        for scene in SCENES:
            reference = render_seeds(binary, scene, "volpt", ref_iterations, ref_seeds, 1000,
                                     REFERENCE_EXTRA, work)
            for algo in ALGORITHMS:
                runs = render_seeds(binary, scene, algo, iterations, seeds, 1, [], work)
                ratio, rel, rel_se = compare(runs, reference)
                print(f"media-rule: {Path(scene).name} {algo}: noise ratio {ratio:.3f}, "
                      f"mean {rel:+.4f} ± {rel_se:.4f}", flush=True)
                rows.append([common.display_path(scene), algo, ratio, rel, rel_se,
                             bool(abs(rel) > 2 * rel_se)])
    command = "scripts/bench --only media-rule" + (" --quick" if quick else "")
    example = common.render_command(binary, SCENES[0], Path("OUT.exr"), algo="volpt",
                                    iterations=ref_iterations, seed=1000, resolution=RESOLUTION,
                                    threads=2, extra=REFERENCE_EXTRA)
    path = Path(docs_dir) / "data" / "media-rule" / "comparison.json"
    datafile.write(path, {
        "stamp": datafile.stamp(command, load_before=load),
        "measured": True,
        "values": {"resolution": f"{RESOLUTION[0]}x{RESOLUTION[1]}", "iterations": iterations,
                   "seeds": seeds, "reference_iterations": ref_iterations,
                   "reference_seeds": ref_seeds,
                   "reference_command": " ".join(example),
                   "minutes": round((time.monotonic() - t0) / 60, 1)},
        "tables": {"comparison": {
            "columns": ["scene", "algorithm", "RMS difference / expected noise",
                        "image mean relative to the reference", "SE (seeds)", "beyond 2 SE"],
            "formats": [None, None, ".3f", "+.4f", ".4f", None],
            "rows": rows}}})
    print(f"media-rule: wrote {path}", flush=True)
    pages.write(["media-rule"], Path(docs_dir))
