"""Ours against the VCM reference implementation (SmallVCM) on its four Cornell boxes: whole-
process wall time and peak memory of 16 iterations at 512 x 512 on 2 threads, A/B alternated,
medians (the speed targets: time <= 0.8x, memory <= 1.2x the reference's;
docs/results/performance-notes.md).

The project never downloads or builds the reference: `scripts/bench --reference-smallvcm PATH`
takes a binary built by hand (docs/results/performance-notes.md, "How the reference binary was
built"). Its command line is `-s SCENE -a ALGO -i ITERATIONS -o FILE` and nothing else:
resolution (512 x 512), path length (10 segments), merging radius (0.003 x the scene's bounding-sphere radius, alpha
0.75) and the base seed are fixed in its config.hxx, and the thread count is
omp_get_num_procs(), the CPUs in the process's affinity mask (OMP_NUM_THREADS is overridden by
its omp_set_num_threads). Both programs therefore run pinned to the same THREADS CPUs. Without
the option the section says "not run".

Per unit of error: both programs' images of the timed runs are compared with the converged
image of each box in docs/references/ (ours, vcm, 256-1024 iterations at 256 x 256, made once by
`scripts/bench --make-references`): each 512 x 512 image is box-averaged 2 x 2 down to 256 x 256
(both programs use a box pixel filter, so the average has the coarse pixel's expectation), and
efficiency = 1 / (MSE x wall seconds). The ratio ours / reference above 1 means ours reaches a
given error sooner; its inverse is the time ours needs for the reference's error, relative to the
reference's time (the time target <= 0.8 read per unit of error). SmallVCM writes its image as
PFM (its driver's `.pfm` output: raw little-endian float RGB, top row first). The timing needs
only the standard library; the error needs numpy and OpenImageIO (scripts/setup installs them).
"""

import os
import statistics
import subprocess
import time
from pathlib import Path

from benchlib import handwritten

# Our scene file for each of SmallVCM's scene ids (its g_SceneConfigs, in order;
# scenes/smallvcm/README.md): 0 glossy floor + small mirror and glass spheres + sun,
# 1 glossy floor + large mirror sphere + light-box area light, 2 small spheres + point light,
# 3 small spheres + constant background.
SCENE_IDS = {"0-gbs_s": 0, "1-glm_c": 1, "2-gbs_p": 2, "3-gbs_b": 3}
ALGORITHMS = ["vcm", "bpt"]
ITERATIONS = 16  # SmallVCM splits -i over its threads: 2 threads x 8 iterations of 512^2 paths
ROUNDS = 3
THREADS = 2
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


def timed(cmd, cpus, env=None):
    """Runs cmd pinned to cpus; returns (wall s, peak RSS MiB, user+system CPU s) of that child
    alone (wait4's rusage)."""
    start = time.monotonic()
    process = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env,
                               preexec_fn=lambda: os.sched_setaffinity(0, cpus))
    _, status, usage = os.wait4(process.pid, 0)
    wall = time.monotonic() - start
    stderr = process.stderr.read().decode(errors="replace")
    process.stderr.close()
    code = os.waitstatus_to_exitcode(status)
    if code != 0:
        raise RuntimeError(f"{' '.join(map(str, cmd))} exited {code}: {stderr.strip()[-500:]}")
    # ru_maxrss is in KiB on Linux
    return wall, usage.ru_maxrss / 1024.0, usage.ru_utime + usage.ru_stime


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


def converged_image(scene):
    """The box's converged image (256 x 256) and its own estimated MSE: the reference's noise,
    (relative error estimate x RMS of the image)^2, from the render:relative_error_estimate
    its header records (half the RMS difference of its odd and even iterations' means over
    the RMS of the mean)."""
    from benchlib import common

    path = Path(__file__).resolve().parents[2] / "docs" / "references" / (
        REFERENCE_IMAGES[scene] + ".exr")
    pixels, attributes = common.read_exr(path)
    relative = float(attributes.get("render:relative_error_estimate", "nan"))
    own_mse = relative * relative * float((pixels * pixels).mean())
    return pixels, own_mse, attributes


def image_error(image, converged):
    """MSE over pixels and channels of `image` (box-averaged down to the converged image's
    size) against the converged image, and the ratio of their means (a bias indicator)."""
    from benchlib import common

    height, width = converged.shape[:2]
    small = common.downscale(image, (width, height))
    diff = small - converged
    return float((diff * diff).mean()), float(small.mean() / converged.mean())


def loadavg():
    with open("/proc/loadavg") as f:
        return f.read().split()[:3]


def run(bin_dir, reference, quick, work, log=print):
    """Measures every (scene, algorithm): ROUNDS rounds of ours then the reference (alternated
    so that a change of the machine's load hits both arms). Returns None without a reference."""
    if not reference:
        return None
    reference = Path(reference).resolve()
    if not os.access(reference, os.X_OK):
        raise FileNotFoundError(f"--reference-smallvcm {reference}: not an executable file")
    scenes = ["1-glm_c"] if quick else list(SCENE_IDS)
    algorithms = ALGORITHMS[:1] if quick else ALGORITHMS
    iterations = 2 if quick else ITERATIONS
    rounds = 1 if quick else ROUNDS
    source = Path(__file__).resolve().parents[2]
    cpus = pinned_cpus()
    rows = []
    started = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    policy = {os.SCHED_FIFO: "SCHED_FIFO", os.SCHED_RR: "SCHED_RR"}.get(
        os.sched_getscheduler(0), "normal")
    load_start = loadavg()
    for scene in scenes:
        for algo in algorithms:
            ours_cmd = [str(Path(bin_dir) / "render"),
                        str(source / "scenes/smallvcm" / f"{scene}.xml"),
                        "--algo", algo, "--iterations", str(iterations),
                        "--threads", str(THREADS), "--out", str(Path(work) / "ours.exr")]
            ref_cmd = [str(reference), "-s", str(SCENE_IDS[scene]), "-a", algo,
                       "-i", str(iterations), "-o", str(Path(work) / "reference.pfm")]
            from benchlib import common

            converged, own_mse, _ = converged_image(scene)
            ours, theirs, ours_errors = [], [], []
            for r in range(rounds):
                log(f"reference comparison: {scene} {algo} round {r + 1}/{rounds} "
                    f"(load {' '.join(loadavg())})")
                # Ours with another seed each round (the MSE of one seed can be dominated by a
                # few fireflies: 2-gbs_p bpt's seed 0 has 56 % of its MSE in 0.1 % of the
                # pixels); SmallVCM's seed is fixed in its config.hxx, so its MSE is one sample.
                ours.append(timed(ours_cmd + ["--seed", str(r)], cpus))
                theirs.append(timed(ref_cmd, cpus))
                ours_errors.append(image_error(common.read_exr(Path(work) / "ours.exr")[0],
                                               converged))
            ref_mse, ref_mean = image_error(read_pfm(Path(work) / "reference.pfm"), converged)
            rows.append({
                "ours_mses": [e for e, _ in ours_errors],
                "ours_mse": statistics.median(e for e, _ in ours_errors),
                "reference_mse": ref_mse, "converged_own_mse": own_mse,
                "ours_mean_ratio": statistics.median(m for _, m in ours_errors),
                "reference_mean_ratio": ref_mean,
                "scene": scene, "algorithm": algo, "iterations": iterations,
                "ours_seconds": [w for w, _, _ in ours],
                "reference_seconds": [w for w, _, _ in theirs],
                "ours_mib": [m for _, m, _ in ours], "reference_mib": [m for _, m, _ in theirs],
                "ours_cpu": [c for _, _, c in ours], "reference_cpu": [c for _, _, c in theirs],
            })
    return {"reference": str(reference), "threads": THREADS, "rounds": rounds, "rows": rows,
            "started": started, "finished": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "load_start": load_start, "load_end": loadavg(), "cpus": sorted(cpus),
            "policy": policy,
            "ours_binary": str((Path(bin_dir) / "render").resolve()),
            "ours_cmd": "build/bin/render scenes/smallvcm/SCENE.xml --algo ALGO --iterations "
                        f"{iterations} --threads {THREADS} --out OUT.exr --seed ROUND",
            "reference_cmd": f"SMALLVCM -s ID -a ALGO -i {iterations} -o OUT.pfm"}


TITLE = "## Against the reference implementation (SmallVCM)"


def section(result, previous=None):
    """The document's lines for the comparison. Without a result this run, the previous
    document's measured section (`previous`, its lines) is kept; without either, "not run"."""
    if not result:
        if previous and any(line.startswith("| ") for line in previous):
            return previous
        return [TITLE, "",
                "Not run: `scripts/bench --only reference --reference-smallvcm PATH` compares "
                "whole-process wall time and peak memory (16 iterations, 512 × 512, 2 threads, "
                "A/B alternated, medians of 3) with a SmallVCM binary built by hand; the "
                "project never downloads or builds it. Targets: time ≤ 0.8× and peak "
                "memory ≤ 1.2× the reference's on each box, for vcm and bpt.", ""]
    L = [TITLE, ""]
    L.append(f"Whole process (start-up and writing the image included), {result['threads']} "
             f"threads, both programs pinned to CPUs {result['cpus']} (SmallVCM takes its "
             "thread count from the affinity mask), the same scene, path length (10 segments), "
             "resolution and merging radius (0.003 × scene radius, alpha 0.75); medians of "
             f"{result['rounds']} rounds, ours and the reference alternated; peak memory is the "
             "process's maximum resident set and CPU the user + system time (`wait4`). "
             f"Run {result['started']} to {result['finished']}, 1/5/15-minute load average "
             f"{' / '.join(result['load_start'])} at the start and "
             f"{' / '.join(result['load_end'])} at the end (other engineers' builds and tests "
             "shared the 2 cores"
             + ("; both arms ran under the real-time scheduling policy "
                f"{result['policy']} (`chrt -f 10`), which preempts that load but not its "
                "use of the memory bus and caches" if result.get("policy", "normal") != "normal"
                else ": absolute times are pessimistic for both arms alike") + "). "
             f"Ours: `{result['ours_binary']}`; reference: `{result['reference']}` (built as "
             "described below).")
    L.append("")
    L.append(f"    {result['ours_cmd']}")
    L.append(f"    {result['reference_cmd']}")
    L.append("")
    L.append("| scene | algorithm | ours s | reference s | ours / reference (target ≤ 0.8) | "
             "ours CPU s | reference CPU s | ours MiB | reference MiB | ours / reference "
             "(target ≤ 1.2) |")
    L.append("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for row in result["rows"]:
        t_ours = statistics.median(row["ours_seconds"])
        t_ref = statistics.median(row["reference_seconds"])
        c_ours = statistics.median(row.get("ours_cpu", [0]))
        c_ref = statistics.median(row.get("reference_cpu", [0]))
        m_ours = statistics.median(row["ours_mib"])
        m_ref = statistics.median(row["reference_mib"])
        L.append(f"| {row['scene']} | {row['algorithm']} | {t_ours:.2f} | {t_ref:.2f} | "
                 f"**{t_ours / t_ref:.2f}** | {c_ours:.1f} | {c_ref:.1f} | {m_ours:.0f} | "
                 f"{m_ref:.0f} | **{m_ours / m_ref:.2f}** |")
    L.append("")
    L.extend(efficiency_lines(result["rows"]))
    L.append("Per-round wall seconds (ours / reference): " + "; ".join(
        f"{row['scene']} {row['algorithm']} "
        + ", ".join(f"{a:.1f}/{b:.1f}" for a, b in zip(row["ours_seconds"],
                                                       row["reference_seconds"]))
        for row in result["rows"]) + ".")
    return L + [""]


def efficiency_lines(rows):
    """The per-unit-of-error table: efficiency 1 / (MSE x median wall seconds) of each program
    against the converged image, and their ratio."""
    rows = [row for row in rows if "ours_mse" in row]
    if not rows:
        return []
    L = ["Per unit of error: MSE of each program's image (box-averaged 2 × 2 to 256 × 256) "
         "against the box's converged image in `docs/references/` (ours, vcm, 256–1024 "
         "iterations), efficiency = 1 / (MSE × wall seconds) with the medians above. "
         "Ours / reference > 1: ours reaches a given error sooner; the time target ≤ 0.8 per "
         "unit of error is an efficiency ratio ≥ 1.25. The converged image's own noise "
         "(estimated from its odd and even iterations) is in both MSEs (its share of ours is "
         "given): it pulls the ratio toward 1. The mean ratio (image mean / converged mean) "
         "shows a bias a noise-free measure would not hide. Ours renders with seed 0, 1, 2 in "
         "the three rounds and its MSE is their median (the rounds' MSEs are listed below); "
         "SmallVCM's seed is fixed in its config, so its MSE is one sample.", "",
         "| scene | algorithm | ours MSE | reference MSE | converged image's own MSE (share of "
         "ours) | ours mean ratio | reference mean ratio | ours efficiency | reference "
         "efficiency | ours / reference (target ≥ 1.25) |",
         "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for row in rows:
        t_ours = statistics.median(row["ours_seconds"])
        t_ref = statistics.median(row["reference_seconds"])
        e_ours = 1.0 / (row["ours_mse"] * t_ours)
        e_ref = 1.0 / (row["reference_mse"] * t_ref)
        L.append(f"| {row['scene']} | {row['algorithm']} | {row['ours_mse']:.3e} | "
                 f"{row['reference_mse']:.3e} | {row['converged_own_mse']:.2e} "
                 f"({row['converged_own_mse'] / row['ours_mse']:.0%}) | "
                 f"{row['ours_mean_ratio']:.4f} | {row['reference_mean_ratio']:.4f} | "
                 f"{e_ours:.4g} | {e_ref:.4g} | **{e_ours / e_ref:.2f}** |")
    L.append("")
    L.append("Ours' MSE per round (seeds 0, 1, 2): " + "; ".join(
        f"{row['scene']} {row['algorithm']} " + ", ".join(f"{e:.3e}" for e in row["ours_mses"])
        for row in rows if "ours_mses" in row) + ".")
    return L + [""]


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
