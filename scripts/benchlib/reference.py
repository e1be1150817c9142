"""Ours against the VCM reference implementation (SmallVCM) on its four Cornell boxes, per unit
of error: efficiency = 1 / (relative MSE x seconds), the same number of independent runs of each
program, against the converged images in docs/references/ (the target: ours / reference >= 2.0
at 2 standard errors; time per iteration <= 0.6x and peak memory <= 1.2x the reference's as
secondary figures; docs/design/smallvcm-comparison.md).

The project never downloads or builds the reference: `scripts/bench --reference-smallvcm PATH`
takes a binary built by hand (docs/design/smallvcm-comparison.md, "How the reference binary is
built"). Its command line is `-s SCENE -a ALGO -i ITERATIONS -o FILE -seed SEED`: resolution
(512 x 512), path length (10 segments) and merging radius (0.003 x the scene's bounding-sphere
radius, alpha 0.75) are fixed in its config.hxx; the seed option is the local build's (SmallVCM's
driver fixes its base seed, so without it every run would repeat one image). Its thread count
is omp_get_num_procs(), the CPUs in the process's affinity mask (OMP_NUM_THREADS is overridden
by its omp_set_num_threads), so a run's thread count is set by pinning. Without the option the
section says "not run".

Two timings (`--reference-timing`):

- cpu (the default): single-threaded runs, CPU seconds (user + system of the child, wait4).
  Ours runs with `--threads 1`, the reference pinned to one CPU (and OMP_NUM_THREADS=1), so
  each uses one thread. CPU time is what a quiet machine's wall time would be, and other load
  disturbs it far less than wall time: on the shared 2-core machine this is the measure that
  can be repeated. The two programs of a round run at the same time, each pinned to its own
  CPU, and swap CPUs every round (with one CPU they run one after the other). Time per
  iteration: (CPU seconds of the run - the mean of two one-iteration runs, one on either CPU)
  / (iterations - 1), the start-up (scene loading, acceleration structure, plug-ins) taken
  out.
- wall: whole-process wall seconds of 2-thread runs, both programs pinned to the same 2 CPUs,
  one after the other; meaningful only on a quiet machine.

Symmetric by construction: run r of each program uses seed r, and every image, ours or the
reference's, is box-averaged 2 x 2 down to 256 x 256 (both programs use a box pixel filter, so
the average has the coarse pixel's expectation) and compared with the box's converged image in
docs/references/ (ours, vcm, 256-1024 iterations at 256 x 256, made once by `scripts/bench
--make-references`) by the same relative MSE. Each side's efficiency is 1 / (mean relative MSE x
mean seconds) over its runs (whole process); the ratio's standard error is the jackknife's over
the rounds (leave one round, both programs' runs of it, out), which also carries the
correlation of a run's error and time and the load shared by a round's two runs. The images'
means against the converged image's, per side, check that the two programs render the same
thing. `scripts/bench --only reference` writes the run to docs/data/performance/reference.json with the commit,
the machine and the load. SmallVCM writes its image as PFM (the local driver's `.pfm` output:
raw little-endian float RGB, top row first). The timing needs only the standard library; the
error needs numpy and OpenImageIO (scripts/setup installs them).
"""

import json
import math
import os
import statistics
import subprocess
import threading
import tempfile
import time
from pathlib import Path

from benchlib import handwritten

# Our scene file for each of SmallVCM's scene ids (its g_SceneConfigs, in order;
# scenes/smallvcm/README.md): 0 glossy floor + small mirror and glass spheres + sun,
# 1 glossy floor + large mirror sphere + light-box area light, 2 small spheres + point light,
# 3 small spheres + constant background.
SCENE_IDS = {"0-gbs_s": 0, "1-glm_c": 1, "2-gbs_p": 2, "3-gbs_b": 3}
ALGORITHMS = ["vcm", "bpt"]
# Iterations of 512^2 paths per run. Wall timing: SmallVCM splits -i over its threads (2 x 8).
# CPU timing: one thread; 4 iterations x 4 runs keep the four boxes and two algorithms near
# 250 CPU seconds on each of the 2 CPUs (the reference costs up to ~3 s a vcm iteration), which
# a loaded machine gives in well under an hour.
ITERATIONS = {"cpu": 4, "wall": 16}
RUNS = 4  # independent runs of each program (seeds 0 .. RUNS - 1)
TIMINGS = ("cpu", "wall")
# What `scripts/bench --only reference` measures when run() is not told otherwise
# (scripts/bench sets these from --reference-timing, --reference-runs, --reference-iterations).
DEFAULTS = {"timing": "cpu", "runs": None, "iterations": None}
# Seed of the one-iteration runs that measure each program's start-up (CPU timing).
FIXED_COST_SEED = 1000
# The seed option of the reference build (not in SmallVCM's own driver, whose base seed is fixed
# in config.hxx: the local build adds it; performance-notes.md, "How the reference binary was
# built"). Without it the reference's runs would repeat one image, which run() refuses.
REFERENCE_SEED_FLAG = "-seed"
# Our merging algorithms default to a radius of one pixel footprint; SmallVCM fixes 0.003 x the
# scene radius, which the comparison passes to ours.
MERGING_ALGORITHMS = ("vcm", "ppm", "bpm")
THREADS = 2  # wall timing; CPU timing runs one thread per program
# The converged image of each box (docs/references/README.md): name of its EXR.
REFERENCE_IMAGES = {"0-gbs_s": "gbs_s", "1-glm_c": "glm_c", "2-gbs_p": "gbs_p", "3-gbs_b": "gbs_b"}


def pinned_cpus():
    """The first THREADS CPUs this process may run on: both arms are pinned to them, so that
    SmallVCM's omp_get_num_procs() sees exactly THREADS and ours cannot use more."""
    cpus = sorted(os.sched_getaffinity(0))
    if len(cpus) < THREADS:
        raise RuntimeError(f"reference comparison needs {THREADS} CPUs, this process has "
                           f"{len(cpus)}")
    return set(cpus[:THREADS])


# GNU time, through which each program is started so that its peak RSS is its own: a child
# forked from this (Python) process inherits the fork's high-water mark across exec (Linux keeps
# it in the signal struct, which exec does not reset), so wait4's ru_maxrss of a child started
# directly is at least the benchmark's own peak (which grows with the images it holds): `true`
# reported 413 MiB under a 400 MiB parent. GNU time is itself such a child, but the program is
# forked from it (~1 MiB), and it reports the program's own ru_maxrss.
PEAK_RSS_TOOL = "/usr/bin/time"


def peak_rss_tool():
    """The GNU time binary if it is there (None: peak memory is not measured)."""
    return PEAK_RSS_TOOL if os.access(PEAK_RSS_TOOL, os.X_OK) else None


def timed(cmd, cpus, env=None):
    """Runs cmd pinned to cpus; returns (wall s, peak RSS MiB of cmd itself, user+system CPU s).
    CPU seconds are wait4's of the child (GNU time's own ~1 ms included); the peak RSS is GNU
    time's report of cmd (nan without GNU time)."""
    tool = peak_rss_tool()
    with tempfile.NamedTemporaryFile("r", suffix=".rss") as rss:
        full = [tool, "-f", "%M", "-o", rss.name, *map(str, cmd)] if tool else cmd
        start = time.monotonic()
        process = subprocess.Popen(full, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                   env=env, preexec_fn=lambda: os.sched_setaffinity(0, cpus))
        _, status, usage = os.wait4(process.pid, 0)
        wall = time.monotonic() - start
        stderr = process.stderr.read().decode(errors="replace")
        process.stderr.close()
        code = os.waitstatus_to_exitcode(status)
        if code != 0:
            raise RuntimeError(f"{' '.join(map(str, cmd))} exited {code}: {stderr.strip()[-500:]}")
        # GNU time's %M is in KiB; its last line (it may note a signal on the lines before).
        lines = rss.read().split()
        peak_mib = float(lines[-1]) / 1024.0 if tool and lines else math.nan
    return wall, peak_mib, usage.ru_utime + usage.ru_stime


def timed_together(jobs, log=print):
    """Runs jobs [(cmd, cpus, env), ...] at the same time, each pinned to its CPUs; returns their
    timed() results in order. CPU seconds are per child (wait4), so running them together does
    not mix their times."""
    results, errors = [None] * len(jobs), []

    def one(i, cmd, cpus, env):
        try:
            results[i] = timed(cmd, cpus, env)
        except Exception as e:  # re-raised below, in this thread
            errors.append(e)

    threads = [threading.Thread(target=one, args=(i, *job)) for i, job in enumerate(jobs)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    if errors:
        raise errors[0]
    return results


def read_pfm(path):
    """A colour PFM as a float64 array of shape H x W x 3, top row first. SmallVCM's SavePFM
    writes its framebuffer's rows in memory order, top row first (its BMP writer flips them for
    BMP's bottom-up order), under a negative (little-endian) scale."""
    import numpy as np

    data = Path(path).read_bytes()
    fields, offset = [], 0
    while len(fields) < 4:  # "PF", width, height, scale, separated by whitespace
        while data[offset:offset + 1].isspace():
            offset += 1
        end = offset
        while not data[end:end + 1].isspace():
            end += 1
        fields.append(data[offset:end].decode())
        offset = end
    offset += 1  # the single whitespace character before the raster
    if fields[0] != "PF":
        raise ValueError(f"{path}: not a colour PFM (magic {fields[0]!r})")
    width, height, scale = int(fields[1]), int(fields[2]), float(fields[3])
    pixels = np.frombuffer(data, dtype="<f4" if scale < 0 else ">f4", count=width * height * 3,
                           offset=offset)
    return pixels.astype(np.float64).reshape(height, width, 3)


def read_ours_image(path):
    """Our image of a run (an EXR; the tests replace this reader)."""
    from benchlib import common

    return common.read_exr(path)[0]


def converged_image(scene):
    """The box's converged image (256 x 256) and an estimate of its own relative MSE (the
    converged image's noise, in every run's error alike): (relative error estimate)^2 times the
    image's mean of r^2 / (r^2 + 0.01), from the render:relative_error_estimate its header
    records (half the RMS difference of its odd and even iterations' means over the RMS of the
    mean)."""
    from benchlib import common

    path = Path(__file__).resolve().parents[2] / "docs" / "references" / (
        REFERENCE_IMAGES[scene] + ".exr")
    pixels, attributes = common.read_exr(path)
    relative = float(attributes.get("render:relative_error_estimate", "nan"))
    squared = pixels * pixels
    own = relative * relative * float(
        (squared / (squared + common.RELATIVE_MSE_EPSILON)).mean())
    return pixels, own


def image_error(image, converged):
    """The error of `image` (box-averaged down to the converged image's size) against the
    converged image: its MSE and relative MSE over pixels and channels (common.error_metrics:
    (x - r)^2 / (r^2 + 0.01), as `render --compare`) and the ratio of the images' means (a bias
    indicator)."""
    from benchlib import common

    height, width = converged.shape[:2]
    small = common.downscale(image, (width, height))
    diff = small - converged
    metrics = common.error_metrics(small, converged)
    return {"mse": float((diff * diff).mean()), "relative_mse": metrics["relative_mse"],
            "mean_ratio": float(small.mean() / converged.mean())}


def loadavg():
    with open("/proc/loadavg") as f:
        return f.read().split()[:3]


def mean_and_se(values):
    """The mean of independent runs' values and its standard error (sample standard deviation
    over sqrt(n); 0 for a single run)."""
    values = [float(v) for v in values]
    mean = statistics.fmean(values)
    se = statistics.stdev(values) / math.sqrt(len(values)) if len(values) > 1 else 0.0
    return mean, se


def efficiency(relative_mses, seconds):
    """One program's efficiency 1 / (relative MSE x seconds) from its independent runs (the
    means of both), and the relative standard error of that estimate (first order: the two
    means' relative standard errors in quadrature; the error and the time of a run are
    treated as independent)."""
    mse, mse_se = mean_and_se(relative_mses)
    t, t_se = mean_and_se(seconds)
    value = 1.0 / (mse * t)
    relative_se = math.sqrt((mse_se / mse) ** 2 + (t_se / t) ** 2)
    return value, relative_se


def _ratio_of_means(row, keep):
    """Ours / reference efficiency over the rounds in `keep`."""
    def mean(key):
        return statistics.fmean(row[key][i] for i in keep)

    return (mean("reference_relative_mses") * mean("reference_seconds")) / (
        mean("ours_relative_mses") * mean("ours_seconds"))


def jackknife(statistic, rounds):
    """A statistic of the rounds 0 .. rounds - 1 (statistic(kept round indices)) and its
    jackknife standard error: leave one round out, sqrt((n - 1) / n x sum of the squared
    deviations of the n leave-one-out values from their mean). 0 with fewer than 2 rounds."""
    everything = list(range(rounds))
    value = statistic(everything)
    if rounds < 2:
        return value, 0.0
    loo = [statistic([j for j in everything if j != i]) for i in everything]
    centre = statistics.fmean(loo)
    return value, math.sqrt((rounds - 1) / rounds * sum((x - centre) ** 2 for x in loo))


def efficiency_ratio(row):
    """Ours / reference efficiency of a row, (mean relative MSE x mean seconds) of the
    reference over ours', and its standard error: the jackknife's over the rounds (round r:
    both programs' run with seed r). Both sides have the same number of independent runs,
    compared with the same converged image by the same metric."""
    rounds = len(row["ours_relative_mses"])
    return jackknife(lambda keep: _ratio_of_means(row, keep), rounds)


def propagated_ratio_se(row):
    """The first-order standard error of the efficiency ratio (the four means' relative
    standard errors in quadrature), kept beside the jackknife's as a check."""
    ours, ours_rse = efficiency(row["ours_relative_mses"], row["ours_seconds"])
    ref, ref_rse = efficiency(row["reference_relative_mses"], row["reference_seconds"])
    return ours / ref * math.sqrt(ours_rse ** 2 + ref_rse ** 2)


def per_iteration(cpu_seconds, fixed_seconds, iterations):
    """CPU seconds per iteration of each run: (run - one-iteration run) / (iterations - 1)."""
    return [max(c - fixed_seconds, 1e-9) / (iterations - 1) for c in cpu_seconds]


def time_ratio(row):
    """Ours / reference CPU seconds per iteration (start-up taken out) and its jackknife
    standard error over the rounds; None without per-iteration times."""
    if "ours_seconds_per_iteration" not in row:
        return None
    ours, ref = row["ours_seconds_per_iteration"], row["reference_seconds_per_iteration"]
    return jackknife(lambda keep: statistics.fmean(ours[i] for i in keep)
                     / statistics.fmean(ref[i] for i in keep), len(ours))


def mean_difference(row):
    """Reference image mean / converged minus ours (both against the same converged image),
    and the standard error of that difference from the two sides' run-to-run spreads: the two
    programs render the same picture when it is within ~2 standard errors of 0."""
    ours, ours_se = mean_and_se(row["ours_mean_ratios"])
    ref, ref_se = mean_and_se(row["reference_mean_ratios"])
    return ref - ours, math.hypot(ours_se, ref_se)


def check_independent(images, who):
    """Raises when two runs gave the same image: the runs were not independent (a program that
    ignored the seed), so their spread would not measure the noise."""
    for i in range(len(images)):
        for j in range(i + 1, len(images)):
            if images[i].shape == images[j].shape and (images[i] == images[j]).all():
                raise RuntimeError(f"{who}: runs {i} and {j} gave the same image; the seed was "
                                   "not applied, so the runs are not independent")


def run(bin_dir, reference, quick, work, log=print, scenes=None, algorithms=None,
        iterations=None, runs=None, reference_images=None, timing=None):
    """Measures every (scene, algorithm): `runs` independent runs of each program, run r of
    either with seed r, ours and the reference in the same round (at the same time on two CPUs
    with CPU timing, one after the other with wall timing; which one goes first or on which
    CPU alternates). Every image is compared with the same converged image by the same metric
    (relative MSE after a 2 x 2 box average). Returns None without a reference.

    timing ("cpu" or "wall"), scenes, algorithms, iterations, runs and reference_images (scene
    -> (pixels, own relative MSE)) default to the benchmark's (DEFAULTS); the tests pass small
    synthetic ones."""
    if not reference:
        return None
    reference = Path(reference).resolve()
    if not os.access(reference, os.X_OK):
        raise FileNotFoundError(f"--reference-smallvcm {reference}: not an executable file")
    timing = timing or DEFAULTS["timing"]
    if timing not in TIMINGS:
        raise ValueError(f"reference timing {timing!r}: one of {', '.join(TIMINGS)}")
    scenes = scenes or (["1-glm_c"] if quick else list(SCENE_IDS))
    algorithms = algorithms or (ALGORITHMS[:1] if quick else ALGORITHMS)
    iterations = iterations or DEFAULTS["iterations"] or (2 if quick else ITERATIONS[timing])
    runs = runs or DEFAULTS["runs"] or (2 if quick else RUNS)
    threads = THREADS if timing == "wall" else 1
    source = Path(__file__).resolve().parents[2]
    if timing == "wall":
        cpus = pinned_cpus()
        slots = [cpus, cpus]
    else:
        # One CPU per program; both on the one CPU there is when there is only one.
        available = sorted(os.sched_getaffinity(0))
        slots = [{available[0]}, {available[min(1, len(available) - 1)]}]
        cpus = slots[0] | slots[1]
    together = timing == "cpu" and slots[0] != slots[1]
    # The reference's thread count is the CPUs it may run on; OMP_NUM_THREADS says the same.
    ref_env = dict(os.environ, OMP_NUM_THREADS=str(threads))
    rows = []
    started = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    policy = {os.SCHED_FIFO: "SCHED_FIFO", os.SCHED_RR: "SCHED_RR"}.get(
        os.sched_getscheduler(0), "normal")
    load_start = loadavg()
    loads = []

    def measure(arms, first_slot):
        """Runs [(arm, cmd)] of one round; returns {arm: timed() result}."""
        jobs = [(cmd, slots[(first_slot + k) % 2], ref_env if arm == "reference" else None)
                for k, (arm, cmd) in enumerate(arms)]
        if together:
            results = timed_together(jobs)
        else:
            results = [timed(*job) for job in jobs]
        return {arm: result for (arm, _), result in zip(arms, results)}

    for scene in scenes:
        if reference_images and scene in reference_images:
            converged, own = reference_images[scene]
        else:
            converged, own = converged_image(scene)
        for algo in algorithms:
            out_ours = Path(work) / "ours.exr"
            out_ref = Path(work) / "reference.pfm"

            def commands(n, seed):
                ours_cmd = [str(Path(bin_dir) / "render"),
                            str(source / "scenes/smallvcm" / f"{scene}.xml"),
                            "--algo", algo, "--iterations", str(n),
                            "--threads", str(threads), "--out", str(out_ours),
                            "--seed", str(seed)]
                # SmallVCM's radius rule (0.003 x scene radius), not our pixel-footprint default:
                # the two programs compute the same estimator.
                if algo in MERGING_ALGORITHMS:
                    ours_cmd += ["--radius-factor", "0.003"]
                ref_cmd = [str(reference), "-s", str(SCENE_IDS[scene]), "-a", algo,
                           "-i", str(n), "-o", str(out_ref), REFERENCE_SEED_FLAG, str(seed)]
                return [("ours", ours_cmd), ("reference", ref_cmd)]

            fixed = None
            if timing == "cpu" and iterations > 1:
                # Start-up: one-iteration runs of each, one on either CPU (their CPU seconds
                # differ), averaged and taken out of the time per iteration.
                log(f"reference comparison: {scene} {algo} start-up (load "
                    f"{' '.join(loadavg())})")
                ones = [measure(commands(1, FIXED_COST_SEED), 0),
                        measure(commands(1, FIXED_COST_SEED)[::-1], 0)]
                fixed = {arm: statistics.fmean(one[arm][2] for one in ones) for arm in ones[0]}
            ours, theirs, ours_err, ref_err, ours_images, ref_images = [], [], [], [], [], []
            for r in range(runs):
                loads.append(loadavg()[0])
                log(f"reference comparison: {scene} {algo} run {r + 1}/{runs} "
                    f"(load {' '.join(loadavg())})")
                # Alternate which program starts a round (wall) or takes the first CPU (cpu).
                arms = commands(iterations, r)
                measured = measure(arms if r % 2 == 0 else arms[::-1], 0)
                ours.append(measured["ours"])
                theirs.append(measured["reference"])
                image = read_ours_image(out_ours)
                ours_images.append(image)
                ours_err.append(image_error(image, converged))
                image = read_pfm(out_ref)
                ref_images.append(image)
                ref_err.append(image_error(image, converged))
            check_independent(ours_images, "ours")
            check_independent(ref_images, "the reference")
            seconds = 2 if timing == "cpu" else 0  # timed(): (wall, MiB, CPU)
            row = {
                "scene": scene, "algorithm": algo, "iterations": iterations, "runs": runs,
                "seeds": list(range(runs)), "timing": timing, "threads": threads,
                "ours_relative_mses": [e["relative_mse"] for e in ours_err],
                "reference_relative_mses": [e["relative_mse"] for e in ref_err],
                "ours_mses": [e["mse"] for e in ours_err],
                "reference_mses": [e["mse"] for e in ref_err],
                "ours_mean_ratios": [e["mean_ratio"] for e in ours_err],
                "reference_mean_ratios": [e["mean_ratio"] for e in ref_err],
                "converged_own_relative_mse": own,
                # The seconds of the efficiency: CPU (cpu timing) or wall (wall timing).
                "ours_seconds": [m[seconds] for m in ours],
                "reference_seconds": [m[seconds] for m in theirs],
                "ours_wall": [m[0] for m in ours], "reference_wall": [m[0] for m in theirs],
                "ours_mib": [m[1] for m in ours], "reference_mib": [m[1] for m in theirs],
                "ours_cpu": [m[2] for m in ours], "reference_cpu": [m[2] for m in theirs],
            }
            if fixed is not None:
                row["ours_fixed_cpu"] = fixed["ours"]
                row["reference_fixed_cpu"] = fixed["reference"]
                row["ours_seconds_per_iteration"] = per_iteration(row["ours_cpu"],
                                                                  fixed["ours"], iterations)
                row["reference_seconds_per_iteration"] = per_iteration(
                    row["reference_cpu"], fixed["reference"], iterations)
            row["efficiency_ratio"], row["efficiency_ratio_se"] = efficiency_ratio(row)
            row["efficiency_ratio_propagated_se"] = propagated_ratio_se(row)
            rows.append(row)
    return {"reference": str(reference), "timing": timing, "threads": threads, "runs": runs,
            "iterations": iterations, "rows": rows, "together": together,
            "started": started, "finished": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "load_start": load_start, "load_end": loadavg(), "load_per_run": loads,
            "cpus": sorted(cpus), "policy": policy, "nice": os.nice(0),
            "ours_binary": str((Path(bin_dir) / "render").resolve()),
            "ours_cmd": "build/bin/render scenes/smallvcm/SCENE.xml --algo ALGO --iterations "
                        f"{iterations} --threads {threads} --out OUT.exr --seed RUN"
                        " (vcm: --radius-factor 0.003)",
            "reference_cmd": (f"OMP_NUM_THREADS={threads} " if timing == "cpu" else "")
                             + f"SMALLVCM -s ID -a ALGO -i {iterations} -o OUT.pfm "
                             f"{REFERENCE_SEED_FLAG} RUN"}


def write_data(result, data_dir, machine, command):
    """Writes the run to data_dir/reference/DATE-COMMIT.json with the commit, the machine, the
    load during the runs and the command; returns the file's path."""
    stamp = time.strftime("%Y%m%dT%H%M", time.gmtime())
    out = Path(data_dir) / "reference" / f"{stamp}-{machine.get('source_revision', 'unknown')}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    from resultslib import data as datafile  # scripts/ is on sys.path (scripts/bench)

    record = {"stamp": datafile.stamp(command, load_before=str(result["load_start"])),
              "commit": machine.get("source_revision", "unknown"), "machine": machine,
              "load": {"start": result["load_start"], "end": result["load_end"],
                       "per_run": result.get("load_per_run", [])},
              "command": command, "result": result}
    out.write_text(json.dumps(record, indent=1) + "\n")
    return out


TITLE = "## Against the reference implementation (SmallVCM)"


def section(result, previous=None):
    """The document's lines for the comparison. Without a result this run, the previous
    document's measured section (`previous`, its lines) is kept; without either, "not run"."""
    if not result:
        if previous and any(line.startswith("| ") for line in previous):
            return previous
        return [TITLE, "",
                "Not run: `scripts/bench --only reference --reference-smallvcm PATH` compares "
                "efficiency, 1 / (relative MSE × seconds), with a SmallVCM binary built by hand "
                "(the project never downloads or builds it): by default single-threaded CPU "
                "seconds, the same number of independent runs of each program. Targets: "
                "efficiency ours / reference ≥ 2.0 at 2 standard errors, time per iteration "
                "≤ 0.6× and peak memory ≤ 1.2× the reference's on each box, for vcm and bpt.",
                ""]
    # "rounds": a raw file from before both sides' runs were independent.
    runs = result.get("runs", result.get("rounds", 0))
    timing = result.get("timing", "wall")
    iterations = result.get("iterations") or (result["rows"][0]["iterations"]
                                              if result["rows"] else "?")
    L = [TITLE, ""]
    if timing == "cpu":
        how = ("CPU seconds (user + system of each child, `wait4`) of single-threaded runs, "
               "whole process (start-up and writing the image included): ours with "
               "`--threads 1`, SmallVCM pinned to one CPU and `OMP_NUM_THREADS=1` (its thread "
               "count is the CPUs it may run on). "
               + ("The two programs of a round ran at the same time, each pinned to its own "
                  f"CPU of {result['cpus']}, swapping CPUs every round. "
                  if result.get("together") else "The two programs ran one after the other. ")
               + f"{iterations} iterations of 512 × 512 paths per run. Time per iteration: "
               "(CPU seconds of a run − the mean of two one-iteration runs of the same program, "
               "one on either CPU) / "
               f"({iterations} − 1), the start-up taken out. CPU time is what a quiet machine's "
               "wall time would be and other load disturbs it far less than wall time (not "
               "entirely: caches and the memory bus are shared).")
    else:
        how = (f"Whole-process wall seconds (start-up and writing the image included), "
               f"{result['threads']} threads, both programs pinned to CPUs {result['cpus']} "
               "(SmallVCM takes its thread count from the affinity mask), one after the other "
               f"(which one starts a round alternating), {iterations} iterations per run.")
    L.append(how + " Same scene, path length (10 segments), resolution and merging radius "
             f"(0.003 × scene radius, alpha 0.75). Each program ran {runs} independent times "
             f"(seeds 0 to {runs - 1}); every image is compared with the same converged image "
             "in `docs/references/` by the same metric. Peak memory is each program's own maximum "
             "resident set, as GNU time reports it (design/smallvcm-comparison.md). "
             f"Run {result['started']} to {result['finished']}, 1/5/15-minute "
             f"load average {' / '.join(result['load_start'])} at the start and "
             f"{' / '.join(result['load_end'])} at the end"
             + (f" (the benchmark at nice {result['nice']})" if result.get("nice") else "")
             + ("; both arms ran under the real-time scheduling policy "
                f"{result['policy']} (`chrt -f 10`), which preempts other load but not its "
                "use of the memory bus and caches" if result.get("policy", "normal") != "normal"
                else "") + ". "
             f"Ours: `{result['ours_binary']}`; reference: `{result['reference']}` (built as "
             "[design/smallvcm-comparison.md](../design/smallvcm-comparison.md) says).")
    L.append("")
    L.append(f"    {result['ours_cmd']}")
    L.append(f"    {result['reference_cmd']}")
    L.append("")
    L.extend(efficiency_lines(result["rows"], timing))
    L.extend(time_lines(result["rows"], timing))
    L.extend(same_image_lines(result["rows"]))
    unit = "CPU" if timing == "cpu" else "wall"
    L.append(f"Per-run {unit} seconds (ours / reference): " + "; ".join(
        f"{row['scene']} {row['algorithm']} "
        + ", ".join(f"{a:.1f}/{b:.1f}" for a, b in zip(row["ours_seconds"],
                                                       row["reference_seconds"]))
        for row in result["rows"]) + ".")
    return L + [""]


def met(ratio, se, target, at_least):
    """The verdict at 2 standard errors: ratio - 2 SE >= target (at_least) or ratio + 2 SE <=
    target."""
    ok = ratio - 2 * se >= target if at_least else ratio + 2 * se <= target
    return "yes" if ok else "**no**"


def efficiency_lines(rows, timing="wall"):
    """The per-unit-of-error table: each program's efficiency 1 / (mean relative MSE x mean
    seconds) over its independent runs, their ratio with its standard error, and whether the
    target (ratio >= 2.0 at 2 standard errors) is met."""
    rows = [row for row in rows if "ours_relative_mses" in row]
    if not rows:
        return []
    unit = "CPU" if timing == "cpu" else "wall"
    L = ["Per unit of error: relative MSE ((x − r)² / (r² + 0.01), as `render --compare`) of "
         "each image, box-averaged 2 × 2 to 256 × 256, against the box's converged image in "
         f"`docs/references/`; efficiency = 1 / (mean relative MSE × mean {unit} seconds of "
         "the whole process) over each program's runs. The ratio's standard error is the "
         "jackknife's over the rounds (leave one round, both programs' runs of it, out). "
         "Target: ours / reference ≥ 2.0 at 2 standard errors (ratio − 2 SE ≥ 2). The "
         "converged image's own noise (estimated from its odd and even iterations) is in both "
         "programs' errors alike and pulls the ratio toward 1; its share of ours is given.", "",
         f"| scene | algorithm | runs | ours rel. MSE (mean ± SE) | reference rel. MSE | "
         f"converged image's own (share of ours) | ours {unit} s | reference {unit} s | "
         "ours / reference efficiency ± SE | ≥ 2.0 at 2 SE |",
         "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for row in rows:
        e_ours, e_ours_se = mean_and_se(row["ours_relative_mses"])
        e_ref, e_ref_se = mean_and_se(row["reference_relative_mses"])
        ratio, se = efficiency_ratio(row)
        own = row.get("converged_own_relative_mse")
        own_text = f"{own:.2e} ({own / e_ours:.0%})" if own is not None else "—"
        L.append(f"| {row['scene']} | {row['algorithm']} | {len(row['ours_relative_mses'])} | "
                 f"{e_ours:.3e} ± {e_ours_se:.1e} | {e_ref:.3e} ± {e_ref_se:.1e} | {own_text} | "
                 f"{statistics.fmean(row['ours_seconds']):.1f} | "
                 f"{statistics.fmean(row['reference_seconds']):.1f} | "
                 f"**{ratio:.2f} ± {se:.2f}** | {met(ratio, se, 2.0, True)} |")
    L.append("")
    return L


def time_lines(rows, timing):
    """The secondary figures: time per iteration (CPU timing: start-up taken out; wall timing:
    whole process over the iterations) and peak memory, ours over the reference's."""
    if not rows:
        return []
    if timing == "cpu":
        head = ("Time per iteration (CPU seconds, start-up taken out; ratio ± jackknife SE, "
                "target ≤ 0.6 at 2 SE) and peak memory (target ≤ 1.2; with one thread SmallVCM "
                "holds one iteration's light vertices, as ours does):")
    else:
        head = ("Time per iteration (whole-process wall seconds over the iterations, target "
                "≤ 0.6) and peak memory (target ≤ 1.2):")
    L = [head, "",
         "| scene | algorithm | ours s / iteration | reference s / iteration | ours / reference "
         "± SE | ≤ 0.6 at 2 SE | ours start-up s | reference start-up s | ours MiB | "
         "reference MiB | ours / reference | ≤ 1.2 |",
         "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for row in rows:
        m_ours, m_ref = max(row["ours_mib"]), max(row["reference_mib"])
        tr = time_ratio(row)
        if tr:
            t_ours = statistics.fmean(row["ours_seconds_per_iteration"])
            t_ref = statistics.fmean(row["reference_seconds_per_iteration"])
            ratio, se = tr
            start = (f"{row['ours_fixed_cpu'] - t_ours:.2f} | "
                     f"{row['reference_fixed_cpu'] - t_ref:.2f}")
        else:
            n = row["iterations"]
            t_ours = statistics.fmean(row["ours_seconds"]) / n
            t_ref = statistics.fmean(row["reference_seconds"]) / n
            ratio, se = jackknife(lambda keep: statistics.fmean(
                row["ours_seconds"][i] for i in keep) / statistics.fmean(
                row["reference_seconds"][i] for i in keep), len(row["ours_seconds"]))
            start = "— | —"
        L.append(f"| {row['scene']} | {row['algorithm']} | {t_ours:.3f} | {t_ref:.3f} | "
                 f"**{ratio:.2f} ± {se:.2f}** | {met(ratio, se, 0.6, False)} | {start} | "
                 f"{m_ours:.0f} | {m_ref:.0f} | **{m_ours / m_ref:.2f}** | "
                 f"{'yes' if m_ours <= 1.2 * m_ref else '**no**'} |")
    L.append("")
    return L


def same_image_lines(rows):
    """The check that both programs render the same picture: each side's image mean over the
    converged image's (mean of its runs ± SE) and the difference with its SE."""
    if not rows or "ours_mean_ratios" not in rows[0]:
        return []
    L = ["Same picture: each program's image mean over the converged image's (mean of its runs "
         "± SE; bpt misses the caustics the converged vcm image has, alike in both programs) "
         "and the reference's minus ours, which is within about 2 standard errors of 0 when "
         "the two render the same thing:", "",
         "| scene | algorithm | ours mean / converged | reference mean / converged | "
         "reference − ours ± SE |",
         "| --- | --- | --- | --- | --- |"]
    for row in rows:
        o, o_se = mean_and_se(row["ours_mean_ratios"])
        r, r_se = mean_and_se(row["reference_mean_ratios"])
        d, d_se = mean_difference(row)
        L.append(f"| {row['scene']} | {row['algorithm']} | {o:.4f} ± {o_se:.4f} | "
                 f"{r:.4f} ± {r_se:.4f} | {d:+.4f} ± {d_se:.4f} |")
    L.append("")
    return L


# Written by hand in docs/results/performance-notes.md (what the comparison means, the changes
# since, how the binary was built, what differs between the programs): performance.py links to
# these sections after the generated one and stops with an error when one is missing there.
NOTES_PAGE = "performance-notes.md"  # relative to docs/results/, beside performance.md
# The generated subsection that links to them (the measured section ends before it).
NOTES_HEADING = "### Analysis, changes since, how the reference was built"
NOTES_SECTIONS = ("### Where the targets stand, and what limits them",
                  "### Shadow rays through their own BVH (branch `speed-occ`)",
                  "### Smaller stored light vertices",
                  "### The merge's fields in one cache line of the stored light vertex",
                  "### How the reference binary was built",
                  "### What the two programs compute differently")


def _split(lines):
    """(before, section, after) of a document's lines around TITLE's section."""
    try:
        start = lines.index(TITLE)
    except ValueError:
        return lines, [], []
    end = next((i for i in range(start + 1, len(lines)) if lines[i].startswith("## ")),
               len(lines))
    return lines[:start], lines[start:end], lines[end:]


def _subsections(section_lines, titles):
    """The named ### subsections of the section's lines."""
    kept, keep = [], False
    for line in section_lines:
        if line.startswith("### ") or line.startswith("## "):
            keep = line.strip() in titles
        if keep:
            kept.append(line)
    while kept and not kept[-1].strip():
        kept.pop()
    return kept + [""] if kept else []


def document_lines(path, result):
    """The section for `result` (or, without one, the previous measured section of the document
    at `path`). The section is generated only: a ### subsection written into it by hand would
    be lost, so that raises (move it to docs/results/performance-notes.md)."""
    try:
        old = Path(path).read_text().split("\n")
    except OSError:
        old = []
    _, previous, _ = _split(old)
    hand = [line for line in previous if line.startswith("### ") and line != NOTES_HEADING]
    if hand:
        raise RuntimeError(f"{path}: the section {TITLE!r} holds subsections that are not "
                           "generated and would be lost: " + "; ".join(hand) + ". Move them to "
                           "docs/results/performance-notes.md (and reference.NOTES_SECTIONS).")
    body = section(result, _subsections(previous, (TITLE,)) if not result else None)
    while body and not body[-1].strip():
        body.pop()
    # The notes page is the repository's (also when --out writes elsewhere).
    notes = Path(__file__).resolve().parents[2] / "docs" / "results" / NOTES_PAGE
    links = handwritten.section_links(notes, NOTES_SECTIONS, NOTES_PAGE)
    return body + ["", NOTES_HEADING, "", f"Written by hand in [{NOTES_PAGE}]({NOTES_PAGE}):",
                   ""] + links + [""]


def replace_in_document(path, result):
    """Rewrites only this section of the document at `path` (`scripts/bench --only reference`)."""
    lines = Path(path).read_text().split("\n")
    before, _, after = _split(lines)
    new = document_lines(path, result)
    while before and not before[-1].strip():
        before.pop()
    Path(path).write_text("\n".join(before + [""] + new + after).rstrip("\n") + "\n")
