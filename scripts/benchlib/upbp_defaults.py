"""upbp's light-path fractions chosen by measured efficiency (`scripts/bench --only
upbp-defaults`, writes docs/data/upbp/defaults.json; the choice is documented in
docs/design/media.md, "Photon beams", and applied in core/integrators/bidirectional/config.h).

`upbp` with every estimator, at the claims' radius (1 % of the scene radius), on the UPBP claim
scenes (scripts/benchlib/claims.py), with photon beams and query beams drawn from the same
fraction F of each iteration's light paths (`--photon-beam-paths F --query-beam-paths F`), for
each F in FRACTIONS. Each (scene, F) is measured as an arm of a claim is (claims.Arm: v, one
iteration's relative variance from independent single-threaded runs, jackknife SE; t, CPU
seconds per iteration), and scored by its equal-time RMSE relative to the best F on that scene,
sqrt(v t / min v t). The default is the F whose worst score over the scenes is lowest (the
robustness UPBP is claimed for: never far from the best on any scene).
"""

import math
import tempfile
import time
from pathlib import Path

from resultslib import data as datafile, pages  # scripts/ is on sys.path (scripts/bench)

from . import claims, common

FRACTIONS = ["0.01", "0.03", "0.1", "0.3", "1"]
SCENES = {c["id"]: c for c in claims.CLAIMS if c["method"] == "UPBP"}
RADIUS = ["--radius-factor", "0.01"]
CFG = {"min_runs": 4, "run_seconds": 0.5, "fixed_runs": 2, "width": 64}
QUICK = {"min_runs": 3, "run_seconds": 0.05, "fixed_runs": 1, "width": 24}


def arm_name(fraction: str) -> str:
    return f"F={fraction}"


def sweep_claim(base: dict) -> dict:
    """The claim's scene with one upbp arm per fraction (claims.evaluate's input)."""
    arms = {arm_name(f): ("upbp", [*RADIUS, "--photon-beam-paths", f, "--query-beam-paths", f])
            for f in FRACTIONS}
    return {"id": f"defaults-{base['id']}", "scene": base["scene"], "defines": base["defines"],
            "arms": arms, "subject": arm_name(FRACTIONS[0]), "target": math.inf,
            "direction": "<="}


def choose(scores: dict) -> tuple[str, dict]:
    """The fraction whose worst score over the scenes is lowest, and each fraction's worst."""
    worst = {f: max(s[arm_name(f)] for s in scores.values()) for f in FRACTIONS}
    return min(FRACTIONS, key=lambda f: worst[f]), worst


def run(build_dir: Path, docs_dir: Path, quick: bool = False, only=None, command=None):
    binary = common.render_binary(build_dir)
    cfg = QUICK if quick else CFG
    chosen_scenes = [s for s in SCENES if not only or any(
        s == o or (o.endswith("-") and s.startswith(o)) for o in only)]
    workdir = Path(tempfile.mkdtemp(prefix="bench-upbp-defaults-"))
    machine = common.machine_info()
    command_line = command or "scripts/bench --only upbp-defaults"
    rows, scores = [], {}
    for sid in chosen_scenes:
        claim = sweep_claim(SCENES[sid])
        resolution = common.resolution_for_width(claims.SCENES / claim["scene"], cfg["width"])
        started, load = time.monotonic(), common.load_average()
        arms = {name: claims.Arm(binary, claim, name, resolution, workdir, cfg["run_seconds"],
                                 cfg["fixed_runs"]) for name in claim["arms"]}
        for a in arms.values():
            for _ in range(cfg["min_runs"]):
                a.add_run()
        stats, *_ = claims.evaluate(claim, arms)
        best = min(s["cost"] for s in stats.values())
        scores[sid] = {n: math.sqrt(s["cost"] / best) for n, s in stats.items()}
        rows.append({"scene": claim["scene"], "claim": sid, "defines": claim["defines"],
                     "resolution": resolution, "arms": stats, "rmse_over_best": scores[sid],
                     "load": load, "load_after": common.load_average(),
                     "seconds": round(time.monotonic() - started, 1)})
        print(f"  {sid:22s} " + "  ".join(f"{n} {scores[sid][n]:.3f} (v {stats[n]['v']:.3g}, "
                                           f"t {stats[n]['t']:.3g})" for n in stats), flush=True)
    fraction, worst = choose(scores)
    print(f"  worst equal-time RMSE / best per fraction: "
          + ", ".join(f"F={f}: {worst[f]:.3f}" for f in FRACTIONS) + f"; chosen F={fraction}")
    data = {"stamp": datafile.stamp(command_line,
                                    load_before=pages.load_text(machine.get("load_average"))),
            "command": command_line, "commit": machine.get("source_revision"),
            "machine": machine, "quick": quick, "fractions": FRACTIONS, "radius": RADIUS,
            "scenes": rows, "worst_over_scenes": worst, "chosen": fraction}
    out = docs_dir / "data" / "upbp" / ("defaults-quick.json" if quick else "defaults.json")
    datafile.write(out, data)
    print(f"bench: wrote {out}")
