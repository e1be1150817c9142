"""A local cluster for the integration tests: a real `server` and real `worker` processes on
127.0.0.1, driven through Python stubs generated at test time from proto/render.proto.

Every test script is run by CTest as

    /usr/bin/python3 tests/integration/test_NAME.py --bin-dir <build>/bin --source-dir <repo>

and calls `cluster.main()`, which parses those two options and runs the unittest cases.

Rules this module keeps: only 127.0.0.1; every wait is bounded in time and count; every process
it starts runs in its own process group and is killed (SIGKILL of the group) when the test ends,
when the script exits (atexit) and when the script itself dies (PR_SET_PDEATHSIG).
"""

import argparse
import atexit
import ctypes
import hashlib
import os
import re
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import unittest

import grpc
import numpy as np

# Set by main() (or by configure() when imported by hand).
SOURCE_DIR = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
BIN_DIR = os.path.join(SOURCE_DIR, "build", "bin")

CHUNK = 1 << 20  # bulk data moves in chunks of at most 1 MiB (proto/render.proto)
LOCALHOST = "127.0.0.1"

# The programs read TLS settings from these variables; a test's processes get them only when
# the test asks (Cluster(tls=...)), never from the environment that runs the tests.
for _name in ("RENDER_TLS_CA", "RENDER_TLS_SERVER_NAME", "RENDER_TLS_CERT", "RENDER_TLS_KEY"):
    os.environ.pop(_name, None)

# A minimal copy of grpc/health/v1/health.proto (the standard health service); compiled at test
# time together with render.proto so that no Python package beyond python3-grpcio is needed.
HEALTH_PROTO = """
syntax = "proto3";
package grpc.health.v1;
message HealthCheckRequest { string service = 1; }
message HealthCheckResponse {
  enum ServingStatus { UNKNOWN = 0; SERVING = 1; NOT_SERVING = 2; SERVICE_UNKNOWN = 3; }
  ServingStatus status = 1;
}
service Health {
  rpc Check(HealthCheckRequest) returns (HealthCheckResponse);
  rpc Watch(HealthCheckRequest) returns (stream HealthCheckResponse);
}
"""

# ---------------------------------------------------------------------------------------------
# Configuration and stubs


def configure(bin_dir=None, source_dir=None):
    global BIN_DIR, SOURCE_DIR
    if source_dir:
        SOURCE_DIR = os.path.abspath(source_dir)
    if bin_dir:
        BIN_DIR = os.path.abspath(bin_dir)


def binary(name):
    path = os.path.join(BIN_DIR, name)
    if not os.access(path, os.X_OK):
        raise FileNotFoundError(f"{name} binary not found at {path} (build it first)")
    return path


_stub_dir = None
_modules = {}


def _rmtree_quiet(path):
    shutil.rmtree(path, ignore_errors=True)


def stubs():
    """Generates (once per process) and imports render_pb2, render_pb2_grpc, health_pb2,
    health_pb2_grpc; returns them as a dict."""
    global _stub_dir
    if _modules:
        return _modules
    _stub_dir = tempfile.mkdtemp(prefix="render-it-stubs-")
    atexit.register(_rmtree_quiet, _stub_dir)
    plugin = shutil.which("grpc_python_plugin") or "/usr/bin/grpc_python_plugin"
    protoc = shutil.which("protoc") or "/usr/bin/protoc"
    proto_dir = os.path.join(SOURCE_DIR, "proto")
    health_dir = os.path.join(_stub_dir, "health_src")
    os.makedirs(health_dir)
    with open(os.path.join(health_dir, "health.proto"), "w") as f:
        f.write(HEALTH_PROTO)
    for include, name in ((proto_dir, "render.proto"), (health_dir, "health.proto")):
        cmd = [protoc, f"--python_out={_stub_dir}", f"--grpc_out={_stub_dir}",
               f"--plugin=protoc-gen-grpc={plugin}", f"-I{include}", name]
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
        if r.returncode != 0:
            raise RuntimeError(f"protoc failed for {name}: {r.stderr}")
    sys.path.insert(0, _stub_dir)
    import render_pb2, render_pb2_grpc, health_pb2, health_pb2_grpc  # noqa: E402
    _modules.update(pb=render_pb2, rpc=render_pb2_grpc, hpb=health_pb2, hrpc=health_pb2_grpc)
    return _modules


def pb():
    return stubs()["pb"]


# ---------------------------------------------------------------------------------------------
# Processes

_all_procs = []
_libc = None


def _set_pdeathsig():
    # Runs in the child between fork and exec: die with the test script.
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except Exception:
        pass


class Proc:
    """A child process in its own process group, its stderr (and stdout unless captured) in a
    log file."""

    def __init__(self, name, args, log_path, capture_stdout=False, env=None):
        self.name = name
        self.args = args
        self.log_path = log_path
        self.log = open(log_path, "ab", buffering=0)
        self.log.write(("$ " + " ".join(args) + "\n").encode())
        self.popen = subprocess.Popen(
            args, stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE if capture_stdout else self.log, stderr=self.log,
            start_new_session=True, preexec_fn=_set_pdeathsig, env=env)
        _all_procs.append(self)

    @property
    def pid(self):
        return self.popen.pid

    def alive(self):
        return self.popen.poll() is None

    def signal_group(self, sig):
        try:
            os.killpg(self.popen.pid, sig)
        except (ProcessLookupError, PermissionError):
            pass

    def kill(self, timeout=10):
        """SIGKILL the whole process group and reap the process."""
        self.signal_group(signal.SIGKILL)
        try:
            self.popen.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            pass
        self._close_files()

    def stop(self, timeout=5):
        """SIGTERM, then SIGKILL after `timeout` seconds."""
        if self.alive():
            self.signal_group(signal.SIGTERM)
            try:
                self.popen.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                pass
        self.kill()

    def _close_files(self):
        try:
            if self.popen.stdout:
                self.popen.stdout.close()
        except Exception:
            pass
        try:
            self.log.close()
        except Exception:
            pass

    def cpu_seconds(self):
        """User + system CPU time of the process so far (Linux /proc)."""
        try:
            with open(f"/proc/{self.popen.pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
            ticks = os.sysconf("SC_CLK_TCK")
            return (int(fields[11]) + int(fields[12])) / ticks
        except (OSError, IndexError, ValueError):
            return 0.0

    def log_text(self):
        try:
            with open(self.log_path, "rb") as f:
                return f.read().decode(errors="replace")
        except OSError:
            return ""

    def log_tail(self, lines=40):
        return "\n".join(self.log_text().splitlines()[-lines:])

    def wait_for_log(self, text, count=1, timeout=30):
        """The whole log once `text` occurs in it at least `count` times, polled for at most
        `timeout` seconds. A process writes its log line just after the event a test observes
        (a stream it cancelled, a job it deleted), so a log read once right after the event
        may not hold the line yet: wait for it instead."""
        found = {}

        def holds():
            found["log"] = self.log_text()
            return found["log"].count(text) >= count
        try:
            wait_until(holds, timeout=timeout, poll=0.05, what=f"{text!r} in {self.name}'s log")
        except AssertionError as e:
            tail = "\n".join(found.get("log", "").splitlines()[-40:])
            raise AssertionError(f"{e}; its log ends:\n{tail}") from None
        return found["log"]


def _kill_all():
    for p in list(_all_procs):
        if p.alive():
            p.kill(timeout=5)


atexit.register(_kill_all)


def _on_term(signum, frame):
    _kill_all()
    sys.exit(128 + signum)


signal.signal(signal.SIGTERM, _on_term)


def read_line_with_timeout(proc, timeout):
    """Reads the first stdout line of `proc` within `timeout` seconds (None on EOF/timeout)."""
    fd = proc.popen.stdout.fileno()
    deadline = time.monotonic() + timeout
    data = getattr(proc, "stdout_rest", b"")  # what the previous call read past its line
    while b"\n" not in data:
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return None
        ready, _, _ = select.select([fd], [], [], min(remaining, 0.5))
        if not ready:
            if not proc.alive():
                # Read what is left, then give up.
                ready2, _, _ = select.select([fd], [], [], 0)
                if not ready2:
                    return None
            else:
                continue
        chunk = os.read(fd, 4096)
        if not chunk:
            return data.decode(errors="replace") if data else None
        data += chunk
    line, rest = data.split(b"\n", 1)
    proc.log.write(b"[stdout] " + line + b"\n")
    proc.stdout_rest = rest
    return line.decode(errors="replace")


def _drain(proc):
    # Keeps reading the server's stdout so that it never blocks on a full pipe.
    try:
        while True:
            chunk = proc.popen.stdout.read1(4096) if hasattr(proc.popen.stdout, "read1") \
                else os.read(proc.popen.stdout.fileno(), 4096)
            if not chunk:
                return
            proc.log.write(chunk)
    except (OSError, ValueError):
        return


# ---------------------------------------------------------------------------------------------
# The API through the generated stubs


def make_channel(address, ca=None, server_name=None):
    """A plaintext channel, or with `ca` (a PEM file) a TLS channel trusting that CA;
    `server_name` overrides the name the server's certificate is checked for."""
    if not ca:
        return grpc.insecure_channel(address)
    with open(ca, "rb") as f:
        credentials = grpc.ssl_channel_credentials(root_certificates=f.read())
    options = [("grpc.ssl_target_name_override", server_name)] if server_name else []
    return grpc.secure_channel(address, credentials, options=options)


class Api:
    """The server's JobService, WorkerService and health service over one channel, with the
    bearer token (if any) on every call and a default deadline; TLS with `ca` (a PEM file)."""

    def __init__(self, address, token=None, timeout=30, ca=None, server_name=None):
        s = stubs()
        self.address = address
        self.token = token
        self.timeout = timeout
        self.channel = make_channel(address, ca, server_name)
        self.jobs = s["rpc"].JobServiceStub(self.channel)
        self.workers = s["rpc"].WorkerServiceStub(self.channel)
        self.health = s["hrpc"].HealthStub(self.channel)

    def close(self):
        self.channel.close()

    def metadata(self, token=None):
        token = self.token if token is None else token
        return [("authorization", f"Bearer {token}")] if token else None

    def call(self, method, request, timeout=None, token=None):
        """Unary (or stream-request) call with metadata and deadline."""
        return method(request, metadata=self.metadata(token), timeout=timeout or self.timeout)

    def wait_ready(self, timeout=15):
        grpc.channel_ready_future(self.channel).result(timeout=timeout)

    # -- assets and jobs

    def upload_asset(self, data, sha256=None, size=None):
        """Uploads one asset in chunks <= 1 MiB; the first chunk carries sha256 and size."""
        P = pb()
        digest = sha256 or hashlib.sha256(data).hexdigest()
        size = len(data) if size is None else size

        def chunks():
            if not data:
                yield P.AssetChunk(sha256=digest, size=size, data=b"")
                return
            for i in range(0, len(data), CHUNK):
                if i == 0:
                    yield P.AssetChunk(sha256=digest, size=size, data=data[i:i + CHUNK])
                else:
                    yield P.AssetChunk(data=data[i:i + CHUNK])

        return self.call(self.jobs.UploadAsset, chunks())

    def upload_bundle(self, files, scene_path):
        """files: {relative path: bytes}. Uploads what HasAssets says is missing and returns the
        SceneBundle."""
        P = pb()
        hashes = {path: hashlib.sha256(data).hexdigest() for path, data in files.items()}
        reply = self.call(self.jobs.HasAssets,
                          P.HasAssetsRequest(sha256=sorted(set(hashes.values()))))
        missing = set(reply.missing)
        uploaded = set()
        for path, data in files.items():
            h = hashes[path]
            if h in missing and h not in uploaded:
                self.upload_asset(data, h)
                uploaded.add(h)
        return P.SceneBundle(
            scene_path=scene_path,
            files=[P.BundleFile(path=p, sha256=hashes[p], size=len(files[p]))
                   for p in sorted(files)])

    def submit(self, scene, algorithm="pt", iterations=16, resolution=(32, 32), seed=1,
               defines=None, name="integration", priority=0, time_budget=0.0, **settings):
        """Packs `scene` (a path) with the files it references, uploads them and submits."""
        P = pb()
        files, scene_path = scene_bundle_files(scene)
        bundle = self.upload_bundle(files, scene_path)
        rs = P.RenderSettings(algorithm=algorithm, iterations=iterations,
                              time_budget_seconds=time_budget, width=resolution[0],
                              height=resolution[1], seed=seed, **settings)
        for k, v in (defines or {}).items():
            rs.defines[k] = v
        return self.call(self.jobs.SubmitJob,
                         P.SubmitJobRequest(name=name, bundle=bundle, settings=rs,
                                            priority=priority))

    def get_job(self, job_id):
        return self.call(self.jobs.GetJob, pb().GetJobRequest(job_id=job_id))

    def cluster_status(self):
        return self.call(self.jobs.ClusterStatus, pb().ClusterStatusRequest())

    def wait_job(self, job_id, states=None, timeout=60, poll=0.2, procs=()):
        """Polls GetJob until the job reaches one of `states` (default DONE); raises on
        timeout, or if it ends in another final state, or if a process of `procs` died."""
        P = pb()
        states = set(states or [P.JOB_STATE_DONE])
        final = {P.JOB_STATE_DONE, P.JOB_STATE_CANCELLED, P.JOB_STATE_FAILED}
        deadline = time.monotonic() + timeout
        job = None
        for _ in range(int(timeout / poll) + 10):
            try:
                job = self.get_job(job_id)
            except grpc.RpcError as e:
                if e.code() != grpc.StatusCode.UNAVAILABLE:
                    raise
                job = None
            if job is not None:
                if job.state in states:
                    return job
                if job.state in final:
                    raise AssertionError(
                        f"job {job_id} ended in {P.JobState.Name(job.state)} "
                        f"(error: {job.error!r}) while waiting for "
                        f"{[P.JobState.Name(s) for s in states]}")
            for p in procs:
                if not p.alive():
                    raise AssertionError(f"{p.name} exited with {p.popen.returncode} while "
                                         f"waiting for job {job_id}:\n{p.log_tail()}")
            if time.monotonic() >= deadline:
                break
            time.sleep(poll)
        raise AssertionError(f"job {job_id} not in the expected state after {timeout} s; "
                             f"last seen: {job}")

    def fetch(self, job_id, frame=0, preview=False, timeout=60):
        """FetchResult: returns the EXR bytes, checking chunk sizes and total_size."""
        P = pb()
        data = bytearray()
        total = None
        for chunk in self.jobs.FetchResult(
                P.FetchResultRequest(job_id=job_id, frame=frame, preview=preview),
                metadata=self.metadata(), timeout=timeout):
            if len(chunk.data) > CHUNK:
                raise AssertionError(f"a ResultChunk of {len(chunk.data)} bytes (> 1 MiB)")
            if chunk.total_size:
                if total is not None and total != chunk.total_size:
                    raise AssertionError("ResultChunk.total_size changed within one stream")
                total = chunk.total_size
            data += chunk.data
        if total is not None and total != len(data):
            raise AssertionError(f"FetchResult sent {len(data)} bytes, total_size {total}")
        if not data:
            raise AssertionError("FetchResult returned no data")
        return bytes(data)

    def fetch_to(self, job_id, path, frame=0, preview=False):
        data = self.fetch(job_id, frame=frame, preview=preview)
        with open(path, "wb") as f:
            f.write(data)
        return path


def http_get(address, path, token=None, timeout=10, method="GET", headers=None):
    """An HTTP request to the server's HTTP side; returns (status, content type, body bytes)."""
    import urllib.error
    import urllib.request
    req = urllib.request.Request(f"http://{address}{path}", method=method,
                                 data=b"" if method == "POST" else None)
    if token:
        req.add_header("Authorization", f"Bearer {token}")
    for name, value in (headers or {}).items():
        req.add_header(name, value)
    opener = urllib.request.build_opener(urllib.request.ProxyHandler({}))  # never a proxy
    try:
        with opener.open(req, timeout=timeout) as r:
            return r.status, r.headers.get("Content-Type", ""), r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.headers.get("Content-Type", ""), e.read()


def parse_metrics(text):
    """Prometheus text exposition to {'name{label="v",...}': value} (labels sorted by name)."""
    out = {}
    for line in text.splitlines():
        if not line or line.startswith("#"):
            continue
        m = re.fullmatch(r'([a-zA-Z_:][a-zA-Z0-9_:]*)(\{(.*)\})?\s+(\S+)(\s+\d+)?', line)
        if not m:
            raise AssertionError(f"unparsable metrics line: {line!r}")
        labels = re.findall(r'([a-zA-Z_][a-zA-Z0-9_]*)="((?:[^"\\]|\\.)*)"', m.group(3) or "")
        key = m.group(1)
        if labels:
            key += "{" + ",".join(f'{k}="{v}"' for k, v in sorted(labels)) + "}"
        out[key] = float(m.group(4))
    return out


def status_code(fn, *args, **kwargs):
    """Runs a call; returns grpc.StatusCode.OK or the error's code (and the error)."""
    try:
        fn(*args, **kwargs)
        return grpc.StatusCode.OK, None
    except grpc.RpcError as e:
        return e.code(), e


# ---------------------------------------------------------------------------------------------
# Scene bundles

_REF_PATTERNS = [
    re.compile(r'<include\s+[^>]*filename\s*=\s*"([^"]+)"'),
    re.compile(r'<string\s+name\s*=\s*"filename"\s+value\s*=\s*"([^"]+)"'),
]


def scene_bundle_files(scene):
    """The scene file and every file it references (include files, meshes, textures), as
    {path relative to the scene folder: bytes}, and the scene's relative path."""
    scene = os.path.abspath(scene)
    root = os.path.dirname(scene)
    files = {}
    todo = [os.path.basename(scene)]
    for _ in range(1000):
        if not todo:
            break
        rel = todo.pop()
        if rel in files:
            continue
        path = os.path.join(root, rel)
        with open(path, "rb") as f:
            data = f.read()
        files[rel] = data
        if rel.endswith(".xml"):
            text = data.decode(errors="replace")
            for pattern in _REF_PATTERNS:
                for ref in pattern.findall(text):
                    if "$" in ref:
                        continue
                    ref_rel = os.path.normpath(os.path.join(os.path.dirname(rel), ref))
                    if os.path.exists(os.path.join(root, ref_rel)):
                        todo.append(ref_rel.replace(os.sep, "/"))
    return files, os.path.basename(scene)


def scene_path(*parts):
    return os.path.join(SOURCE_DIR, "scenes", *parts)


def cornell_box():
    return scene_path("bitterli", "cornell-box", "scene_v3.xml")


# ---------------------------------------------------------------------------------------------
# The cluster


class TlsFiles:
    """PEM files of a test CA and a server certificate it signed (make_tls_files)."""

    def __init__(self, ca, cert, key):
        self.ca, self.cert, self.key = ca, cert, key


def openssl():
    """The openssl program, or None."""
    return shutil.which("openssl")


def _openssl(*args, cwd):
    r = subprocess.run([openssl(), *args], cwd=cwd, capture_output=True, text=True,
                       timeout=60, stdin=subprocess.DEVNULL)
    if r.returncode != 0:
        raise RuntimeError(f"openssl {' '.join(args)} failed: {r.stderr}")


def make_tls_files(folder, name="ca", hosts=("127.0.0.1", "localhost")):
    """Makes, with the openssl program, a CA (`name`.crt) and a server certificate and key
    (`name`-server.crt/.key) it signed for `hosts` (IP addresses and DNS names, as
    subjectAltName) in `folder`; returns their TlsFiles. Valid for 2 days."""
    os.makedirs(folder, exist_ok=True)
    ca, ca_key = f"{name}.crt", f"{name}.key"
    cert, key, csr = f"{name}-server.crt", f"{name}-server.key", f"{name}-server.csr"
    ext = f"{name}-server.ext"
    _openssl("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", ca_key, "-out", ca,
             "-days", "2", "-subj", f"/CN=render test CA {name}", cwd=folder)
    _openssl("req", "-newkey", "rsa:2048", "-nodes", "-keyout", key, "-out", csr, "-subj",
             "/CN=render-server", cwd=folder)
    alt = ",".join((f"IP:{h}" if re.fullmatch(r"[0-9.]+|[0-9a-fA-F:]+", h) else f"DNS:{h}")
                   for h in hosts)
    with open(os.path.join(folder, ext), "w") as f:
        f.write(f"subjectAltName={alt}\n")
    _openssl("x509", "-req", "-in", csr, "-CA", ca, "-CAkey", ca_key, "-CAcreateserial",
             "-out", cert, "-days", "2", "-extfile", ext, cwd=folder)
    return TlsFiles(*(os.path.join(folder, f) for f in (ca, cert, key)))


class Cluster:
    """One server and its workers, with a temporary store, caches and logs. With `tls` (a
    TlsFiles) the server serves TLS and the workers and `api` trust its CA; without it a
    server with a token gets --insecure (plaintext on 127.0.0.1)."""

    def __init__(self, token=None, lease_timeout=None, heartbeat=None, server_args=(),
                 tls=None):
        self.dir = tempfile.mkdtemp(prefix="render-it-")
        self.store = os.path.join(self.dir, "store")
        os.makedirs(self.store)
        self.token = token
        self.lease_timeout = lease_timeout
        self.heartbeat = heartbeat
        self.server_args = list(server_args)
        self.tls = tls
        self.server = None
        self.port = None
        self.address = None
        self.workers = []
        self.procs = []  # every process started, for the logs
        self.api = None
        self._n_server = 0
        self._n_worker = 0

    # -- server

    def start_server(self, port=0, timeout=20):
        """Starts the server on 127.0.0.1:port (0 = ephemeral); returns the port."""
        self._n_server += 1
        args = [binary("server"), "--listen", f"{LOCALHOST}:{port}", "--store", self.store]
        if self.token:
            args += ["--token", self.token]
        if self.tls:
            args += ["--tls-cert", self.tls.cert, "--tls-key", self.tls.key]
        elif self.token:
            args += ["--insecure"]
        if self.lease_timeout is not None:
            args += ["--lease-timeout", str(self.lease_timeout)]
        if self.heartbeat is not None:
            args += ["--heartbeat", str(self.heartbeat)]
        args += self.server_args
        log = os.path.join(self.dir, f"server-{self._n_server}.log")
        proc = Proc(f"server#{self._n_server}", args, log, capture_stdout=True)
        self.procs.append(proc)
        line = read_line_with_timeout(proc, timeout)
        m = re.fullmatch(r"listening on 127\.0\.0\.1:(\d+)", (line or "").strip())
        if not m:
            proc.kill()
            raise RuntimeError(f"server did not print 'listening on 127.0.0.1:PORT' within "
                               f"{timeout} s (got {line!r}):\n{proc.log_tail()}")
        # `metrics on HOST:PORT` / `http on HOST:PORT` / `health on HOST:PORT` follow for
        # --metrics / --http / --health-listen.
        self.http_addresses = {}
        for _ in range(sum(1 for a in args if a in ("--metrics", "--http", "--health-listen"))):
            extra = read_line_with_timeout(proc, timeout)
            m2 = re.fullmatch(r"(metrics|http|health) on (127\.0\.0\.1:\d+)",
                              (extra or "").strip())
            if not m2:
                proc.kill()
                raise RuntimeError(f"server did not print its HTTP address (got {extra!r}):\n"
                                   f"{proc.log_tail()}")
            self.http_addresses[m2.group(1)] = m2.group(2)
        if getattr(proc, "stdout_rest", b""):
            proc.log.write(proc.stdout_rest)
        threading.Thread(target=_drain, args=(proc,), daemon=True).start()
        self.server = proc
        self.port = int(m.group(1))
        if port:
            assert self.port == port, f"asked for port {port}, server says {self.port}"
        self.address = f"{LOCALHOST}:{self.port}"
        if self.api:
            self.api.close()
        self.api = Api(self.address, self.token, ca=self.tls.ca if self.tls else None)
        self.api.wait_ready(timeout=15)
        return self.port

    def kill_server(self):
        if self.server:
            self.server.kill()

    def restart_server(self, port, workers, threads=1):
        """Starts the server again on `port` after kill_server(). When the port is not free
        again, starts it on a new port with `workers` new workers (the old ones know only the
        old address) and kills the old ones. Returns the port."""
        try:
            return self.start_server(port=port)
        except (RuntimeError, AssertionError) as e:
            print(f"restart on port {port} failed ({e}); restarting on a new port with new "
                  f"workers")
            for w in self.workers:
                w.kill()
            port = self.start_server()
            self.start_workers(workers, threads=threads)
            return port

    # -- workers

    def start_worker(self, threads=1, token=None, extra=(), env=None):
        """A worker process; `env`: variables added to this environment for it."""
        self._n_worker += 1
        n = self._n_worker
        cache = os.path.join(self.dir, f"cache-{n}")
        os.makedirs(cache, exist_ok=True)
        args = [binary("worker"), "--server", self.address, "--threads", str(threads),
                "--cache", cache]
        token = self.token if token is None else token
        if token:
            args += ["--token", token]
        if self.tls:
            args += ["--tls-ca", self.tls.ca]
        args += list(extra)
        proc = Proc(f"worker#{n}", args, os.path.join(self.dir, f"worker-{n}.log"),
                    env={**os.environ, **env} if env else None)
        self.workers.append(proc)
        self.procs.append(proc)
        return proc

    def start_workers(self, n, threads=1):
        return [self.start_worker(threads) for _ in range(n)]

    def live_workers(self):
        return [w for w in self.workers if w.alive()]

    def wait_workers_registered(self, n, timeout=20):
        """Waits until ClusterStatus lists at least n workers."""
        deadline = time.monotonic() + timeout
        status = None
        for _ in range(int(timeout / 0.1) + 10):
            status = self.api.cluster_status()
            if len(status.workers) >= n:
                return status
            for w in self.workers:
                if not w.alive():
                    raise AssertionError(f"{w.name} exited with {w.popen.returncode}:\n"
                                         f"{w.log_tail()}")
            if time.monotonic() >= deadline:
                break
            time.sleep(0.1)
        raise AssertionError(f"{n} workers not registered after {timeout} s: {status}")

    # -- teardown

    def close(self):
        if self.api:
            self.api.close()
        for p in self.procs:
            if p.alive():
                p.stop(timeout=3)
            else:
                p.kill()

    def logs(self, lines=60):
        out = []
        for p in self.procs:
            out.append(f"----- {p.name} (pid {p.pid}, exit {p.popen.returncode}) "
                       f"{p.log_path}\n{p.log_tail(lines)}")
        return "\n".join(out)

    def remove_dir(self):
        shutil.rmtree(self.dir, ignore_errors=True)

    def path(self, name):
        return os.path.join(self.dir, name)


# ---------------------------------------------------------------------------------------------
# Reference renders and images

_reference_cache = {}
_ref_dir = None


def render_reference(scene, algorithm, iterations, resolution, seed, threads=2, defines=None,
                     frame=0):
    """Renders the scene with the local `render` binary in one process (as the job's frame
    `frame`: it seeds the random numbers); cached per settings. Returns the EXR path."""
    global _ref_dir
    key = (scene, algorithm, iterations, tuple(resolution), seed,
           tuple(sorted((defines or {}).items())), frame)
    if key in _reference_cache:
        return _reference_cache[key]
    if _ref_dir is None:
        _ref_dir = tempfile.mkdtemp(prefix="render-it-ref-")
        atexit.register(_rmtree_quiet, _ref_dir)
    out = os.path.join(_ref_dir, f"ref-{len(_reference_cache)}.exr")
    args = [binary("render"), scene, "--algo", algorithm, "--iterations", str(iterations),
            "--resolution", f"{resolution[0]}x{resolution[1]}", "--seed", str(seed),
            "--threads", str(threads), "--out", out]
    if frame:
        args += ["--frame", str(frame)]
    for k, v in (defines or {}).items():
        args += ["-D", f"{k}={v}"]
    r = subprocess.run(args, capture_output=True, text=True, timeout=300,
                       start_new_session=True)
    if r.returncode != 0 or not os.path.exists(out):
        raise RuntimeError(f"render failed ({r.returncode}): {' '.join(args)}\n{r.stderr}")
    _reference_cache[key] = out
    return out


def read_exr(path):
    """The R, G, B channels of an EXR as a float64 array of shape (height, width, 3)."""
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise AssertionError(f"cannot open {path}: {oiio.geterror()}")
    try:
        spec = inp.spec()
        pixels = inp.read_image(0, 0, 0, spec.nchannels, "float")
        if pixels is None:
            raise AssertionError(f"cannot read {path}: {inp.geterror()}")
        pixels = np.asarray(pixels, dtype=np.float64).reshape(spec.height, spec.width,
                                                               spec.nchannels)
        names = list(spec.channelnames)
        try:
            idx = [names.index(c) for c in ("R", "G", "B")]
        except ValueError:
            idx = [0, 1, 2]
        return pixels[:, :, idx]
    finally:
        inp.close()


def read_exr_channels(path):
    """Every channel of an EXR as float32 (height, width, channels), the channel names, and the
    header's extra attributes as strings."""
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise AssertionError(f"cannot open {path}: {oiio.geterror()}")
    try:
        spec = inp.spec()
        pixels = np.asarray(inp.read_image(0, 0, 0, spec.nchannels, "float"), dtype=np.float32)
        header = {a.name: str(a.value) for a in spec.extra_attribs}
        return (pixels.reshape(spec.height, spec.width, spec.nchannels),
                list(spec.channelnames), header)
    finally:
        inp.close()

def compare_images(a, b, rel=1e-5, abs_=1e-7):
    """Returns (ok, message): ok when |a-b| <= rel*max(|a|,|b|) + abs_ for every value."""
    if a.shape != b.shape:
        return False, f"shapes differ: {a.shape} vs {b.shape}"
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return False, "non-finite values in an image"
    diff = np.abs(a - b)
    bound = rel * np.maximum(np.abs(a), np.abs(b)) + abs_
    bad = diff > bound
    scale = np.maximum(np.maximum(np.abs(a), np.abs(b)), 1e-30)
    max_rel = float(np.max(np.where(scale > 1e-30, diff / scale, 0.0)))
    msg = (f"max |a-b| {float(diff.max()):.3g}, max relative difference {max_rel:.3g}, "
           f"{int(bad.sum())} of {bad.size} values beyond {rel}*max(|a|,|b|)+{abs_}; "
           f"means {a.mean():.6g} vs {b.mean():.6g}")
    if bad.any():
        y, x, c = np.unravel_index(int(np.argmax(diff - bound)), a.shape)
        msg += f"; worst at pixel ({x},{y}) channel {c}: {a[y, x, c]!r} vs {b[y, x, c]!r}"
    return not bad.any(), msg


# ---------------------------------------------------------------------------------------------
# unittest glue


class ClusterTestCase(unittest.TestCase):
    """A test case with `self.new_cluster(...)`: clusters are closed after the test, and their
    logs printed if the test failed."""

    def setUp(self):
        self._clusters = []
        stubs()

    def new_cluster(self, **kwargs):
        c = Cluster(**kwargs)
        self._clusters.append(c)
        return c

    def run(self, result=None):
        result = result or self.defaultTestResult()
        before = len(result.failures) + len(result.errors)
        try:
            return super().run(result)
        finally:
            failed = len(result.failures) + len(result.errors) > before
            for c in getattr(self, "_clusters", []):
                c.close()
                if failed:
                    sys.stderr.write(f"\n===== logs of {self.id()} =====\n{c.logs()}\n")
                if failed and os.environ.get("RENDER_IT_KEEP"):
                    sys.stderr.write(f"(kept {c.dir})\n")
                else:
                    c.remove_dir()

    # -- helpers shared by the tests

    def assertImagesMatch(self, test_path, reference_path, rel=1e-5, abs_=1e-7):
        a, b = read_exr(test_path), read_exr(reference_path)
        self.assertGreater(float(np.abs(b).max()), 0.0, "the reference image is black")
        ok, msg = compare_images(a, b, rel, abs_)
        self.assertTrue(ok, f"{test_path} vs {reference_path}: {msg}")
        return msg

    def assertStatus(self, expected, fn, *args, what="", **kwargs):
        """Asserts that the call fails with one of `expected` (a StatusCode or a set)."""
        if isinstance(expected, grpc.StatusCode):
            expected = {expected}
        code, err = status_code(fn, *args, **kwargs)
        details = err.details() if err is not None else ""
        self.assertIn(code, expected,
                      f"{what}: expected {sorted(e.name for e in expected)}, got {code.name} "
                      f"({details!r})")
        return code, details


def wait_until(predicate, timeout, poll=0.1, what="condition"):
    """Polls predicate() (bounded in count and time); returns its first truthy value."""
    deadline = time.monotonic() + timeout
    for _ in range(int(timeout / poll) + 10):
        value = predicate()
        if value:
            return value
        if time.monotonic() >= deadline:
            break
        time.sleep(poll)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


# The exit status CTest reports as "Skipped" (SKIP_RETURN_CODE in tests/CMakeLists.txt).
SKIP_EXIT = 77


def _without(suite, excluded):
    """The suite's cases but those whose method name is in `excluded`."""
    kept = unittest.TestSuite()
    for test in suite:
        if isinstance(test, unittest.TestSuite):
            kept.addTest(_without(test, excluded))
        elif getattr(test, "_testMethodName", None) not in excluded:
            kept.addTest(test)
    return kept


class _Program(unittest.TestProgram):
    def __init__(self, excluded, **kwargs):
        self._excluded = set(excluded)
        super().__init__(**kwargs)

    def createTests(self, *args, **kwargs):
        super().createTests(*args, **kwargs)
        if self._excluded:
            self.test = _without(self.test, self._excluded)


def main():
    """Runs the script's cases (all, or those named on the command line, but any given with
    `--exclude METHOD`). Exits 0 when every case ran and passed, 1 on a failure, and SKIP_EXIT
    when none failed but one was skipped (a tool it needs is missing): a check that did not run
    is never reported as passed. A case that needs a tool is registered as a CTest test of its
    own (tests/CMakeLists.txt), so that its skip does not hide the cases that ran."""
    parser = argparse.ArgumentParser(add_help=False)
    parser.add_argument("--bin-dir")
    parser.add_argument("--source-dir")
    parser.add_argument("--exclude", action="append", default=[])
    args, rest = parser.parse_known_args()
    configure(args.bin_dir, args.source_dir)
    program = _Program(args.exclude, module="__main__", argv=[sys.argv[0]] + rest, verbosity=2,
                       exit=False)
    result = program.result
    if not result.wasSuccessful():
        sys.exit(1)
    if result.skipped:
        for test, reason in result.skipped:
            print(f"SKIPPED {test}: {reason}")
        sys.exit(SKIP_EXIT)
    sys.exit(0)
