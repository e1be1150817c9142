"""Performance report: runs the Google Benchmark microbenchmarks (build/bin/render_bench, sources
in bench/), measures the overhead of distribution with a real local cluster, optionally profiles
one bidirectional iteration with `perf`, and writes docs/results/performance.md from scratch.

    run(build_dir, docs_dir, quick)   # scripts/bench calls this

`quick` runs a tiny subset once (for checking that the pipeline works); the full run takes the
median of 5 repetitions of everything. Only the Python standard library is used.
"""

import datetime
import json
import os
import platform
import re
import shlex
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchlib import reference
from resultslib import data as datafile, pages  # scripts/ is on sys.path (scripts/bench)

SOURCE_DIR = Path(__file__).resolve().parents[2]

# The distribution job: the demo's job (docs/guide/service.md), so the figures can be compared.
DIST_SCENE = "scenes/smallvcm/1-glm_c.xml"
DIST_ALGO = "vcm"
DIST_ITERATIONS = 32
DIST_RESOLUTION = "256x256"
QUICK_DIST_ITERATIONS = 4

REPETITIONS = 5
QUICK_FILTER = ("^(rays/(closest|occluded)/(ours|embree)/cornell-box"
                "|iteration/1-glm_c/(pt|vcm)/threads:2"
                "|hash_grid/(build|query)/1-glm_c)$")

RAY_SCENES = ["cornell-box", "veach-mis", "veach-bidir", "0-gbs_s", "1-glm_c", "2-gbs_p",
              "3-gbs_b", "procedural-1M"]
REFERENCE_SCENES = ["0-gbs_s", "1-glm_c", "2-gbs_p", "3-gbs_b"]
MEDIA_SCENES = ["isosph", "glasssph", "volumetric-caustic", "smoke"]
MEDIA_ALGORITHMS = ["volpt", "bpt", "vcm"]
PERF_TARGETS = ["iteration/1-glm_c/bpt/threads:1", "iteration/1-glm_c/vcm/threads:1"]


# ---------------------------------------------------------------------------------------------
# Helpers: commands, machine


def log(message):
    print(f"[performance] {message}", file=sys.stderr, flush=True)


def rel(path):
    """A path as the commands in the report show it: relative to the checkout when inside it."""
    path = Path(path).resolve()
    try:
        return str(path.relative_to(SOURCE_DIR))
    except ValueError:
        return str(path)


def show(cmd):
    return " ".join(shlex.quote(rel(c)) if os.path.isabs(str(c)) else shlex.quote(str(c))
                    for c in cmd)


def run_cmd(cmd, timeout=3600, **kwargs):
    """Runs a command, returns (completed process, wall seconds); raises on failure."""
    t0 = time.monotonic()
    r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=timeout,
                       cwd=SOURCE_DIR, **kwargs)
    seconds = time.monotonic() - t0
    if r.returncode != 0:
        raise RuntimeError(f"{show(cmd)} exited {r.returncode}:\n{r.stderr[-3000:]}")
    return r, seconds


def machine_info():
    model = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        loadavg = Path("/proc/loadavg").read_text().split()[:3]
    except OSError:
        loadavg = ["?", "?", "?"]
    try:
        mem_kb = int(re.search(r"MemTotal:\s+(\d+)", Path("/proc/meminfo").read_text()).group(1))
        memory = f"{mem_kb / 2**20:.1f} GiB"
    except (OSError, AttributeError):
        memory = "?"
    return {
        "cores": os.cpu_count(),
        "model": model,
        "loadavg": loadavg,
        "memory": memory,
        "kernel": platform.release(),
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
    }


def median(values):
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def fmt(value, digits=3):
    if value is None:
        return "–"
    if value == 0:
        return "0"
    magnitude = abs(value)
    if magnitude >= 1e9:
        return f"{value / 1e9:.{digits}g} G"
    if magnitude >= 1e6:
        return f"{value / 1e6:.{digits}g} M"
    if magnitude >= 1e4:
        return f"{value / 1e3:.{digits}g} k"
    return f"{value:.{digits}g}"


def fmt_ratio(value):
    return "–" if value is None else f"{value:.2f}"


# ---------------------------------------------------------------------------------------------
# 1. Google Benchmark


def run_render_bench(bench, quick, work):
    out = work / "render_bench.json"
    cmd = [bench, "--benchmark_format=json", f"--benchmark_out={out}",
           "--benchmark_out_format=json"]
    if quick:
        cmd += [f"--benchmark_filter={QUICK_FILTER}", "--benchmark_min_time=0.05",
                "--benchmark_repetitions=1"]
    else:
        cmd += [f"--benchmark_repetitions={REPETITIONS}",
                "--benchmark_report_aggregates_only=true"]
    log("running " + show(cmd))
    _, seconds = run_cmd(cmd, timeout=4 * 3600)
    data = json.loads(out.read_text())
    shown = [c for c in cmd if not str(c).startswith("--benchmark_out")]
    return parse_benchmarks(data), show(shown), seconds, data.get("context", {})


def parse_benchmarks(data):
    """name -> the median run (or the only run) of each benchmark."""
    medians, singles = {}, {}
    for b in data.get("benchmarks", []):
        name = b.get("run_name", b["name"])
        if b.get("run_type") == "aggregate":
            if b.get("aggregate_name") == "median":
                medians[name] = b
        else:
            singles.setdefault(name, b)
    singles.update(medians)
    return singles


def seconds_of(b, key="real_time"):
    scale = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}[b.get("time_unit", "ns")]
    return b[key] * scale


# ---------------------------------------------------------------------------------------------
# 2. Distribution overhead: local cluster against `render --threads 2`


def _term_with_parent():
    # In the child before exec: SIGTERM (the launcher's clean stop) if this script dies.
    try:
        import ctypes
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except Exception:
        pass


class Cluster:
    """deploy/local-cluster in the background (its own process group), stopped with SIGTERM."""

    def __init__(self, bin_dir, workers, threads, work):
        self.dir = Path(tempfile.mkdtemp(prefix=f"cluster-{workers}x{threads}-", dir=work))
        self.logs = self.dir / "logs"
        self.address_file = self.dir / "address"
        self.cmd = [SOURCE_DIR / "deploy" / "local-cluster", str(workers), "--threads",
                    str(threads), "--bin-dir", bin_dir, "--address-file", self.address_file,
                    "--log-dir", self.logs]
        self.out = open(self.dir / "local-cluster.out", "w")
        self.proc = subprocess.Popen([str(c) for c in self.cmd], cwd=SOURCE_DIR,
                                     stdin=subprocess.DEVNULL, stdout=self.out, stderr=self.out,
                                     start_new_session=True, preexec_fn=_term_with_parent)
        deadline = time.monotonic() + 60
        while not self.address_file.exists():
            if self.proc.poll() is not None or time.monotonic() > deadline:
                self.stop()
                raise RuntimeError("local cluster did not start: " +
                                   (self.dir / "local-cluster.out").read_text()[-2000:])
            time.sleep(0.1)
        self.address = self.address_file.read_text().strip()
        # Wait until every worker has registered, so the first job does not time start-up.
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            registered = sum("event=registered" in p.read_text(errors="replace")
                             for p in self.logs.glob("worker-*.log"))
            if registered >= workers:
                break
            time.sleep(0.1)

    def server_log(self):
        return (self.logs / "server.log").read_text(errors="replace")

    def stop(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)  # the launcher stops workers, then the server
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(timeout=10)
        self.out.close()


def kv_lines(text, event):
    for line in text.splitlines():
        if f" event={event} " in line or line.rstrip().endswith(f" event={event}"):
            yield dict(re.findall(r'(\w+)=("[^"]*"|\S+)', line))


def run_distribution(bin_dir, quick, work):
    runs = 1 if quick else REPETITIONS
    iterations = QUICK_DIST_ITERATIONS if quick else DIST_ITERATIONS
    job = [DIST_SCENE, "--algo", DIST_ALGO, "--iterations", str(iterations), "--resolution",
           DIST_RESOLUTION]
    result = {"iterations": iterations, "runs": runs, "configs": []}

    out_exr = work / "render.exr"
    render_cmd = [bin_dir / "render", *job, "--threads", "2", "--out", out_exr]
    result["render_cmd"] = show(render_cmd[:-2] + ["--out", "/tmp/render.exr"])
    times = []
    for k in range(runs):
        log(f"render --threads 2, run {k + 1}/{runs}")
        _, seconds = run_cmd(render_cmd)
        times.append(seconds)
    result["render_seconds"] = times
    result["render_it_per_s"] = iterations / median(times)

    for workers, threads in ((1, 2), (2, 1)):
        log(f"local cluster {workers} worker(s) x {threads} thread(s)")
        cluster = Cluster(bin_dir, workers, threads, work)
        shown = [*cluster.cmd[:-4], "--address-file", "ADDRESS_FILE"]
        config = {"workers": workers, "threads": threads, "cluster_cmd": show(shown)}
        try:
            env = dict(os.environ, RENDER_SERVER=cluster.address)
            submit = [bin_dir / "client", "submit", *job, "--wait", "--out", work / "cluster.exr"]
            config["submit_cmd"] = show(submit[:-2] + ["--out", "/tmp/cluster.exr"])
            times = []
            for k in range(runs):
                log(f"  submit, run {k + 1}/{runs}")
                _, seconds = run_cmd(submit, env=env)
                times.append(seconds)
            text = cluster.server_log()
        finally:
            cluster.stop()
        reports = list(kv_lines(text, "report_received"))
        merged = list(kv_lines(text, "merged"))
        config["seconds"] = times
        config["it_per_s"] = iterations / median(times)
        config["ratio"] = config["it_per_s"] / result["render_it_per_s"]
        config["reports"] = len(reports)
        total_bytes = sum(int(r["bytes"]) for r in reports)
        total_iterations = sum(int(r["iterations"]) for r in reports)
        config["report_bytes"] = median([int(r["bytes"]) for r in reports])
        config["bytes_per_iteration"] = total_bytes / total_iterations if total_iterations else None
        config["iterations_per_report"] = total_iterations / len(reports) if reports else None
        config["receive_us"] = median([int(r["receive_us"]) for r in reports])
        config["merge_us"] = median([int(r["merge_us"]) for r in reports])
        config["add_us"] = median([int(m["add_us"]) for m in merged if "add_us" in m])
        config["checkpoint_us"] = median([int(m["checkpoint_us"]) for m in merged
                                          if "checkpoint_us" in m])
        result["configs"].append(config)
    return result


# ---------------------------------------------------------------------------------------------
# 3. perf profile of bidirectional iterations


def classify(dso, symbol):
    s = symbol.lower()
    if "embree" in dso:
        return "ray queries (Embree)"
    if "tbb" in dso:
        return "threading (TBB)"
    if dso.startswith("libc") or dso.startswith("ld-") or "[kernel" in dso:
        return "kernel, libc, loader"
    if "hashgrid" in s or "for_each_within_radius" in s or "merge" in s:
        return "merging (hash grid)"
    if "intersect" in s or "occluded" in s or "fill_interaction" in s or "spawn_ray" in s:
        return "ray queries (our wrapper)"
    if any(k in s for k in ("accumulationbuffer", "splat", "technique", "layers")):
        return "accumulation"
    return "shading and sampling"


def run_perf(bench, quick, work):
    perf = shutil.which("perf")
    if not perf or quick:
        return None
    profiles = []
    for target in PERF_TARGETS:
        data = work / ("perf-" + re.sub(r"[^\w]+", "_", target) + ".data")
        record = [perf, "record", "-F", "999", "-o", data, "--", bench,
                  f"--benchmark_filter=^{target}$", "--benchmark_min_time=3"]
        log("profiling " + target)
        try:
            run_cmd(record)
            report = [perf, "report", "-i", data, "--stdio", "--no-children", "--sort",
                      "dso,symbol", "--percent-limit", "0.3"]
            r, _ = run_cmd(report)
        except (RuntimeError, subprocess.TimeoutExpired) as e:
            log(f"perf failed, skipping the profile: {e}")
            return None
        rows = []
        for line in r.stdout.splitlines():
            m = re.match(r"\s*([\d.]+)%\s+(\S+)\s+\[[.kH]\]\s+(.*)$", line)
            if m:
                rows.append((float(m.group(1)), m.group(2), m.group(3).strip()))
        categories = {}
        for pct, dso, sym in rows:
            key = classify(dso, sym)
            categories[key] = categories.get(key, 0.0) + pct
        profiles.append({"target": target,
                         "cmd": show(record[:4] + ["-o", "perf.data"] + record[6:]) +
                         " && perf report -i perf.data --stdio --no-children --sort dso,symbol",
                         "top": rows[:12], "categories": categories})
    return profiles


# ---------------------------------------------------------------------------------------------
# 4. The document


def short_symbol(symbol, width=90):
    symbol = symbol.strip()
    symbol = re.sub(r"\(anonymous namespace\)::", "", symbol)
    symbol = re.sub(r"render::", "", symbol)
    return symbol if len(symbol) <= width else symbol[:width - 1] + "…"


def write_document(path, machine, bench, dist, profiles, quick, started, total_seconds,
                   reference_result=None):
    results, bench_cmd, bench_seconds, context = bench
    try:
        loaded = float(machine["loadavg"][0]) > 0.5 * float(machine["cores"])
    except (TypeError, ValueError):
        loaded = False
    L = []
    add = L.append
    add("# Performance")
    add("")
    add("Generated by `scripts/bench` (`scripts/benchlib/performance.py`); every number below "
        "comes from the commands shown with it. `scripts/bench` regenerates it from scratch "
        "(`scripts/bench --only performance` for this document alone; `--quick` for a smoke "
        "run).")
    if quick:
        add("")
        add("**Quick mode**: a small subset, one run each. These figures only show that the "
            "pipeline works; do not quote them.")
    add("")
    add("## Machine and conditions")
    add("")
    load = " / ".join(machine["loadavg"])
    add(f"- CPU: {machine['model']}, {machine['cores']} cores (`os.cpu_count()`), "
        f"{machine['memory']} RAM, Linux {machine['kernel']}.")
    add(f"- Started {started}; the whole run took {total_seconds / 60:.1f} min "
        f"(of which render_bench {bench_seconds / 60:.1f} min).")
    add(f"- Load average at the start (`/proc/loadavg`, 1 / 5 / 15 min): **{load}**. "
        "Anything well above 0 means other processes were competing for the cores and the "
        "absolute times below are pessimistic; the ratios compare runs made under the same load.")
    if context:
        add(f"- render_bench reported {context.get('num_cpus', '?')} CPUs at "
            f"{context.get('mhz_per_cpu', '?')} MHz. Google Benchmark is Debian's libbenchmark "
            "(1.7.1), which calls itself a *debug* library build; that flag concerns the "
            "library's own assertions, not the code measured (render_bench and render_core are "
            "Release builds).")
    reps = "1 run" if quick else f"median of {REPETITIONS} repetitions"
    add(f"- Microbenchmarks: {reps} (`--benchmark_repetitions`), release build.")
    add("")
    add("All microbenchmarks:")
    add("")
    add(f"    {bench_cmd}")
    add("")
    add("(`render_bench --benchmark_list_tests` lists them; `--benchmark_filter=REGEX` runs a "
        "subset.)")

    # What was measured by hand is linked by the page's template
    # (scripts/resultslib/templates/performance.md.in), not from the data.

    # --- ray queries
    if L[-1].strip():
        add("")
    add("## Ray queries")
    add("")
    add("Rays/s of one thread over a fixed ray set per scene (`bench/ray_queries.cpp`, "
        "`bench/bench_scenes.cpp`): for closest hits, one camera ray per cell of a 256 × 256 "
        "grid over the image (jittered, fixed seed) plus, for every first hit, one "
        "cosine-distributed ray about the geometric normal; for occlusion, one shadow ray per "
        "first hit toward a point sampled on a light, offset at both ends as the integrators do. "
        "Rays are generated before timing. **ours** goes through `Scene::intersect` (which also "
        "fills the `SurfaceInteraction`: hit point, normals, shading frame, BSDF; uv and dp/du "
        "only for materials that vary over the surface) and "
        "`Scene::occluded`; **embree** calls `rtcIntersect1` / `rtcOccluded1` on the same "
        "`RTCScene` with the same ray set-up. `procedural-1M` is a displaced sphere of "
        "1,048,576 triangles on a ground quad, generated in memory "
        "(`bench/procedural_mesh.cpp`).")
    add("")
    add("| scene | closest: ours | closest: Embree | ours / Embree | occluded: ours | "
        "occluded: Embree | ours / Embree |")
    add("| --- | --- | --- | --- | --- | --- | --- |")
    closest_ratios, occluded_ratios = [], []
    for scene in RAY_SCENES:
        row = [scene]
        present = False
        for kind in ("closest", "occluded"):
            ours = results.get(f"rays/{kind}/ours/{scene}")
            embree = results.get(f"rays/{kind}/embree/{scene}")
            o = ours.get("items_per_second") if ours else None
            e = embree.get("items_per_second") if embree else None
            ratio = o / e if o and e else None
            if ratio:
                (closest_ratios if kind == "closest" else occluded_ratios).append(ratio)
            present |= bool(o or e)
            row += [fmt(o) + " rays/s" if o else "–", fmt(e) + " rays/s" if e else "–",
                    fmt_ratio(ratio)]
        if present:
            add("| " + " | ".join(row) + " |")
    add("")
    add("Rates are per CPU second of the benchmark thread (Google Benchmark's default), so "
        "other load on the machine affects them less than wall-clock figures. ")
    add("What limits it: the BVH traversal inside Embree. ")
    if closest_ratios:
        add(f"Our closest-hit path runs at {min(closest_ratios):.2f}–{max(closest_ratios):.2f} "
            "of bare Embree's speed; the difference is `fill_interaction` (a virtual call per "
            "hit, then for meshes three vertex positions and normals fetched from memory "
            "and interpolated, and a shading frame built). On the 1 M-triangle mesh those "
            "fetches are cache misses into about 25 MB of vertex and index data, so the wrapper's share does "
            "not shrink with scene size (the speed target is 0.92: see \"Closest hits through "
            f"Scene::intersect\" in [{NOTES_PAGE}]({NOTES_PAGE})). ")
    if occluded_ratios:
        add(f"Occlusion rays do no extra work in our wrapper (ratio "
            f"{min(occluded_ratios):.2f}–{max(occluded_ratios):.2f}: noise). ")
    add("Both loops trace one ray at a time (`rtcIntersect1`); packets or streams "
        "(`rtcIntersect4/8`, `rtcIntersect1M`) are not used anywhere in the renderer.")

    # --- iterations
    add("")
    add("## Seconds per iteration")
    add("")
    add("One progressive iteration (one sample per pixel, and for the light-path algorithms one "
        "light path per pixel) of each algorithm on the reference Cornell boxes at their "
        "reference resolution (512 × 512, from the scene files), rendered exactly as `render` "
        "and the worker do: one `IterationRenderer` (integrator, task arena and buffers made "
        "once) adding one iteration at a time, consecutive iteration indices, after one "
        "untimed warm-up iteration that allocates the buffers the others reuse; the thread "
        "count set by `tbb::global_control` and the settings' task arena "
        "(`bench/iterations.cpp`, names `iteration/<scene>/<algo>/threads:<n>`). Wall-clock "
        "seconds per iteration; *speed-up* is threads:1 / threads:2.")
    # The algorithms render_bench measured: the table's rows of the "performance" suite
    # (Algorithm::benchmarks), in table order.
    algorithms = list(dict.fromkeys(k.split("/")[2] for k in results
                                    if k.startswith("iteration/") and k.count("/") == 3))
    for scene in REFERENCE_SCENES:
        rows = []
        for algo in algorithms:
            one = results.get(f"iteration/{scene}/{algo}/threads:1")
            two = results.get(f"iteration/{scene}/{algo}/threads:2")
            if not one and not two:
                continue
            t1 = seconds_of(one) if one else None
            t2 = seconds_of(two) if two else None
            rays = (one or two).get("rays_per_iteration")
            mrays = rays / t2 / 1e6 if rays and t2 else None
            rows.append(f"| {algo} | {fmt(t1)} | {fmt(t2)} | "
                        f"{fmt_ratio(t1 / t2 if t1 and t2 else None)} | {fmt(rays)} | "
                        f"{fmt(mrays)} |")
        if rows:
            add("")
            add(f"**{scene}**")
            add("")
            add("| algorithm | s / iteration, 1 thread | s / iteration, 2 threads | speed-up | "
                "rays / iteration | M rays/s (2 threads) |")
            add("| --- | --- | --- | --- | --- | --- |")
            L.extend(rows)
    add("")
    add("**Participating media** ([media.md](../design/media.md)): seconds per iteration at each media "
        "scene's own resolution, 2 threads (the bidirectional algorithms refuse the smoke's "
        "grid medium). On the surface-only boxes above, `volpt` against `pt` is what the "
        "media-aware path tracer costs on a scene without media.")
    add("")
    add("| scene | " + " | ".join(f"{a} s / iteration" for a in MEDIA_ALGORITHMS) + " | pixels |")
    add("| --- | " + " | ".join("---" for _ in MEDIA_ALGORITHMS) + " | --- |")
    for scene in MEDIA_SCENES:
        cells, pixels = [], None
        for algo in MEDIA_ALGORITHMS:
            b = results.get(f"iteration/{scene}/{algo}/threads:2")
            cells.append(fmt(seconds_of(b)) if b else "–")
            if b and b.get("pixels"):
                pixels = b["pixels"]
        add(f"| {scene} | " + " | ".join(cells) + f" | {fmt(pixels)} |")
    add("")
    if loaded:
        add("")
        add(f"**Caution:** the load average at the start ({machine['loadavg'][0]}) exceeded half "
            f"the {machine['cores']} cores, so two render threads competed with other processes "
            "for the cores: the 2-thread times and the speed-ups of this run are not "
            "meaningful (the 1-thread times are pessimistic too). Rerun on an idle machine.")
    add("")
    add("What limits it: path tracing is embarrassingly parallel over pixels (its speed-up "
        "should approach the core count on an idle machine). The bidirectional algorithms "
        "(lt, bpt, ppm, bpm, vcm) trace their light paths in parallel chunks through a TBB "
        "pipeline whose last stage gathers each chunk in chunk order (vertices, grid "
        "positions, splats added to the image) on one thread while the others trace later "
        "chunks; the hash grid is built in parallel, then the eye pass is parallel over "
        "16 × 16 tiles (`core/integrators/bidirectional/light_pass.cpp` and "
        "`core/integrators/pixel_loop.h`, "
        "\"Parallel iteration steps and peak "
        f"memory\" in [{NOTES_PAGE}]({NOTES_PAGE})). What is left per iteration is waiting at the end of each parallel "
        "phase for its last chunk or tile, and the two threads sharing the memory bus and "
        "the L3 cache.")
    if profiles:
        add("")
        add("In the profiles below, `BidirectionalIntegrator::render_iteration` (named "
            "`VertexConnectionMerging::render_iteration` in profiles recorded before the "
            "integrators were split) and `Iteration::trace_eye_path` include what the compiler inlined into them (the eye "
            "pass, MIS weights, connections, merging visits, adding splats); kernel symbols such "
            "as `pvm_irq_enable` are time the virtual machine spent in the kernel and hypervisor "
            "(page faults of the per-iteration buffers, and preemption by other load), and "
            "`do_lookup_x` is the dynamic loader at start-up.")
        for prof in profiles:
            add("")
            add(f"Profile of `{prof['target']}` (`perf`, one thread, all samples of the "
                "benchmark process, including scene loading):")
            add("")
            add(f"    {prof['cmd']}")
            add("")
            cats = sorted(prof["categories"].items(), key=lambda kv: -kv[1])
            add("Time by kind (symbols above 0.3 %): " +
                "; ".join(f"{name} {pct:.0f} %" for name, pct in cats) + ".")
            add("")
            add("| self % | where | symbol |")
            add("| --- | --- | --- |")
            for pct, dso, sym in prof["top"]:
                add(f"| {pct:.1f} | {dso} | `{short_symbol(sym)}` |")

    # --- hash grid
    add("")
    add("## Hash grid (VCM merging)")
    add("")
    add("One iteration's worth of work on the grid of `core/integrators/hash_grid.h` at the "
        "reference resolution (`bench/hash_grid.cpp`): **build** indexes the light-subpath "
        "vertices of 512 × 512 light paths; **query** looks up the neighbours of every "
        "eye-subpath vertex of one camera ray per pixel, with the first iteration's radius "
        "(0.003 × scene radius, the largest). Vertex positions are realistic: light subpaths "
        "are traced in the benchmark helper (choose a light by power, `emit`, intersect, then "
        "BSDF sampling in importance mode with a roulette on the sampled weight, storing every "
        "hit with a non-delta BSDF), eye subpaths likewise from jittered camera rays "
        "(`bench/bench_scenes.cpp`). One thread, CPU seconds; the share column divides by the CPU "
        "time of a one-thread vcm iteration. VCM builds and queries in parallel.")
    add("")
    add("| scene | light vertices | build ms | eye vertices (queries) | query ms | "
        "neighbours / query | build + query, share of a 1-thread vcm iteration |")
    add("| --- | --- | --- | --- | --- | --- | --- |")
    for scene in REFERENCE_SCENES:
        b = results.get(f"hash_grid/build/{scene}")
        q = results.get(f"hash_grid/query/{scene}")
        if not b and not q:
            continue
        it = results.get(f"iteration/{scene}/vcm/threads:1")
        tb = seconds_of(b, "cpu_time") if b else None
        tq = seconds_of(q, "cpu_time") if q else None
        share = (tb + tq) / seconds_of(it, "cpu_time") if (tb and tq and it) else None
        add(f"| {scene} | {fmt(b.get('vertices') if b else None)} | "
            f"{fmt(tb * 1e3 if tb else None)} | {fmt(q.get('queries') if q else None)} | "
            f"{fmt(tq * 1e3 if tq else None)} | "
            f"{fmt(q.get('neighbours_per_query') if q else None)} | "
            f"{'–' if share is None else f'{100 * share:.1f} %'} |")
    add("")
    add("What limits it: the build is a stable counting sort in two levels (points into groups "
        "of 4096 buckets block by block, then each group by bucket, both passes parallel and "
        "the order independent of the threads) and is memory-bound; it runs on all the "
        "arena's threads inside every VCM/BPM/PPM iteration. "
        "A query visits up to 8 cells; its cost is the random access to the cells' point "
        "indices and positions. The query figure here counts neighbours only; in VCM each "
        "neighbour also evaluates a BSDF and a MIS weight (in the iteration times above).")

    # --- distribution
    add("")
    add("## Distribution overhead")
    add("")
    if dist:
        runs_text = "one run" if dist["runs"] == 1 else f"median of {dist['runs']} runs"
        add(f"The same job — `{DIST_SCENE}`, {DIST_ALGO}, {dist['iterations']} iterations at "
            f"{DIST_RESOLUTION}, seed 0 — rendered by `render --threads 2` and by a local "
            f"cluster (server + workers on loopback, `deploy/local-cluster`) in two shapes; "
            f"{runs_text} each, "
            "wall-clock from the start of the command to the image on disk (`render`: scene "
            "load, iterations, EXR; cluster: `client submit --wait --out`, i.e. upload or "
            "asset check, leasing, worker scene load, reports, merging, EXR write and fetch). "
            "One cluster per shape; its jobs run one after another, so only the first one "
            "uploads the scene. The workers' registration is not timed.")
        add("")
        add(f"    {dist['render_cmd']}")
        for c in dist["configs"]:
            add(f"    {c['cluster_cmd']} &   # then RENDER_SERVER=$(cat ADDRESS_FILE)")
            add(f"    {c['submit_cmd']}")
        add("")
        add("| configuration | s (median) | iterations/s | ratio to render --threads 2 | "
            "reports per job | iterations / report | bytes / report | bytes / iteration | "
            "receive ms / report | merge ms / report (of which add + checkpoint) |")
        add("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
        add(f"| render --threads 2 | {median(dist['render_seconds']):.2f} | "
            f"{dist['render_it_per_s']:.2f} | 1 | – | – | – | – | – | – |")
        for c in dist["configs"]:
            runs = max(1, dist["runs"])
            add(f"| {c['workers']} worker{'s' if c['workers'] > 1 else ''} × {c['threads']} "
                f"thread{'s' if c['threads'] > 1 else ''}"
                f" | {median(c['seconds']):.2f} | {c['it_per_s']:.2f} | {c['ratio']:.2f} | "
                f"{c['reports'] / runs:.1f} | {fmt(c['iterations_per_report'])} | "
                f"{fmt(c['report_bytes'])} | {fmt(c['bytes_per_iteration'])} | "
                f"{fmt(c['receive_us'] / 1e3 if c['receive_us'] is not None else None)} | "
                f"{fmt(c['merge_us'] / 1e3 if c['merge_us'] is not None else None)} "
                f"({fmt(c['add_us'] / 1e3 if c['add_us'] is not None else None)} + "
                f"{fmt(c['checkpoint_us'] / 1e3 if c['checkpoint_us'] is not None else None)}) |")
        add("")
        add("Bytes, receive and merge times come from the server's log (`event=report_received "
            "bytes=… iterations=… receive_us=… merge_us=…` and `event=merged … add_us=… "
            "checkpoint_us=…`, see docs/guide/service.md), medians over all reports of all runs. "
            "*receive* runs from the report's header to its last value chunk (the worker's "
            "sending and the loopback transfer); *merge* is the whole of `JobManager::report` "
            "(lease bookkeeping in SQLite, adding the sums, writing the checkpoint file and the "
            "store rows, progress); *add* is the addition into the frame's sums alone and "
            "*checkpoint* the checkpoint file plus the store rows. "
            "`bytes` counts the report header plus the values: `sum` and `odd_sum` as float64 "
            "RGB, 2 × 3 × 8 bytes per pixel whatever the number of iterations in the report "
            "(`sum` alone for a one-iteration report), so the bytes per iteration fall as "
            "leases grow (the scheduler sizes a lease to at least 3 s and at most 30 s of a "
            "worker's measured rate, docs/guide/service.md).")
        add("")
        per_report = [c for c in dist["configs"] if c["merge_us"] is not None]
        server_ms = max(((c["receive_us"] or 0) + c["merge_us"]) / 1e3 for c in per_report) \
            if per_report else None
        add("What limits it: transfer and merging cost the server "
            + (f"at most {server_ms:.0f} ms per report (median)" if server_ms else "little")
            + ", against seconds of rendering per lease; checkpoints are written at most "
            "every 30 s by the server's tick, not by the reports (see *Costs that grow with "
            f"the work* in [{NOTES_PAGE}]({NOTES_PAGE})). "
            "The per-job fixed costs are the asset check, each worker's scene load, a lease "
            "round trip per lease, and the first one-iteration lease of every worker (its rate "
            "is unknown until then); the scheduler sizes later leases to at least 3 s of the "
            "worker's rate (one iteration when an iteration is longer). At the end the job "
            "waits for the last "
            "lease while the other core may idle. 2 × 1 workers render whole iterations "
            "independently, so the serial steps of a bidirectional iteration (previous "
            "sections) do not idle a core — on an idle machine that is what lets 2 × 1 beat "
            "one 2-thread process (docs/results/service-measurements.md links the record of "
            "that measurement); under other load the ratio is dominated by how the cores were "
            "shared.")
    else:
        add("Not measured in this run.")
    add("")
    publish(path, L, reference.document_lines(path, reference_result),
            reference_measured=reference_result is not None, load=machine["loadavg"])


def without_notes_links(section):
    """The SmallVCM section without its heading (the page's template holds it) and without the
    list of hand-written notes reference.document_lines appends (the template links them)."""
    if reference.NOTES_HEADING in section:
        section = section[:section.index(reference.NOTES_HEADING)]
    while section and (not section[0].strip() or section[0] == reference.TITLE):
        section.pop(0)
    while section and not section[-1].strip():
        section.pop()
    return section


def publish(path, lines, reference_lines, *, reference_measured, load=None):
    """Writes the data files of DOCS/results/performance.md (path) and generates the page from
    its template (docs/guide/results.md): benchmark.json holds this run's lines, reference.json
    the SmallVCM section, rewritten only when this run measured it."""
    docs_dir = Path(path).parent.parent
    reference_file = docs_dir / "data" / "performance" / "reference.json"
    if reference_measured:
        datafile.write(reference_file, {
            "stamp": datafile.stamp("scripts/bench --only performance --reference-smallvcm PATH",
                                    load_before=pages.load_text(load)),
            "measured": True, "blocks": {"section": without_notes_links(list(reference_lines))}})
    elif not reference_file.exists():
        datafile.write(reference_file, datafile.not_measured(
            "scripts/bench --only reference --reference-smallvcm PATH",
            "It needs a SmallVCM binary built by hand"))
    pages.publish_blocks(docs_dir, "performance", lines, "scripts/bench --only performance",
                         load_before=pages.load_text(load), block="page")


# The page of measurements made by hand at past commits, which the prose links to.
NOTES_PAGE = "performance-notes.md"  # beside the generated page, docs/results/


def document_path(docs_dir) -> Path:
    """The generated page under the docs folder (docs/ by default): a results page, so its
    links are relative to docs/results/ (as common.results_page says)."""
    return Path(docs_dir) / "results" / "performance.md"


# ---------------------------------------------------------------------------------------------


def run(build_dir: Path, docs_dir: Path, quick: bool, reference_smallvcm=None) -> None:
    build_dir, docs_dir = Path(build_dir).resolve(), Path(docs_dir).resolve()
    bin_dir = build_dir / "bin"
    for name in ("render_bench", "render", "server", "worker", "client"):
        if not os.access(bin_dir / name, os.X_OK):
            raise FileNotFoundError(f"{bin_dir / name} not found: build first")
    waited = wait_for_quiet_machine()
    machine = machine_info()  # before anything of ours runs: the load average of others
    machine["waited_for_quiet_seconds"] = waited
    started = machine["date"]
    log(f"load average at start: {' '.join(machine['loadavg'])}")
    t0 = time.monotonic()
    work = Path(tempfile.mkdtemp(prefix="render-perf-"))
    try:
        bench = run_render_bench(bin_dir / "render_bench", quick, work)
        dist = run_distribution(bin_dir, quick, work)
        profiles = run_perf(bin_dir / "render_bench", quick, work)
        reference_result = reference.run(bin_dir, reference_smallvcm, quick, work, log=log)
        raw = {"machine": machine, "bench": bench, "dist": dist, "profiles": profiles,
               "reference": reference_result, "quick": quick, "started": started,
               "seconds": time.monotonic() - t0}
        # The raw measurements, so that the document can be rewritten without rerunning
        # (write_from_raw).
        (build_dir / "performance-raw.json").write_text(json.dumps(raw, indent=1))
        document_path(docs_dir).parent.mkdir(parents=True, exist_ok=True)
        write_document(document_path(docs_dir), machine, bench, dist, profiles, quick,
                       started, raw["seconds"], reference_result)
        log(f"wrote {document_path(docs_dir)} in {(time.monotonic() - t0) / 60:.1f} min")
    finally:
        shutil.rmtree(work, ignore_errors=True)


def wait_for_quiet_machine(limit_seconds=240.0):
    """Waits until the 1-minute load average falls below a quarter of the cores, at most
    limit_seconds. When scripts/bench runs the convergence part first, its own 2-thread renders
    keep the 1-minute average near 2 for a minute or two after they end; starting at once would
    record that as competing load. Returns the seconds waited."""
    cores = os.cpu_count() or 1
    start = time.monotonic()
    while time.monotonic() - start < limit_seconds:
        with open("/proc/loadavg") as f:
            if float(f.read().split()[0]) < 0.25 * cores:
                break
        time.sleep(5)
    waited = time.monotonic() - start
    if waited > 1:
        log(f"waited {waited:.0f} s for the load average to settle")
    return waited


# ---------------------------------------------------------------------------------------------
# Closest hits by instruction count: ours (Scene::intersect) against bare rtcIntersect1


# The loops of bench/ray_queries.cpp, out of line for this count (their symbols' names).
CLOSEST_LOOPS = {"ours": "render::bench::trace_closest_ours", "embree": "render::bench::trace_closest_embree"}
# Not procedural-1M: building its 1 M-triangle scene under callgrind takes longer than all of
# these together.
RAY_INSTRUCTION_SCENES = ["cornell-box", "0-gbs_s", "1-glm_c", "2-gbs_p", "3-gbs_b", "veach-mis"]
QUICK_RAY_INSTRUCTION_SCENES = ["cornell-box"]
RAY_INSTRUCTIONS_TARGET = 0.92  # ours / Embree in rays per instruction (issue's speed target)


def callgrind_calls_and_cost(out_file, symbol):
    """(calls, inclusive instructions) of `symbol` in a callgrind output file written with
    --toggle-collect=SYMBOL*: the collected total is the function's inclusive cost, and the
    calls are summed from the `calls=` lines under its caller's `cfn=` entries."""
    names, calls, current_cfn, total = {}, 0, None, None
    for line in Path(out_file).read_text().splitlines():
        m = re.match(r"c?fn=\((\d+)\)(?: (.*))?$", line)
        if m:
            if m.group(2):
                names[m.group(1)] = m.group(2)
            if line.startswith("cfn="):
                current_cfn = names.get(m.group(1), "")
            continue
        if line.startswith("calls=") and current_cfn is not None:
            if current_cfn.startswith(symbol + "("):
                calls += int(line.split("=", 1)[1].split()[0])
            current_cfn = None
            continue
        if line.startswith("summary:") or line.startswith("totals:"):
            total = int(line.split()[1])
    if total is None or calls == 0:
        raise RuntimeError(f"{out_file}: no cost or no call of {symbol}")
    return calls, total


def measure_closest_instructions(bench, scene, arm, work):
    """Instructions per ray of one closest-hit loop (`arm` "ours" or "embree") on `scene`:
    callgrind collects only inside the loop function, so the ray generation, the scene build
    and Google Benchmark's own code are not counted. Instruction counts repeat under load,
    where wall-clock rates do not."""
    symbol = CLOSEST_LOOPS[arm]
    out = work / f"callgrind.{arm}.{scene}"
    js = work / f"bench.{arm}.{scene}.json"
    cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
           f"--toggle-collect={symbol}*", str(bench),
           f"--benchmark_filter=^rays/closest/{arm}/{scene}$",
           "--benchmark_min_time=0.01", f"--benchmark_out={js}", "--benchmark_out_format=json"]
    run_cmd(cmd, timeout=3600)
    calls, total = callgrind_calls_and_cost(out, symbol)
    b = json.loads(js.read_text())["benchmarks"][0]
    rays = int(round(b["items_per_second"] * b["cpu_time"] /
                     {"ns": 1e9, "us": 1e6, "ms": 1e3, "s": 1.0}[b["time_unit"]] / b["iterations"]))
    return {"calls": calls, "instructions": total, "rays_per_call": rays,
            "per_ray": total / (calls * rays),
            "command": shlex.join(cmd[:-2]).replace(str(out), "OUT")}


def run_ray_instructions(build_dir: Path, docs_dir: Path, quick: bool) -> None:
    """`scripts/bench --only ray-instructions`: the closest-hit loops of bench/ray_queries.cpp
    counted by callgrind, ours against bare Embree, written to
    docs/data/performance/ray_instructions.json; then the page is generated again."""
    bench = Path(build_dir).resolve() / "bin" / "render_bench"
    if not os.access(bench, os.X_OK):
        raise FileNotFoundError(f"{bench} not found: build first")
    if not shutil.which("valgrind"):
        raise FileNotFoundError("valgrind not found")
    load = machine_info()["loadavg"]
    work = Path(tempfile.mkdtemp(prefix="render-ray-instructions-"))
    rows, command = [], None
    try:
        for scene in QUICK_RAY_INSTRUCTION_SCENES if quick else RAY_INSTRUCTION_SCENES:
            ours = measure_closest_instructions(bench, scene, "ours", work)
            embree = measure_closest_instructions(bench, scene, "embree", work)
            command = ours["command"]
            ratio = embree["per_ray"] / ours["per_ray"]
            log(f"{scene}: ours {ours['per_ray']:.1f}, embree {embree['per_ray']:.1f} "
                f"instructions/ray, ratio {ratio:.3f}")
            rows.append([scene, ours["rays_per_call"], ours["per_ray"], embree["per_ray"],
                         ours["per_ray"] - embree["per_ray"], ratio,
                         ratio >= RAY_INSTRUCTIONS_TARGET])
    finally:
        shutil.rmtree(work, ignore_errors=True)
    path = Path(docs_dir) / "data" / "performance" / "ray_instructions.json"
    datafile.write(path, {
        "stamp": datafile.stamp("scripts/bench --only ray-instructions" +
                                (" --quick" if quick else ""),
                                load_before=pages.load_text(tuple(load)),
                                root=SOURCE_DIR),
        "measured": True,
        "values": {"target": RAY_INSTRUCTIONS_TARGET, "callgrind_command": command},
        "tables": {"closest": {
            "columns": ["scene", "rays", "ours: instructions / ray",
                        "Embree: instructions / ray", "ours − Embree", "ours / Embree",
                        f"≥ {RAY_INSTRUCTIONS_TARGET}"],
            "formats": [None, None, ".1f", ".1f", ".1f", ".3f", None],
            "rows": rows}}})
    log(f"wrote {path}")
    pages.write(["performance"], Path(docs_dir))
    log(f"wrote {document_path(docs_dir)}")


def run_reference_only(build_dir: Path, docs_dir: Path, quick: bool, reference_smallvcm) -> None:
    """`scripts/bench --only reference`: measures ours against SmallVCM and rewrites only that
    section's data file (docs_dir/data/performance/reference.json), then the page."""
    if not reference_smallvcm:
        raise ValueError("--only reference needs --reference-smallvcm PATH")
    bin_dir = Path(build_dir).resolve() / "bin"
    if not os.access(bin_dir / "render", os.X_OK):
        raise FileNotFoundError(f"{bin_dir / 'render'} not found: build first")
    # Under a real-time policy (`chrt -f 10 scripts/bench ...`) other load is preempted anyway.
    if os.sched_getscheduler(0) not in (os.SCHED_FIFO, os.SCHED_RR):
        wait_for_quiet_machine()
    work = Path(tempfile.mkdtemp(prefix="render-reference-"))
    try:
        result = reference.run(bin_dir, reference_smallvcm, quick, work, log=log)
        (Path(build_dir).resolve() / "reference-raw.json").write_text(json.dumps(result, indent=1))
        from benchlib import common

        # Every run, stamped (docs/data/reference/), and the page's block (performance.md is
        # generated again from its template).
        data = reference.write_data(result, Path(docs_dir) / "data", common.machine_info(),
                                    " ".join(sys.argv))
        log(f"wrote {data}")
        # Only reference.json is rewritten; the page is generated again from its template.
        path = document_path(docs_dir)
        datafile.write(path.parent.parent / "data" / "performance" / "reference.json", {
            "stamp": datafile.stamp("scripts/bench --only reference --reference-smallvcm PATH"),
            "measured": True,
            "blocks": {"section": without_notes_links(reference.document_lines(path, result))}})
        pages.write(["performance"], path.parent.parent)
        log(f"wrote the SmallVCM section of {document_path(docs_dir)}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


def write_from_raw(raw_file: Path, docs_dir: Path) -> None:
    """Rewrites docs_dir/results/performance.md from a previous run's build/performance-raw.json."""
    raw = json.loads(Path(raw_file).read_text())
    write_document(document_path(docs_dir), raw["machine"], tuple(raw["bench"]),
                   raw["dist"], raw["profiles"], raw["quick"], raw["started"], raw["seconds"],
                   raw.get("reference"))
