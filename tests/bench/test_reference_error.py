#!/usr/bin/python3
"""The per-unit-of-error part of `scripts/bench --reference-smallvcm` (CTest:
bench.reference_error), without SmallVCM: a PFM written as SmallVCM's driver writes it (top row
first, negative scale) reads back in the right orientation, both byte orders; the error of a
512 x 512 image against a 256 x 256 converged one is the MSE of its 2 x 2 box average; the
efficiency table's ratio is (MSE_ref x t_ref) / (MSE_ours x t_ours). Exact inputs, so the
checks are exact up to float32 rounding. Nothing is timed."""

import argparse
import struct
import sys
import tempfile
from pathlib import Path

import numpy as np


def write_pfm(path, image, little_endian=True):
    """A colour PFM the way SmallVCM's SavePFM writes one: rows in memory order, top first."""
    height, width, _ = image.shape
    order = "<" if little_endian else ">"
    header = f"PF\n{width} {height}\n{-1 if little_endian else 1}\n".encode()
    path.write_bytes(header + image.astype(order + "f4").tobytes())


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--source-dir", type=Path, required=True)
    args = parser.parse_args()
    sys.path.insert(0, str(args.source_dir / "scripts"))
    from benchlib import reference

    rng = np.random.default_rng(7)
    # A top-bottom and left-right asymmetric image: a flipped or mirrored read changes it.
    image = rng.random((6, 4, 3))
    image[0, :, 0] += 10.0
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
    mse, mean_ratio = reference.image_error(fine, converged)
    expected = 3 * 0.1 ** 2 / converged.size
    assert abs(mse - expected) < 1e-12, (mse, expected)
    assert abs(mean_ratio - (converged.mean() + 0.4 * 3 / fine.size) / converged.mean()) < 1e-12

    row = {"scene": "2-gbs_p", "algorithm": "vcm", "ours_seconds": [10.0, 12.0, 11.0],
           "reference_seconds": [20.0, 22.0, 21.0], "ours_mse": 0.02, "reference_mse": 0.015,
           "converged_own_mse": 0.001, "ours_mean_ratio": 1.0, "reference_mean_ratio": 1.0,
           "ours_mses": [0.03, 0.02, 0.01]}
    lines = reference.efficiency_lines([row])
    table = [line for line in lines if line.startswith("| 2-gbs_p |")]
    assert len(table) == 1, lines
    ratio = (0.015 * 21.0) / (0.02 * 11.0)  # medians 11 and 21 s
    assert f"**{ratio:.2f}**" in table[0], (table[0], ratio)
    assert "(5%)" in table[0], table[0]
    assert any("2-gbs_p vcm 3.000e-02, 2.000e-02, 1.000e-02" in line for line in lines), lines
    print(f"bench.reference_error: PFM orientation, error and efficiency ratio ({ratio:.2f}) "
          "as expected")
    return 0


if __name__ == "__main__":
    sys.exit(main())
