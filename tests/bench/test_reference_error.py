#!/usr/bin/python3
"""The per-unit-of-error part of `scripts/bench --reference-smallvcm` (CTest:
bench.reference_error), without SmallVCM and without timing anything:

1. A PFM written as SmallVCM's driver writes it (top row first, negative scale) reads back in the
   right orientation, both byte orders; the error of a 512 x 512 image against a 256 x 256
   converged one is that of its 2 x 2 box average. Exact inputs, exact checks.
2. The efficiency ratio and its standard error follow their formulas (exact inputs).
3. The symmetric run on synthetic programs: a fake `render` and a fake reference write the
   converged image plus Gaussian noise from their seed (the reference's noise twice ours', its
   run time, as the replaced timer reports it, twice ours). run() gives both sides the same
   number of runs with seeds 0.., compares all images with the same converged image, and its
   ratio is within 4 of its own standard errors of the true ratio 8 (4 x the error, 2 x the
   time; 4 SE: a correct estimate misses by chance with probability < 1e-4, and the fixed
   seeds make the check deterministic). A fake reference that ignores the seed is refused:
   its runs are not independent.
4. The data file carries the commit, the machine, the load and the command."""

import argparse
import json
import math
import os
import struct
import subprocess
import sys
import tempfile
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
    rse = math.sqrt((0.01 / math.sqrt(3) / 0.02) ** 2 + (1.0 / math.sqrt(3) / 11.0) ** 2
                    + (0.01 / math.sqrt(3) / 0.05) ** 2 + (1.0 / math.sqrt(3) / 21.0) ** 2)
    assert abs(se - ratio * rse) < 1e-12, (se, ratio * rse)
    # Swapping the sides inverts the ratio and keeps its relative standard error.
    swapped = {"ours_relative_mses": row["reference_relative_mses"],
               "ours_seconds": row["reference_seconds"],
               "reference_relative_mses": row["ours_relative_mses"],
               "reference_seconds": row["ours_seconds"]}
    ratio2, se2 = reference.efficiency_ratio(swapped)
    assert abs(ratio * ratio2 - 1) < 1e-12 and abs(se / ratio - se2 / ratio2) < 1e-12


def check_symmetric_run(reference, common, rng, work):
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

    commands = []

    def fake_timed(cmd, cpus):
        # No clock: ours "takes" 1 s, the reference 2 s, whatever the machine does.
        subprocess.run(cmd, check=True)
        commands.append(cmd)
        return (1.0 if Path(cmd[0]).name == "render" else 2.0), 10.0, 1.0

    reference.timed = fake_timed
    reference.read_ours_image = lambda path: np.load(path)
    runs = 5
    result = reference.run(bin_dir, work / "smallvcm", False, work, log=lambda m: None,
                           scenes=["2-gbs_p"], algorithms=["vcm"], iterations=2, runs=runs,
                           reference_images={"2-gbs_p": (converged, 0.0)})
    (row,) = result["rows"]
    assert len(row["ours_relative_mses"]) == len(row["reference_relative_mses"]) == runs, row
    ours_seeds = [int(c[c.index("--seed") + 1]) for c in commands if c[0].endswith("render")]
    ref_seeds = [int(c[c.index(reference.REFERENCE_SEED_FLAG) + 1]) for c in commands
                 if c[0].endswith("smallvcm")]
    assert ours_seeds == ref_seeds == list(range(runs)), (ours_seeds, ref_seeds)
    firsts = [Path(commands[2 * r][0]).name for r in range(runs)]
    assert firsts == ["render", "smallvcm"] * (runs // 2) + ["render"], firsts
    ratio, se = row["efficiency_ratio"], row["efficiency_ratio_se"]
    assert (ratio, se) == reference.efficiency_ratio(row)
    assert se > 0, se
    # True ratio: relative MSE 4 x lower (noise 0.02 against 0.04), time 2 x shorter.
    assert abs(ratio - 8.0) < 4 * se, (ratio, se)
    lines = reference.section(result)
    table = [line for line in lines if line.startswith("| 2-gbs_p | vcm | 5 |")]
    assert len(table) == 1 and f"**{ratio:.2f} ± {se:.2f}**" in table[0], (table, lines)
    assert table[0].rstrip().endswith("| yes |"), table[0]  # 8 - 2 SE >= 2

    try:
        reference.run(bin_dir, work / "smallvcm-fixed-seed", False, work, log=lambda m: None,
                      scenes=["2-gbs_p"], algorithms=["vcm"], iterations=2, runs=2,
                      reference_images={"2-gbs_p": (converged, 0.0)})
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
    return ratio, se


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
    with tempfile.TemporaryDirectory() as work:
        ratio, se = check_symmetric_run(reference, common, rng, work)
    print(f"bench.reference_error: PFM orientation, relative error, the ratio's formula and a "
          f"symmetric run on synthetic programs (ratio {ratio:.2f} ± {se:.2f}, true 8) as expected")
    return 0


if __name__ == "__main__":
    sys.exit(main())
