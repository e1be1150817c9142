"""Joint path sampling in pictures, and its convergence rate (`scripts/bench --only joint-figures`,
writes docs/results/joint-figures.md and docs/img/joint-sampling/*.png).

1. Convergence slopes (ALGORITHMS-NEXT.md 3.8 b2). volpt renders the double-scattering paths
   camera -> c -> b -> light of the fog box (point light, max_depth 3; the `s1_t3` layer of
   `--layers st`) with one technique alone, unweighted (`--volpt-technique`, a diagnostic):
   - dl, the 0-connection: c and b by distance sampling, then a shadow ray to the light. Its
     estimate carries the unsampled 1/|b - a|^2 of a point light: infinite variance, so its
     error should fall like N^(-1/3) (a stable law of index 3/2);
   - j3, joint sampling: c, b sampled together, no geometric singularity left: finite variance,
     error like N^(-1/2).
   For N = 2^k iterations (RUNS independent runs per N, own seeds) the error is the mean
   absolute pixel error (over pixels and channels) against a reference (`volpt`, every technique
   by MIS, REFERENCE_FACTOR times the largest N); not the RMSE, which does not exist for the
   0-connection. The slope is the least-squares fit of log(error) against log(N), over the N
   from FIT_FROM on, with its standard error from the fit's residuals. Claim to check: -1/3 for
   dl, -1/2 for j3, each within 0.07.
2. Pictures at equal time: volpt with `--jis off` and `--jis on` (isotropic fog box and g = 0.9)
   and bpt with `--joint-connections off` and `on` (isotropic), each arm rendered for the same
   `--time` on one thread, beside a reference (`volpt`, `--jis on`, many iterations on every
   thread) and false-colour images of the absolute error (mean over the channels, one colour
   scale per row). Rows: the double-scattering paths alone (volpt's `s1_t3` layer; in bpt the
   layers with s + t = 4) and the whole image (single and double scattering). Display: linear,
   scaled so that the reference's 99th percentile is white, then sRGB.
"""

import math
import tempfile
from pathlib import Path

import numpy as np

from resultslib import pages  # scripts/ is on sys.path (scripts/bench)

from . import common
from .joint_sampling import read_layer, read_path_class

SCENE = common.REPO_ROOT / "scenes" / "tests" / "fog-box.xml"
LAYER = "s1_t3"  # camera -> c -> b -> light
IMAGE_DIR = "img/joint-sampling"

TECHNIQUES = {"dl (0-connection)": "dl", "j3 (joint)": "j3"}
CLAIMED_SLOPES = {"dl": -1 / 3, "j3": -1 / 2}
SLOPE_TOLERANCE = 0.07
SLOPES = {"width": 32, "exponents": list(range(0, 12)), "runs": 6, "reference_factor": 16,
          "fit_from": 8}
QUICK_SLOPES = {"width": 8, "exponents": [0, 1, 2], "runs": 2, "reference_factor": 2,
                "fit_from": 1}

PICTURE_VARIANTS = {"isotropic": ["-D", "g=0"], "g = 0.9": ["-D", "g=0.9"]}
PICTURES = {"width": 96, "seconds": 4.0, "iterations": None, "reference_iterations": 3072}
QUICK_PICTURES = {"width": 12, "seconds": None, "iterations": 2, "reference_iterations": 4}


def render_to(binary, out, *, algo="volpt", flags=(), seed=0, resolution, threads,
              iterations=None, seconds=None, realtime=False):
    """Renders with `--layers st`; returns (render's summary, the command)."""
    cmd = common.render_command(binary, SCENE, out, algo=algo, iterations=iterations,
                                seconds=seconds, seed=seed, resolution=resolution,
                                threads=threads, extra=[*flags, "--layers", "st"])
    if realtime:
        cmd = [*common.realtime_prefix(), *cmd]
    return common.run_render(cmd), cmd


# --------------------------------------------------------------------------------------------
# 1. Convergence slopes


def fit_slope(ns, errors):
    """Least-squares slope of log(error) against log(N) and its standard error."""
    x, y = np.log(np.asarray(ns, float)), np.log(np.asarray(errors, float))
    design = np.stack([x, np.ones_like(x)], axis=1)
    coeffs, *_ = np.linalg.lstsq(design, y, rcond=None)
    residuals = y - design @ coeffs
    dof = max(len(x) - 2, 1)
    se = math.sqrt(float(residuals @ residuals) / dof / float(((x - x.mean()) ** 2).sum()))
    return float(coeffs[0]), se, float(coeffs[1])


def measure_slopes(binary, workdir, cfg, threads, commands):
    resolution = common.resolution_for_width(SCENE, cfg["width"])
    n_max = 2 ** max(cfg["exponents"])
    ref_iterations = cfg["reference_factor"] * n_max
    out = workdir / "slope-reference.exr"
    run, cmd = render_to(binary, out, seed=777, resolution=resolution, threads=threads,
                         iterations=ref_iterations)
    commands["slope reference"] = cmd
    reference, _ = read_layer(out, LAYER)
    print(f"  slopes: reference {ref_iterations} iterations in {run.seconds:.1f} s", flush=True)
    results = {}
    for t_index, (name, technique) in enumerate(TECHNIQUES.items()):
        rows = []
        for k in cfg["exponents"]:
            n = 2 ** k
            errors = []
            for r in range(cfg["runs"]):
                seed = 100_000 * (t_index + 1) + 1_000 * k + r  # independent per N and run
                out = workdir / f"slope-{technique}-{k}-{r}.exr"
                _, cmd = render_to(binary, out, flags=["--volpt-technique", technique],
                                   seed=seed, resolution=resolution, threads=threads,
                                   iterations=n)
                image, _ = read_layer(out, LAYER)
                out.unlink()
                errors.append(float(np.abs(image - reference).mean()))
            commands[f"slope {technique}"] = cmd
            mae = float(np.mean(errors))
            se = float(np.std(errors, ddof=1) / math.sqrt(len(errors)))
            rows.append((n, mae, se))
            print(f"  slopes: {technique} N {n:5d} MAE {mae:.4g} ± {se:.2g}", flush=True)
        fitted = [(n, e) for n, e, _ in rows if n >= cfg["fit_from"]]
        slope, slope_se, intercept = fit_slope(*zip(*fitted))
        # The local slope over the last doubling steps, to see whether the rate still drifts.
        tail = rows[-4:]
        tail_slope, tail_se, _ = fit_slope([n for n, _, _ in tail], [e for _, e, _ in tail])
        results[name] = {"technique": technique, "rows": rows, "slope": slope,
                         "slope_se": slope_se, "intercept": intercept,
                         "tail_slope": tail_slope, "tail_se": tail_se,
                         "tail_from": tail[0][0]}
    return results, resolution, ref_iterations


def plot_slopes(path: Path, results, fit_from):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for (name, r), colour in zip(results.items(), ("tab:red", "tab:blue")):
        ns = np.array([n for n, _, _ in r["rows"]], float)
        maes = np.array([e for _, e, _ in r["rows"]])
        ses = np.array([s for _, _, s in r["rows"]])
        ax.errorbar(ns, maes, yerr=ses, fmt="o", color=colour, ms=4, capsize=2,
                    label=f"{name}: fitted slope {r['slope']:.3f} ± {r['slope_se']:.3f}")
        fit_ns = ns[ns >= fit_from]
        ax.plot(fit_ns, np.exp(r["intercept"]) * fit_ns ** r["slope"], "-", color=colour, lw=1)
        claimed = CLAIMED_SLOPES[r["technique"]]
        anchor = maes[ns >= fit_from][0] * (fit_ns / fit_ns[0]) ** claimed
        ax.plot(fit_ns, anchor, ":", color=colour, lw=1,
                label=f"slope {'-1/3' if r['technique'] == 'dl' else '-1/2'} (claim)")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("iterations N (samples per pixel)")
    ax.set_ylabel("mean absolute error of double scattering")
    ax.set_title("fog box, point light: unweighted single techniques")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


# --------------------------------------------------------------------------------------------
# 2. Pictures


def srgb(image, scale):
    x = np.clip(image * scale, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def picture_figure(path: Path, title, rows, arm_names):
    """rows: [(row name, reference image, {arm: (image, caption)})]; one row of pictures per
    entry: reference, the arms, then the arms' absolute errors in false colour."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    columns = 1 + 2 * len(arm_names)
    fig, axes = plt.subplots(len(rows), columns, figsize=(2.1 * columns, 2.35 * len(rows) + 0.5),
                             squeeze=False)
    for i, (row_name, reference, arms) in enumerate(rows):
        scale = 1.0 / max(float(np.percentile(reference, 99)), 1e-6)
        errors = {a: np.abs(arms[a][0] - reference).mean(axis=2) for a in arm_names}
        vmax = max(float(np.percentile(e, 99)) for e in errors.values()) or 1.0
        axes[i][0].imshow(srgb(reference, scale), interpolation="nearest")
        axes[i][0].set_title(f"reference\n{row_name}", fontsize=8)
        for j, arm in enumerate(arm_names):
            image, caption = arms[arm]
            axes[i][1 + j].imshow(srgb(image, scale), interpolation="nearest")
            axes[i][1 + j].set_title(f"{arm}\n{caption}", fontsize=8)
            err = errors[arm]
            im = axes[i][1 + len(arm_names) + j].imshow(err, cmap="inferno", vmin=0, vmax=vmax,
                                                        interpolation="nearest")
            axes[i][1 + len(arm_names) + j].set_title(
                f"|error| {arm}\nMAE {err.mean():.3g}, RMSE "
                f"{math.sqrt(float((err ** 2).mean())):.3g}", fontsize=8)
        fig.colorbar(im, ax=axes[i][-1], fraction=0.046, pad=0.04)
        for ax in axes[i]:
            ax.set_xticks([])
            ax.set_yticks([])
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def render_pictures(binary, workdir, cfg, threads, commands):
    """Renders every arm and reference; returns {figure name: (file, title, rows, arms, runs)}."""
    resolution = common.resolution_for_width(SCENE, cfg["width"])
    realtime = cfg["seconds"] is not None
    figures = {}
    references = {}
    for variant, defines in PICTURE_VARIANTS.items():
        out = workdir / "picture-reference.exr"
        run, cmd = render_to(binary, out, flags=[*defines, "--jis", "on"], seed=4242,
                             resolution=resolution, threads=threads,
                             iterations=cfg["reference_iterations"])
        commands[f"picture reference, {variant}"] = cmd
        references[variant] = (read_layer(out, LAYER)[0], read_layer(out, None)[0])
        print(f"  pictures: reference {variant}: {run.iterations} iterations in "
              f"{run.seconds:.1f} s", flush=True)

    def arm_images(algo, flags, seed, tag):
        out = workdir / ("picture-" + "".join(c if c.isalnum() else "-" for c in tag) + ".exr")
        run, cmd = render_to(binary, out, algo=algo, flags=flags, seed=seed,
                             resolution=resolution, threads=1, iterations=cfg["iterations"],
                             seconds=cfg["seconds"], realtime=realtime)
        commands[f"picture {tag}"] = cmd
        double = (read_layer(out, LAYER)[0] if algo == "volpt"
                  else read_path_class(out, 4)[0])
        whole = read_layer(out, None)[0]
        caption = f"{run.iterations} it. in {run.seconds:.2f} s"
        print(f"  pictures: {tag}: {caption}", flush=True)
        return double, whole, caption, run

    for variant, defines in PICTURE_VARIANTS.items():
        arms, runs = {}, {}
        for arm, flags in {"--jis off": ["--jis", "off"], "--jis on": ["--jis", "on"]}.items():
            double, whole, caption, run = arm_images(
                "volpt", [*defines, *flags], 31, f"volpt {variant} {arm}")
            arms[arm] = (double, whole, caption)
            runs[arm] = run
        name = "isotropic" if variant == "isotropic" else "g09"
        figures[f"volpt, fog box, {variant}"] = (
            f"fog-box-{name}-volpt.png", f"volpt on the fog box ({variant}), equal time",
            references[variant], arms, runs)
    arms, runs = {}, {}
    for arm, flags in {"bpt": ["--joint-connections", "off"],
                       "bpt + J1": ["--joint-connections", "on"]}.items():
        double, whole, caption, run = arm_images("bpt", [*PICTURE_VARIANTS["isotropic"], *flags],
                                                 31, f"bpt isotropic {arm}")
        arms[arm] = (double, whole, caption)
        runs[arm] = run
    figures["bpt, fog box, isotropic"] = (
        "fog-box-isotropic-bpt.png", "bpt on the fog box (isotropic), equal time",
        references["isotropic"], arms, runs)
    return figures, resolution


def write_pictures(docs_dir: Path, figures):
    """Draws every figure; returns the document's lines for them."""
    lines = []
    for name, (file, title, (ref_double, ref_whole), arms, runs) in figures.items():
        arm_names = list(arms)
        rows = [("double scattering", ref_double,
                 {a: (arms[a][0], arms[a][2]) for a in arm_names}),
                ("whole image", ref_whole, {a: (arms[a][1], arms[a][2]) for a in arm_names})]
        picture_figure(docs_dir / IMAGE_DIR / file, title, rows, arm_names)
        lines += [f"### {name}", "", f"![{title}](../{IMAGE_DIR}/{file})", "",
                  "| arm | iterations | seconds | double scattering MAE / RMSE | "
                  "whole image MAE / RMSE |", "| --- | --- | --- | --- | --- |"]
        for a in arm_names:
            cells = []
            for image, ref in ((arms[a][0], ref_double), (arms[a][1], ref_whole)):
                err = np.abs(image - ref)
                cells.append(f"{err.mean():.4g} / {math.sqrt(float((err ** 2).mean())):.4g}")
            lines.append(f"| {a} | {runs[a].iterations} | {runs[a].seconds:.2f} | {cells[0]} | "
                         f"{cells[1]} |")
        lines.append("")
    return lines


# --------------------------------------------------------------------------------------------


def run(build_dir: Path, docs_dir: Path, quick: bool = False, threads=None):
    binary = common.render_binary(build_dir)
    workdir = Path(tempfile.mkdtemp(prefix="bench-joint-figures-"))
    slope_cfg = QUICK_SLOPES if quick else SLOPES
    picture_cfg = QUICK_PICTURES if quick else PICTURES
    machine = common.machine_info()
    commands = {}
    start_cpu = common_cpu_seconds()
    slopes, slope_resolution, ref_iterations = measure_slopes(binary, workdir, slope_cfg,
                                                              threads, commands)
    plot_slopes(docs_dir / IMAGE_DIR / "slopes.png", slopes, slope_cfg["fit_from"])
    figures, picture_resolution = render_pictures(binary, workdir, picture_cfg, threads,
                                                  commands)
    cpu = common_cpu_seconds() - start_cpu
    load_after = common.load_average()

    lines = ["# Joint path sampling: pictures and convergence slopes", "",
             "Written by `scripts/bench --only joint-figures` (scripts/benchlib/joint_figures.py);"
             " do not edit by hand. The technique: [media.md](../design/media.md), \"Joint path sampling\";"
             " equal-time error ratios: [joint-sampling.md](joint-sampling.md).", "",
             __doc__.strip(), "",
             f"Machine: {machine.get('cpu_model')}, {machine.get('cores')} cores (shared), "
             f"{machine.get('date_utc')}; revision {revision()}; load "
             f"average before {(machine.get('load_average') or ['?'])[0]}, after "
             f"{(load_after or ['?'])[0]}; {threads or 'all'} threads for the references and "
             f"the slope runs, 1 thread for the equal-time arms"
             + (" under SCHED_FIFO (`chrt -f 10`)" if common.realtime_prefix() else
                " at normal priority")
             + f". CPU time of all renders: {cpu:.0f} s{' (quick mode)' if quick else ''}.", "",
             "## Convergence slopes", "",
             f"{slope_resolution[0]}x{slope_resolution[1]}, N = "
             f"{', '.join(str(2 ** k) for k in slope_cfg['exponents'])}, {slope_cfg['runs']} "
             f"runs per N; reference: {ref_iterations} iterations of volpt (MIS); fit over "
             f"N >= {slope_cfg['fit_from']}.", "",
             f"Commands (last of each): `{' '.join(commands['slope reference'])}`; "
             f"`{' '.join(commands['slope dl'])}`; `{' '.join(commands['slope j3'])}`", "",
             f"![mean absolute error against N](../{IMAGE_DIR}/slopes.png)", "",
             "| technique | " + " | ".join(f"N = {n}" for n, _, _ in
                                           next(iter(slopes.values()))["rows"]) + " |",
             "| --- |" + " --- |" * len(next(iter(slopes.values()))["rows"])]
    for name, r in slopes.items():
        lines.append(f"| {name} | " + " | ".join(f"{e:.4g}" for _, e, _ in r["rows"]) + " |")
    lines += ["", "| technique | fitted slope (± SE) | local slope, N >= "
              f"{next(iter(slopes.values()))['tail_from']} (± SE) | claim | within "
              f"{SLOPE_TOLERANCE}? |", "| --- | --- | --- | --- | --- |"]
    for name, r in slopes.items():
        claimed = CLAIMED_SLOPES[r["technique"]]
        held = abs(r["slope"] - claimed) <= SLOPE_TOLERANCE
        lines.append(f"| {name} | {r['slope']:.3f} ± {r['slope_se']:.3f} | "
                     f"{r['tail_slope']:.3f} ± {r['tail_se']:.3f} | {claimed:.3f} | "
                     f"**{'held' if held else 'not held'}** |")
    lines += ["", "## Pictures at equal time", "",
              f"{picture_resolution[0]}x{picture_resolution[1]}; each arm "
              + (f"`--time {picture_cfg['seconds']:g}` on 1 thread"
                 if picture_cfg["seconds"] else f"{picture_cfg['iterations']} iterations")
              + f"; references: {picture_cfg['reference_iterations']} iterations of volpt "
              "`--jis on` (the g = 0.9 reference is itself heavy-tailed: a point light seen "
              "through the phase function's forward peak, which no technique samples). "
              "Errors are against the reference, so they include its own noise.", "",
              f"Commands (isotropic): `{' '.join(commands['picture reference, isotropic'])}`; "
              f"`{' '.join(commands['picture volpt isotropic --jis on'])}`; "
              f"`{' '.join(commands['picture bpt isotropic bpt + J1'])}`", ""]
    lines += write_pictures(docs_dir, figures)
    # The page is generated from its template and this data file (docs/guide/results.md).
    out_doc = pages.publish_blocks(docs_dir, "joint-figures", lines,
                                   "scripts/bench --only joint-figures" + (" --quick" if quick else ""),
                                   load_before=pages.load_text(machine.get("load_average")))
    print(f"bench: wrote {out_doc}")


def revision() -> str:
    """The checked-out commit (also in a git worktree, where .git is a file)."""
    import subprocess
    r = subprocess.run(["git", "-C", str(common.REPO_ROOT), "rev-parse", "--short=12", "HEAD"],
                       capture_output=True, text=True)
    return r.stdout.strip() if r.returncode == 0 else common.source_revision()


def common_cpu_seconds() -> float:
    """CPU seconds used by finished child processes (the renders) so far."""
    import resource
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime
