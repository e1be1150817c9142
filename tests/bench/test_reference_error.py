#!/usr/bin/python3
"""The per-unit-of-error part of `scripts/bench --reference-smallvcm` (CTest:
bench.reference_error), without SmallVCM and without timing anything:

1. A PFM written as SmallVCM's driver writes it (top row first, negative scale) reads back in the
   right orientation, both byte orders; the error of a 512 x 512 image against a 256 x 256
   converged one is that of its 2 x 2 box average. Exact inputs, exact checks.
2. The efficiency ratio and its jackknife standard error over the rounds, the first-order
   (propagated) standard error, the time-per-iteration ratio and the image-mean difference
   follow their formulas (exact inputs, each computed here independently of the module).
3. The symmetric run on synthetic programs, with both timings: a fake `render` and a fake
   reference write the converged image plus Gaussian noise from their seed (the reference's
   noise twice ours'); the replaced timer reports their seconds (wall timing: ours 1 s, the
   reference 2 s; CPU timing: a start-up plus a cost per iteration, ours 0.5 + 1 s x n, the
   reference 0.1 + 2 s x n). run() gives both sides the same number of runs with seeds 0..,
   compares all images with the same converged image, and its efficiency ratio is within 4 of
   its own standard errors of the true one (4 SE: a correct estimate misses by chance with
   probability < 1e-4, and the fixed seeds make the check deterministic). With CPU timing the
   two programs of a round run on different CPUs and swap them each round, the reference gets
   OMP_NUM_THREADS=1 and ours --threads 1, a one-iteration run of each on either CPU
   measures the start-up, and the time per iteration is exactly 1 / 2 with no spread. A fake reference that
   ignores the seed is refused: its runs are not independent.
4. The data file carries the commit, the machine, the load and the command."""

import argparse
import json
import math
import os
import struct
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

import numpy as np

FAKE_PROGRAM = r'''#!/usr/bin/python3
# A fake renderer: the converged image (2 x 2 upsampled) plus Gaussian noise of SIGMA from the
# seed after SEED_FLAG (or seed 0 when IGNORE_SEED; the two programs' noise streams differ);
# writes .npy (ours) or PFM (the reference).
import sys
import numpy as np
args = sys.argv[1:]
seed = 0 if IGNORE_SEED else int(args[args.index(SEED_FLAG) + 1])
out = args[args.index(OUT_FLAG) + 1]
converged = np.load(CONVERGED)
fine = np.repeat(np.repeat(converged, 2, axis=0), 2, axis=1)
image = fine + np.random.default_rng([seed, int(SIGMA * 1e6)]).normal(0.0, SIGMA, fine.shape)
if out.endswith(".pfm"):
    h, w, _ = image.shape
    open(out, "wb").write(f"PF\n{w} {h}\n-1\n".encode() + image.astype("<f4").tobytes())
else:
    with open(out, "wb") as f:
        np.save(f, image)
'''


def write_pfm(path, image, little_endian=True):
    """A colour PFM the way SmallVCM's SavePFM writes one: rows in memory order, top first."""
    height, width, _ = image.shape
    order = "<" if little_endian else ">"
    header = f"PF\n{width} {height}\n{-1 if little_endian else 1}\n".encode()
    path.write_bytes(header + image.astype(order + "f4").tobytes())


def fake_program(path, converged, sigma, seed_flag, out_flag, ignore_seed=False):
    text = FAKE_PROGRAM
    for name, value in (("IGNORE_SEED", repr(ignore_seed)), ("SEED_FLAG", repr(seed_flag)),
                        ("OUT_FLAG", repr(out_flag)), ("CONVERGED", repr(str(converged))),
                        ("SIGMA", repr(sigma))):
        text = text.replace(name, value)
    path.write_text(text)
    path.chmod(0o755)


def check_images_and_error(reference, rng):
    image = rng.random((6, 4, 3))
    image[0, :, 0] += 10.0  # top-bottom and left-right asymmetric: a flipped read changes it
    image = image.astype(np.float32).astype(np.float64)  # what a PFM holds exactly
    with tempfile.TemporaryDirectory() as work:
        for little in (True, False):
            path = Path(work) / "image.pfm"
            write_pfm(path, image, little)
            read = reference.read_pfm(path)
            assert read.shape == (6, 4, 3), read.shape
            assert np.array_equal(read, image), f"little_endian={little}: pixels differ"
        bad = Path(work) / "grey.pfm"
        bad.write_bytes(b"Pf\n1 1\n-1\n" + struct.pack("<f", 1.0))
        try:
            reference.read_pfm(bad)
            raise AssertionError("a greyscale PFM was accepted")
        except ValueError as e:
            assert "grey.pfm" in str(e), e

    converged = rng.random((4, 4, 3))
    fine = np.repeat(np.repeat(converged, 2, axis=0), 2, axis=1)  # 8 x 8, same averages
    fine[0, 0, :] += 0.4  # one fine pixel: its 2 x 2 average moves by 0.1 in 3 channels
    error = reference.image_error(fine, converged)
    expected = 3 * 0.1 ** 2 / converged.size
    assert abs(error["mse"] - expected) < 1e-12, (error, expected)
    r = converged[0, 0, :]
    expected_relative = float((0.1 ** 2 / (r * r + 0.01)).sum()) / converged.size
    assert abs(error["relative_mse"] - expected_relative) < 1e-12, (error, expected_relative)
    assert abs(error["mean_ratio"]
               - (converged.mean() + 0.4 * 3 / fine.size) / converged.mean()) < 1e-12


def check_ratio_formula(reference):
    row = {"ours_relative_mses": [0.01, 0.02, 0.03], "ours_seconds": [10.0, 12.0, 11.0],
           "reference_relative_mses": [0.04, 0.05, 0.06], "reference_seconds": [20.0, 21.0, 22.0]}
    ratio, se = reference.efficiency_ratio(row)
    # means: ours 0.02 and 11 s, reference 0.05 and 21 s
    assert abs(ratio - (0.05 * 21.0) / (0.02 * 11.0)) < 1e-12, ratio
    # Jackknife over the three rounds: leave round i out of both sides.
    loo = []
    for i in range(3):
        keep = [j for j in range(3) if j != i]

        def m(key):
            return sum(row[key][j] for j in keep) / 2

        loo.append(m("reference_relative_mses") * m("reference_seconds")
                   / (m("ours_relative_mses") * m("ours_seconds")))
    centre = sum(loo) / 3
    expected = math.sqrt(2 / 3 * sum((x - centre) ** 2 for x in loo))
    assert abs(se - expected) < 1e-12, (se, expected)
    # The first-order error: the four means' relative standard errors in quadrature.
    rse = math.sqrt((0.01 / math.sqrt(3) / 0.02) ** 2 + (1.0 / math.sqrt(3) / 11.0) ** 2
                    + (0.01 / math.sqrt(3) / 0.05) ** 2 + (1.0 / math.sqrt(3) / 21.0) ** 2)
    propagated = reference.propagated_ratio_se(row)
    assert abs(propagated - ratio * rse) < 1e-12, (propagated, ratio * rse)
    # Swapping the sides inverts the ratio.
    swapped = {"ours_relative_mses": row["reference_relative_mses"],
               "ours_seconds": row["reference_seconds"],
               "reference_relative_mses": row["ours_relative_mses"],
               "reference_seconds": row["ours_seconds"]}
    ratio2, se2 = reference.efficiency_ratio(swapped)
    assert abs(ratio * ratio2 - 1) < 1e-12, (ratio, ratio2)
    assert abs(reference.propagated_ratio_se(swapped) / ratio2 - propagated / ratio) < 1e-12
    # A single round has no spread to estimate from.
    one = {k: v[:1] for k, v in row.items()}
    assert reference.efficiency_ratio(one)[1] == 0.0

    # Time per iteration: (run - one-iteration run) / (iterations - 1), ratio by jackknife.
    assert reference.per_iteration([9.0, 11.0], 3.0, 4) == [2.0, 8.0 / 3]
    timed = {"ours_seconds_per_iteration": [1.0, 2.0, 3.0],
             "reference_seconds_per_iteration": [4.0, 4.0, 4.0]}
    t_ratio, t_se = reference.time_ratio(timed)
    assert abs(t_ratio - 0.5) < 1e-12, t_ratio
    loo = [(5 / 2) / 4, (4 / 2) / 4, (3 / 2) / 4]
    centre = sum(loo) / 3
    expected = math.sqrt(2 / 3 * sum((x - centre) ** 2 for x in loo))
    assert abs(t_se - expected) < 1e-12, (t_se, expected)
    assert reference.time_ratio(row) is None  # no per-iteration times (wall timing)

    # The picture check: reference mean ratio minus ours, SEs in quadrature.
    means = {"ours_mean_ratios": [0.99, 1.01], "reference_mean_ratios": [1.02, 1.04]}
    d, d_se = reference.mean_difference(means)
    assert abs(d - 0.03) < 1e-12, d
    assert abs(d_se - math.hypot(0.01, 0.01)) < 1e-12, d_se
    # The verdicts at 2 SE.
    assert reference.met(2.5, 0.2, 2.0, True) == "yes"
    assert reference.met(2.5, 0.3, 2.0, True) != "yes"
    assert reference.met(0.5, 0.04, 0.6, False) == "yes"
    assert reference.met(0.5, 0.06, 0.6, False) != "yes"


def check_symmetric_run(reference, common, rng, work, timing):
    work = Path(work)
    converged = 0.2 + rng.random((16, 16, 3))
    np.save(work / "converged.npy", converged)
    bin_dir = work / "bin"
    bin_dir.mkdir()
    fake_program(bin_dir / "render", work / "converged.npy", 0.02, "--seed", "--out")
    fake_program(work / "smallvcm", work / "converged.npy", 0.04, reference.REFERENCE_SEED_FLAG,
                 "-o")
    fake_program(work / "smallvcm-fixed-seed", work / "converged.npy", 0.04,
                 reference.REFERENCE_SEED_FLAG, "-o", ignore_seed=True)

    calls = []
    lock = threading.Lock()

    def iterations_of(cmd):
        return int(cmd[cmd.index("--iterations" if "--iterations" in cmd else "-i") + 1])

    def fake_timed(cmd, cpus, env=None):
        # No clock. Wall timing: ours "takes" 1 s, the reference 2 s. CPU timing: a start-up
        # and a cost per iteration (ours 0.5 + 1 x n, the reference 0.1 + 2 x n).
        subprocess.run(cmd, check=True)
        ours = Path(cmd[0]).name == "render"
        n = iterations_of(cmd)
        seconds = (1.0 if ours else 2.0) if timing == "wall" else (
            0.5 + n if ours else 0.1 + 2.0 * n)
        with lock:
            calls.append((cmd, set(cpus), dict(env) if env else None))
        return seconds, 10.0, seconds

    reference.timed = fake_timed
    reference.read_ours_image = lambda path: np.load(path)
    # Five rounds with wall timing (the first program alternates), four with CPU timing (an even
    # number: each program runs as often on either CPU).
    runs = 5 if timing == "wall" else 4
    result = reference.run(bin_dir, work / "smallvcm", False, work, log=lambda m: None,
                           scenes=["2-gbs_p"], algorithms=["vcm"], iterations=2, runs=runs,
                           reference_images={"2-gbs_p": (converged, 0.0)}, timing=timing)
    (row,) = result["rows"]
    assert row["timing"] == timing and result["timing"] == timing
    assert len(row["ours_relative_mses"]) == len(row["reference_relative_mses"]) == runs, row
    main_calls = [c for c in calls if iterations_of(c[0]) == 2]
    ours_seeds = sorted(int(c[c.index("--seed") + 1]) for c, _, _ in main_calls
                        if c[0].endswith("render"))
    ref_seeds = sorted(int(c[c.index(reference.REFERENCE_SEED_FLAG) + 1]) for c, _, _ in main_calls
                       if c[0].endswith("smallvcm"))
    assert ours_seeds == ref_seeds == list(range(runs)), (ours_seeds, ref_seeds)
    ours_calls = [c for c in calls if c[0][0].endswith("render")]
    ref_calls = [c for c in calls if c[0][0].endswith("smallvcm")]
    if timing == "wall":
        firsts = [Path(calls[2 * r][0][0]).name for r in range(runs)]
        assert firsts == ["render", "smallvcm"] * (runs // 2) + ["render"], firsts
        assert all(c[0][c[0].index("--threads") + 1] == str(reference.THREADS) for c in ours_calls)
        assert len(calls) == 2 * runs  # no start-up runs
        expected = 4.0 * 2.0  # relative MSE 4 x lower (noise 0.02 against 0.04), time 2 x shorter
    else:
        # Two one-iteration runs of each for the start-up, one on either CPU, then the rounds.
        assert len(calls) == 2 * runs + 4, len(calls)
        starts = [(Path(c[0]).name, next(iter(cpus))) for c, cpus, _ in calls
                  if iterations_of(c) == 1]
        assert sorted(starts) == sorted({(n, cpu) for n, _ in starts for _, cpu in starts}), starts
        assert all(c[0][c[0].index("--threads") + 1] == "1" for c in ours_calls)
        assert all(c[2] and c[2].get("OMP_NUM_THREADS") == "1" for c in ref_calls)
        assert all(len(cpus) == 1 for _, cpus, _ in calls)
        # In each round the two programs ran on different CPUs and swapped them every round.
        by_seed = {}
        for cmd, cpus, _ in main_calls:
            flag = "--seed" if cmd[0].endswith("render") else reference.REFERENCE_SEED_FLAG
            by_seed.setdefault(int(cmd[cmd.index(flag) + 1]), {})[
                Path(cmd[0]).name] = next(iter(cpus))
        for seed, cpus in by_seed.items():
            assert cpus["render"] != cpus["smallvcm"], (seed, cpus)
            assert cpus["render"] == by_seed[seed % 2]["render"], by_seed
        assert by_seed[0]["render"] != by_seed[1]["render"], by_seed
        # Start-up 0.5 s and 0.1 s; 1 s and 2 s per iteration, exactly.
        assert row["ours_fixed_cpu"] == 1.5 and row["reference_fixed_cpu"] == 2.1, row
        t_ratio, t_se = reference.time_ratio(row)
        assert abs(t_ratio - 0.5) < 1e-12 and t_se < 1e-12, (t_ratio, t_se)
        expected = 4.0 * (0.1 + 2 * 2.0) / (0.5 + 2 * 1.0)
    ratio, se = row["efficiency_ratio"], row["efficiency_ratio_se"]
    assert (ratio, se) == reference.efficiency_ratio(row)
    assert se > 0, se
    assert abs(ratio - expected) < 4 * se, (ratio, se, expected)
    lines = reference.section(result)
    table = [line for line in lines if line.startswith(f"| 2-gbs_p | vcm | {runs} |")]
    assert len(table) == 1 and f"**{ratio:.2f} ± {se:.2f}**" in table[0], (table, lines)
    assert table[0].rstrip().endswith("| yes |"), table[0]  # true ratio - 2 SE >= 2
    header = next(i for i, line in enumerate(lines) if "| ours s / iteration |" in line)
    times = [line for line in lines[header:] if line.startswith("| 2-gbs_p | vcm | ")][:1]
    assert len(times) == 1, lines
    if timing == "cpu":
        assert "**0.50 ± 0.00** | yes |" in times[0], times[0]

    if timing == "wall":  # the refusal does not depend on the timing
        try:
            reference.run(bin_dir, work / "smallvcm-fixed-seed", False, work, log=lambda m: None,
                          scenes=["2-gbs_p"], algorithms=["vcm"], iterations=2, runs=2,
                          reference_images={"2-gbs_p": (converged, 0.0)}, timing=timing)
            raise AssertionError("a reference that ignores the seed was accepted")
        except RuntimeError as e:
            assert "not independent" in str(e), e

    machine = common.machine_info() if common else {"source_revision": "abc123"}
    data = reference.write_data(result, work / "data", machine, "scripts/bench --only reference")
    record = json.loads(data.read_text())
    assert record["commit"] == machine["source_revision"], record["commit"]
    assert record["load"]["start"] == result["load_start"], record["load"]
    assert len(record["load"]["per_run"]) == runs, record["load"]
    assert record["command"] == "scripts/bench --only reference"
    assert json.loads(json.dumps(machine)) == record["machine"], record["machine"]
    assert record["result"]["rows"][0]["runs"] == runs
    return ratio, se, expected


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--source-dir", type=Path, required=True)
    args = parser.parse_args()
    sys.path.insert(0, str(args.source_dir / "scripts"))
    from benchlib import reference
    try:
        from benchlib import common
    except ImportError:  # common needs nothing beyond numpy today; keep the test independent
        common = None

    rng = np.random.default_rng(7)
    check_images_and_error(reference, rng)
    check_ratio_formula(reference)
    if len(os.sched_getaffinity(0)) < reference.THREADS:
        print(f"bench.reference_error: the symmetric run needs {reference.THREADS} CPUs")
        return 1
    results = []
    for timing in reference.TIMINGS:
        with tempfile.TemporaryDirectory() as work:
            results.append((timing, *check_symmetric_run(reference, common, rng, work, timing)))
    print("bench.reference_error: PFM orientation, relative error, the ratios' formulas and a "
          "symmetric run on synthetic programs with each timing ("
          + ", ".join(f"{timing}: ratio {r:.2f} ± {se:.2f}, true {e:.2f}"
                      for timing, r, se, e in results) + ") as expected")
    return 0


if __name__ == "__main__":
    sys.exit(main())
