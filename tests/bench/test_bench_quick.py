#!/usr/bin/python3
"""Smoke test of `scripts/bench --quick --only convergence` (CTest: bench.quick).

Runs the reduced convergence benchmark into a temporary directory and checks that it wrote
the document, one plot per scene and results.json, and that every measurement in the JSON is
a finite positive number (every other number finite). It never checks timings.

    test_bench_quick.py --source-dir SRC --build-dir BUILD
"""

import argparse
import json
import math
import subprocess
import sys
import tempfile
from pathlib import Path

POSITIVE_KEYS = ("iterations", "seconds", "process_seconds", "rmse", "relative_mse",
                 "samples_per_second", "estimated_relative_error")


def reject_constant(name):
    """json.loads hook: NaN and Infinity are failures, not numbers."""
    raise AssertionError(f"results.json contains {name}")


def walk_numbers(value, path="results"):
    """Yields (path, number) for every number in a JSON value (bools excluded)."""
    if isinstance(value, dict):
        for k, v in value.items():
            yield from walk_numbers(v, f"{path}.{k}")
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from walk_numbers(v, f"{path}[{i}]")
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        yield path, value


def check_results(out: Path) -> None:
    """Asserts the files exist and the numbers are sane."""
    doc = out / "results" / "speed-vs-error.md"
    img = out / "img" / "speed-vs-error"
    results_file = img / "results.json"
    assert doc.is_file() and doc.stat().st_size > 0, f"missing {doc}"
    assert results_file.is_file(), f"missing {results_file}"
    results = json.loads(results_file.read_text(), parse_constant=reject_constant)
    text = doc.read_text()
    assert results["scenes"], "no scene measured"
    for path, number in walk_numbers(results):
        assert math.isfinite(number), f"{path} = {number}"
    for name, scene in results["scenes"].items():
        png = img / f"{name}.png"
        assert png.is_file() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", f"bad {png}"
        assert f"## {name}" in text, f"{doc} has no section for {name}"
        assert scene["series"], f"{name}: no algorithm measured"
        for algo, points in scene["series"].items():
            assert len(points) >= 2, f"{name} {algo}: {len(points)} points"
            for p in points:
                for key in POSITIVE_KEYS:
                    assert p[key] > 0, f"{name} {algo} {p['iterations']} it: {key} = {p[key]}"
            slope = scene["slopes"][algo]
            assert slope is not None and math.isfinite(slope), f"{name} {algo}: slope {slope}"
        if "claim" in scene:
            assert scene["claim"]["verdict"] in text, f"{name}: verdict not in the document"
    print(f"bench.quick: {len(results['scenes'])} scenes, "
          f"{sum(len(p) for s in results['scenes'].values() for p in s['series'].values())} "
          f"points, {results['total_seconds']:.0f} s")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--source-dir", type=Path, required=True)
    parser.add_argument("--build-dir", type=Path, required=True)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-quick-") as tmp:
        cmd = ["/usr/bin/python3", str(args.source_dir / "scripts" / "bench"), "--quick",
               "--only", "convergence", "--out", tmp, "--build-dir", str(args.build_dir)]
        print("running:", " ".join(cmd), flush=True)
        subprocess.run(cmd, check=True)
        check_results(Path(tmp))
    return 0


if __name__ == "__main__":
    sys.exit(main())
