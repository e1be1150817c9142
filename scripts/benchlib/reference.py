"""Ours against the VCM reference implementation (SmallVCM) on its four Cornell boxes: whole-
process wall time and peak memory of 16 iterations at 512 x 512, A/B alternated, medians
(issue 16's targets: time <= 0.8x, memory <= 1.2x the reference's).

The project never downloads or builds the reference: `scripts/bench --reference-smallvcm PATH`
takes a binary built by hand (its command line: `-s SCENE -a ALGO -i ITERATIONS -o FILE`); without
it the section says "not run". Only the Python standard library is used.
"""

import os
import statistics
import subprocess
import time
from pathlib import Path

# Our scene files of SmallVCM's scenes 0-3 (scenes/smallvcm/README.md), in its scene order.
SCENES = ["0-gbs_s", "1-glm_c", "2-gbs_p", "3-gbs_b"]
ALGORITHMS = ["vcm", "bpt"]
ITERATIONS = 16
ROUNDS = 3
THREADS = 2


def timed(cmd, env=None):
    """Runs cmd; returns (wall seconds, peak RSS in MiB) of that child alone (wait4's rusage)."""
    start = time.monotonic()
    process = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    _, status, usage = os.wait4(process.pid, 0)
    wall = time.monotonic() - start
    stderr = process.stderr.read().decode(errors="replace")
    process.stderr.close()
    code = os.waitstatus_to_exitcode(status)
    if code != 0:
        raise RuntimeError(f"{' '.join(map(str, cmd))} exited {code}: {stderr.strip()[-500:]}")
    return wall, usage.ru_maxrss / 1024.0  # ru_maxrss is in KiB on Linux


def run(bin_dir, reference, quick, work, log=print):
    """Measures every (scene, algorithm): ROUNDS rounds of ours then the reference (alternated
    so that a change of the machine's load hits both arms). Returns None without a reference."""
    if not reference:
        return None
    reference = Path(reference).resolve()
    if not os.access(reference, os.X_OK):
        raise FileNotFoundError(f"--reference-smallvcm {reference}: not an executable file")
    scenes = SCENES[1:2] if quick else SCENES
    algorithms = ALGORITHMS[:1] if quick else ALGORITHMS
    iterations = 1 if quick else ITERATIONS
    rounds = 1 if quick else ROUNDS
    source = Path(__file__).resolve().parents[2]
    env = dict(os.environ, OMP_NUM_THREADS=str(THREADS))
    rows = []
    for index, scene in enumerate(SCENES):
        if scene not in scenes:
            continue
        for algo in algorithms:
            ours_cmd = [str(Path(bin_dir) / "render"), str(source / "scenes/smallvcm" /
                                                           f"{scene}.xml"),
                        "--algo", algo, "--iterations", str(iterations),
                        "--threads", str(THREADS), "--out", str(Path(work) / "ours.exr")]
            ref_cmd = [str(reference), "-s", str(index), "-a", algo, "-i", str(iterations),
                       "-o", str(Path(work) / "reference.hdr")]
            ours, theirs = [], []
            for r in range(rounds):
                log(f"reference comparison: {scene} {algo} round {r + 1}/{rounds}")
                ours.append(timed(ours_cmd))
                theirs.append(timed(ref_cmd, env))
            rows.append({
                "scene": scene, "algorithm": algo, "iterations": iterations,
                "ours_seconds": [w for w, _ in ours], "reference_seconds": [w for w, _ in theirs],
                "ours_mib": [m for _, m in ours], "reference_mib": [m for _, m in theirs],
            })
    return {"reference": str(reference), "threads": THREADS, "rounds": rounds, "rows": rows,
            "ours_cmd": "build/bin/render scenes/smallvcm/SCENE.xml --algo ALGO --iterations "
                        f"{iterations} --threads {THREADS} --out OUT.exr",
            "reference_cmd": f"OMP_NUM_THREADS={THREADS} SMALLVCM -s N -a ALGO -i {iterations} "
                             "-o OUT.hdr"}


def section(result):
    """The document's lines for the comparison (or for its absence)."""
    L = ["## Against the reference implementation (SmallVCM)", ""]
    if not result:
        L.append("Not run: `scripts/bench --reference-smallvcm PATH` compares whole-process wall "
                 "time and peak memory (16 iterations, 512 × 512, 2 threads, A/B alternated, "
                 "medians of 3) with a SmallVCM binary built by hand; the project never "
                 "downloads or builds it. Targets (issue 16): time ≤ 0.8× and peak memory "
                 "≤ 1.2× the reference's on each box, for vcm and bpt.")
        return L + [""]
    L.append(f"Whole process (start-up included), {result['threads']} threads, the same scene, "
             f"path length and radius; medians of {result['rounds']} rounds, ours and the "
             "reference alternated; peak memory is the process's maximum resident set "
             f"(`wait4`). Reference: `{result['reference']}`.")
    L.append("")
    L.append(f"    {result['ours_cmd']}")
    L.append(f"    {result['reference_cmd']}")
    L.append("")
    L.append("| scene | algorithm | ours s | reference s | ours / reference | ours MiB | "
             "reference MiB | ours / reference |")
    L.append("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for row in result["rows"]:
        t_ours = statistics.median(row["ours_seconds"])
        t_ref = statistics.median(row["reference_seconds"])
        m_ours = statistics.median(row["ours_mib"])
        m_ref = statistics.median(row["reference_mib"])
        L.append(f"| {row['scene']} | {row['algorithm']} | {t_ours:.2f} | {t_ref:.2f} | "
                 f"{t_ours / t_ref:.2f} | {m_ours:.0f} | {m_ref:.0f} | {m_ours / m_ref:.2f} |")
    return L + [""]
