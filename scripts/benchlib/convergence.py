"""The convergence ("speed against error") benchmark: docs/results/speed-vs-error.md.

For each scene of SCENES and each algorithm that can converge on it, `render` is run with a
doubling schedule of iteration counts (1, 2, 4, ... iterations, each point a fresh run whose
seed is its iteration count), from about `min_seconds` up to `max_seconds` of wall time. Every
image is compared with the scene's reference image (docs/references/, made by
`scripts/bench --make-references`). The document gets, per scene, a table of RMSE at equal
times, a log-log plot of relative MSE against time, the least-squares convergence slope per
algorithm and, on scenes with specular-diffuse-specular paths, whether the VCM claim held.
"""

from __future__ import annotations

import dataclasses
import json
import math
import shlex
import tempfile
import time
from pathlib import Path
from typing import Optional

import numpy as np

from resultslib import pages  # scripts/ is on sys.path (scripts/bench)

from . import common

# --------------------------------------------------------------------------------------------
# The scene table. Add a row to benchmark another scene (e.g. media scenes later).

# Every series, in table order: the algorithms whose row names the "convergence" suite
# (Algorithm::benchmarks, read from `render --describe-options` by run()), with the extra series
# of SERIES_FLAGS after the algorithm they run.
ALL_ALGOS: list = []

# Series that are an algorithm with options: name -> (algorithm, extra render flags). Both vpl
# series clamp the connection distance at 1 % of the scene radius with the shrinking schedule
# (the default schedule: consistent, so they converge to the reference; unclamped VPLs have
# infinite variance in the Cornell box's corners). vpl+div adds the importance-driven VPL
# distribution, ic importance caching over the same VPLs (docs/reference/algorithms.md).
VPL_FLAGS = ("--vpl-clamp", "0.01")
SERIES_FLAGS = {
    "vpl": ("vpl", VPL_FLAGS),
    "vpl+div": ("vpl", VPL_FLAGS + ("--vpl-distribution", "importance")),
    "ic": ("ic", VPL_FLAGS),
}
MANY_LIGHT_SERIES = ("vpl", "vpl+div", "ic")


def series_from_table(algorithms: list) -> list:
    """The series of the given algorithms: each algorithm, then the extra series that run it
    (vpl: vpl+div)."""
    out = []
    for algo in algorithms:
        out.append(algo)
        out += [name for name, (a, _) in SERIES_FLAGS.items() if a == algo and name != algo]
    return out


def series_command(name: str) -> tuple[str, tuple[str, ...]]:
    """The algorithm and the extra render flags of a series."""
    return SERIES_FLAGS.get(name, (name, ()))

# Why an algorithm cannot converge on a scene (see docs/reference/algorithms.md). Such combinations are
# not run; the document lists them with these reasons.


def lt_sees_no_specular(what: str) -> str:
    """Why light tracing cannot converge when `what` (specular surfaces) is visible."""
    return ("cannot see anything through a specular (delta) surface: a light path cannot "
            f"connect to the camera from a mirror or glass vertex, so the image is black where "
            f"{what} should be seen "
            "(`E S+ D … L` is missing)")


PT_DELTA_CAUSTICS = ("misses every caustic of a delta light (`E … D S+ L` with a point or "
                     "directional light): next-event estimation cannot pass a specular vertex "
                     "and BSDF sampling cannot hit a delta light")
BPT_DELTA_SDS = ("misses the glass sphere's caustic seen in the mirror sphere (`E S D S L` "
                 "with a delta light): no connection technique can sample it")
VPL_CAUSTICS = ("misses caustics on diffuse surfaces (`E S* D S+ … L`): a specular vertex "
                "cannot be a VPL and next-event estimation cannot pass it")
VPL_MEDIA = "renders surfaces only (it refuses scenes with participating media)"
VPL_GLOSSY = ("not benchmarked here: glossy plates lit by small lights are the case VPLs handle "
              "worst (each VPL a spike in the glossy lobe); the many-light scenes are "
              "cornell-box and two-rooms")
NO_VPL = {name: VPL_CAUSTICS for name in MANY_LIGHT_SERIES}
NO_VPL_MEDIA = {name: VPL_MEDIA for name in MANY_LIGHT_SERIES}


@dataclasses.dataclass(frozen=True)
class BenchScene:
    """One row of the scene table."""

    path: str  # scene file, relative to the repository root
    name: str  # short name: file names of the reference and the plot
    reference_algo: str  # algorithm of the reference image
    reference_iterations: int  # its iteration count (at REFERENCE_WIDTH)
    skipped: dict  # algorithm -> why it cannot converge here (not run)
    sds: bool  # has specular-diffuse-specular paths: the VCM claim is checked here
    description: str

    @property
    def algos(self) -> tuple[str, ...]:
        """The algorithms that are run on this scene."""
        return tuple(a for a in ALL_ALGOS if a not in self.skipped)


LT_SPHERES = lt_sees_no_specular("the spheres")
# Surface-only scenes: volpt runs exactly pt's estimator there (docs/design/media.md), so it is not
# benchmarked twice.
VOLPT_IS_PT = "is the path tracer on a scene without media (same estimator as pt)"
SURFACE = {"volpt": VOLPT_IS_PT}
DELTA_LIGHT_SKIPS = {**SURFACE, **NO_VPL, "pt": PT_DELTA_CAUSTICS, "lt": LT_SPHERES,
                     "bpt": BPT_DELTA_SDS}
# Media scenes (docs/design/media.md).
PT_IGNORES_MEDIA = "ignores participating media (it refuses media scenes; volpt is its media form)"
GRID_SKIPS = {"pt": PT_IGNORES_MEDIA, **NO_VPL_MEDIA}

# path, short name, reference algorithm, reference iterations, skipped algorithms (the others
# run), S-D-S scene (claim checked), description. The reference iteration counts take a few
# minutes each at 2 threads on an idle machine.
SCENES: tuple[BenchScene, ...] = (
    BenchScene("scenes/bitterli/cornell-box/scene_v3.xml", "cornell-box", "pt", 2048, SURFACE,
               False, "diffuse Cornell box, area light"),
    BenchScene("scenes/tests/two-rooms.xml", "two-rooms", "pt", 2048, SURFACE, False,
               "two rooms joined by a doorway; the light is in the room the camera does not "
               "see (light around a corner: the many-light scene of ALGORITHMS-NEXT.md 5)"),
    BenchScene("scenes/bitterli/veach-mis/scene_v3.xml", "veach-mis", "bpt", 512,
               {**SURFACE, **{name: VPL_GLOSSY for name in MANY_LIGHT_SERIES}}, False,
               "glossy plates reflecting four spherical area lights (their glossy "
               "caustics on the wall are fireflies for pt); max_depth 3"),
    BenchScene("scenes/bitterli/veach-bidir/scene_v3.xml", "veach-bidir", "bpt", 128,
               {**SURFACE, **NO_VPL, "lt": lt_sees_no_specular("the glass egg")},
               False, "room lit indirectly by a lamp inside a shade, glass egg on the table "
               "(its S–D–S paths are a small part of the image)"),
    BenchScene("scenes/smallvcm/0-gbs_s.xml", "gbs_s", "vcm", 1024, DELTA_LIGHT_SKIPS,
               True, "SmallVCM box, mirror + glass sphere, directional (sun) light"),
    BenchScene("scenes/smallvcm/1-glm_c.xml", "glm_c", "vcm", 256,
               {**SURFACE, **NO_VPL, "lt": lt_sees_no_specular("the mirror sphere's reflections")},
               True,
               "SmallVCM box, large mirror sphere, small area light (`E S D S L` everywhere "
               "in the sphere)"),
    BenchScene("scenes/smallvcm/2-gbs_p.xml", "gbs_p", "vcm", 512, DELTA_LIGHT_SKIPS,
               True, "SmallVCM box, mirror + glass sphere, point light"),
    BenchScene("scenes/smallvcm/3-gbs_b.xml", "gbs_b", "vcm", 512,
               {**SURFACE, **NO_VPL, "lt": LT_SPHERES}, True, "SmallVCM box, mirror + glass sphere, constant background light"),
    # Participating media.
    BenchScene("scenes/smallupbp/isosph.xml", "isosph", "volpt", 1024,
               {"pt": PT_IGNORES_MEDIA, **NO_VPL_MEDIA}, False,
               "SmallUPBP box: index-matched sphere of isotropic albedo-1 medium, small area "
               "light"),
    BenchScene("scenes/smallupbp/glasssph.xml", "glasssph", "bpt", 256,
               {"pt": PT_IGNORES_MEDIA, **NO_VPL_MEDIA,
                "lt": lt_sees_no_specular("the medium inside the glass sphere")}, False,
               "SmallUPBP box: glass sphere filled with a dense chromatic back-scattering "
               "medium, ceiling light"),
    BenchScene("scenes/bitterli/volumetric-caustic/scene_v3.xml", "volumetric-caustic", "vcm",
               256, {"pt": PT_IGNORES_MEDIA, **NO_VPL_MEDIA,
                     "lt": lt_sees_no_specular("the glass sphere")}, True,
               "gas-filled box; a glass sphere focuses a tiny light into a volumetric caustic "
               "(`E M S L` paths; volpt must hit the 2e-5 m^2 light by chance)"),
    BenchScene("scenes/smoke/scene.xml", "smoke", "volpt", 512, GRID_SKIPS, False,
               "heterogeneous smoke grid in a Cornell-like room (volpt only)"),
    # pbrt-v4 scene (docs/reference/scene-format.md, "pbrt-v4 scenes").
    BenchScene("scenes/bitterli-pbrt/water-caustic/scene-v4.pbrt", "water-caustic", "vcm", 768,
               {**SURFACE, **NO_VPL, "lt": lt_sees_no_specular("the water surface")}, True,
               "Cornell box under a water surface (dielectric), lit by a tiny bright light: the "
               "floor's caustics are `E S D S L` paths seen through the water (pbrt-v4 file)"),
)

QUICK_SCENES = ("cornell-box", "glm_c")  # the default scene set of --quick

REFERENCE_WIDTH = 256  # references are this wide; height by the scene's aspect ratio
REFERENCE_SEED = 1_000_000  # never equal to a measurement seed (those are powers of two)
DEFAULT_MAX_SECONDS = 16.0
DEFAULT_MIN_SECONDS = 1.0
QUICK_WIDTH = 64  # divides REFERENCE_WIDTH: quick mode box-downscales the references
QUICK_MAX_SECONDS = 0.3
QUICK_MIN_SECONDS = 0.0
OVERSHOOT = 1.25  # the next doubling is run if its predicted time is <= OVERSHOOT * max
MIN_POINTS = 3  # every series gets at least this many fitted points, whatever max_seconds says
MAX_POINTS = 24  # safety limit of one series


def select_scenes(names: Optional[list[str]], quick: bool) -> list[BenchScene]:
    """The scene rows selected by --scenes (short names), default all (QUICK_SCENES in quick)."""
    by_name = {s.name: s for s in SCENES}
    if not names:
        names = list(QUICK_SCENES) if quick else [s.name for s in SCENES]
    unknown = [n for n in names if n not in by_name]
    if unknown:
        raise SystemExit(f"bench: unknown scene(s) {unknown}; known: {sorted(by_name)}")
    return [by_name[n] for n in names]


# --------------------------------------------------------------------------------------------
# References


def reference_path(references_dir: Path, scene: BenchScene) -> Path:
    """Where a scene's reference EXR lives."""
    return references_dir / f"{scene.name}.exr"


def make_reference(binary: Path, scene: BenchScene, references_dir: Path,
                   threads: Optional[int]) -> dict:
    """Renders one reference image and rewrites it as half-float, zip-compressed EXR with the
    exact command, iteration count and algorithm in its header. Returns its description."""
    references_dir.mkdir(parents=True, exist_ok=True)
    out = reference_path(references_dir, scene)
    png = out.with_suffix(".png")
    resolution = common.resolution_for_width(common.REPO_ROOT / scene.path, REFERENCE_WIDTH)
    cmd = common.render_command(binary, scene.path, out, algo=scene.reference_algo,
                                iterations=scene.reference_iterations, seed=REFERENCE_SEED,
                                resolution=resolution, threads=threads, png=png)
    print(f"bench: reference {scene.name}: {shlex.join(cmd)}", flush=True)
    run = common.run_render(cmd)
    pixels, attributes = common.read_exr(out)
    machine = common.machine_info()
    attributes.update({
        "render:command": shlex.join(cmd),
        "render:postprocess": "scripts/bench --make-references: rewritten as half-float EXR, "
                              "zip compression",
        "render:resolution": f"{resolution[0]}x{resolution[1]}",
        "render:machine": f"{machine['cpu_model']}, {machine['cores']} cores",
        "render:date": machine["date_utc"],
        "render:load_average_after": " ".join(f"{x:.2f}" for x in
                                              common.load_average() or ()),
    })
    attributes = {k: v for k, v in attributes.items() if k.startswith("render:")}
    common.write_exr(out, pixels, attributes, half=True, compression="zip")
    print(f"bench: reference {scene.name}: {run.iterations} iterations in {run.seconds:.1f} s, "
          f"estimated relative error {run.estimated_relative_error:.3g}", flush=True)
    return attributes


def write_references_readme(references_dir: Path) -> Path:
    """(Re)writes docs/references/README.md from the headers of every reference EXR there."""
    rows = []
    for scene in SCENES:
        path = reference_path(references_dir, scene)
        if not path.exists():
            continue
        _, attr = common.read_exr(path)
        rows.append((scene, path, attr))
    lines = [
        "# Reference images of the convergence benchmark",
        "",
        "Made by `scripts/bench --make-references` (module `scripts/benchlib/convergence.py`,",
        "whose scene table sets the algorithm and iteration count of each). Each is one `render`",
        f"run at {REFERENCE_WIDTH} px wide (height by the scene's aspect ratio) with seed "
        f"{REFERENCE_SEED},",
        "which no measurement uses, so its noise is independent of the measured images. The",
        "float EXR that `render` wrote is then rewritten as half-float with zip compression",
        "(half's relative precision, 2^-11, adds about 1e-7 to a relative MSE). The header holds",
        "the exact command (`render:command`), `render:iterations`, `render:algorithm`,",
        "`render:seconds` and `render:relative_error_estimate`; the `.png` next to each is",
        "`render --png` output (sRGB, clamped). Regenerating gives the same images up to",
        "floating-point summation order: an iteration is a pure function of scene, settings,",
        "seed and index, whatever the thread count.",
        "",
        "The estimated relative error is what `render` printed: half the RMS difference of the",
        "means of the odd and even iterations over the RMS of the mean (noise only, no bias).",
        "`docs/results/speed-vs-error.md` also estimates each reference's own relative MSE from the",
        "reference algorithm's measured curve. The seconds are wall time on the machine named,",
        "which may have been shared with other jobs (see `render:load_average_after`).",
        "",
        "`scripts/bench --quick` renders at 64 px wide and box-averages these references 4x4 down",
        "to that size (exact for `render`'s box pixel filter), so it never re-renders them.",
        "",
        "| scene | file | algorithm | iterations | resolution | seconds | est. relative error | "
        "machine |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for scene, path, attr in rows:
        lines.append(
            f"| `{scene.path}` | [{path.name}]({path.name}) | {attr.get('render:algorithm')} | "
            f"{attr.get('render:iterations')} | {attr.get('render:resolution', '?')} | "
            f"{float(attr.get('render:seconds', 'nan')):.0f} | "
            f"{float(attr.get('render:relative_error_estimate', 'nan')):.4f} | "
            f"{attr.get('render:machine', '?')} |")
    lines += ["", "Commands (run from the repository root):", ""]
    for scene, path, attr in rows:
        lines.append(f"    {attr.get('render:command')}")
    lines.append("")
    readme = references_dir / "README.md"
    readme.write_text("\n".join(lines))
    return readme


def make_references(build_dir: Path, references_dir: Path, scenes: list[BenchScene],
                    threads: Optional[int]) -> None:
    """The --make-references mode: renders the references of the selected scenes."""
    binary = common.render_binary(build_dir)
    for scene in scenes:
        make_reference(binary, scene, references_dir, threads)
        write_references_readme(references_dir)
    print(f"bench: wrote {references_dir / 'README.md'}")


def load_reference(references_dir: Path, scene: BenchScene,
                   resolution: tuple[int, int]) -> tuple[np.ndarray, dict]:
    """The scene's reference image at `resolution` (box-downscaled when smaller) and its
    header. Exits with a hint when the reference has not been made."""
    path = reference_path(references_dir, scene)
    if not path.exists():
        raise SystemExit(f"bench: no reference {path}; run scripts/bench --make-references "
                         f"--scenes {scene.name}")
    pixels, attributes = common.read_exr(path)
    made = (attributes.get("render:algorithm"), attributes.get("render:iterations"))
    if made != (scene.reference_algo, str(scene.reference_iterations)):
        print(f"bench: warning: {path.name} was made with {made[0]}, {made[1]} iterations; "
              f"the scene table says {scene.reference_algo}, {scene.reference_iterations} "
              f"(run scripts/bench --make-references --scenes {scene.name})", flush=True)
    return common.downscale(pixels, resolution), attributes


# --------------------------------------------------------------------------------------------
# Measuring


@dataclasses.dataclass
class Settings:
    """How the measurements are taken (recorded in the results)."""

    width: int
    threads: Optional[int]
    min_seconds: float
    max_seconds: float
    quick: bool


def measure_point(binary: Path, scene: BenchScene, algo: str, iterations: int,
                  resolution: tuple[int, int], settings: Settings, reference: np.ndarray,
                  workdir: Path) -> dict:
    """One fresh `render` run (seed = iteration count) and its errors against the reference."""
    out = workdir / f"{scene.name}-{algo}-{iterations}.exr"
    algorithm, flags = series_command(algo)
    cmd = common.render_command(binary, scene.path, out, algo=algorithm, iterations=iterations,
                                seed=iterations, resolution=resolution,
                                threads=settings.threads, extra=flags)
    run = common.run_render(cmd)
    image, header = common.read_exr(out)
    out.unlink()
    errors = common.error_metrics(image, reference)
    # The same wall time as the summary line, which rounds it to 0.01 s; the header has 1e-6 s.
    seconds = float(header.get("render:seconds", run.seconds))
    point = {
        "iterations": run.iterations,
        "seed": iterations,
        "seconds": seconds,
        "process_seconds": run.process_seconds,
        "samples_per_second": run.samples_per_second,
        "estimated_relative_error": run.estimated_relative_error,
        "non_finite_dropped": run.non_finite_dropped,
        **errors,
    }
    point["in_fit"] = seconds > 0 and seconds >= 0.5 * settings.min_seconds
    print(f"  {scene.name:12s} {algo:7s} {run.iterations:6d} it {seconds:8.3f} s  "
          f"rmse {errors['rmse']:.4g}  relMSE {errors['relative_mse']:.4g}", flush=True)
    return point


def first_iteration_count(seconds_for_one: float, min_seconds: float) -> int:
    """The power of two whose predicted time is at most min_seconds (at least 2), from the
    time of a 1-iteration run. The first iteration of the merging algorithms is the slowest
    (largest radius), so the prediction errs on the short side."""
    if seconds_for_one <= 0:
        return 2
    return max(2, 2 ** int(math.floor(math.log2(max(1.0, min_seconds / seconds_for_one)))))


def measure_series(binary: Path, scene: BenchScene, algo: str, resolution: tuple[int, int],
                   settings: Settings, reference: np.ndarray, workdir: Path) -> list[dict]:
    """The doubling schedule of one scene and algorithm.

    A 1-iteration run comes first. If it took less than min_seconds, the schedule jumps to the
    power of two predicted to take about min_seconds; from there the iteration count doubles
    while the next run is predicted to take at most OVERSHOOT * max_seconds, and in any case
    until MIN_POINTS points are at least min_seconds / 2 long (so every slope has 3 points).
    """
    points = [measure_point(binary, scene, algo, 1, resolution, settings, reference, workdir)]
    n = 2
    if points[0]["seconds"] < settings.min_seconds:
        n = first_iteration_count(points[0]["seconds"], settings.min_seconds)
    while len(points) < MAX_POINTS:
        last = points[-1]
        predicted = last["seconds"] * n / last["iterations"]
        enough = sum(p["in_fit"] for p in points) >= MIN_POINTS
        if enough and predicted > OVERSHOOT * settings.max_seconds:
            break
        points.append(measure_point(binary, scene, algo, n, resolution, settings, reference,
                                    workdir))
        n *= 2
    return points


def extend_to_overlap(binary: Path, scene: BenchScene, series: dict,
                      resolution: tuple[int, int], settings: Settings, reference: np.ndarray,
                      workdir: Path) -> None:
    """Continues the doubling of every series whose longest run is shorter than the latest
    first point of the scene, so that every pair of algorithms has a common time range to be
    compared in (this only happens when one algorithm's first iteration is very slow, e.g.
    with a small --max-seconds or on a busy machine)."""
    firsts = [fitted(points)[0]["seconds"] for points in series.values() if fitted(points)]
    if not firsts:
        return
    start = max(firsts)
    for algo, points in series.items():
        while len(points) < MAX_POINTS and max(p["seconds"] for p in points) < start:
            n = 2 * max(p["iterations"] for p in points)
            points.append(measure_point(binary, scene, algo, n, resolution, settings,
                                        reference, workdir))


# --------------------------------------------------------------------------------------------
# Analysis


def fitted(points: list[dict]) -> list[dict]:
    """The points used for tables, plots and fits, sorted by time."""
    return sorted((p for p in points if p["in_fit"]), key=lambda p: p["seconds"])


def convergence_slope(points: list[dict]) -> Optional[float]:
    """Least-squares slope of log(relative MSE) against log(time); None with < 2 points."""
    pts = fitted(points)
    if len(pts) < 2:
        return None
    x = np.log([p["seconds"] for p in pts])
    y = np.log([p["relative_mse"] for p in pts])
    if np.ptp(x) == 0:
        return None
    return float(np.polyfit(x, y, 1)[0])


def interpolate_loglog(points: list[dict], seconds: float, key: str) -> Optional[float]:
    """points[key] at `seconds`, linearly interpolated in log-log between the measured points;
    None outside the measured time range (no extrapolation)."""
    pts = fitted(points)
    if not pts:
        return None
    t = np.array([p["seconds"] for p in pts])
    if seconds < t[0] * (1 - 1e-9) or seconds > t[-1] * (1 + 1e-9):
        return None
    v = np.log([p[key] for p in pts])
    return float(np.exp(np.interp(math.log(seconds), np.log(t), v)))


def time_range(points: list[dict]) -> Optional[tuple[float, float]]:
    """(shortest, longest) time of the fitted points."""
    pts = fitted(points)
    return (pts[0]["seconds"], pts[-1]["seconds"]) if pts else None


def reference_noise_estimate(series: dict, scene: BenchScene, reference_attr: dict,
                             width: int) -> Optional[float]:
    """An estimate of the reference's own relative MSE at the measured resolution.

    If the reference algorithm's error is noise decaying like 1/N, a point with n iterations
    and relative MSE m gives m * n / N_ref (N_ref = reference iterations, times the number of
    reference pixels averaged into one measured pixel). The smallest such value over the
    reference algorithm's points is used (bias or the reference's own noise only make m
    larger, so this errs high)."""
    points = fitted(series.get(scene.reference_algo, []))
    if not points:
        return None
    ref_iterations = int(reference_attr.get("render:iterations", scene.reference_iterations))
    pixels_averaged = (REFERENCE_WIDTH / width) ** 2
    return min(p["relative_mse"] * p["iterations"] for p in points) / (
        ref_iterations * pixels_averaged)


def compare_at_equal_time(series: dict, a: str, b: str) -> dict:
    """relative MSE of algorithm a over algorithm b at up to three times spread over the
    common time range (log-log interpolation)."""
    ra, rb = time_range(series.get(a, [])), time_range(series.get(b, []))
    if not ra or not rb or max(ra[0], rb[0]) > min(ra[1], rb[1]):
        return {"times": [], "ratios": []}
    lo, hi = max(ra[0], rb[0]), min(ra[1], rb[1])
    times = sorted({lo, math.sqrt(lo * hi), hi})
    ratios = [interpolate_loglog(series[a], t, "relative_mse")
              / interpolate_loglog(series[b], t, "relative_mse") for t in times]
    return {"times": times, "ratios": ratios}


def check_claim(series: dict, slopes: dict) -> dict:
    """Checks the thesis's claim on one scene from the measurements:
    (1) VCM has a lower relative MSE than BPT and PPM at equal time, and
    (2) VCM's MSE falls faster than PPM's (a more negative slope; expected -1 vs -2/3).
    Returns the comparisons and a verdict: "held", "did not hold", "partly held" or
    "not checked"."""
    result = {"equal_time": {}, "slopes": {}, "parts": []}
    if "vcm" not in series:
        result["verdict"] = "not checked"
        result["reason"] = "VCM was not run"
        return result
    for other in ("bpt", "ppm"):
        if other not in series:
            continue
        cmp = compare_at_equal_time(series, "vcm", other)
        result["equal_time"][other] = cmp
        if cmp["ratios"]:
            lower = [r < 1 for r in cmp["ratios"]]
            result["parts"].append(all(lower) if all(lower) or not any(lower) else None)
    if "ppm" in series and slopes.get("vcm") is not None and slopes.get("ppm") is not None:
        result["slopes"] = {"vcm": slopes["vcm"], "ppm": slopes["ppm"]}
        result["parts"].append(slopes["vcm"] < slopes["ppm"])
    else:
        result["notes"] = ["slopes not compared: PPM not run or fewer than 2 points"]
    parts = result["parts"]
    if not parts:
        result["verdict"] = "not checked"
        result["reason"] = "no algorithm to compare with over a common time range"
    elif all(p is True for p in parts):
        result["verdict"] = "held"
    elif all(p is False for p in parts):
        result["verdict"] = "did not hold"
    else:
        result["verdict"] = "partly held"
    return result


# --------------------------------------------------------------------------------------------
# Output

ALGO_STYLE = {"pt": ("tab:blue", "o"), "volpt": ("tab:cyan", "P"), "lt": ("tab:orange", "v"),
              "bpt": ("tab:green", "s"), "ppm": ("tab:red", "^"), "bpm": ("tab:purple", "D"),
              "vcm": ("black", "*"), "vpl": ("tab:brown", "X"), "vpl+div": ("tab:olive", "h"),
              "ic": ("tab:pink", "p")}


def plot_scene(path: Path, scene: BenchScene, series: dict, slopes: dict,
               reference_noise: Optional[float]) -> None:
    """The log-log plot of relative MSE against time of one scene."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.6), dpi=100)
    for algo in ALL_ALGOS:
        pts = fitted(series.get(algo, []))
        if not pts:
            continue
        color, marker = ALGO_STYLE.get(algo, ("tab:gray", "."))  # a new row: any style
        slope = slopes.get(algo)
        label = algo + (f" (slope {slope:.2f})" if slope is not None else "")
        ax.loglog([p["seconds"] for p in pts], [p["relative_mse"] for p in pts],
                  color=color, marker=marker, label=label)
    if reference_noise:
        ax.axhline(reference_noise, color="grey", linestyle="--", linewidth=1,
                   label="reference noise (est.)")
    ax.set_xlabel("wall time [s]")
    ax.set_ylabel("relative MSE")
    ax.set_title(f"{scene.name}: relative MSE vs time")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)


def format_number(value: Optional[float], digits: int = 3) -> str:
    """A number with `digits` significant digits, '–' for None."""
    return "–" if value is None else f"{value:.{digits}g}"


def format_slope(value: Optional[float]) -> str:
    """A slope with two decimals, '–' for None."""
    return "–" if value is None else f"{value:.2f}"


def equal_time_table(series: dict, algos: list[str], max_seconds: float) -> list[str]:
    """Markdown rows: RMSE per algorithm at power-of-two times (log-log interpolation)."""
    ranges = [time_range(series[a]) for a in algos if time_range(series.get(a, []))]
    if not ranges:
        return ["(no measurements)"]
    lo, hi = min(r[0] for r in ranges), max(r[1] for r in ranges)
    times = []
    t = 2.0 ** math.floor(math.log2(lo))
    while t <= hi * (1 + 1e-9):
        if t >= lo * (1 - 1e-9):
            times.append(t)
        t *= 2
    if not times:
        times = [lo]
    lines = ["| time | " + " | ".join(algos) + " |", "| --- |" + " --- |" * len(algos)]
    for t in times:
        cells = []
        rmse = {a: interpolate_loglog(series.get(a, []), t, "rmse") for a in algos}
        best = min((v for v in rmse.values() if v is not None), default=None)
        for a in algos:
            cell = format_number(rmse[a])
            cells.append(f"**{cell}**" if rmse[a] is not None and rmse[a] == best else cell)
        lines.append(f"| {t:.3g} s | " + " | ".join(cells) + " |")
    return lines


def raw_table(series: dict, algos: list[str]) -> list[str]:
    """Markdown rows of every measured point."""
    lines = ["| algo | iterations | seed | seconds | RMSE | relative MSE | est. rel. error "
             "(render) | used |", "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for a in algos:
        for p in series.get(a, []):
            lines.append(f"| {a} | {p['iterations']} | {p['seed']} | {p['seconds']:.3g} | "
                         f"{p['rmse']:.4g} | {p['relative_mse']:.4g} | "
                         f"{p['estimated_relative_error']:.3g} | "
                         f"{'yes' if p['in_fit'] else 'no (< min time)'} |")
    return lines


def claim_lines(claim: dict) -> list[str]:
    """The verdict of check_claim() in words, with the numbers it rests on."""
    lines = [f"**Claim {claim['verdict']}.**" + (f" ({claim['reason']})" if "reason" in claim
                                                  else "")]
    lines += [f"- Not checked: {note}." for note in claim.get("notes", [])]
    for other, cmp in claim["equal_time"].items():
        if not cmp["ratios"]:
            lines.append(f"- VCM vs {other.upper()} at equal time: no common time range.")
            continue
        pairs = ", ".join(f"{t:.3g} s: {r:.3g}" for t, r in zip(cmp["times"], cmp["ratios"]))
        n_lower = sum(r < 1 for r in cmp["ratios"])
        word = ("lower at every compared time" if n_lower == len(cmp["ratios"]) else
                "higher at every compared time" if n_lower == 0 else
                f"lower at {n_lower} of {len(cmp['ratios'])} compared times")
        lines.append(f"- VCM vs {other.upper()} at equal time: VCM's relative MSE is {word} "
                     f"(VCM / {other.upper()}: {pairs}).")
    if claim["slopes"]:
        v, p = claim["slopes"]["vcm"], claim["slopes"]["ppm"]
        lines.append(f"- Slopes: VCM {v:.2f} (claim ≈ −1), PPM {p:.2f} (claim ≈ −2/3; between "
                     f"−0.75 and −0.5 with α = 0.75): VCM's MSE "
                     f"{'falls faster' if v < p else 'does not fall faster'} than PPM's.")
    return lines


def machine_lines(machine: dict, settings: Settings, command: str, build_dir: Path,
                  load_after) -> list[str]:
    """The 'how this was measured' paragraph."""
    load = machine.get("load_average")
    load_text = (f"{load[0]:.2f} before, {load_after[0]:.2f} after (1-minute)"
                 if load and load_after else "unknown")
    return [
        f"- Command: `{command}` (from the repository root; `render` from "
        f"`{common.display_path(build_dir)}/bin/render`).",
        f"- Machine: {machine['cpu_model']}, {machine['cores']} cores"
        + (f", {machine['memory_gib']:.1f} GiB" if machine.get("memory_gib") else "")
        + f", {machine['kernel']}; load average {load_text}.",
        f"- Date: {machine['date_utc']}; source revision {machine['source_revision']}.",
        f"- Settings: {settings.width} px wide (height by aspect ratio), "
        f"{settings.threads} threads, points from {settings.min_seconds:g} s to "
        f"{settings.max_seconds:g} s" + (" (quick mode)." if settings.quick else "."),
    ]


def write_document(path: Path, results: dict) -> None:
    """docs/results/speed-vs-error.md from the results (everything in it is derived from them)."""
    settings = Settings(**results["settings"])
    scenes = {s.name: s for s in SCENES}
    lines = [
        "# Speed against error: convergence of the algorithms",
        "",
        "Generated by `scripts/bench` (`scripts/benchlib/convergence.py`); do not edit by hand.",
        "The numbers are in [img/speed-vs-error/results.json](../img/speed-vs-error/results.json).",
        "",
        *machine_lines(results["machine"], settings, results["command"],
                       Path(results["build_dir"]), results.get("load_average_after")),
        "",
        "## Method",
        "",
        "- Every scene × algorithm is rendered with a doubling schedule of iteration counts "
        "(1, then the power of two predicted to take about the minimum time, then doubling "
        "while the next run is predicted to fit in "
        f"{OVERSHOOT:g} × the maximum time, for at least {MIN_POINTS} points; a series that "
        "ends before another algorithm's first point is continued until they overlap). Each "
        "point is a fresh `render` run whose seed is its iteration count, so no point reuses "
        "another's samples. Points shorter than half the minimum time are measured but "
        "neither shown nor fitted. The time is the wall time "
        "`render` prints on its last line (rendering only, scene loading and image output "
        "excluded), read at full precision from the EXR header's `render:seconds` (the last "
        "line rounds it to 0.01 s).",
        "- Errors are against the scene's reference ([references/README.md]"
        "(../references/README.md)), box-downscaled when the measurement is smaller:",
        "  - RMSE = sqrt(mean over pixels and channels of (x − r)²);",
        f"  - relative MSE = mean over pixels and channels of (x − r)² / (r² + "
        f"{common.RELATIVE_MSE_EPSILON:g}) (as `render --compare`). It is heavy-tailed: one "
        "firefly in a dark pixel (e.g. a merge of an isolated caustic photon) can carry most "
        "of an image's relative MSE, so single points can jump up; the fitted slopes average "
        "over that.",
        "- Slope: least-squares fit of log(relative MSE) against log(time) over the points "
        "shown. An unbiased algorithm has −1 while its error is noise. For PPM and BPM with "
        "radius reduction α = 0.75 the variance falls like N^−0.75 and the squared bias like "
        "N^−0.5, so their slope goes from about −0.75 (noise-dominated) toward −0.5 "
        "(bias-dominated); −2/3, the thesis's figure, is the best possible rate (α = 2/3). "
        "Every curve flattens when it reaches the reference's own noise.",
        "- Equal-time comparisons interpolate linearly in log-log between measured points "
        "(never extrapolating), at the start, the geometric middle and the end of the common "
        "time range.",
        "- The reference noise (dashed line) is estimated from the reference algorithm's own "
        "points, assuming its error is noise decaying like 1/N: min(relative MSE × N) / N_ref. "
        "Measured errors near it are limited by the reference, not by the algorithm.",
        "- The references of the SmallVCM boxes are VCM renders (independent seed). Their "
        "merging bias is that of a much smaller radius than any measured VCM run's, but they "
        "slightly favour VCM-like images.",
        "",
        "## Scenes",
        "",
        "| scene | short name | reference | algorithms run | not run | "
        "S–D–S paths |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for name, r in results["scenes"].items():
        s = scenes[name]
        lines.append(f"| `{s.path}` | {name} | {s.reference_algo}, {r['reference']['iterations']}"
                     f" it | {', '.join(r['algos'])} | {', '.join(s.skipped) or '–'} | "
                     f"{'yes' if s.sds else 'no'} |")
    lines += ["", "Why the other combinations are not run (docs/reference/algorithms.md, docs/design/media.md):", ""]
    for name, r in results["scenes"].items():
        for algo, reason in scenes[name].skipped.items():
            lines.append(f"- {name}, {algo}: {reason}.")
    claims = {n: r["claim"] for n, r in results["scenes"].items() if "claim" in r}
    if claims:
        lines += ["", "## The VCM claim", "",
                  "Claim (thesis): on scenes with specular–diffuse–specular paths VCM reaches a "
                  "lower error than BPT and PPM at equal time, and its MSE falls faster than "
                  "PPM's (slope ≈ −1 vs ≈ −2/3). Verdicts from the measurements below:", "",
                  "| scene | verdict | VCM slope | PPM slope | VCM/BPT relMSE at equal time | "
                  "VCM/PPM relMSE at equal time |",
                  "| --- | --- | --- | --- | --- | --- |"]
        for name, c in claims.items():
            def ratios(other):
                cmp = c["equal_time"].get(other)
                if cmp is None:
                    return ("cannot converge, not run" if other in scenes[name].skipped
                            else "not run")
                return ", ".join(f"{r:.2g}" for r in cmp["ratios"]) or "no common range"
            slopes = results["scenes"][name]["slopes"]
            lines.append(f"| {name} | {c['verdict']} | {format_slope(slopes.get('vcm'))} | "
                         f"{format_slope(slopes.get('ppm'))} | {ratios('bpt')} | "
                         f"{ratios('ppm')} |")
        lines += ["", "Ratios below 1 mean VCM has the lower relative MSE; they are taken at the "
                  "start, middle and end of the common time range. Where BPT cannot converge "
                  "it is not run (reasons above), and the equal-time part is checked against "
                  "PPM only. \"held\" means every checked part held, \"did not hold\" that "
                  "none did."]
    for name, r in results["scenes"].items():
        s = scenes[name]
        algos = r["algos"]
        ref = r["reference"]
        lines += ["", f"## {name}", "", f"`{s.path}`: {s.description}.", "",
                  f"Reference: {ref['algorithm']}, {ref['iterations']} iterations, "
                  f"`render`'s estimated relative error "
                  f"{format_number(float(ref['estimated_relative_error'] or 'nan'))}; "
                  f"estimated reference relative MSE at this resolution "
                  f"{format_number(r['reference_noise'])}.", "",
                  f"![{name}](../img/speed-vs-error/{name}.png)", "",
                  "RMSE at equal time (bold: lowest):", "",
                  *equal_time_table(r["series"], algos, settings.max_seconds), "",
                  "Fitted slope of log relative MSE against log time: "
                  + ", ".join(f"{a} {format_slope(r['slopes'].get(a))}" for a in algos)
                  + "."]
        if "claim" in r:
            lines += ["", *claim_lines(r["claim"])]
        lines += many_light_lines(r["series"])
        measured = r.get("measured")
        if measured and measured.get("source_revision") != results["machine"].get(
                "source_revision"):
            lines += ["", f"Measured in an earlier run ({measured.get('date_utc')}, source "
                      f"revision {measured.get('source_revision')}, `{measured.get('command')}`)"
                      "; the run named at the top did not re-measure this scene."]
        lines += ["", "<details><summary>All measured points</summary>", "",
                  *raw_table(r["series"], algos), "", "</details>"]
    # The page is generated from its template and a data file holding these lines
    # (docs/guide/results.md); path is DOCS/results/speed-vs-error.md.
    load = results["machine"].get("load_average")
    pages.publish_blocks(Path(path).parent.parent, "speed-vs-error", lines, results["command"],
                         load_before=pages.load_text(load))


def many_light_lines(series: dict) -> list[str]:
    """Equal-time ratios of the importance-driven VPLs and of importance caching against the
    other series of a scene."""
    lines = []
    for name in ("vpl+div", "ic"):
        parts = []
        for other in ("vpl", "pt", "bpt"):
            cmp = (compare_at_equal_time(series, name, other)
                   if name in series and other in series else None)
            if cmp and cmp["ratios"]:
                parts.append(f"{other} " + ", ".join(f"{r:.2g}" for r in cmp["ratios"]))
        if parts:
            lines += ["", f"Many-light rendering: relMSE({name}) / relMSE(X) at the start, "
                      f"middle and end of the common time range (below 1: {name} is ahead): "
                      + "; ".join(parts) + "."]
    return lines


def previous_scene_results(img_dir: Path, measured_now: list[str]) -> dict:
    """The scene entries of the last full run's results.json that this run does not measure
    (a run of some scenes keeps the others' results, each with when and how it was measured)."""
    path = img_dir / "results.json"
    if not path.exists():
        return {}
    previous = json.loads(path.read_text())
    known = {s.name for s in SCENES}
    kept = {}
    for name, entry in previous.get("scenes", {}).items():
        if name in measured_now or name not in known:
            continue
        entry.setdefault("measured", {
            "date_utc": previous["machine"].get("date_utc"),
            "source_revision": previous["machine"].get("source_revision"),
            "command": previous.get("command")})
        kept[name] = entry
    return kept


def assert_finite(results: dict) -> None:
    """Fails loudly if a measurement is not a finite positive number (the smoke test's check,
    also applied to every run)."""
    for name, r in results["scenes"].items():
        for algo, points in r["series"].items():
            for p in points:
                for key in ("seconds", "rmse", "relative_mse"):
                    if not (math.isfinite(p[key]) and p[key] > 0):
                        raise RuntimeError(f"{name} {algo}: {key} = {p[key]}")


# --------------------------------------------------------------------------------------------
# Entry point


def run(*, build_dir: Path, docs_dir: Path, references_dir: Path, scenes: list[BenchScene],
        algos: Optional[list[str]], quick: bool, threads: Optional[int],
        max_seconds: Optional[float], min_seconds: Optional[float], command: str) -> dict:
    """Measures every selected scene and algorithm and writes the document, the plots and
    results.json under docs_dir. Returns the results."""
    binary = common.render_binary(build_dir)
    settings = Settings(
        width=QUICK_WIDTH if quick else REFERENCE_WIDTH, threads=threads, quick=quick,
        min_seconds=(min_seconds if min_seconds is not None else
                     QUICK_MIN_SECONDS if quick else DEFAULT_MIN_SECONDS),
        max_seconds=(max_seconds if max_seconds is not None else
                     QUICK_MAX_SECONDS if quick else DEFAULT_MAX_SECONDS))
    ALL_ALGOS[:] = series_from_table(common.benchmarked_algorithms(build_dir, "convergence"))
    if algos:
        unknown = set(algos) - set(ALL_ALGOS)
        if unknown:
            raise SystemExit(f"bench: unknown algorithm(s) {sorted(unknown)}")
    img_dir = docs_dir / "img" / "speed-vs-error"
    img_dir.mkdir(parents=True, exist_ok=True)
    results = {"command": command, "build_dir": str(build_dir), "machine": common.machine_info(),
               "settings": dataclasses.asdict(settings), "scenes": {}}
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="bench-convergence-") as tmp:
        for scene in scenes:
            resolution = common.resolution_for_width(common.REPO_ROOT / scene.path,
                                                     settings.width)
            reference, ref_attr = load_reference(references_dir, scene, resolution)
            run_algos = [a for a in scene.algos if not algos or a in algos]
            print(f"bench: {scene.name} at {resolution[0]}x{resolution[1]}: "
                  f"{', '.join(run_algos)}", flush=True)
            series = {a: measure_series(binary, scene, a, resolution, settings, reference,
                                        Path(tmp)) for a in run_algos}
            extend_to_overlap(binary, scene, series, resolution, settings, reference, Path(tmp))
            slopes = {a: convergence_slope(series[a]) for a in run_algos}
            noise = reference_noise_estimate(series, scene, ref_attr, settings.width)
            entry = {
                "path": scene.path, "algos": run_algos, "resolution": list(resolution),
                "reference": {
                    "file": common.display_path(reference_path(references_dir, scene)),
                    "algorithm": ref_attr.get("render:algorithm"),
                    "iterations": int(ref_attr.get("render:iterations", 0)),
                    "estimated_relative_error": ref_attr.get("render:relative_error_estimate"),
                    "command": ref_attr.get("render:command"),
                },
                "reference_noise": noise, "series": series, "slopes": slopes,
                "skipped": scene.skipped,
                "measured": {"date_utc": results["machine"].get("date_utc"),
                             "source_revision": results["machine"].get("source_revision"),
                             "command": command},
            }
            if scene.sds:
                entry["claim"] = check_claim(series, slopes)
            results["scenes"][scene.name] = entry
            plot_scene(img_dir / f"{scene.name}.png", scene, series, slopes, noise)
    results["load_average_after"] = common.load_average()
    results["total_seconds"] = time.monotonic() - started
    if not quick and len(scenes) < len(SCENES):
        results["scenes"].update(previous_scene_results(img_dir, [s.name for s in scenes]))
        order = [s.name for s in SCENES]
        results["scenes"] = dict(sorted(results["scenes"].items(),
                                        key=lambda item: order.index(item[0])))
    assert_finite(results)
    (img_dir / "results.json").write_text(json.dumps(results, indent=1))
    doc = common.results_page(docs_dir, "speed-vs-error.md")
    doc.parent.mkdir(parents=True, exist_ok=True)
    write_document(doc, results)
    print(f"bench: wrote {doc}, {img_dir}/*.png, results.json "
          f"({results['total_seconds']:.0f} s)")
    return results
