#!/usr/bin/python3
"""Smoke test of `scripts/bench --quick --only upbp` (CTest: bench.upbp_quick): the density sweep
runs end to end on tiny images and writes its document and plot, with every scene and arm in
the tables and a verdict. Nothing is timed or compared here; the figures are the bench's."""

import sys

from quick_bench import quick_bench
from benchlib import upbp  # noqa: E402  (scripts/ is on the path through quick_bench)


def main():
    with quick_bench("upbp", "upbp.md") as (out, text):
        for scene in upbp.SCENES:
            assert f"## {scene}" in text, f"no section for {scene}"
        for arm in upbp.ARMS:
            rows = [line for line in text.split("\n") if line.startswith(f"| {arm} |")]
            assert len(rows) == len(upbp.SCENES), f"{arm}: {len(rows)} table rows"
        assert "**held**" in text or "**not held**" in text, "no verdict"
        assert (out / "img" / "upbp" / "density-sweep.png").stat().st_size > 0
    print("bench.upbp_quick: document, tables and plot written")
    return 0


if __name__ == "__main__":
    sys.exit(main())
