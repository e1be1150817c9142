"""Shared helpers for the benchmarks: machine information, running `render`, parsing its
output, EXR input/output and image error metrics.

Nothing here knows about a particular benchmark, so every benchmark module can use it.
"""

from __future__ import annotations

import dataclasses
import datetime
import functools
import json
import math
import os
import re
import shlex
import shutil
import subprocess
import sys
import time
import xml.etree.ElementTree as ElementTree
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[2]

# The generated pages are results pages: DOCS/results/NAME.md. Their images stay in DOCS/img/
# and the pages they link to are in DOCS/design/, DOCS/references/ ..., so the links a
# generator writes are relative to DOCS/results/ ("../img/...", "../design/media.md").
RESULTS_DIR = "results"


def results_page(docs_dir: Path, name: str) -> Path:
    """Where a generated page NAME.md goes under the docs folder DOCS_DIR (docs/ by default)."""
    return Path(docs_dir) / RESULTS_DIR / name


# --------------------------------------------------------------------------------------------
# Machine information


def cpu_model() -> str:
    """The CPU model name from /proc/cpuinfo ("unknown" when it cannot be read)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown"


def load_average() -> Optional[tuple[float, float, float]]:
    """The 1, 5 and 15 minute load averages, or None where /proc/loadavg does not exist."""
    try:
        fields = Path("/proc/loadavg").read_text().split()
        return float(fields[0]), float(fields[1]), float(fields[2])
    except (OSError, ValueError, IndexError):
        return None


def memory_gib() -> Optional[float]:
    """Total memory in GiB from /proc/meminfo, or None."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                return int(line.split()[1]) / (1024 * 1024)
    except (OSError, ValueError, IndexError):
        pass
    return None


def source_revision() -> str:
    """The checked-out commit, read from .git without running git ("unknown" otherwise).

    In a linked worktree .git is a file naming the worktree's own git folder (which holds HEAD)
    and that folder's `commondir` names the repository's (which holds the refs)."""
    git = REPO_ROOT / ".git"
    try:
        git_dir = git
        if git.is_file():
            git_dir = (git.parent / git.read_text().strip().split(None, 1)[1]).resolve()
        common_dir = git_dir
        commondir_file = git_dir / "commondir"
        if commondir_file.exists():
            common_dir = (git_dir / commondir_file.read_text().strip()).resolve()
        head = (git_dir / "HEAD").read_text().strip()
        if not head.startswith("ref:"):
            return head[:12]
        ref = head.split(None, 1)[1]
        for folder in (git_dir, common_dir):
            ref_file = folder / ref
            if ref_file.exists():
                return ref_file.read_text().strip()[:12]
        packed = common_dir / "packed-refs"
        if packed.exists():
            for line in packed.read_text().splitlines():
                if line.endswith(" " + ref):
                    return line.split()[0][:12]
    except (OSError, IndexError):
        pass
    return "unknown"


def machine_info() -> dict:
    """A JSON-friendly description of the machine the benchmark runs on."""
    uname = os.uname()
    return {
        "cores": os.cpu_count(),
        "cpu_model": cpu_model(),
        "memory_gib": memory_gib(),
        "kernel": f"{uname.sysname} {uname.release}",
        "load_average": load_average(),
        "date_utc": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "source_revision": source_revision(),
    }


# --------------------------------------------------------------------------------------------
# Running `render`


@dataclasses.dataclass
class RenderRun:
    """What one `render` invocation reported (its final stdout line) plus its command."""

    iterations: int
    seconds: float  # the render loop's wall time as printed by `render` (scene loading excluded)
    samples_per_second: float
    rays_per_second: float
    estimated_relative_error: float
    non_finite_dropped: int
    process_seconds: float  # wall time of the whole process, scene loading included
    command: list[str]


SUMMARY_PATTERN = re.compile(
    r"(?P<iterations>\d+) iterations in (?P<seconds>\S+) s: (?P<sps>\S+) samples/s, "
    r"(?P<rps>\S+) rays/s, estimated relative error (?P<error>\S+), "
    r"(?P<nonfinite>\d+) non-finite samples dropped"
)


def parse_render_summary(stdout: str) -> dict:
    """Parses the last summary line `render` prints ("N iterations in T s: ...").

    Returns a dict with iterations, seconds, samples_per_second, rays_per_second,
    estimated_relative_error and non_finite_dropped. Raises ValueError if there is none.
    """
    matches = list(SUMMARY_PATTERN.finditer(stdout))
    if not matches:
        raise ValueError("no summary line in render output:\n" + stdout[-2000:])
    m = matches[-1]
    return {
        "iterations": int(m["iterations"]),
        "seconds": float(m["seconds"]),
        "samples_per_second": float(m["sps"]),
        "rays_per_second": float(m["rps"]),
        "estimated_relative_error": float(m["error"]),
        "non_finite_dropped": int(m["nonfinite"]),
    }


def render_binary(build_dir: Path) -> Path:
    """The `render` executable of a build directory; exits with a hint if it is missing."""
    binary = Path(build_dir) / "bin" / "render"
    if not binary.exists():
        sys.exit(f"bench: {binary} not found; build it first "
                 f"(cmake --build {build_dir} --target render)")
    return binary


def algorithm_table(build_dir: Path) -> dict:
    """The algorithm and option tables of a build (`render --describe-options`)."""
    out = subprocess.run([str(render_binary(build_dir)), "--describe-options"], check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out)


def benchmarked_algorithms(build_dir: Path, suite: str) -> list:
    """The algorithms whose table row names `suite` among its benchmarks, in table order: the
    suites read them from the build instead of keeping a list (docs/design/architecture.md)."""
    return [a["name"] for a in algorithm_table(build_dir)["algorithms"]
            if suite in a.get("benchmarks", [])]


def display_path(path: Path | str) -> str:
    """A path relative to the repository root when it lies inside it, for printed commands
    (commands run in the repository root). Relative inputs are taken as relative to it."""
    p = Path(path)
    if not p.is_absolute():
        p = REPO_ROOT / p
    try:
        return str(p.resolve().relative_to(REPO_ROOT))
    except ValueError:
        return str(p)


def render_command(binary: Path, scene: Path | str, out: Path, *, algo: str,
                   iterations: Optional[int] = None, seconds: Optional[float] = None,
                   seed: int = 0, resolution: Optional[tuple[int, int]] = None,
                   threads: Optional[int] = None, png: Optional[Path] = None,
                   extra: Sequence[str] = ()) -> list[str]:
    """The argument list of one `render` invocation (paths shown relative to the repo)."""
    cmd = [display_path(binary), display_path(scene), "--algo", algo]
    if iterations is not None:
        cmd += ["--iterations", str(iterations)]
    if seconds is not None:
        cmd += ["--time", f"{seconds:g}"]
    cmd += ["--seed", str(seed)]
    if resolution is not None:
        cmd += ["--resolution", f"{resolution[0]}x{resolution[1]}"]
    if threads is not None:
        cmd += ["--threads", str(threads)]
    cmd += list(extra)
    cmd += ["--out", display_path(out)]
    if png is not None:
        cmd += ["--png", display_path(png)]
    return cmd


def run_render(cmd: list[str], *, timeout: Optional[float] = None) -> RenderRun:
    """Runs a command from render_command() in the repository root and parses its summary.

    Raises RuntimeError (with the output) when `render` fails.
    """
    start = time.monotonic()
    proc = subprocess.run(cmd, cwd=REPO_ROOT, capture_output=True, text=True, timeout=timeout)
    process_seconds = time.monotonic() - start
    if proc.returncode != 0:
        raise RuntimeError(f"render failed ({proc.returncode}): {shlex.join(cmd)}\n"
                           f"{proc.stdout[-2000:]}{proc.stderr[-2000:]}")
    summary = parse_render_summary(proc.stdout)
    return RenderRun(process_seconds=process_seconds, command=list(cmd), **summary)


# --------------------------------------------------------------------------------------------
# Scenes


def pbrt_film_size(scene: Path) -> tuple[int, int]:
    """A pbrt-v4 file's Film `xresolution`/`yresolution` (pbrt's 1280x720 when absent)."""
    text = Path(scene).read_text()

    def value(name: str, default: int) -> int:
        m = re.search(r'"integer\s+' + name + r'"\s*\[?\s*(\d+)', text)
        return int(m.group(1)) if m else default

    return value("xresolution", 1280), value("yresolution", 720)


def scene_film_size(scene: Path) -> tuple[int, int]:
    """The film size a scene file asks for: its `resx`/`resy` defaults when present,
    otherwise the film's integer `width`/`height` (Mitsuba's 768x576 when neither is set).
    pbrt-v4 files (.pbrt): their Film's resolution."""
    if Path(scene).suffix == ".pbrt":
        return pbrt_film_size(scene)
    root = ElementTree.parse(scene).getroot()
    defaults = {d.get("name"): d.get("value") for d in root.iter("default")}

    def resolve(value: Optional[str]) -> Optional[int]:
        if value is None:
            return None
        if value.startswith("$"):
            value = defaults.get(value[1:])
        return int(value) if value is not None else None

    width = height = None
    for film in root.iter("film"):
        for integer in film.iter("integer"):
            if integer.get("name") == "width":
                width = resolve(integer.get("value"))
            elif integer.get("name") == "height":
                height = resolve(integer.get("value"))
    width = width or resolve(defaults.get("resx")) or 768
    height = height or resolve(defaults.get("resy")) or 576
    return width, height


def resolution_for_width(scene: Path, width: int) -> tuple[int, int]:
    """(width, height) with the scene's aspect ratio, height rounded to the nearest pixel."""
    film_w, film_h = scene_film_size(scene)
    return width, max(1, round(width * film_h / film_w))


# --------------------------------------------------------------------------------------------
# Images


def read_exr(path: Path) -> tuple[np.ndarray, dict]:
    """Reads the RGB channels of an EXR (float64, shape H x W x 3) and its attributes."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise RuntimeError(f"cannot open {path}: {oiio.geterror()}")
    spec = inp.spec()
    pixels = inp.read_image(0, 0, 0, 3, oiio.FLOAT)
    inp.close()
    attributes = {a.name: a.value for a in spec.extra_attribs}
    return np.asarray(pixels, dtype=np.float64).reshape(spec.height, spec.width, 3), attributes


def read_exr_layers(path: Path) -> tuple[dict, dict]:
    """Every RGB layer of an EXR as float64 H x W x 3 arrays, keyed by layer name ("" for the
    image itself: `--layers` writes "st.R" beside "R"), and the file's attributes."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise RuntimeError(f"cannot open {path}: {oiio.geterror()}")
    spec = inp.spec()
    pixels = np.asarray(inp.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT), dtype=np.float64)
    inp.close()
    pixels = pixels.reshape(spec.height, spec.width, spec.nchannels)
    channels = {}
    for i, name in enumerate(spec.channelnames):
        layer, _, channel = name.rpartition(".")
        if channel in ("R", "G", "B"):
            channels.setdefault(layer, {})[channel] = pixels[..., i]
    layers = {layer: np.stack([c[k] for k in "RGB"], axis=-1)
              for layer, c in channels.items() if len(c) == 3}
    return layers, {a.name: a.value for a in spec.extra_attribs}


def write_exr(path: Path, pixels: np.ndarray, attributes: dict, *, half: bool = True,
              compression: str = "zip") -> None:
    """Writes an RGB EXR (half or float, given compression) with string/number attributes."""
    import OpenImageIO as oiio

    height, width, channels = pixels.shape
    spec = oiio.ImageSpec(width, height, channels, oiio.HALF if half else oiio.FLOAT)
    spec.channelnames = ("R", "G", "B")[:channels]
    spec.attribute("compression", compression)
    for name, value in attributes.items():
        if isinstance(value, (int, float, str)):
            spec.attribute(name, value)
    out = oiio.ImageOutput.create(str(path))
    if out is None or not out.open(str(path), spec):
        raise RuntimeError(f"cannot write {path}: {oiio.geterror()}")
    out.write_image(np.ascontiguousarray(pixels, dtype=np.float32))
    out.close()


def downscale(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Box-averages an H x W x C image down to size = (width, height).

    The sizes must divide exactly. With `render`'s box filter, the average of the k x k
    pixels of a fine image has the same expectation as one pixel of the coarse image.
    """
    height, width = image.shape[:2]
    new_w, new_h = size
    if (new_w, new_h) == (width, height):
        return image
    if width % new_w or height % new_h or width // new_w != height // new_h:
        raise ValueError(f"cannot box-downscale {width}x{height} to {new_w}x{new_h}")
    k = width // new_w
    return image.reshape(new_h, k, new_w, k, -1).mean(axis=(1, 3))


RELATIVE_MSE_EPSILON = 0.01


def error_metrics(image: np.ndarray, reference: np.ndarray) -> dict:
    """RMSE and relative MSE of an image against a reference (same shape).

    rmse         = sqrt(mean over pixels and channels of (x - r)^2)
    relative_mse = mean over pixels and channels of (x - r)^2 / (r^2 + 0.01)
    (the same definitions as `render --compare`). Also the mean difference.
    """
    if image.shape != reference.shape:
        raise ValueError(f"image {image.shape} and reference {reference.shape} differ in size")
    diff = image - reference
    sq = diff * diff
    return {
        "rmse": float(math.sqrt(sq.mean())),
        "relative_mse": float((sq / (reference * reference + RELATIVE_MSE_EPSILON)).mean()),
        "mean_difference": float(diff.mean()),
        "non_finite_pixels": int((~np.isfinite(image)).any(axis=-1).sum()),
    }


@functools.lru_cache(maxsize=None)
def realtime_prefix() -> tuple[str, ...]:
    """`chrt -f 10` where real-time scheduling is allowed (root): timing runs then take the
    cores from other load on the machine (Linux leaves others 5 % of each second)."""
    chrt = shutil.which("chrt")
    if chrt and subprocess.run([chrt, "-f", "10", "true"], capture_output=True).returncode == 0:
        return (chrt, "-f", "10")
    return ()


def variance_and_time(render, variance, cfg) -> dict:
    """The two factors of an equal-time comparison of unbiased estimators (relMSE(T) = v t / T):
    v, one iteration's variance from cfg["runs"] independent runs of cfg["iterations"] each
    (`variance(images, iterations)`), with its standard error over cfg["groups"] disjoint
    groups of runs; and t, the median over cfg["timing_repeats"] real-time runs of about
    cfg["timing_seconds"] of render's own seconds per iteration.
    `render(index, seed, iterations, realtime)` renders and returns (image, header)."""
    images = [render(f"v-{i}", 10_000 + 100 * i, cfg["iterations"], False)[0]
              for i in range(cfg["runs"])]
    v = variance(images, cfg["iterations"])
    size = cfg["runs"] // cfg["groups"]
    groups = [variance(images[g * size:(g + 1) * size], cfg["iterations"])
              for g in range(cfg["groups"])]
    v_se = float(np.std(groups, ddof=1) / math.sqrt(len(groups)))
    # Seconds per iteration: a short run predicts the count that takes timing_seconds.
    _, header = render("probe", 7, 1, True)
    count = max(2, round(cfg["timing_seconds"] / max(float(header["render:seconds"]), 1e-3)))
    per_iteration = [float(render("timing", 20_000 + repeat, count, True)[1]["render:seconds"])
                     / count for repeat in range(cfg["timing_repeats"])]
    return {"v": v, "v_se": v_se, "t": float(np.median(per_iteration)), "images": images,
            "timing_iterations": count}
