"""Adaptive against uniform sampling at equal cost (`scripts/bench --only adaptive`).

For each scene of SCENES (pt or volpt; three with uneven noise, a caustic or glossy region beside
diffuse walls, and one with even noise) and of BIDIRECTIONAL_SCENES (bpt):

1. a reference: REFERENCE_ITERATIONS uniform iterations with `--layers variance`, whose variance
   layer gives the reference's own remaining error (mean over pixels and channels of the variance
   of its mean, MSE_ref);
2. the adaptive arm: `render --adaptive T` for at most ADAPTIVE_ITERATIONS iterations; its camera
   samples are the sum of its `samples` layer;
3. the uniform arm: as many iterations as give the adaptive arm's samples (rounded);
4. each arm's MSE against the reference, less MSE_ref (the reference's noise is independent of
   the arm's and adds to its measured MSE; what is left estimates the arm's own MSE).

Cost is CPU time (user + system of the render process, less a one-iteration run's CPU time
minus one uniform iteration's share: scene loading and set-up), not wall-clock time: the machine
is shared with other jobs, and CPU time is what the renders spend whatever the load. The uniform
arm's MSE is scaled to the adaptive arm's cost as MSE x cost_uniform / cost_adaptive (a uniform
render's MSE falls as 1 / iterations), and the ratio of RMSEs at equal cost is
sqrt(MSE_uniform_scaled / MSE_adaptive). The same ratio at equal camera samples is given beside
it. Each arm is rendered with SEEDS seeds and its MSEs averaged.

Writes docs/data/adaptive/benchmark.json (SCENES) and bidirectional.json (BIDIRECTIONAL_SCENES);
docs/results/adaptive-sampling.md is generated from them.
"""

import math
import resource
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from benchlib import common
from resultslib import data as datafile, pages


@dataclass(frozen=True)
class Scene:
    name: str
    path: str
    algo: str
    width: int
    noise: str  # "uneven" or "even": what the scene is chosen to show


SCENES = [
    # Glossy and mirror spheres in a Cornell box: the reflections are far noisier than the walls.
    Scene("glm_c", "scenes/smallvcm/1-glm_c.xml", "pt", 64, "uneven"),
    # Glass and mirror spheres: caustics on the floor beside diffuse walls.
    Scene("gbs_s", "scenes/smallvcm/0-gbs_s.xml", "pt", 64, "uneven"),
    # Bitterli's Cornell box: diffuse walls; nearly all of its noise is in the pixels along the
    # visible light's edge (partly covered by a very bright emitter), not in a caustic.
    Scene("cornell-box", "scenes/bitterli/cornell-box/scene_v3.xml", "pt", 64, "uneven"),
    # Veach's bidirectional scene: a lamp's caustic-like indirect light on a table and walls.
    Scene("veach-bidir", "scenes/bitterli/veach-bidir/scene_v3.xml", "pt", 64, "uneven"),
    # A glass sphere in a medium (volpt): its noise is less uneven than it looks (see the best
    # possible ratio on the results page).
    Scene("glasssph", "scenes/smallupbp/glasssph.xml", "volpt", 64, "uneven"),
    # Two diffuse rooms lit through a door: the noise is spread over the whole image.
    Scene("two-rooms", "scenes/tests/two-rooms.xml", "pt", 64, "even"),
]
# The bidirectional family (docs/reference/adaptive-sampling.md, "The bidirectional family"):
# eye subpaths from the active pixels only, the light pass whole, so an iteration's cost falls
# less than its active fraction. Their own data file and table (bidirectional.json).
BIDIRECTIONAL_SCENES = [
    Scene("glm_c-bpt", "scenes/smallvcm/1-glm_c.xml", "bpt", 64, "uneven"),
    Scene("cornell-box-bpt", "scenes/bitterli/cornell-box/scene_v3.xml", "bpt", 64, "uneven"),
]
THRESHOLD = 0.05
MIN_ITERATIONS = 16
ROUND = 8
ADAPTIVE_ITERATIONS = 1024
REFERENCE_ITERATIONS = 4096
SEEDS = 2
# One render thread: the benchmark's 64 x 64 film is 16 tiles, and when few pixels are left a
# second thread's wait for the last tiles is CPU time that a full-size film does not spend.
THREADS = 1
QUICK = {"adaptive_iterations": 32, "reference_iterations": 128, "seeds": 1}


def best_ratio(variance: np.ndarray) -> float:
    """The largest RMSE ratio uniform / adaptive any per-pixel allocation of the same samples
    reaches, from the per-channel variances of the reference's pixel means: a pixel's MSE is
    v_p / n_p (v_p its variance per sample, summed over the channels), which for a given total
    of samples is least with n_p proportional to sqrt(v_p) (Neyman allocation). The ratio is
    then sqrt(mean v) / mean sqrt(v): 1 for even noise."""
    v = variance.sum(axis=-1).ravel()
    mean_sqrt = float(np.sqrt(v).mean())
    return math.sqrt(float(v.mean())) / mean_sqrt if mean_sqrt > 0 else float("nan")


def read_layers(path: Path) -> dict:
    """Every layer of an EXR as H x W x 3 float64 arrays: "" for the image, else the layer name."""
    return common.read_exr_layers(path)[0]


def cpu_run(cmd: list[str]) -> tuple[float, str]:
    """Runs a render command (from the repository root); its CPU seconds and its stdout."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run(cmd, cwd=common.REPO_ROOT, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"render failed: {' '.join(cmd)}\n{proc.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, proc.stdout


def render(binary, scene, resolution, out, *, iterations, seed, extra=()):
    cmd = common.render_command(binary, scene.path, out, algo=scene.algo, iterations=iterations,
                                seed=seed, resolution=resolution, threads=THREADS,
                                extra=list(extra))
    cpu, _ = cpu_run(cmd)
    return cpu, read_layers(out), cmd


def measure_scene(binary, scene, cfg, work):
    resolution = common.resolution_for_width(common.REPO_ROOT / scene.path, scene.width)
    pixels = resolution[0] * resolution[1]
    _, ref, _ = render(binary, scene, resolution, work / "ref.exr",
                       iterations=cfg["reference_iterations"], seed=1000,
                       extra=["--layers", "variance"])
    reference = ref[""]
    mse_ref = float(ref["variance"].mean())
    bound = best_ratio(ref["variance"])
    # Relative MSE as `render --compare` defines it (common.error_metrics), and the reference's
    # share of it.
    rel_weight = 1.0 / (reference * reference + common.RELATIVE_MSE_EPSILON)
    rel_ref = float((ref["variance"] * rel_weight).mean())
    # Set-up cost: a one-iteration run less one iteration's share of the uniform arm.
    setup_cpu, _, _ = render(binary, scene, resolution, work / "one.exr", iterations=1, seed=999)
    arms = {"adaptive": [], "uniform": []}
    adaptive_cmd = uniform_cmd = None
    for seed in range(1, cfg["seeds"] + 1):
        cpu_a, a, adaptive_cmd = render(
            binary, scene, resolution, work / "a.exr", iterations=cfg["adaptive_iterations"],
            seed=seed, extra=["--adaptive", f"{THRESHOLD:g}", "--adaptive-min-iterations",
                              str(MIN_ITERATIONS), "--adaptive-round", str(ROUND)])
        samples_a = float(a["samples"][..., 0].sum())
        n_uniform = max(1, round(samples_a / pixels))
        cpu_u, u, uniform_cmd = render(binary, scene, resolution, work / "u.exr",
                                       iterations=n_uniform, seed=seed)
        one_iteration = cpu_u / n_uniform
        overhead = max(0.0, setup_cpu - one_iteration)
        for arm, image, cpu, samples in (("adaptive", a[""], cpu_a, samples_a),
                                         ("uniform", u[""], cpu_u, float(n_uniform * pixels))):
            mse = float(((image - reference) ** 2).mean())
            rel = float(((image - reference) ** 2 * rel_weight).mean())
            # The image mean's difference: a stopping rule that ends heavy-tailed pixels before
            # their rare bright paths shows as a darker adaptive image.
            arms[arm].append({"mse": mse, "rel": rel,
                              "mean_difference": float((image - reference).mean()), "cpu": max(1e-9, cpu - overhead), "samples": samples,
                              "iterations": n_uniform if arm == "uniform" else None})
        print(f"adaptive: {scene.name} seed {seed}: adaptive {samples_a / pixels:.1f} samples/px "
              f"{cpu_a:.1f} s CPU, uniform {n_uniform} it. {cpu_u:.1f} s CPU, set-up "
              f"{overhead:.2f} s", flush=True)

    def mean(arm, key):
        return sum(r[key] for r in arms[arm]) / len(arms[arm])

    mse_a = mean("adaptive", "mse") - mse_ref
    mse_u = mean("uniform", "mse") - mse_ref
    cpu_a, cpu_u = mean("adaptive", "cpu"), mean("uniform", "cpu")
    samples_a, samples_u = mean("adaptive", "samples"), mean("uniform", "samples")
    rel_a = mean("adaptive", "rel") - rel_ref
    rel_u = mean("uniform", "rel") - rel_ref
    rel_ratio = (math.sqrt(rel_u * cpu_u / cpu_a / rel_a) if rel_a > 0 and rel_u > 0
                 else float("nan"))
    valid = mse_a > 0 and mse_u > 0
    ratio_time = math.sqrt(mse_u * cpu_u / cpu_a / mse_a) if valid else float("nan")
    ratio_samples = math.sqrt(mse_u * samples_u / samples_a / mse_a) if valid else float("nan")
    return {
        "scene": scene, "resolution": resolution, "mse_ref": mse_ref, "mse_a": mse_a,
        "mse_u": mse_u, "cpu_a": cpu_a, "cpu_u": cpu_u, "samples_per_pixel_a": samples_a / pixels,
        "iterations_u": samples_u / pixels, "ratio_time": ratio_time,
        "ratio_samples": ratio_samples, "rel_ratio": rel_ratio,
        "mean_difference_a": mean("adaptive", "mean_difference"),
        "mean_difference_u": mean("uniform", "mean_difference"),
        "best_ratio": bound,
        "reference_mean": float(reference.mean()), "adaptive_cmd": adaptive_cmd, "uniform_cmd": uniform_cmd,
    }


def verdict(row):
    """The issue's targets: >= 1.5x lower RMSE on uneven noise, <= 1.05x worse on even noise."""
    r = row["ratio_time"]
    if not math.isfinite(r):
        return "not measurable (MSE below the reference's noise)"
    if row["scene"].noise == "uneven":
        return "held" if r >= 1.5 else "not held"
    return "held" if r >= 1 / 1.05 else "not held"


def write_data(path: Path, rows, cfg, command: str, load, minutes: float) -> None:
    table = [[r["scene"].name, r["scene"].algo, f"{r['resolution'][0]}x{r['resolution'][1]}",
              r["scene"].noise, r["samples_per_pixel_a"], r["iterations_u"], r["cpu_a"],
              r["cpu_u"], math.sqrt(max(r["mse_a"], 0)), math.sqrt(max(r["mse_u"], 0)),
              math.sqrt(r["mse_ref"]), r["best_ratio"], r["ratio_samples"], r["ratio_time"],
              r["rel_ratio"], verdict(r)]
             for r in rows]
    datafile.write(path, {
        "stamp": datafile.stamp(command, load_before=load),
        "measured": True,
        "values": {"threshold": THRESHOLD, "min_iterations": MIN_ITERATIONS, "round": ROUND,
                   "adaptive_iterations": cfg["adaptive_iterations"],
                   "reference_iterations": cfg["reference_iterations"], "seeds": cfg["seeds"],
                   "threads": THREADS, "minutes": minutes},
        "blocks": {"commands": ["```"] + [" ".join(r["adaptive_cmd"]) for r in rows]
                   + [" ".join(r["uniform_cmd"]) for r in rows] + ["```"]},
        "tables": {"equal_cost": {
            "columns": ["scene", "algorithm", "film", "noise", "adaptive samples/px",
                        "uniform iterations", "adaptive CPU s", "uniform CPU s",
                        "adaptive RMSE", "uniform RMSE", "reference RMSE",
                        "best possible RMSE ratio, equal samples", "RMSE ratio, equal samples", "RMSE ratio, equal CPU time",
                        "relative RMSE ratio, equal CPU time", "RMSE target"],
            "formats": [None, None, None, None, ".1f", ".1f", ".1f", ".1f", ".3g", ".3g",
                        ".2g", ".2f", ".2f", ".2f", ".2f", None],
            "rows": table},
            "image_mean": {
            "columns": ["scene", "reference image mean", "adaptive mean - reference (relative)",
                        "uniform mean - reference (relative)"],
            "formats": [None, ".4g", "+.4f", "+.4f"],
            "rows": [[r["scene"].name, r["reference_mean"],
                      r["mean_difference_a"] / r["reference_mean"],
                      r["mean_difference_u"] / r["reference_mean"]] for r in rows]}}})
    print(f"adaptive: wrote {path}", flush=True)


def run(build_dir: Path, docs_dir: Path, quick: bool, command: str, only=None) -> None:
    """Renders the scenes of SCENES and BIDIRECTIONAL_SCENES (those named in `only`, if given)
    and writes each list's data file that had a scene rendered: benchmark.json,
    bidirectional.json."""
    binary = common.render_binary(build_dir)
    cfg = dict(QUICK) if quick else {"adaptive_iterations": ADAPTIVE_ITERATIONS,
                                     "reference_iterations": REFERENCE_ITERATIONS,
                                     "seeds": SEEDS}
    load = datafile.load()
    t0 = time.monotonic()
    for scene_list, name in ((SCENES, "benchmark.json"),
                             (BIDIRECTIONAL_SCENES, "bidirectional.json")):
        scenes = [s for s in scene_list if not only or s.name in only]
        if not scenes:
            continue
        rows = []
        with tempfile.TemporaryDirectory(prefix="render-adaptive-") as tmp:
            for scene in scenes:
                row = measure_scene(binary, scene, cfg, Path(tmp))
                print(f"adaptive: {scene.name}: RMSE ratio uniform/adaptive "
                      f"{row['ratio_time']:.3f} at equal CPU time, {row['ratio_samples']:.3f} "
                      f"at equal samples", flush=True)
                rows.append(row)
        write_data(Path(docs_dir) / "data" / "adaptive" / name, rows, cfg, command, load,
                   round((time.monotonic() - t0) / 60, 1))
    pages.write(["adaptive-sampling"], Path(docs_dir))
