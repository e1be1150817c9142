"""Ours against the VCM reference implementation (SmallVCM) on its four Cornell boxes: whole-
process wall time and peak memory of 16 iterations at 512 x 512 on 2 threads, A/B alternated,
medians (issue 16's targets: time <= 0.8x, memory <= 1.2x the reference's).

The project never downloads or builds the reference: `scripts/bench --reference-smallvcm PATH`
takes a binary built by hand (docs/performance.md, "How the reference binary was built"). Its
command line is `-s SCENE -a ALGO -i ITERATIONS -o FILE` and nothing else: resolution (512 x 512),
path length (10 segments), merging radius (0.003 x the scene's bounding-sphere radius, alpha
0.75) and the base seed are fixed in its config.hxx, and the thread count is
omp_get_num_procs(), the CPUs in the process's affinity mask (OMP_NUM_THREADS is overridden by
its omp_set_num_threads). Both programs therefore run pinned to the same THREADS CPUs. Without
the option the section says "not run". Only the Python standard library is used.
"""

import os
import statistics
import subprocess
import time
from pathlib import Path

# Our scene file for each of SmallVCM's scene ids (its g_SceneConfigs, in order;
# scenes/smallvcm/README.md): 0 glossy floor + small mirror and glass spheres + sun,
# 1 glossy floor + large mirror sphere + light-box area light, 2 small spheres + point light,
# 3 small spheres + constant background.
SCENE_IDS = {"0-gbs_s": 0, "1-glm_c": 1, "2-gbs_p": 2, "3-gbs_b": 3}
ALGORITHMS = ["vcm", "bpt"]
ITERATIONS = 16  # SmallVCM splits -i over its threads: 2 threads x 8 iterations of 512^2 paths
ROUNDS = 3
THREADS = 2


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
                       "-i", str(iterations), "-o", str(Path(work) / "reference.bmp")]
            ours, theirs = [], []
            for r in range(rounds):
                log(f"reference comparison: {scene} {algo} round {r + 1}/{rounds} "
                    f"(load {' '.join(loadavg())})")
                ours.append(timed(ours_cmd, cpus))
                theirs.append(timed(ref_cmd, cpus))
            rows.append({
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
                        f"{iterations} --threads {THREADS} --out OUT.exr",
            "reference_cmd": f"SMALLVCM -s ID -a ALGO -i {iterations} -o OUT.bmp"}


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
                "project never downloads or builds it. Targets (issue 16): time ≤ 0.8× and peak "
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
    L.append("Per-round wall seconds (ours / reference): " + "; ".join(
        f"{row['scene']} {row['algorithm']} "
        + ", ".join(f"{a:.1f}/{b:.1f}" for a, b in zip(row["ours_seconds"],
                                                       row["reference_seconds"]))
        for row in result["rows"]) + ".")
    return L + [""]


# Written by hand (how the binary was built, what differs between the programs): carried over
# whenever the section is regenerated.
HAND_WRITTEN = ("### Where the targets stand, and what limits them",
                "### Since: smaller stored light vertices (issue 16)",
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
    """The section for `result` (or the previous measured one) followed by the hand-written
    subsections of the document at `path`."""
    try:
        old = Path(path).read_text().split("\n")
    except OSError:
        old = []
    _, previous, _ = _split(old)
    hand = _subsections(previous, HAND_WRITTEN)
    measured = [line for line in previous if line not in hand] if previous else []
    body = section(result, _subsections(measured, (TITLE,)) if not result else None)
    return body + hand


def replace_in_document(path, result):
    """Rewrites only this section of the document at `path` (`scripts/bench --only reference`)."""
    lines = Path(path).read_text().split("\n")
    before, _, after = _split(lines)
    new = document_lines(path, result)
    while before and not before[-1].strip():
        before.pop()
    Path(path).write_text("\n".join(before + [""] + new + after).rstrip("\n") + "\n")
