"""Shared by the bench smoke tests (tests/bench/test_bench_*_quick.py): run one part of
`scripts/bench --quick` into a temporary directory and hand the test its written document.
Nothing here times or compares anything; the figures are the bench's."""

import argparse
import contextlib
import subprocess
import sys
import tempfile
from pathlib import Path

SOURCE_DIR = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(SOURCE_DIR / "scripts"))


def parse_dirs():
    """The --source-dir and --build-dir every bench smoke test takes from CTest."""
    parser = argparse.ArgumentParser()
    parser.add_argument("--source-dir", type=Path, required=True)
    parser.add_argument("--build-dir", type=Path, required=True)
    return parser.parse_args()


@contextlib.contextmanager
def quick_bench(only: str, document: str):
    """Runs `scripts/bench --quick --only ONLY --threads 1` into a temporary directory and
    yields (that directory, the text of results/DOCUMENT in it); the directory is removed after."""
    args = parse_dirs()
    with tempfile.TemporaryDirectory(prefix=f"bench-{only}-quick-") as tmp:
        cmd = ["/usr/bin/python3", str(args.source_dir / "scripts" / "bench"), "--quick",
               "--only", only, "--threads", "1", "--out", tmp, "--build-dir",
               str(args.build_dir)]
        print("running:", " ".join(cmd), flush=True)
        subprocess.run(cmd, check=True)
        yield Path(tmp), (Path(tmp) / "results" / document).read_text()
