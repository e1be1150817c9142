"""The published claims of the many-light, joint-sampling and UPBP methods, measured at equal
time (`scripts/bench --only claims`, writes docs/data/claims.json, docs/results/claims.md and
docs/img/claims/).

Each claim compares arms that estimate the same image (docs/design/algorithms-next.md gives the
claims and their targets). For an estimator whose iterations are independent, the squared error
after a time T is v t / T (v: one iteration's variance, t: the cost of one iteration), so the
equal-time ratio of two arms is (v t)_a / (v t)_b at every T, and the two factors are measured
apart:

- v: independent `render --iterations N` runs of the arm (own seeds); the per-pixel sample
  variance over the runs times N, weighted as the relative MSE is (1 / (r^2 + 0.01), r the mean
  of every run of the claim) and averaged over pixels and channels (or over a region, see the
  metric). Its standard error is the jackknife's over the runs (leave one run out). The DIV
  claims pool every iteration of the runs instead (the per-pixel variance layers, div_claim).
- t: CPU seconds per iteration of single-threaded renders: the child's user + system time over
  the variance runs, less a one-iteration run's (scene loading), divided by the iterations in
  between. With one thread, CPU time is the wall time a quiet machine would show, and it is
  far less disturbed by other load than wall time (the machine is shared; the load is stamped).
- The runs' lengths: about `run_seconds` of CPU time each, and for the VPL claims, whose arms
  trace different numbers of light paths per iteration, at least the same number of light
  paths in every arm's run, so that a heavy-tailed arm samples its rare light paths as often
  as the others (few runs of a few iterations each underestimate a heavy-tailed variance).

Runs are added to the arms until the ratio's standard error is under 10 % of the ratio
(first-order propagation of v's and t's standard errors; for the DIV claims, whose judged
arms render the same seeds, the jackknife over the pairs of runs) or the claim's run budget is spent
(at most 24 runs per arm, 200 for the DIV claims, whose uniform arm is heavy-tailed, 400 for the short runs of the IC claims, or `--budget-minutes` of
wall time on a loaded machine); a claim that stops at the budget says so. t's SE is the spread of the variance runs; the one-iteration
runs that give the fixed cost add an uncertainty it does not include. With few runs (4-6, a
budgeted run) the jackknife SE is itself uncertain. The verdict is taken at 2 standard errors: a claim
"ratio >= target" is held when ratio - 2 SE >= target, a bar "ratio <= target" when
ratio + 2 SE <= target. The merging arms (vcm, upbp) are biased by their kernels (fixed radius,
no shrinking over the runs' few iterations); their bias is not part of v.
"""

from __future__ import annotations

import fcntl
import json
import math
import os
import re
import shlex
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from . import common, upbp
from resultslib import data as datafile, pages  # scripts/ is on sys.path (scripts/bench)

SCENES = common.REPO_ROOT / "scenes"
CLAMP = ["--vpl-clamp", "0.01", "--vpl-clamp-schedule", "fixed"]
# The UPBP claims use the density sweep's arms (docs/results/upbp.md), radius included, with
# the photon beams drawn from a fraction of the light paths (--photon-beam-paths) and the query
# beams gathering the photon points of the same fraction (--query-beam-paths): the fraction
# `scripts/bench --only upbp-defaults` chose (docs/data/upbp/defaults.json: the lowest worst
# equal-time RMSE over the scenes swept; docs/design/media.md "Choosing the fractions").
UPBP_BEAM_PATHS = ["--photon-beam-paths", "0.01"]
UPBP_QUERY_PATHS = ["--query-beam-paths", "0.01"]


def _upbp_arm(algorithm, args):
    if algorithm != "upbp":
        return algorithm, args
    beams_off = "--photon-beams" in args and args[args.index("--photon-beams") + 1] == "off"
    query_off = "--query-beams" in args and args[args.index("--query-beams") + 1] == "off"
    return algorithm, [*args, *([] if beams_off else UPBP_BEAM_PATHS),
                       *([] if query_off else UPBP_QUERY_PATHS)]


UPBP_ARMS = {name: _upbp_arm(algorithm, args) for name, (algorithm, args) in upbp.ARMS.items()}
UPBP_SUBJECT = "upbp: all"
UPBP_FACTOR = 1.5


# Light paths per iteration of the uniform VPL arms (render's default).
VPL_PATHS = 64


# The importance records per iteration of render's default, and the larger count the acceptance
# check renders with (div_claim, "record_check").
IMPORTANCE_RECORDS = 100
RECORD_CHECK_RECORDS = 1000


def div_claim(cid, scene, defines, kind, target, width, paper_paths, run_seconds=None):
    """Uniform VPLs from VPL_PATHS light paths per iteration against the importance-driven
    distribution from the same light paths (`vpl --vpl-distribution importance`), on which the
    claim is judged, and from `paper_paths` (an equal number of kept VPLs), shown beside it.

    The judged arm is the comparison our spec defines (docs/design/algorithms-next.md 1.7 b:
    `vpl` with DIV on against `vpl` with it off, at equal wall time; 1.3: the same fixed number
    of light paths per iteration, "as now"). The paper's own procedure traces light paths until
    a set number of VPLs is accepted, which is what made its VPL counts equal; the spec forbids
    it (0.4, a random stopping count), and "more efficient" is an equal-time statement, which
    is what both of our arms' ratios measure. The paper's efficiency gain is the same VPLs'
    worth of image for fewer rendered connections: from the same light paths the roulette
    keeps the VPLs that light what the camera sees and drops the others, so one iteration's
    variance stays about the same and its cost falls. The equal-count arm (VPL_PATHS / the
    share kept, measured at an earlier revision on other seeds) asks more: the same rendering
    cost for lower variance. This choice was made after both arms had been measured (the
    equal-count arm judged the claim before, CHANGELOG.md); both ratios stay on the page.

    The uniform and the plain importance arm render the same seeds with the same light paths
    (run k of every arm renders seed 10000 + 100 k), so their variances share the same rare
    light paths; the ratio's standard error is the jackknife's over the pairs of runs
    (`paired_arms`, leave run k out of both), which the correlation makes far smaller than
    the two variances' own standard errors.

    Every arm's variance runs hold the same number of light paths (`run_paths`, two iterations
    of the equal-count arm): where the light reaches what the camera sees through few paths, a
    uniform iteration's image is heavy-tailed (most iterations light the visible room with no
    VPL, a rare one with a bright VPL inside it), and a run of a few uniform iterations samples
    those rare paths far less often than the importance arm's runs do.

    v is the pooled variance of all the runs' iterations (`--layers variance`, pooled_variance),
    whose noise, where runs hold many iterations (the uniform arm's 20-30), is smaller than
    that of the runs' means; the runs' means' variance is kept beside it as a check (both
    estimate the same v).

    The record check: the share of candidates kept with RECORD_CHECK_RECORDS importance records
    instead of IMPORTANCE_RECORDS (a short run of the importance arm's flags, same seeds). If the
    share stays, it is the scene's (how much of the light reaches what the camera sees), not an
    artefact of too few records missing the VPLs' contributions (docs/design/algorithms-next.md
    1.5)."""
    paths = ["--vpl-paths", str(VPL_PATHS)]
    importance = [*CLAMP, "--vpl-distribution", "importance"]
    arms = {"uniform": ("vpl", [*CLAMP, *paths]), "importance": ("vpl", [*importance, *paths]),
            "importance, equal VPL count": ("vpl", [*importance, "--vpl-paths",
                                                    str(paper_paths)])}
    common_fields = dict(id=cid, scene=scene, defines=defines, arms=arms, target=target,
                         width=width, run_paths=2 * paper_paths, min_runs=12, max_runs=200,
                         variance_layers=True, paired_arms=("uniform", "importance"),
                         record_check=("vpl", [*importance, *paths, "--importance-records",
                                               str(RECORD_CHECK_RECORDS)]))
    if run_seconds:
        common_fields["run_seconds"] = run_seconds
    if kind == "gain":
        return dict(**common_fields, method="importance-driven VPLs",
                    metric="equal-time relMSE(uniform) / relMSE(importance)",
                    numerator="uniform", denominator="importance", direction=">=",
                    paper="light around a corner behind the camera: 7 % of the VPLs accepted, "
                          "more than an order of magnitude more efficient")
    return dict(**common_fields, method="importance-driven VPLs (control)",
                metric="equal-time relMSE(importance) / relMSE(uniform)",
                numerator="importance", denominator="uniform", direction="<=",
                paper="our bar: no more than 15 % worse where every VPL matters")


def light_paths(extra) -> int | None:
    """The light paths per iteration an arm's flags give (`--vpl-paths`), or None."""
    flags = list(extra)
    return int(flags[flags.index("--vpl-paths") + 1]) if "--vpl-paths" in flags else None



def ic_claim(cid, scene, width):
    """Importance caching against power-proportional VPL choice, both drawing 16 VPLs per
    shading point from the same VPLs. The paper's estimator (docs/design/algorithms-next.md 2.1)
    estimates the many-light sum over a given VPL set; its variance is what importance caching
    lowers. Each run is therefore paired with a `vpl` render of the same seed and iterations
    (the same light paths, hence the same VPLs, and the same next-event estimation: every
    shading point connects to every VPL), and v is the variance of the difference, the
    sampling variance alone. The arms' own variance adds the VPL set's and next-event
    estimation's, which both arms share (the total, reported beside it)."""
    return dict(id=cid, method="importance caching", scene=scene, defines=[],
                arms={"power": ("ic", [*CLAMP, "--ic-distributions", "power"]),
                      "ic": ("ic", CLAMP)},
                paired_reference=("vpl", CLAMP),
                metric="variance of the VPL sampling, power / ic, at equal sample count (16 "
                       "VPLs per shading point; each run less a vpl run over the same VPLs)",
                numerator="power", denominator="ic", direction=">=", target=10.0,
                equal="samples", width=width, iterations=4, max_runs=400,
                paper="more than an order of magnitude lower variance in highly occluded "
                      "scenes")

# The cache of the judged IC-connection arm: tables over the first 16 light paths' vertices and
# one record per 400 pixels (render's defaults: 64 and 1 / 16). Chosen by CPU time and variance
# per iteration on scenes/claims/ic-rooms.xml (CHANGELOG.md, importance caching, has the sweep):
# the variance per iteration barely changed from the defaults' (every eye vertex still finds
# records in its room), while the tables' shadow rays and the record look-up, most of the
# cached arm's extra cost at the defaults (callgrind), fell with the records and vertices. The
# defaults' arm is shown beside it, not judged.
IC_CONNECTION_CACHE = ["--ic-light-paths", "16", "--ic-record-density", "0.0025"]

CLAIMS = [
    # Light paths for an equal VPL count: VPL_PATHS / the share kept at that count (7.0 %,
    # 29.5 %, 59.4 %: the equal-count arms' "VPLs kept" in docs/data/claims.json, measured at
    # revision 5bd13d67d48f).
    div_claim("div-corner", "claims/div-corner.xml", [], "gain", 5.0, 96, 915),
    div_claim("div-two-rooms", "tests/two-rooms.xml", [], "gain", 5.0, 64, 217),
    # The control's iterations are short (0.05-0.08 s of CPU at 64x64): runs of 1.5 s of CPU
    # (about 20 iterations) so that the scene loading subtracted from each run's CPU time is a
    # small part of it and the pooled variance holds many iterations per run.
    div_claim("div-cornell-control", "bitterli/cornell-box/scene_v3.xml", [], "control", 1.15,
              64, 108, run_seconds=1.5),
    ic_claim("ic-rooms", "claims/ic-rooms.xml", 96),
    ic_claim("ic-two-rooms", "tests/two-rooms.xml", 64),
    dict(id="ic-connections-rooms", method="IC-resampled bpt connections",
         scene="claims/ic-rooms.xml", defines=[],
         arms={"bpt": ("bpt", []),
               "bpt-ic": ("bpt", ["--connections", "ic", *IC_CONNECTION_CACHE]),
               "bpt-ic, defaults": ("bpt", ["--connections", "ic"])},
         metric="equal-time relMSE(bpt) / relMSE(bpt --connections ic)", numerator="bpt",
         denominator="bpt-ic", direction=">=", target=1.0, width=96,
         # Runs of several iterations: t of a 2-iteration run less a 1-iteration one was
         # dominated by the noise of the two CPU times on a loaded machine.
         run_seconds=2.0,
         paper="a better choice of light vertices for the connections"),
    dict(id="joint-fog-box", method="joint path sampling", scene="tests/fog-box.xml",
         defines=["-D", "max_depth=3"],
         arms={"jis off": ("volpt", ["--jis", "off"]), "jis on": ("volpt", ["--jis", "on"])},
         metric="equal-time mean absolute error near the light, jis off / jis on (double "
                "scattering, layer s1_t3)", numerator="jis off", denominator="jis on",
         direction=">=", target=5.0, width=64, layer="s1_t3", region="light",
         paper="5-37x lower RMSE near the light"),
] + [
    dict(id=f"upbp-{name}", method="UPBP", scene=f"claims/upbp-{name}.xml", defines=[],
         arms=UPBP_ARMS, metric=f"equal-time RMSE of {UPBP_SUBJECT} / the best arm's",
         subject=UPBP_SUBJECT, direction="<=", target=UPBP_FACTOR, width=64,
         paper="robust: never far from the best single technique across media")
    for name in ("mirror-balls", "lantern", "still-life", "bathroom")
] + [
    dict(id=f"upbp-isosph-{label}", method="UPBP", scene="smallupbp/isosph.xml",
         defines=["-D", f"density={density}"], arms=UPBP_ARMS,
         metric=f"equal-time RMSE of {UPBP_SUBJECT} / the best arm's", subject=UPBP_SUBJECT,
         direction="<=", target=UPBP_FACTOR, width=64,
         paper="robust: never far from the best single technique across media")
    for label, density in (("x0.1", "0.1"), ("x1", "1"), ("x10", "10"))
] + [
    dict(id="upbp-glasssph", method="UPBP", scene="smallupbp/glasssph.xml", defines=[],
         arms=UPBP_ARMS, metric=f"equal-time RMSE of {UPBP_SUBJECT} / the best arm's",
         subject=UPBP_SUBJECT, direction="<=", target=UPBP_FACTOR, width=64,
         paper="robust: never far from the best single technique across media"),
]

FULL = {"min_runs": 8, "max_runs": 24, "run_seconds": 0.5, "se_fraction": 0.10,
        "picture_seconds": 2.0, "width_scale": 1.0, "fixed_runs": 2}
# The smoke test: one claim of each kind on tiny images, three runs per arm, no SE target.
QUICK = {"min_runs": 3, "max_runs": 3, "run_seconds": 0.02, "se_fraction": 0.10,
         "picture_seconds": 0.02, "width_scale": 0.25, "fixed_runs": 1, "quick": True}
QUICK_CLAIMS = ("div-corner", "div-cornell-control", "ic-rooms", "ic-connections-rooms",
                "joint-fog-box", "upbp-mirror-balls")


# --------------------------------------------------------------------------------------------
# The algorithm table


def check_arms(table: dict, claims) -> None:
    """Every arm's algorithm exists in the build's table and reads every option the arm gives
    (`render --describe-options`): a renamed option fails here, before any rendering."""
    algorithms = {a["name"] for a in table["algorithms"]}
    flags = {}
    for option in table["options"]:
        for flag in (option.get("flag"), option.get("negated_flag")):
            if flag:
                flags[flag] = set(option.get("read_by", []))
    for claim in claims:
        for arm, (algo, extra) in claim["arms"].items():
            if algo not in algorithms:
                raise SystemExit(f"claims: {claim['id']}/{arm}: no algorithm {algo!r}")
            for word in extra:
                if word.startswith("--") and algo not in flags.get(word, set()):
                    raise SystemExit(f"claims: {claim['id']}/{arm}: {algo} does not read {word}")


# --------------------------------------------------------------------------------------------
# Rendering


def read_image(path: Path, layer=None):
    """RGB of the image (or of one `--layers st` layer) as float64 H x W x 3."""
    return common.read_exr_layers(path)[0][layer or ""]


def run_cpu(cmd) -> tuple[float, str]:
    """Runs a command in the repository root; returns (its CPU seconds, user + system, and its
    stdout). The benchmark runs one child at a time, so the increase of the children's times
    around the call is this child's."""
    before = os.times()
    proc = subprocess.run(cmd, cwd=common.REPO_ROOT, capture_output=True, text=True)
    after = os.times()
    if proc.returncode != 0:
        raise RuntimeError(f"render failed: {shlex.join(map(str, cmd))}\n{proc.stderr[-2000:]}")
    cpu = (after.children_user - before.children_user) + (after.children_system -
                                                          before.children_system)
    return cpu, proc.stdout


def render(binary, claim, arm, seed, iterations, resolution, out, png=None, spread=False):
    """One single-threaded render of an arm: (image, CPU seconds, stdout, command), and with
    `spread` (a claim with "variance_layers") also the run's within-run sum of squares per
    pixel, sum over its iterations of (x_i - mean)^2, from the `--layers variance` layer
    (docs/reference/variance-layers.md: variance = s^2 / N, s^2 = that sum / (N - 1))."""
    algo, extra = claim["arms"][arm]
    flags = [*claim["defines"], *extra]
    if claim.get("layer"):
        flags += ["--layers", "st"]
    elif spread:
        flags += ["--layers", "variance"]
    cmd = common.render_command(binary, SCENES / claim["scene"], out, algo=algo,
                                iterations=iterations, seed=seed, resolution=resolution,
                                threads=1, extra=flags, png=png)
    cpu, stdout = run_cpu(cmd)
    image = read_image(out, claim.get("layer"))
    within = None
    if spread:
        within = read_image(out, "variance") * iterations * max(iterations - 1, 0)
    out.unlink()
    if spread:
        return image, cpu, stdout, cmd, within
    return image, cpu, stdout, cmd


def acceptance(stdout: str):
    """The share of VPLs kept that render prints for importance-driven VPLs (percent), or None."""
    for line in stdout.splitlines():
        if line.startswith("VPLs:") and "accepted" in line:
            return float(line.split(",")[1].split("%")[0])
    return None


# The paired reference images already rendered: (claim, seed, iterations, resolution) -> image.
REFERENCE_RENDERS = {}


class Arm:
    """The runs of one arm: images, CPU seconds, the fixed cost, the iterations per run."""

    def __init__(self, binary, claim, name, resolution, workdir, run_seconds, fixed_runs):
        self.binary, self.claim, self.name = binary, claim, name
        self.resolution, self.workdir = resolution, workdir
        self.images, self.cpu, self.kept = [], [], []
        # With "variance_layers": each run's within-run sum of squares per pixel (render()).
        self.within = []
        # With a paired reference (ic_claim): each run's difference from the reference render
        # of the same seed and iterations, and the reference images themselves.
        self.differences, self.references = [], []
        self.command = None
        # The fixed cost (loading, the scene's acceleration structure): the median of three
        # one-iteration runs, which also give the iteration count of the variance runs.
        ones = [self._render(90_000 + k, 1)[1] for k in range(fixed_runs)]
        self.fixed = float(np.median(ones))
        # Two iterations less one: one iteration's cost. The variance does not need long runs
        # (v is per iteration whatever the run's length); the runs are long enough only for
        # their CPU time to measure t.
        per_iteration = self._render(91_000, 2)[1] - self.fixed
        self.iterations = max(2, round(run_seconds / max(per_iteration, 1e-3)))
        if claim.get("iterations"):
            # A variance-only claim (equal sample count): v is per iteration whatever the
            # run's length, and short runs leave time for more of them.
            self.iterations = claim["iterations"]
        # Claims whose arms trace different numbers of light paths per iteration hold the
        # light paths of a run equal across the arms (div_claim): heavy-tailed arms then sample
        # their rare paths as often as the others.
        paths = light_paths(claim["arms"][name][1])
        if claim.get("run_paths") and paths:
            self.iterations = max(self.iterations, math.ceil(claim["run_paths"] / paths))

    def _render(self, seed, iterations, spread=False):
        out = self.workdir / f"{self.claim['id']}-{self.name.replace(' ', '_').replace(':', '')}.exr"
        image, cpu, stdout, cmd, *within = render(self.binary, self.claim, self.name, seed,
                                                  iterations, self.resolution, out,
                                                  spread=spread)
        self.command = cmd
        kept = acceptance(stdout)
        if spread:
            return image, cpu, kept, within[0]
        return image, cpu, kept

    def add_run(self):
        seed = 10_000 + 100 * len(self.images)
        if self.claim.get("variance_layers"):
            image, cpu, kept, within = self._render(seed, self.iterations, spread=True)
            self.within.append(within)
        else:
            image, cpu, kept = self._render(seed, self.iterations)
        self.images.append(image)
        self.cpu.append(cpu)
        if self.claim.get("paired_reference"):
            key = (self.claim["id"], seed, self.iterations, tuple(self.resolution))
            reference = REFERENCE_RENDERS.get(key)
            if reference is None:
                # Arms with the same seeds and iterations share their reference renders.
                algo, extra = self.claim["paired_reference"]
                out = self.workdir / f"{self.claim['id']}-reference.exr"
                cmd = common.render_command(self.binary, SCENES / self.claim["scene"], out,
                                            algo=algo, iterations=self.iterations, seed=seed,
                                            resolution=self.resolution, threads=1,
                                            extra=[*self.claim["defines"], *extra])
                run_cpu(cmd)  # its CPU time is not the arm's
                reference = REFERENCE_RENDERS[key] = read_image(out)
                out.unlink()
            self.references.append(reference)
            self.differences.append(image - reference)
        if kept is not None:
            self.kept.append(kept)

    def t(self) -> tuple[float, float]:
        """CPU seconds per iteration and its standard error."""
        per = (np.array(self.cpu) - self.fixed) / (self.iterations - 1)
        per = np.maximum(per, 1e-6)
        return float(per.mean()), float(per.std(ddof=1) / math.sqrt(len(per)))


def weighted_variance(stack, iterations, weight, mask, mae):
    """One iteration's variance (or, for the mean absolute error, its square root per pixel)
    from independent runs, averaged over the mask."""
    var = stack.var(axis=0, ddof=1) * iterations
    if mae:
        return float(np.sqrt(var)[mask].mean())
    return float((var * weight)[mask].mean())


def pooled_variance(stack, within, iterations, weight, mask):
    """One iteration's variance from every iteration of the runs, not only their means: per
    pixel, (within-run sums of squares + N x the runs' means' sum of squares about the grand
    mean) / (R N - 1), the unbiased sample variance of all R N iterations (R runs of N
    iterations each, independent), weighted and averaged over the mask like
    weighted_variance. It has R N - 1 degrees of freedom per pixel where the runs' means have
    R - 1: with many iterations per run the part of its error that does not come from a heavy
    tail shrinks by about N (the tail's part, the fourth moment over R N iterations, is the
    same for both)."""
    r = stack.shape[0]
    between = iterations * ((stack - stack.mean(axis=0)) ** 2).sum(axis=0)
    var = (within.sum(axis=0) + between) / (r * iterations - 1)
    return float((var * weight)[mask].mean())


def jackknife(images, iterations, weight, mask, mae, within=None) -> tuple[float, float]:
    """The statistic over all runs and its jackknife standard error (leave one run out); with
    `within` (the runs' within-run sums of squares) the pooled variance, else the variance
    of the runs' means."""
    stack = np.stack(images)
    if within is not None:
        spread = np.stack(within)
        stat = lambda s, w: pooled_variance(s, w, iterations, weight, mask)  # noqa: E731
    else:
        spread = np.zeros(len(images))
        stat = lambda s, w: weighted_variance(s, iterations, weight, mask, mae)  # noqa: E731
    full = stat(stack, spread)
    n = len(images)
    loo = [stat(np.delete(stack, i, axis=0), np.delete(spread, i, axis=0)) for i in range(n)]
    se = math.sqrt((n - 1) / n * sum((x - np.mean(loo)) ** 2 for x in loo))
    return full, se


def paired_cost_ratio(claim, arms, weight, mask) -> tuple[float, float]:
    """The equal-time ratio (v t)_numerator / (v t)_denominator of two arms that render the
    same seeds (`paired_arms`, div_claim) and its jackknife standard error over the pairs of
    runs: leaving run k out of both arms keeps the correlation of their variances (the same
    rare light paths), which the first-order propagation of the two arms' own standard
    errors ignores. The pairs are the first n runs of each (the arms grow together)."""
    num, den = arms[claim["numerator"]], arms[claim["denominator"]]
    n = min(len(num.images), len(den.images))

    def cost(a, keep):
        images = [a.images[i] for i in keep]
        within = np.stack([a.within[i] for i in keep])
        v = pooled_variance(np.stack(images), within, a.iterations, weight, mask)
        per = np.maximum((np.array([a.cpu[i] for i in keep]) - a.fixed) / (a.iterations - 1),
                         1e-6)
        return v * float(per.mean())

    every = list(range(n))
    full = cost(num, every) / cost(den, every)
    loo = [cost(num, every[:i] + every[i + 1:]) / cost(den, every[:i] + every[i + 1:])
           for i in range(n)]
    se = math.sqrt((n - 1) / n * sum((x - np.mean(loo)) ** 2 for x in loo))
    return full, se


def light_region(reference: np.ndarray) -> np.ndarray:
    """The pixels near the light: a disc of radius width / 8 around the brightest pixel of the
    smoothed mean image (single scattering peaks where the camera rays pass the light)."""
    lum = reference.mean(axis=-1)
    h, w = lum.shape
    k = max(1, w // 16)
    padded = np.pad(lum, k, mode="edge")
    smooth = sum(padded[k + dy:k + dy + h, k + dx:k + dx + w]
                 for dy in range(-k, k + 1) for dx in range(-k, k + 1))
    y, x = np.unravel_index(int(np.argmax(smooth)), smooth.shape)
    yy, xx = np.mgrid[0:h, 0:w]
    disc = (yy - y) ** 2 + (xx - x) ** 2 <= (w / 8) ** 2
    return np.broadcast_to(disc[:, :, None], reference.shape)


# --------------------------------------------------------------------------------------------
# One claim


def evaluate(claim, arms):
    """Per arm v, t and their product; the claim's ratio, SE and verdict."""
    everything = [img for a in arms.values() for img in a.images]
    reference = np.mean(everything, axis=0)
    weight = 1.0 / (reference * reference + common.RELATIVE_MSE_EPSILON)
    mae = claim.get("region") == "light"
    mask = light_region(reference) if mae else np.ones(reference.shape, dtype=bool)
    stats = {}
    for name, a in arms.items():
        paired = bool(claim.get("paired_reference"))
        pooled = bool(claim.get("variance_layers")) and not paired and not mae
        v, v_se = jackknife(a.differences if paired else a.images, a.iterations, weight, mask,
                            mae, within=a.within if pooled else None)
        t, t_se = a.t()
        # The squared-error cost: v t (relMSE x s); for the MAE, sqrt(v) sqrt(t) (MAE x sqrt s).
        if mae:
            cost = v * math.sqrt(t)
            rel = math.hypot(v_se / v, 0.5 * t_se / t) if v > 0 else math.inf
        elif claim.get("equal") == "samples":
            cost, rel = v, (v_se / v if v > 0 else math.inf)
        else:
            cost = v * t
            rel = math.hypot(v_se / v, t_se / t) if v > 0 else math.inf
        stats[name] = {"v": v, "v_se": v_se, "t": t, "t_se": t_se, "cost": cost,
                       "cost_rel_se": rel, "runs": len(a.images), "iterations": a.iterations,
                       "fixed_cpu_seconds": a.fixed,
                       "vpls_kept_percent": (float(np.mean(a.kept)) if a.kept else None),
                       "command": shlex.join(map(str, a.command))}
        if pooled:
            # The variance of the runs' means alone (the estimator of the other claims), as a
            # check: both estimate the same v, the pooled one with less noise.
            means, means_se = jackknife(a.images, a.iterations, weight, mask, mae)
            stats[name].update({"v_of_run_means": means, "v_of_run_means_se": means_se})
        if paired:
            # The arm's own variance (sampling, VPL set, next-event estimation) and the
            # reference's (VPL set and next-event estimation only).
            total, total_se = jackknife(a.images, a.iterations, weight, mask, mae)
            ref, ref_se = jackknife(a.references, a.iterations, weight, mask, mae)
            stats[name].update({"v_total": total, "v_total_se": total_se,
                                "v_reference": ref, "v_reference_se": ref_se})
    if "subject" in claim:
        # RMSE at equal time is sqrt(v t): the subject against the best arm.
        rmse = {n: math.sqrt(s["cost"]) for n, s in stats.items()}
        best = min(rmse, key=rmse.get)
        worst = max(rmse, key=rmse.get)
        subject = claim["subject"]
        ratio = rmse[subject] / rmse[best]
        se = 0.0 if best == subject else ratio * 0.5 * math.hypot(
            stats[subject]["cost_rel_se"], stats[best]["cost_rel_se"])
        held = worst != subject and ratio + 2 * se <= claim["target"]
        extra = {"best": best, "worst": worst,
                 "rmse_over_best": {n: r / rmse[best] for n, r in rmse.items()}}
    else:
        num, den = stats[claim["numerator"]], stats[claim["denominator"]]
        if claim.get("paired_arms"):
            ratio, se = paired_cost_ratio(claim, arms, weight, mask)
        else:
            ratio = num["cost"] / den["cost"]
            se = ratio * math.hypot(num["cost_rel_se"], den["cost_rel_se"])
        held = (ratio - 2 * se >= claim["target"] if claim["direction"] == ">=" else
                ratio + 2 * se <= claim["target"])
        extra = {}
    return stats, ratio, se, held, extra


def measure(binary, claim, cfg, workdir, img_dir):
    if claim.get("max_runs") and cfg["max_runs"] < claim["max_runs"] and not cfg.get("quick"):
        # Short variance-only runs (ic_claim): their heavy-tailed sampling variance needs more
        # runs than the default cap to reach its SE target.
        cfg = {**cfg, "max_runs": claim["max_runs"]}
    if claim.get("min_runs") and cfg["min_runs"] < claim["min_runs"] and not cfg.get("quick"):
        # Paired arms (div_claim): their ratio's jackknife SE is small early; enough pairs that
        # it is not the SE of a handful of runs.
        cfg = {**cfg, "min_runs": claim["min_runs"]}
    width = max(16, int(claim["width"] * cfg["width_scale"]))
    resolution = common.resolution_for_width(SCENES / claim["scene"], width)
    started = time.monotonic()
    run_seconds = cfg["run_seconds"] if cfg.get("quick") else claim.get("run_seconds",
                                                                         cfg["run_seconds"])
    arms = {name: Arm(binary, claim, name, resolution, workdir, run_seconds, cfg["fixed_runs"])
            for name in claim["arms"]}
    for a in arms.values():
        for _ in range(cfg["min_runs"]):
            a.add_run()
    while True:
        stats, ratio, se, held, extra = evaluate(claim, arms)
        if ratio > 0 and se / ratio < cfg["se_fraction"]:
            break
        if cfg.get("budget_seconds") and time.monotonic() - started > cfg["budget_seconds"]:
            break
        # More runs for the arms whose uncertainty dominates (all of them when comparing against
        # the best: it may change).
        worst_rel = max(s["cost_rel_se"] for s in stats.values())
        grow = [n for n, s in stats.items() if s["cost_rel_se"] >= 0.5 * worst_rel]
        if claim.get("paired_arms") and set(claim["paired_arms"]) & set(grow):
            grow = sorted(set(grow) | set(claim["paired_arms"]))  # the pairs grow together
        if all(arms[n].images and len(arms[n].images) >= cfg["max_runs"] for n in grow):
            break
        for n in grow:
            if len(arms[n].images) < cfg["max_runs"]:
                for _ in range(max(1, len(arms[n].images) // 2)):
                    if len(arms[n].images) < cfg["max_runs"]:
                        arms[n].add_run()
    # Pictures at equal CPU time: each arm's iteration count from its measured cost.
    pictures = {}
    for name, s in stats.items():
        iterations = max(1, round(cfg["picture_seconds"] / s["t"]))
        slug = f"{claim['id']}-{picture_name(name)}"
        png = img_dir / f"{slug}.png"
        out = workdir / f"{slug}.exr"
        render(binary, claim, name, 30_000, iterations, resolution, out, png=png)
        pictures[name] = {"file": png.name, "iterations": iterations}
    if claim.get("record_check") and not cfg.get("quick"):
        extra["record_check"] = record_check(binary, claim, resolution, workdir)
    return {"resolution": list(resolution), "stats": stats, "ratio": ratio, "se": se,
            "held": held, "se_target_met": ratio > 0 and se / ratio < cfg["se_fraction"],
            "pictures": pictures, **extra}


def record_check(binary, claim, resolution, workdir, iterations=4, seed=40_000) -> dict:
    """The share of candidates the importance arm keeps with its default records and with
    RECORD_CHECK_RECORDS, on the same seeds (the same light paths, hence the same candidates)."""
    shares = {}
    for records, (algo, extra) in ((IMPORTANCE_RECORDS, claim["arms"]["importance"]),
                                   (RECORD_CHECK_RECORDS, claim["record_check"])):
        out = workdir / f"{claim['id']}-records-{records}.exr"
        cmd = common.render_command(binary, SCENES / claim["scene"], out, algo=algo,
                                    iterations=iterations, seed=seed, resolution=resolution,
                                    threads=1, extra=[*claim["defines"], *extra])
        shares[records] = acceptance(run_cpu(cmd)[1])
        out.unlink(missing_ok=True)
    return {"iterations": iterations, "seed": seed, "records": RECORD_CHECK_RECORDS,
            "kept_percent": shares[RECORD_CHECK_RECORDS], "default_records": IMPORTANCE_RECORDS,
            "default_kept_percent": shares[IMPORTANCE_RECORDS]}


# --------------------------------------------------------------------------------------------
# The data file and the page


# What each measurement can and cannot show (the numbers are in the rows).
NOTES = {
    "importance-driven VPLs":
        "Our importance-driven distribution is Russian roulette on the VPLs of a fixed number "
        "of light paths per iteration (docs/design/algorithms-next.md 1.2-1.3): a VPL is kept "
        "with probability P_k from its estimated contribution to the image (the importance "
        "records' shadow rays) and weighted by 1 / P_k. The claim is judged on the comparison "
        "the spec defines (docs/design/algorithms-next.md 1.7 b): `vpl` with the importance "
        "distribution against `vpl` with the uniform one, the same light paths per iteration, "
        "at equal CPU time. The paper reaches an equal VPL count by tracing light paths until "
        "enough VPLs are accepted, a random stopping count the spec rules out (0.4); its "
        "\"more efficient\" is an equal-time statement, which both of our ratios measure. "
        "From the same light paths the roulette keeps the VPLs that light what the camera "
        "sees, so one iteration's variance stays about the same while its cost falls with the "
        "share of VPLs kept (less the records' shadow rays, records x candidates): the "
        "efficiency gain is the rendering work saved. The equal-count arm (1 / share kept "
        "times the light paths) asks instead for lower variance at the same rendering cost; "
        "it is shown, not judged (it judged the claim until both arms had been measured; the "
        "arm was changed for the reason above, and CHANGELOG.md records it). The uniform and "
        "importance arms render the same seeds, so the ratio's standard error is the "
        "jackknife's over the pairs of runs. Where few light paths reach what the camera sees "
        "(div-corner: the light comes around a corner behind the camera), a uniform "
        "iteration's image is heavy-tailed: most iterations have no VPL in the visible room, "
        "a rare one has one that lights it all; every arm's variance runs therefore hold the "
        "same number of light paths (two iterations of the equal-count arm).",
    "importance-driven VPLs (control)":
        "Where every VPL matters, the roulette keeps most VPLs and adds the variance of the ones "
        "it drops with underestimated importance (weight up to 1 / P_min), while the records' "
        "shadow rays (records x candidates) are paid every iteration. Judged, like the gain "
        "claims, on the importance arm with the same light paths as uniform. What the "
        "importance arm pays is not the records: in callgrind instructions (CHANGELOG.md, "
        "importance-driven VPLs, for the commands and numbers) its iteration is the eye pass "
        "over the VPLs kept, in proportion to the share kept, plus the records' connections, a "
        "few percent of it; the CPU-time ratio in the table agrees. What it loses is variance "
        "(the variance ratio above): where the share kept is 60 %, the work saved is at most "
        "40 %, and a VPL dropped by the roulette returns, when kept, with its power times 1 / "
        "P_k, up to 1 / P_min. Runs of 1.5 s of CPU each (the iterations column), so that each "
        "run's CPU time less the scene loading measures t well.",
    "importance caching":
        "Compared at equal sample count (16 VPLs per shading point in both arms), the paper's "
        "comparison: the variance of the VPL sampling at a given VPL set (the estimator of "
        "docs/design/algorithms-next.md 2.1). Power-proportional sampling wastes the samples "
        "that land on VPLs which light nothing the camera sees; importance caching draws from "
        "distributions that include visibility. Per iteration, both arms also carry the "
        "variance of the VPL set itself (a few light paths per iteration) and of next-event "
        "estimation, which no VPL sampling can lower: the arms' own variance ratio is bounded "
        "by it (the totals above). The sampling variance of ic is heavy-tailed: its large "
        "values are single draws of a bright VPL with a tiny pmf, at shading points whose "
        "records cannot see that VPL even unoccluded, so that only the uniform table C (pmf "
        "1 / M) draws it. Two rules of the record look-up keep shading points off such records "
        "(docs/reference/algorithms.md, importance caching): a point behind a record's surface "
        "(the far side of a doorway's wall) does not use it, and the look-up's normal term, "
        "weighted by half the scene's diameter (the thesis' distance in units of the scene "
        "size), prefers records on the point's own surface to nearer ones on a perpendicular "
        "surface (before this rule most of the tail sat in one concave corner, a ceiling pixel "
        "next to a wall, CHANGELOG.md).",
    "IC-resampled bpt connections":
        "Both arms are unbiased with the same expectation; the cached arm pays for its records "
        "and tables every iteration. The judged arm builds its caches over the first 16 light "
        "paths with one record per 400 pixels (`--ic-light-paths 16 --ic-record-density "
        "0.0025`), chosen on this scene by a sweep of both (CHANGELOG.md, importance caching); "
        "the arm with render's defaults (64 light paths, one record per 16 pixels) is shown "
        "beside it. At the defaults, callgrind puts most of the cached arm's extra "
        "instructions in the records' tables (one MIS-weighted connection and shadow ray per "
        "record and cached vertex) and, once those are few, in the record look-up at every "
        "eye vertex (the k-d tree over the records prunes little: the look-up's normal term, "
        "half the scene's diameter, keeps the R-th best distance large) and the mixture's "
        "pmfs per draw; far fewer records and cached vertices barely raise the variance per "
        "iteration, since every eye vertex still finds records in its own room. Why the "
        "variance gain itself is bounded: the caches replace only the connections between a light vertex and an eye "
        "vertex (docs/design/algorithms-next.md 2.6). In this scene's dark camera room the "
        "variance of plain bpt is mostly next-event estimation (shadow rays to lamps in other "
        "rooms, rarely unoccluded) and light tracing, which the caches leave alone (`render "
        "--layers st`); even noise-free connections would lower bpt's variance per iteration "
        "only a few times, and the caches already reach most of that (the variance ratio "
        "above), so the cached arm wins only where its price per iteration is well under the "
        "variance it saves. A more occluded variant of the scene (5 x 5 rooms) gave the same "
        "variance gain. "
        "What would change it is drawing next-event estimation from the caches as well "
        "(pg2015 connects its s = 1 technique to cached emission vertices; ours keeps fresh "
        "light samples, as the spec says), not more occlusion.",
    "joint path sampling":
        "The metric is the equal-time mean absolute error of the double-scattering layer in a "
        "disc around the light's image; per pixel the absolute error of a mean of independent "
        "iterations is proportional to its standard deviation, so MAE(T) is the mean over the "
        "disc of sqrt(v_p t / T), and the ratio of two arms does not depend on T.",
    "UPBP":
        "The merging arms run at a fixed radius (1 % of the scene radius) with their kernel "
        "bias left out of the error; the verdict asks that `upbp: all` is not the worst arm and "
        "that its equal-time RMSE is within the target factor of the best arm's. Compare the "
        "arms' v and t: where `upbp: all` has the lowest variance per iteration but loses at "
        "equal time, its cost decides it (the line before this note gives both ratios). Photon "
        "beams come from a fraction of each iteration's light paths (`--photon-beam-paths` in "
        "the commands below), as in the reference implementation. What remains is the gathers: "
        "photon points (query beams) and photon beams are gathered along every camera segment "
        "in a medium, at a cost of the camera segments times the points or beams near them (one "
        "walk of the segment's pieces serves both gathers, and the segment's distance sampling "
        "reuses that walk's closest hits). "
        "That is largest in a small dense medium (upbp-lantern: every light path scatters many "
        "times inside the glass ball, and every camera ray through the ball gathers them), "
        "where the reference implementation can also keep beams out of media whose mean free "
        "path is short against the beam radius (its beam storage factor), which ours cannot "
        "yet. Where bpt is the best arm (thin media), `upbp: all` pays for every estimator at "
        "once for little less variance (the line on extra costs above gives the figures). "
        "Where every arm has about bpt's variance, the arms' CPU times decide the worst place, "
        "and they differ by less than the spread that a loaded machine puts between arms "
        "measured minutes apart (an arm that adds an estimator to bpt can read cheaper than "
        "bpt above): the place is then the timing's, and callgrind instruction counts "
        "(CHANGELOG.md, 2026-11-29, upbp's eye pass) are the repeatable comparison. "
        "Query beams likewise gather the photon points of a fraction of the light paths "
        "(`--query-beam-paths`). In upbp-lantern, gathering every path's photons raised the "
        "relative variance per iteration above bpt's although the absolute variance fell 4x: "
        "the merge densities count every light path as an independent sample, but all of them "
        "share the one eye subpath, so on the walls (eye path: wall, glass, the wax) the query "
        "beams took 80-90 % of the weight from light tracing and made rare large values; with "
        "the photons of 1 % of the paths (the fraction the sweep of `scripts/bench --only upbp-defaults` chose) they take less of those paths and cost less "
        "(docs/design/media.md, \"Query beams from a fraction of the light paths\").",
}


def picture_name(arm: str) -> str:
    """An arm's name as part of a file name: "upbp: connections + query beams" ->
    "upbp-connections-and-query-beams"."""
    return re.sub(r"[^A-Za-z0-9]+", "-", arm.replace("+", "and")).strip("-")


def anchor(heading: str) -> str:
    """The anchor GitHub (and tests/docs/check_docs.py) gives a heading."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def verdict_text(row) -> str:
    return "held" if row["held"] else "not held"


def upbp_cost_line(definition, row) -> str:
    """What each upbp arm and vcm add to bpt's CPU time per iteration, and whether `upbp: all`
    costs more than bpt plus its parts' extras: where bpt is the best arm and every arm has
    about its variance, the extra cost is what decides the verdict."""
    arms = row["arms"]
    if "bpt" not in arms:
        return ""
    base = arms["bpt"]["t"]
    extra = {name: arms[name]["t"] / base - 1 for name in arms if name != "bpt"}
    subject = definition.get("subject")
    parts = [f"{name} {100 * e:+.0f} %" for name, e in extra.items() if name != subject]
    variance = ", ".join(f"{name} {arms[name]['v'] / arms['bpt']['v']:.3g}×"
                         for name in arms if name != "bpt")
    text = ("CPU time per iteration over bpt's: " + ", ".join(parts)
            + (f"; {subject} {100 * extra[subject]:+.0f} %" if subject in extra else "")
            + f". Variance per iteration over bpt's: {variance}.")
    if not row["held"]:
        reasons = []
        if row["worst"] == subject:
            reasons.append(f"{subject} is the worst arm")
        if row["ratio"] + 2 * row["se"] > row["target"]:
            reasons.append(f"its ratio + 2 SE, {row['ratio'] + 2 * row['se']:.3g}, is above "
                           f"{row['target']:g}")
        if reasons:
            text += " Not held because " + " and ".join(reasons) + "."
    return text


def write_page(path: Path, data: dict) -> None:
    m = data["machine"]
    lines = ["# The methods' published claims, measured", "",
             "Written by `scripts/bench --only claims` (scripts/benchlib/claims.py) from "
             "[docs/data/claims.json](../data/claims.json); do not edit by hand.", "",
             "Each claim's section gives its own commit, machine, load and command (the "
             "claims may be measured in separate runs, `--claims`). Last written by "
             f"`{data['command']}`. Machine: {m.get('cpu_model')}, {m.get('cores')} "
             f"cores, {m.get('date_utc')}; revision {data['commit']}; load average before "
             f"{data['load_before']}, after {data['load_after']}"
             + (" (**taken under load**: other jobs shared the machine; the costs are CPU "
                "seconds of single-threaded renders, which load disturbs far less than wall "
                "time)" if max(data['load_before'] or [0])
                > 1.0 else "") + (" (quick mode: a smoke test, not a measurement)"
                                  if data["quick"] else "") + ".", "",
             common_doc(), "",
             "## Summary", "",
             "| claim | method | scene | metric | ratio ± SE | target (2 SE) | verdict |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for row in data["claims"]:
        lines.append(f"| [{row['id']}](#{anchor(row['id'])}) | {row['method']} | `{row['scene']}` | "
                     f"{row['metric']} | {row['ratio']:.3g} ± {row['se']:.2g} | "
                     f"{row['direction']} {row['target']:g} | **{verdict_text(row)}** |")
    missing = [c["id"] for c in CLAIMS if c["id"] not in {r["id"] for r in data["claims"]}]
    if missing and not data.get("quick"):
        lines += ["", "Defined in scripts/benchlib/claims.py but not measured yet (no row in the "
                  "data file): " + ", ".join(f"`{m}`" for m in missing) + "."]
    lines.append("")
    for row in data["claims"]:
        definition = next((c for c in CLAIMS if c["id"] == row["id"]), {})
        lines += [f"## {row['id']}", "",
                  f"{row['method']} on `scenes/{row['scene']}`"
                  + (f" ({' '.join(row['defines'])})" if row["defines"] else "")
                  + f", {row['resolution'][0]}x{row['resolution'][1]}. Published: "
                  f"{row['paper']}. Metric: {row['metric']}: **{row['ratio']:.3g} ± "
                  f"{row['se']:.2g}** (target {row['direction']} {row['target']:g} at 2 SE): "
                  f"**{verdict_text(row)}**"
                  + ("" if row["se_target_met"] else
                     " (the run budget ended before the SE reached 10 % of the ratio)") + ".",
                  ""]
        load = row.get("load") or ["?"]
        lines += [f"Measured {row.get('date_utc', '?')} at revision {row.get('commit', '?')} on "
                  f"{row.get('machine', '?')}, load average {load[0]} before"
                  + (" (under load)" if isinstance(load[0], float) and load[0] > 1.0 else "")
                  + f", by `{row.get('command', '?')}`.", ""]
        if "best" in row:
            lines += [f"Best arm: {row['best']}; worst: {row['worst']}.", ""]
            subject, best = definition.get("subject"), row["best"]
            if subject in row["arms"] and subject != best:
                a, b = row["arms"][subject], row["arms"][best]
                lines += [f"Per iteration, {subject} costs {a['t'] / b['t']:.3g}× {best}'s CPU "
                          f"time and has {a['v'] / b['v']:.3g}× its variance.", ""]
        elif "numerator" in definition:
            num, den = definition["numerator"], definition["denominator"]
            a, b = row["arms"][num], row["arms"][den]
            lines += [f"Per iteration, {num} costs {a['t'] / b['t']:.3g}× {den}'s CPU time and "
                      f"has {a['v'] / b['v']:.3g}× its "
                      f"{'mean absolute error' if definition.get('region') else 'variance'}.",
                      ""]
            if "v_total" in a and "v_total" in b:
                ref_algo = definition["paired_reference"][0]
                lines += [f"v is the variance of (arm − {ref_algo}) over runs of the same seeds: "
                          "the sampling variance alone. The arms' own variance per iteration, "
                          "which adds the VPL set's and next-event estimation's, is "
                          f"{a['v_total']:.4g} ± {a['v_total_se']:.2g} ({num}) and "
                          f"{b['v_total']:.4g} ± {b['v_total_se']:.2g} ({den}), a ratio of "
                          f"{a['v_total'] / b['v_total']:.3g}; {ref_algo} alone (every VPL at "
                          f"every shading point) has {b['v_reference']:.4g} ± "
                          f"{b['v_reference_se']:.2g}, which bounds that ratio by "
                          f"{(b['v_reference'] + a['v']) / b['v_reference']:.3g} however "
                          f"good the sampling.", ""]
        if row["method"] == "UPBP" and "best" in row:
            lines += [upbp_cost_line(definition, row), ""]
        if definition.get("run_paths") and "uniform" in row["arms"]:
            lines += [div_paths_line(definition, row), ""]
        lines += [NOTES.get(row["method"], ""), ""]
        lines += ["| arm | runs × iterations | v (± SE) | CPU s per iteration | cost |"
                  + (" RMSE / best |" if "best" in row else " VPLs kept |"),
                  "| --- | --- | --- | --- | --- | --- |"]
        for name, s in row["arms"].items():
            last = (f"{row['rmse_over_best'][name]:.3g}" if "best" in row else
                    "–" if s["vpls_kept_percent"] is None else f"{s['vpls_kept_percent']:.1f} %")
            lines.append(f"| {name} | {s['runs']} × {s['iterations']} | {s['v']:.4g} ± "
                         f"{s['v_se']:.2g} | {s['t']:.4g} ± {s['t_se']:.2g} | "
                         f"{s['cost']:.4g} | {last} |")
        lines += ["", "Commands (the last variance run of each arm):", ""]
        lines += [f"- {name}: `{s['command']}`" for name, s in row["arms"].items()]
        lines += ["", "Pictures at equal CPU time ("
                  + ", ".join(f"{n}: {p['iterations']} iterations"
                              for n, p in row["pictures"].items()) + "):", "",
                  " ".join(f"![{row['id']} {n}](../img/claims/{p['file']})"
                           for n, p in row["pictures"].items()), ""]
    # The page is generated (scripts/results): its body goes, with the claims' stamp, to
    # docs/data/claims/page.json and the template scripts/resultslib/templates/claims.md.in
    # shows it.
    docs_dir = path.parent.parent
    body = lines[1:]
    while body and not body[0].strip():
        body.pop(0)
    datafile.write(docs_dir / "data" / "claims" / "page.json",
                   {"stamp": data["stamp"], "measured": True, "blocks": {"page": body}})
    pages.write(["claims"], docs_dir)


def div_paths_line(definition, row) -> str:
    """The importance-driven VPL claims' arms from the row's numbers: the judged arm (the same
    light paths as uniform) and the equal-count arm beside it."""
    equal = "importance, equal VPL count"
    uniform_paths = light_paths(definition["arms"]["uniform"][1])
    equal_paths = light_paths(definition["arms"][equal][1])
    u, i = row["arms"]["uniform"], row["arms"]["importance"]
    e = row["arms"].get(equal)
    kept = i.get("vpls_kept_percent")
    text = (f"Light paths per iteration: uniform and importance {uniform_paths}"
            + (f" (importance keeps {kept:.1f} % of the candidates)" if kept is not None else "")
            + f", equal VPL count {equal_paths}; each variance run holds "
            f"{definition['run_paths']} light paths. The importance arm's variance per "
            f"iteration is {i['v'] / u['v']:.3g}× uniform's and its CPU time "
            f"{i['t'] / u['t']:.3g}×: the equal-time ratio is the product.")
    if e:
        text += (f" Shown beside it, not judged: at an equal VPL count ({equal_paths} light "
                 f"paths) the importance arm's variance per iteration is "
                 f"{e['v'] / u['v']:.3g}× uniform's at {e['t'] / u['t']:.3g}× the CPU time, an "
                 f"equal-time ratio uniform / equal count of {u['cost'] / e['cost']:.3g} ± "
                 f"{u['cost'] / e['cost'] * math.hypot(u['cost_rel_se'], e['cost_rel_se']):.2g} "
                 f"(unpaired: the two arms' light paths differ, so uniform's heavy tail enters "
                 f"in full).")
    return text + div_pooled_check(row) + div_record_check(row) + div_verdict_reason(row, kept)


def div_record_check(row) -> str:
    """The share kept with ten times the importance records, from the row's record check."""
    check = row.get("record_check")
    if not check or check.get("kept_percent") is None:
        return ""
    return (f" The records decide the share kept only through their estimate of each VPL's "
            f"contribution: with {check['records']} importance records instead of "
            f"{check['default_records']} the importance arm keeps {check['kept_percent']:.1f} % "
            f"of the candidates against {check['default_kept_percent']:.1f} % ("
            f"{check['iterations']} iterations of seed {check['seed']}, the same light paths).")


def div_pooled_check(row) -> str:
    """The pooled variance against the runs' means' variance (both estimate v), per arm."""
    parts = [f"{name} {s['v_of_run_means']:.4g} ± {s['v_of_run_means_se']:.2g}"
             for name, s in row["arms"].items() if "v_of_run_means" in s]
    if not parts:
        return (" This row was measured before the pooled estimator: its v is the variance of "
                "the runs' means.")
    return (" v pools every iteration of the runs (the per-pixel variance layers); the "
            "variance of the runs' means alone, the same quantity with more noise, is "
            + ", ".join(parts) + ".")


def div_verdict_reason(row, kept) -> str:
    """Why a gain claim of the VPL distribution is not held, from the row's numbers: the share
    of candidates kept bounds the cost saving, or the standard error hides a ratio above it."""
    if row["direction"] != ">=" or row["held"]:
        return ""
    if kept and 100.0 / kept < row["target"]:
        u, i = row["arms"]["uniform"], row["arms"]["importance"]
        return (f" From the same light paths the roulette cannot lower an iteration's variance "
                f"(here it is {i['v'] / u['v']:.3g}× uniform's) and the cost falls at most to "
                f"the share of VPLs kept ({kept:.1f} %), so the ratio cannot "
                f"pass about {100.0 / kept:.3g}, below the target {row['target']:g}: the scene "
                f"keeps too large a share of its candidates. The paper's order of magnitude is "
                f"that of its teaser, which keeps 7 %; its interiors keep 23-33 % (Sponza, "
                f"Living room: docs/design/algorithms-next.md 1.6), where the same bound is "
                f"3-4x.")
    if row["ratio"] >= row["target"]:
        return (f" The measured ratio is above the target {row['target']:g}, but the ratio "
                f"less 2 standard errors, {row['ratio'] - 2 * row['se']:.3g}, is not.")
    return ""


def common_doc() -> str:
    return __doc__.split("\n\n", 1)[1].strip()


def write_page_only(docs_dir: Path) -> None:
    """Rewrites docs/results/claims.md from docs/data/claims.json (no rendering)."""
    data = json.loads((docs_dir / "data" / "claims.json").read_text())
    write_page(common.results_page(docs_dir, "claims.md"), data)
    print(f"bench: wrote {common.results_page(docs_dir, 'claims.md')}")


def run(build_dir: Path, docs_dir: Path, quick: bool = False, threads=None, command=None,
        only=None, budget_minutes=None, min_runs=None):
    """Measures every claim (or those named in `only`: ids, or prefixes ending in "-"), writes the data
    file, the page and the pictures. `threads` is ignored: the renders are single-threaded."""
    binary = common.render_binary(build_dir)
    claims = [c for c in CLAIMS if not only or any(
        c["id"] == o or (o.endswith("-") and c["id"].startswith(o)) for o in only)]
    if not claims:
        raise SystemExit(f"claims: no claim matches {only}; ids: {[c['id'] for c in CLAIMS]}")
    if quick and not only:
        claims = [c for c in claims if c["id"] in QUICK_CLAIMS]
    check_arms(common.algorithm_table(build_dir), claims)
    cfg = dict(QUICK if quick else FULL)
    if budget_minutes:
        # Wall-clock minutes per claim after which no runs are added (a loaded machine).
        cfg["budget_seconds"] = 60 * budget_minutes
    if min_runs:
        cfg["min_runs"] = min_runs
    workdir = Path(tempfile.mkdtemp(prefix="bench-claims-"))
    img_dir = docs_dir / "img" / "claims"
    img_dir.mkdir(parents=True, exist_ok=True)
    machine = common.machine_info()
    command_line = command or "scripts/bench --only claims"
    rows = []
    for claim in claims:
        started = time.monotonic()
        load = common.load_average()
        r = measure(binary, claim, cfg, workdir, img_dir)
        row = {k: claim[k] for k in ("id", "method", "scene", "defines", "metric", "direction",
                                     "target", "paper", "numerator", "denominator", "region",
                                     "equal") if k in claim}
        row.update({"arms": r["stats"], "ratio": r["ratio"], "se": r["se"], "held": r["held"],
                    "se_target_met": r["se_target_met"], "resolution": r["resolution"],
                    "pictures": r["pictures"], "commit": machine.get("source_revision"),
                    "machine": f"{machine.get('cpu_model')}, {machine.get('cores')} cores",
                    "date_utc": machine.get("date_utc"), "load": load,
                    "load_after": common.load_average(), "command": command_line,
                    "seconds": round(time.monotonic() - started, 1)})
        for k in ("best", "worst", "rmse_over_best", "record_check"):
            if k in r:
                row[k] = r[k]
        rows.append(row)
        print(f"  {claim['id']:26s} {r['ratio']:.3g} ± {r['se']:.2g}  "
              f"{claim['direction']} {claim['target']:g}: {verdict_text(r)}", flush=True)
    data = {"stamp": datafile.stamp(command_line,
                                    load_before=pages.load_text(machine.get("load_average"))),
            "command": command_line, "commit":
            machine.get("source_revision"), "machine": machine,
            "load_before": machine.get("load_average"), "load_after": common.load_average(),
            "quick": quick, "claims": rows}
    out_json = docs_dir / "data" / "claims.json"
    out_json.parent.mkdir(parents=True, exist_ok=True)
    # Partial runs (--claims) may run side by side: the read-merge-write is under a lock.
    with open(out_json.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if only and out_json.exists() and not quick:
            # A partial run replaces its own claims and keeps the others' rows (each row
            # carries its own commit, machine, load and command).
            old = json.loads(out_json.read_text())
            kept = [r for r in old.get("claims", []) if r["id"] not in {c["id"] for c in claims}]
            data["claims"] = kept + rows
            order = {c["id"]: i for i, c in enumerate(CLAIMS)}
            data["claims"].sort(key=lambda r: order.get(r["id"], len(order)))
        out_json.write_text(json.dumps(data, indent=1) + "\n")
        write_page(common.results_page(docs_dir, "claims.md"), data)
    out_json.with_suffix(".lock").unlink(missing_ok=True)
    print(f"bench: wrote {out_json} and {common.results_page(docs_dir, 'claims.md')}")
