#!/usr/bin/python3
"""The peak memory of `scripts/bench --only reference` is each program's own
(scripts/benchlib/reference.py, timed()), not the benchmark's: a child forked from a Python
process carries the fork's RSS high-water mark across exec, so wait4's ru_maxrss of a child
started directly is at least the parent's peak. Here the parent first touches PARENT_MIB, then
timed() runs `true` (its own peak ~1 MiB) and a program that touches CHILD_MIB. The first must
report far less than the parent's peak, the second at least CHILD_MIB and less than
CHILD_MIB + the parent's peak (Python's own start-up is ~10 MiB). Nothing is timed: only the
memory figure is checked. Without GNU time (/usr/bin/time) timed() reports no peak (nan), which
is checked instead."""

import argparse
import math
import sys
from pathlib import Path

PARENT_MIB = 300
CHILD_MIB = 100


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--source-dir", required=True)
    args = parser.parse_args()
    sys.path.insert(0, str(Path(args.source_dir) / "scripts"))
    from benchlib import reference

    parent = bytearray(PARENT_MIB << 20)
    for i in range(0, len(parent), 4096):
        parent[i] = 1
    cpus = {sorted(__import__("os").sched_getaffinity(0))[0]}
    _, true_mib, _ = reference.timed(["true"], cpus)
    touch = (f"a = bytearray({CHILD_MIB} << 20)\n"
             "for i in range(0, len(a), 4096): a[i] = 1\n")
    _, child_mib, _ = reference.timed([sys.executable, "-c", touch], cpus)
    if reference.peak_rss_tool() is None:
        assert math.isnan(true_mib) and math.isnan(child_mib), (true_mib, child_mib)
        # The figure this test checks is not measured without GNU time: report a skip (CTest
        # SKIP_RETURN_CODE 77), not a pass.
        print("SKIP: no GNU time (/usr/bin/time): peak memory reported as nan, as documented")
        sys.exit(77)
    assert true_mib < 0.25 * PARENT_MIB, f"`true` reported {true_mib} MiB: the parent's peak"
    assert CHILD_MIB <= child_mib < CHILD_MIB + 0.5 * PARENT_MIB, child_mib
    print(f"peak memory: true {true_mib:.1f} MiB, {CHILD_MIB} MiB program {child_mib:.1f} MiB "
          f"(parent {PARENT_MIB} MiB)")


if __name__ == "__main__":
    main()
