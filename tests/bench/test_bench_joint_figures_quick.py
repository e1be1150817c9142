#!/usr/bin/python3
"""Smoke test of `scripts/bench --quick --only joint-figures` (CTest: bench.joint_figures_quick):
the convergence-slope experiment and the equal-time pictures of joint path sampling run end to
end on tiny images (fixed iteration counts, no `--time`), and the document, its tables, the
verdicts and the four figures are written. Nothing is timed or compared here; the figures are
the bench's."""

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
from benchlib import joint_figures  # noqa: E402


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--source-dir", type=Path, required=True)
    parser.add_argument("--build-dir", type=Path, required=True)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-joint-figures-quick-") as tmp:
        cmd = ["/usr/bin/python3", str(args.source_dir / "scripts" / "bench"), "--quick",
               "--only", "joint-figures", "--threads", "1", "--out", tmp, "--build-dir",
               str(args.build_dir)]
        print("running:", " ".join(cmd), flush=True)
        subprocess.run(cmd, check=True)
        text = (Path(tmp) / "joint-figures.md").read_text()
        for name in joint_figures.TECHNIQUES:
            rows = [line for line in text.split("\n") if line.startswith(f"| {name} |")]
            assert len(rows) == 2, f"{name}: {len(rows)} table rows (errors and slope)"
            assert "**held**" in rows[1] or "**not held**" in rows[1], f"{name}: no verdict"
        for section in ("### volpt, fog box, isotropic", "### volpt, fog box, g = 0.9",
                        "### bpt, fog box, isotropic"):
            assert section in text, f"no section {section}"
        images = Path(tmp) / joint_figures.IMAGE_DIR
        for png in ("slopes.png", "fog-box-isotropic-volpt.png", "fog-box-g09-volpt.png",
                    "fog-box-isotropic-bpt.png"):
            assert (images / png).stat().st_size > 0, f"{png} empty"
            assert f"({joint_figures.IMAGE_DIR}/{png})" in text, f"{png} not referenced"
    print("bench.joint_figures_quick: document, tables, verdicts and figures written")
    return 0


if __name__ == "__main__":
    sys.exit(main())
