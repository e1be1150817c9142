#!/usr/bin/python3
"""Smoke test of `scripts/bench --quick --only upbp` (CTest: bench.upbp_quick): the density sweep
runs end to end on tiny images and writes its document and plot, with every scene and arm in
the tables and a verdict. Nothing is timed or compared here; the figures are the bench's."""

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
from benchlib import upbp  # noqa: E402


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--source-dir", type=Path, required=True)
    parser.add_argument("--build-dir", type=Path, required=True)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-upbp-quick-") as tmp:
        cmd = ["/usr/bin/python3", str(args.source_dir / "scripts" / "bench"), "--quick",
               "--only", "upbp", "--threads", "1", "--out", tmp, "--build-dir",
               str(args.build_dir)]
        print("running:", " ".join(cmd), flush=True)
        subprocess.run(cmd, check=True)
        text = (Path(tmp) / "upbp.md").read_text()
        for scene in upbp.SCENES:
            assert f"## {scene}" in text, f"no section for {scene}"
        for arm in upbp.ARMS:
            rows = [line for line in text.split("\n") if line.startswith(f"| {arm} |")]
            assert len(rows) == len(upbp.SCENES), f"{arm}: {len(rows)} table rows"
        assert "**held**" in text or "**not held**" in text, "no verdict"
        assert (Path(tmp) / "img" / "upbp" / "density-sweep.png").stat().st_size > 0
    print("bench.upbp_quick: document, tables and plot written")
    return 0


if __name__ == "__main__":
    sys.exit(main())
