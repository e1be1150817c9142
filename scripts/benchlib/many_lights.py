"""Many-light rendering: uniform against importance-driven VPLs at equal time
(`scripts/bench --only many-lights`, writes docs/many-lights.md).

Both arms are the same estimator in expectation (`vpl` with the same fixed clamp, d_min = 1 % of
the scene radius, so the variance is finite), so the reference is one long run of that
estimator: the uniform arm (no 1/P_k weights, so no rare heavy VPL in the reference itself),
with a seed no measurement uses; its own noise is stated next to the errors. Each measurement is a fresh `render
--time T` with its own seed, three per point; the error is the relative MSE against the
reference (the definition of docs/speed-vs-error.md), averaged over the three runs (the range
is shown too). Scenes: two-rooms (the light in the next room, the case
the importance-driven distribution was made for) and the Cornell box (every VPL matters: the
control).
"""

import math
import subprocess
import tempfile
from pathlib import Path

from . import common

CLAMP = ["--vpl-clamp", "0.01", "--vpl-clamp-schedule", "fixed"]
ARMS = {
    "uniform": CLAMP,
    "importance": CLAMP + ["--vpl-distribution", "importance"],
}
SCENES = {
    "two-rooms": common.REPO_ROOT / "scenes" / "tests" / "two-rooms.xml",
    "cornell-box": common.REPO_ROOT / "scenes" / "bitterli" / "cornell-box" / "scene_v3.xml",
}
WIDTH = 128
TIMES = (2.0, 4.0, 8.0)
QUICK_TIMES = (0.3,)
SEEDS = 3  # runs per point: single runs of VPL images have heavy-tailed errors
REFERENCE_SECONDS = 240.0
QUICK_REFERENCE_SECONDS = 2.0


def acceptance(stdout: str):
    """The acceptance percentage render prints for importance-driven VPLs, or None."""
    for line in stdout.splitlines():
        if line.startswith("VPLs:") and "accepted" in line:
            return float(line.split(",")[1].split("%")[0])
    return None


def render(binary, scene, out, arm, seconds, seed, resolution, threads):
    cmd = common.render_command(binary, scene, out, algo="vpl", seconds=seconds, seed=seed,
                                resolution=resolution, threads=threads, extra=ARMS[arm])
    proc = subprocess.run(cmd, cwd=common.REPO_ROOT, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"render failed: {' '.join(cmd)}\n{proc.stderr[-2000:]}")
    image, header = common.read_exr(out)
    return image, header, acceptance(proc.stdout), cmd


def run(build_dir: Path, docs_dir: Path, quick: bool = False, threads=None):
    binary = common.render_binary(build_dir)
    workdir = Path(tempfile.mkdtemp(prefix="bench-many-lights-"))
    times = QUICK_TIMES if quick else TIMES
    lines = ["# Many-light rendering: uniform against importance-driven VPLs", "",
             "Written by `scripts/bench --only many-lights` (scripts/benchlib/many_lights.py).",
             "", __doc__.strip(), ""]
    machine = common.machine_info()
    lines += [f"Machine: {machine.get('cpu_model')}, {machine.get('cores')} cores, "
              f"{machine.get('date_utc')}; revision {machine.get('source_revision', '?')}.", ""]
    for name, scene in SCENES.items():
        resolution = common.resolution_for_width(scene, WIDTH)
        ref_path = workdir / f"{name}-reference.exr"
        reference, ref_header, _, ref_cmd = render(
            binary, scene, ref_path, "uniform",
            QUICK_REFERENCE_SECONDS if quick else REFERENCE_SECONDS, 1_000_000, resolution,
            threads)
        lines += [f"## {name} ({resolution[0]}x{resolution[1]})", "",
                  f"Reference: `{' '.join(ref_cmd)}` — {ref_header.get('render:iterations')} "
                  f"iterations, its own estimated relative error "
                  f"{float(ref_header.get('render:relative_error_estimate', 'nan')):.4f}.", "",
                  "| arm | seconds | iterations (per run) | VPLs kept | relative MSE, mean "
                  "(min–max) |",
                  "| --- | --- | --- | --- | --- |"]
        results = {}
        for t in times:
            for arm in ARMS:
                errors, iterations, kept = [], [], []
                for run_index in range(1 if quick else SEEDS):
                    out = workdir / f"{name}-{arm}-{t:g}-{run_index}.exr"
                    image, header, accepted, _ = render(binary, scene, out, arm, t,
                                                        int(t * 1000) + run_index, resolution,
                                                        threads)
                    errors.append(common.error_metrics(image, reference)["relative_mse"])
                    iterations.append(header["render:iterations"])
                    kept.append(accepted if accepted is not None else 100.0)
                mean = sum(errors) / len(errors)
                results[(arm, t)] = mean
                lines.append(f"| {arm} | {t:g} | {', '.join(iterations)} | "
                             f"{sum(kept) / len(kept):.1f} % | {mean:.4g} "
                             f"({min(errors):.3g}–{max(errors):.3g}) |")
                print(f"  {name:12s} {arm:10s} {t:5.1f} s  relMSE {mean:.4g} "
                      f"({min(errors):.3g}-{max(errors):.3g})  kept {kept[-1]:.1f} %",
                      flush=True)
        ratios = [results[("uniform", t)] / results[("importance", t)] for t in times
                  if results[("importance", t)] > 0]
        if ratios:
            lines += ["", f"Mean relMSE(uniform) / mean relMSE(importance) at equal time: "
                      + ", ".join(f"{r:.2f}" for r in ratios)
                      + f" (geometric mean {math.exp(sum(map(math.log, ratios)) / len(ratios)):.2f}).",
                      ""]
    docs_dir.mkdir(parents=True, exist_ok=True)
    out_doc = docs_dir / "many-lights.md"
    out_doc.write_text("\n".join(lines) + "\n")
    print(f"bench: wrote {out_doc}")
