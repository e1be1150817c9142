"""vcm on the water caustic at equal CPU time: the merging radius, its reduction and the light
path count chosen by measured error (`scripts/bench --only water-caustic`).

The water caustic (scenes/bitterli-pbrt/water-caustic, seen through the water surface) is the
scene where merging is the only way: its caustic on the floor is a specular-diffuse-specular
path that no connection samples. Every arm is one `render --algo vcm` configuration; its error
is measured at an equal CPU-time budget, not per iteration, because merging is biased and its
bias falls with the iteration count (docs/reference/algorithms.md, "Merging radius"): the
relative RMSE of a run of the budget holds its noise and its bias together.

- CPU time as the claims bench measures it (scripts/benchlib/claims.py): single-threaded
  renders, the child's user + system seconds (os.wait4), which other load on the machine
  disturbs far less than wall time. Each arm's cost per iteration comes from a probe run of
  PROBE_ITERATIONS, less the scene's fixed cost (the median of one-iteration runs); the arm then
  renders budget / cost iterations. The table gives each run's measured CPU seconds.
- Error: the relative RMSE, sqrt(mean over pixels and channels of (x - r)^2 / (r^2 + 0.01))
  (benchlib.common.error_metrics), against docs/references/water-caustic.exr box-averaged to
  the bench's resolution, both clipped at CLIP (10, as the issue's figures were): the scene's
  estimators are heavy-tailed and one firefly pixel of the reference alone doubles its mean
  (scripts/benchlib/merging_bias.py). Each arm's figure is the root of the mean relative MSE of
  its seeds, with a standard error over the seeds.
- The small version: 64 x 64 with one light path per pixel. With the radius in pixel
  footprints (--radius-pixels) every pixel sees the same merging kernel and the same photon
  density per pixel at any resolution, so an iteration's relative error per pixel does not
  depend on the resolution, while its cost is 16 times smaller than at 256 x 256: the budget
  is chosen so that an arm renders about as many iterations as 60 s of wall time on 2 threads
  at 256 x 256 gave in the issue's measurement (127), i.e. the same point of the radius
  schedule. Main's scene-relative radius (0.003 x the scene radius) is 4 times smaller in
  pixels at 64 px than at 256 px, so main's 64 px figure is worse than its 256 px one would be,
  and a 64 px pixel averages more of the caustic's detail than a 256 px one, so the bias of a
  larger kernel is understated here: the ratio of the two defaults at 256 px is not measured
  by this bench (one run there costs 16 times as much).

The sweep goes in stages, each from the best arm of the one before: the initial radius in
pixel footprints (the smallest within RADIUS_TOLERANCE, 10 %, of the lowest error: 64 px
understates the bias a larger kernel adds at higher resolutions), then the reduction alpha,
then the light paths per iteration (the lowest error). The defaults
comparison renders main's defaults (given as flags: the scene-relative radius 0.003, alpha 0.75,
one light path per pixel) and the binary's own defaults with the same seeds, and, on the four
SmallVCM boxes, the same two arms against their references (docs/references/*.exr).

Writes docs/data/performance/water_caustic.json; docs/results/performance.md shows it.
"""

from __future__ import annotations

import concurrent.futures
import math
import os
import shlex
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from benchlib import common
from resultslib import data as datafile, pages

SCENE = "scenes/bitterli-pbrt/water-caustic/scene-v4.pbrt"
REFERENCE = "docs/references/water-caustic.exr"
RESOLUTION = (64, 64)
CLIP = 10.0
# CPU seconds of rendering per run (the fixed cost excluded): about the issue's 127 iterations
# at 64 x 64 on this machine.
BUDGET_SECONDS = 8.0
PROBE_ITERATIONS = 16
SWEEP_SEEDS = 2
COMPARE_SEEDS = 3
# Renders at once (each single-threaded; CPU time is per child, so they do not disturb each
# other's figure beyond sharing caches).
PARALLEL = 4

# Main's defaults at 526e508, given as flags so that the arm renders main's image bit for bit.
MAIN_FLAGS = ["--radius-factor", "0.003", "--alpha", "0.75", "--light-paths", "0"]
# The binary's default alpha (render --help), for arms that do not set it.
DEFAULT_ALPHA = 0.75
RADII_PIXELS = [0.5, 1, 2, 4]
RADIUS_TOLERANCE = 0.10
# The measurement the bench answers (docs/results/performance.md quotes it).
ISSUE_MEASUREMENT = ("60 s of wall time on 2 threads at 256 x 256, 127 iterations, relative "
                     "RMSE 0.57 against a converged render, values clipped at 10")
ALPHAS = [0.5, 0.75, 0.9]
LIGHT_PATH_SCALES = [0.25, 1, 4]

BOXES = [("gbs_s", "scenes/smallvcm/0-gbs_s.xml"), ("glm_c", "scenes/smallvcm/1-glm_c.xml"),
         ("gbs_p", "scenes/smallvcm/2-gbs_p.xml"), ("gbs_b", "scenes/smallvcm/3-gbs_b.xml")]
BOX_BUDGET_SECONDS = 3.0
BOX_SEEDS = 2

QUICK = {"budget": 1.0, "radii": [0.5, 2], "alphas": [0.75], "paths": [1], "sweep_seeds": 1,
         "compare_seeds": 1, "boxes": BOXES[:1], "box_budget": 0.5, "box_seeds": 1}


# --------------------------------------------------------------------------------------------
# Running renders and timing them


class _Popen(subprocess.Popen):
    """Popen that reaps its child with os.wait4 and keeps the child's CPU seconds."""

    cpu = float("nan")

    def _try_wait(self, wait_flags):
        pid, sts, usage = os.wait4(self.pid, wait_flags)
        if pid == self.pid:
            self.cpu = usage.ru_utime + usage.ru_stime
        return pid, sts


def run_cpu(cmd) -> float:
    """Runs one render from the repository root; returns its CPU seconds (user + system of
    that child alone, so that renders may run in parallel)."""
    proc = _Popen(cmd, cwd=common.REPO_ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                  text=True)
    _, err = proc.communicate()
    if proc.returncode != 0:
        raise RuntimeError(f"render failed: {shlex.join(map(str, cmd))}\n{err[-2000:]}")
    return proc.cpu


class Bench:
    """Renders of one binary into a work folder; each returns its image and CPU seconds."""

    def __init__(self, binary: Path, work: Path):
        self.binary, self.work = binary, work
        self.count = 0
        self.pool = concurrent.futures.ThreadPoolExecutor(PARALLEL)

    def command(self, scene, out, iterations, seed, flags, resolution=RESOLUTION):
        return common.render_command(self.binary, scene, out, algo="vcm", iterations=iterations,
                                     seed=seed, resolution=resolution, threads=1, extra=flags)

    def render(self, scene, iterations, seed, flags, resolution=RESOLUTION):
        self.count += 1
        out = self.work / f"r{self.count}.exr"
        cmd = self.command(scene, out, iterations, seed, flags, resolution)
        cpu = run_cpu(cmd)
        image, _ = common.read_exr(out)
        out.unlink()
        return image, cpu

    def map(self, jobs):
        """Runs render(*job) for every job, PARALLEL at a time, in order."""
        return list(self.pool.map(lambda job: self.render(*job), jobs))


def fixed_cost(bench: Bench, scene, resolution) -> float:
    """The scene's fixed CPU cost (loading, acceleration structure, one iteration's set-up): the
    median of three one-iteration runs, less nothing (a one-iteration run is fixed + t)."""
    runs = bench.map([(scene, 1, 90_000 + k, MAIN_FLAGS, resolution) for k in range(3)])
    return float(np.median([cpu for _, cpu in runs]))


def per_iteration(bench: Bench, scene, flag_lists, fixed, resolution) -> list:
    """Each arm's CPU seconds per iteration: a probe of PROBE_ITERATIONS, less the fixed cost of
    a one-iteration run, over the iterations after the first."""
    probes = bench.map([(scene, PROBE_ITERATIONS, 91_000, flags, resolution)
                        for flags in flag_lists])
    return [max((cpu - fixed) / (PROBE_ITERATIONS - 1), 1e-4) for _, cpu in probes]


# --------------------------------------------------------------------------------------------
# Error


def reference_image(path: Path, resolution) -> np.ndarray:
    pixels, _ = common.read_exr(path)
    return common.downscale(pixels, resolution).clip(max=CLIP)


def relative_mse(image, reference) -> float:
    return common.error_metrics(image.clip(max=CLIP), reference)["relative_mse"]


def arm_error(values):
    """sqrt(mean relative MSE over the seeds) and its standard error (delta method over the
    seeds' relative MSEs; nan with one seed)."""
    m = float(np.mean(values))
    if len(values) < 2:
        return math.sqrt(m), float("nan")
    se = float(np.std(values, ddof=1) / math.sqrt(len(values)))
    return math.sqrt(m), se / (2 * math.sqrt(m))


def noise_part(images, reference) -> float:
    """The runs' own noise in the relative MSE: half the relative MSE between two runs of
    different seeds (weighted by the reference as relative_mse is), averaged over the pairs. Their
    bias and the reference's error are common to both runs and cancel, so relative MSE - this
    is the squared bias plus the reference's own error; nan with one run."""
    pairs = [(i, j) for i in range(len(images)) for j in range(i + 1, len(images))]
    if not pairs:
        return float("nan")
    weight = 1.0 / (reference * reference + common.RELATIVE_MSE_EPSILON)
    clipped = [img.clip(max=CLIP) for img in images]
    return float(np.mean([((clipped[i] - clipped[j]) ** 2 * weight).mean() / 2
                          for i, j in pairs]))


def alpha_of(flags) -> float:
    return float(flags[flags.index("--alpha") + 1]) if "--alpha" in flags else DEFAULT_ALPHA


def measure_arms(bench, scene, reference, flag_lists, seeds, budget, fixed,
                 resolution=RESOLUTION) -> list:
    """Arms at the budget, their runs in parallel: for each, the iterations, CPU s per iteration,
    mean CPU s of the runs (fixed cost excluded), relative RMSE at the budget and its SE, and the
    relative RMSE of the runs' noise alone. A run's iteration count comes from the probe, so its
    CPU time misses the budget by the probe's error (the machine is shared): each run's
    relative MSE is brought to the budget as (CPU s / budget)^alpha, the rate at which a
    merging estimator's MSE falls with its iterations (docs/reference/algorithms.md, "Merging
    radius"); the table shows the CPU seconds the runs took."""
    ts = per_iteration(bench, scene, flag_lists, fixed, resolution)
    counts = [max(2, round(budget / t)) for t in ts]
    jobs = [(scene, n, 1 + s, flags, resolution)
            for flags, n in zip(flag_lists, counts) for s in range(seeds)]
    runs = bench.map(jobs)
    results = []
    for k, (flags, n, t) in enumerate(zip(flag_lists, counts, ts)):
        mine = runs[k * seeds:(k + 1) * seeds]
        cpu = [max(c - fixed, 1e-3) for _, c in mine]
        alpha = alpha_of(flags)
        errors = [relative_mse(img, reference) * (c / budget) ** alpha
                  for (img, _), c in zip(mine, cpu)]
        rmse, se = arm_error(errors)
        noise = noise_part([img for img, _ in mine], reference)
        results.append({"iterations": n, "t": t, "cpu": float(np.mean(cpu)), "rmse": rmse,
                        "se": se, "noise": math.sqrt(noise) if noise == noise else noise})
    return results


# --------------------------------------------------------------------------------------------
# The sweep and the comparison


def radius_flags(pixels, alpha, paths):
    return ["--radius-pixels", f"{pixels:g}", "--alpha", f"{alpha:g}", "--light-paths",
            str(paths)]


def sweep(bench, reference, fixed, cfg, log):
    """The staged sweep on the water caustic: rows and the chosen (pixels, alpha, path scale)."""
    pixels_count = RESOLUTION[0] * RESOLUTION[1]
    rows = []
    best = {"pixels": 1.0, "alpha": DEFAULT_ALPHA, "paths": 1.0}
    measured = {}

    def stage(name, arms):
        """arms: (pixels, alpha, path scale) each; returns their relative RMSEs."""
        todo = [a for a in arms if a not in measured]
        flag_lists = [radius_flags(p, al, round(sc * pixels_count)) for p, al, sc in todo]
        for arm, flags, r in zip(todo, flag_lists,
                                 measure_arms(bench, SCENE, reference, flag_lists,
                                              cfg["sweep_seeds"], cfg["budget"], fixed)):
            log(f"water-caustic: {name}: {' '.join(flags)}: {r['iterations']} iterations, "
                f"{r['cpu']:.2f} CPU s, relative RMSE {r['rmse']:.4f} ± {r['se']:.4f} "
                f"(noise {r['noise']:.4f})")
            rows.append([name, *arm, r["iterations"], r["t"] * 1e3, r["cpu"], r["rmse"],
                         r["se"], r["noise"]])
            measured[arm] = r["rmse"]
        return {a: measured[a] for a in arms}

    errors = stage("radius", [(p, best["alpha"], best["paths"]) for p in cfg["radii"]])
    # The smallest radius within RADIUS_TOLERANCE of the lowest error: at 64 px a pixel averages
    # more of the caustic's detail than at 256 px, so this size understates the bias that a
    # larger kernel adds at higher resolutions; of radii that do about as well, the smaller.
    lowest = min(errors.values())
    best["pixels"] = min(a[0] for a, e in errors.items() if e <= lowest * (1 + RADIUS_TOLERANCE))
    errors = stage("alpha", [(best["pixels"], a, best["paths"]) for a in cfg["alphas"]])
    best["alpha"] = min(errors, key=errors.get)[1]
    errors = stage("light paths", [(best["pixels"], best["alpha"], s) for s in cfg["paths"]])
    best["paths"] = min(errors, key=errors.get)[2]
    return rows, best


def compare(bench, scene, reference, seeds, budget, fixed, resolution):
    """Main's defaults against the binary's own at the same budget and seeds."""
    return measure_arms(bench, scene, reference, [MAIN_FLAGS, []], seeds, budget, fixed,
                        resolution)


def compare_row(name, old, new):
    ratio = new["rmse"] / old["rmse"]
    # First-order propagation of the two arms' standard errors (independent runs).
    ratio_se = ratio * math.hypot(old["se"] / old["rmse"], new["se"] / new["rmse"])
    return [name, old["iterations"], old["cpu"], old["rmse"], old["se"], old["noise"],
            new["iterations"], new["cpu"], new["rmse"], new["se"], new["noise"], ratio, ratio_se]


def run(build_dir: Path, docs_dir: Path, quick: bool, command: str) -> None:
    binary = common.render_binary(build_dir)
    cfg = QUICK if quick else {"budget": BUDGET_SECONDS, "radii": RADII_PIXELS,
                               "alphas": ALPHAS, "paths": LIGHT_PATH_SCALES,
                               "sweep_seeds": SWEEP_SEEDS, "compare_seeds": COMPARE_SEEDS,
                               "boxes": BOXES, "box_budget": BOX_BUDGET_SECONDS,
                               "box_seeds": BOX_SEEDS}
    load = pages.load_text(common.load_average())
    t0 = time.monotonic()

    def log(line):
        print(f"{line}  [{(time.monotonic() - t0) / 60:.1f} min]", flush=True)

    with tempfile.TemporaryDirectory(prefix="render-water-caustic-") as tmp:
        bench = Bench(binary, Path(tmp))
        reference = reference_image(common.REPO_ROOT / REFERENCE, RESOLUTION)
        fixed = fixed_cost(bench, SCENE, RESOLUTION)
        log(f"water-caustic: fixed cost {fixed:.3f} CPU s")
        sweep_rows, best = sweep(bench, reference, fixed, cfg, log)
        log(f"water-caustic: best {best}")
        old, new = compare(bench, SCENE, reference, cfg["compare_seeds"], cfg["budget"], fixed,
                           RESOLUTION)
        compare_rows = [compare_row("water caustic", old, new)]
        log(f"water-caustic: defaults: main {old['rmse']:.4f} ± {old['se']:.4f}, "
            f"new {new['rmse']:.4f} ± {new['se']:.4f}, ratio {compare_rows[0][-2]:.3f}")
        for name, scene in cfg["boxes"]:
            ref = reference_image(common.REPO_ROOT / "docs" / "references" / f"{name}.exr",
                                  RESOLUTION)
            box_fixed = fixed_cost(bench, scene, RESOLUTION)
            o, n = compare(bench, scene, ref, cfg["box_seeds"], cfg["box_budget"], box_fixed,
                           RESOLUTION)
            compare_rows.append(compare_row(name, o, n))
            log(f"water-caustic: {name}: main {o['rmse']:.4f} ± {o['se']:.4f}, "
                f"new {n['rmse']:.4f} ± {n['se']:.4f}")
        example = bench.command(SCENE, Path("OUT.exr"), 127, 1, [])
        bench.pool.shutdown()
    ratio = compare_rows[0][-2]
    path = Path(docs_dir) / "data" / "performance" / "water_caustic.json"
    datafile.write(path, {
        "stamp": datafile.stamp(command, load_before=load),
        "measured": True,
        "values": {
            "scene": SCENE, "reference": REFERENCE,
            "resolution": f"{RESOLUTION[0]}x{RESOLUTION[1]}", "clip": CLIP,
            "budget": cfg["budget"], "box_budget": cfg["box_budget"],
            "sweep_seeds": cfg["sweep_seeds"], "compare_seeds": cfg["compare_seeds"],
            "box_seeds": cfg["box_seeds"], "fixed_cpu_seconds": round(fixed, 3),
            "best_radius_pixels": best["pixels"], "best_alpha": best["alpha"],
            "best_light_path_scale": best["paths"],
            "main_flags": " ".join(MAIN_FLAGS),
            "issue_measurement": ISSUE_MEASUREMENT,
            "radius_tolerance": f"{RADIUS_TOLERANCE:.0%}".replace("%", " %"),
            "ratio": round(ratio, 3),
            "half_held": "held" if ratio <= 0.5 else "not held",
            "example_command": shlex.join(map(str, example)),
            "minutes": round((time.monotonic() - t0) / 60, 1)},
        "tables": {
            "sweep": {
                "columns": ["stage", "radius (pixel footprints)", "alpha",
                            "light paths per pixel", "iterations", "CPU ms per iteration",
                            "CPU s per run", "relative RMSE", "SE", "its noise alone"],
                "formats": [None, "g", "g", "g", None, ".3g", ".3g", ".4f", ".4f", ".4f"],
                "rows": sweep_rows},
            "defaults": {
                "columns": ["scene", "main: iterations", "CPU s", "relative RMSE", "SE",
                            "noise alone", "new: iterations", "CPU s", "relative RMSE", "SE",
                            "noise alone", "new / main", "SE"],
                "formats": [None, None, ".3g", ".4f", ".4f", ".4f", None, ".3g", ".4f", ".4f",
                            ".4f", ".3f", ".3f"],
                "rows": compare_rows}}})
    print(f"water-caustic: wrote {path}", flush=True)
    pages.write(["performance"], Path(docs_dir))
