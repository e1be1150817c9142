#!/usr/bin/python3
"""Smoke test of `scripts/bench --quick --only claims` (CTest: bench.claims_quick): the claims
suite runs end to end on tiny images and writes its data file, page and pictures. It checks the
file's shape and that every figure is a finite positive number; nothing is timed, and no verdict
is asserted (the quick run is far too short to decide a claim)."""

import json
import math
import sys

from quick_bench import quick_bench
from benchlib import claims  # noqa: E402  (scripts/ is on the path through quick_bench)

ROW_KEYS = {"id", "method", "scene", "metric", "arms", "ratio", "se", "target", "direction",
            "held", "commit", "machine", "load", "command", "pictures", "resolution"}
ARM_KEYS = {"v", "v_se", "t", "t_se", "cost", "runs", "iterations", "command"}


def positive(value, what):
    assert isinstance(value, (int, float)) and math.isfinite(value) and value > 0, \
        f"{what}: {value!r} is not a finite positive number"


def main():
    with quick_bench("claims", "claims.md") as (out, text):
        data = json.loads((out / "data" / "claims.json").read_text())
        assert data["quick"] is True
        ids = [row["id"] for row in data["claims"]]
        assert ids == [c["id"] for c in claims.CLAIMS if c["id"] in claims.QUICK_CLAIMS], ids
        for row in data["claims"]:
            missing = ROW_KEYS - row.keys()
            assert not missing, f"{row['id']}: missing {missing}"
            assert isinstance(row["held"], bool), f"{row['id']}: held is {row['held']!r}"
            positive(row["ratio"], f"{row['id']} ratio")
            positive(row["target"], f"{row['id']} target")
            assert math.isfinite(row["se"]) and row["se"] >= 0, f"{row['id']} se {row['se']}"
            assert row["direction"] in (">=", "<="), row["direction"]
            claim = next(c for c in claims.CLAIMS if c["id"] == row["id"])
            assert set(row["arms"]) == set(claim["arms"]), f"{row['id']}: arms {list(row['arms'])}"
            for name, arm in row["arms"].items():
                missing = ARM_KEYS - arm.keys()
                assert not missing, f"{row['id']}/{name}: missing {missing}"
                for key in ("v", "t", "cost"):
                    positive(arm[key], f"{row['id']}/{name} {key}")
                assert arm["runs"] >= 2 and arm["iterations"] >= 2, f"{row['id']}/{name}"
                picture = out / "img" / "claims" / row["pictures"][name]["file"]
                assert picture.stat().st_size > 0, f"{picture} is empty"
            assert f"## {row['id']}" in text, f"no section for {row['id']} in the page"
            assert f"[{row['id']}](#{claims.anchor(row['id'])})" in text, f"no summary row for {row['id']}"
    print("bench.claims_quick: data file, page and pictures written, every figure finite")
    return 0


if __name__ == "__main__":
    sys.exit(main())
