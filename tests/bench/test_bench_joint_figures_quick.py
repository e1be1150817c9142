#!/usr/bin/python3
"""Smoke test of `scripts/bench --quick --only joint-figures` (CTest: bench.joint_figures_quick):
the convergence-slope experiment and the equal-time pictures of joint path sampling run end to
end on tiny images (fixed iteration counts, no `--time`), and the document, its tables, the
verdicts and the four figures are written. Nothing is timed or compared here; the figures are
the bench's."""

import sys

from quick_bench import quick_bench
from benchlib import joint_figures  # noqa: E402  (scripts/ is on the path through quick_bench)


def main():
    with quick_bench("joint-figures", "joint-figures.md") as (out, text):
        for name in joint_figures.TECHNIQUES:
            rows = [line for line in text.split("\n") if line.startswith(f"| {name} |")]
            assert len(rows) == 2, f"{name}: {len(rows)} table rows (errors and slope)"
            assert "**held**" in rows[1] or "**not held**" in rows[1], f"{name}: no verdict"
        for section in ("### volpt, fog box, isotropic", "### volpt, fog box, g = 0.9",
                        "### bpt, fog box, isotropic"):
            assert section in text, f"no section {section}"
        images = out / joint_figures.IMAGE_DIR
        for png in ("slopes.png", "fog-box-isotropic-volpt.png", "fog-box-g09-volpt.png",
                    "fog-box-isotropic-bpt.png"):
            assert (images / png).stat().st_size > 0, f"{png} empty"
            assert f"(../{joint_figures.IMAGE_DIR}/{png})" in text, f"{png} not referenced"
    print("bench.joint_figures_quick: document, tables, verdicts and figures written")
    return 0


if __name__ == "__main__":
    sys.exit(main())
