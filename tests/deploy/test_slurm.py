"""Deployment test: deploy/slurm/render-workers.sbatch on a real single-node Slurm.

The test starts its own Slurm on this machine, in a temporary folder, touching no system
configuration: munged (with a fresh key and its own socket), slurmctld and slurmd (Debian
`slurm-wlm` 22.05, `slurm.conf` written here for this host on 127.0.0.1, free ports,
proctrack/linuxproc, no cgroups, no accounting). Then, against a real render server on
127.0.0.1:
* `sbatch --nodes=1 --cpus-per-task=1 deploy/slurm/render-workers.sbatch` with RENDER_SERVER
  and RENDER_WORKER_BIN, as docs/guide/deploy.md says; the batch script starts the worker with srun;
* a Cornell box job submitted to the server is rendered by that worker, and its EXR equals
  `render`'s (same tolerance as the other integration tests: 1e-5 relative);
* the worker registered with SLURM_CPUS_PER_TASK threads;
* `scancel --batch --signal=TERM JOB` (the graceful stop of docs/guide/deploy.md) makes the batch
  shell forward one SIGTERM to the worker step; the worker exits 0, the script prints
  `workers ended (srun status 0)` and the Slurm job ends COMPLETED with exit code 0.

Skipped (exit 77, CTest "Skipped") with the reason when it cannot run: not root (munged and
slurmd need it), munge/slurm not installed, or the test's own Slurm does not come up (its
daemons' logs are printed) (`scripts/setup` installs slurm-wlm and munge;
installing them starts no service inside a container whose policy-rc.d forbids it, and the
test never uses the system's daemons).

    /usr/bin/python3 tests/deploy/test_slurm.py --bin-dir build/bin --source-dir .
"""

import argparse
import os
import re
import shutil
import socket
import subprocess
import sys
import time
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "integration"))
import cluster  # noqa: E402

TOOLS = {"munged": "/usr/sbin/munged", "slurmctld": "/usr/sbin/slurmctld",
         "slurmd": "/usr/sbin/slurmd", "sbatch": "sbatch", "scontrol": "scontrol",
         "scancel": "scancel", "sinfo": "sinfo", "munge": "munge"}
RESOLUTION = (32, 32)
ITERATIONS = 16
SEED = 3


def skip_reason():
    if os.geteuid() != 0:
        return "not root: munged -f and slurmd need root"
    missing = [name for name, path in TOOLS.items() if not shutil.which(path)]
    if missing:
        return (f"{', '.join(missing)} not found (Debian packages slurm-wlm and munge, "
                "installed by scripts/setup)")
    return None


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for(what, predicate, timeout, procs=()):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        for p in procs:
            if not p.alive():
                raise AssertionError(f"{p.name} exited while waiting for {what}:\n"
                                     f"{p.log_tail()}")
        time.sleep(0.2)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


class Slurm:
    """munged, slurmctld and slurmd for this host, in `folder`."""

    def __init__(self, folder):
        self.dir = folder
        self.host = socket.gethostname().split(".")[0]
        for sub in ("munge", "state", "spool", "log"):
            os.makedirs(os.path.join(folder, sub), exist_ok=True)
        os.chmod(os.path.join(folder, "munge"), 0o700)
        self.socket = os.path.join(folder, "munge", "munge.sock")
        key = os.path.join(folder, "munge", "munge.key")
        with open(key, "wb") as f:
            f.write(os.urandom(1024))
        os.chmod(key, 0o600)
        self.conf = os.path.join(folder, "slurm.conf")
        cpus = os.cpu_count() or 1
        d = folder
        with open(self.conf, "w") as f:
            f.write(f"""ClusterName=rendertest
SlurmctldHost={self.host}(127.0.0.1)
SlurmctldPort={free_port()}
SlurmdPort={free_port()}
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket={self.socket}
SlurmUser=root
SlurmdUser=root
StateSaveLocation={d}/state
SlurmdSpoolDir={d}/spool
SlurmctldPidFile={d}/slurmctld.pid
SlurmdPidFile={d}/slurmd.pid
SlurmctldLogFile={d}/log/slurmctld.log
SlurmdLogFile={d}/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/builtin
ReturnToService=2
MpiDefault=none
KillWait=10
NodeName={self.host} NodeAddr=127.0.0.1 CPUs={cpus} State=UNKNOWN
PartitionName=render Nodes={self.host} Default=YES MaxTime=INFINITE State=UP
""")
        self.env = {**os.environ, "SLURM_CONF": self.conf}
        for name in list(self.env):
            if name.startswith(("SLURM_", "SBATCH_", "SRUN_")) and name != "SLURM_CONF":
                del self.env[name]
        self.procs = []

    def start(self):
        log = lambda name: os.path.join(self.dir, "log", f"{name}.out")  # noqa: E731
        self.procs.append(cluster.Proc("munged", [
            TOOLS["munged"], "-F", "-f", f"--socket={self.socket}",
            f"--key-file={self.dir}/munge/munge.key", f"--pid-file={self.dir}/munge/munged.pid",
            f"--log-file={self.dir}/log/munged.log", f"--seed-file={self.dir}/munge/seed"],
            log("munged")))
        wait_for("munged's socket", lambda: os.path.exists(self.socket), 15, self.procs)
        self.procs.append(cluster.Proc("slurmctld", [TOOLS["slurmctld"], "-D", "-f", self.conf],
                                       log("slurmctld"), env=self.env))
        self.procs.append(cluster.Proc("slurmd", [TOOLS["slurmd"], "-D", "-f", self.conf,
                                                  "-N", self.host], log("slurmd"), env=self.env))

        def idle():
            r = self.run("sinfo", "-h", "-o", "%T", check=False)
            return r.returncode == 0 and r.stdout.strip() == "idle"
        try:
            wait_for("the Slurm node to be idle", idle, 60, self.procs)
        except AssertionError as e:
            raise AssertionError(f"{e}\n{self.logs()}")

    def run(self, tool, *args, check=True, timeout=30):
        r = subprocess.run([shutil.which(TOOLS[tool]), *args], env=self.env,
                           capture_output=True, text=True, timeout=timeout)
        if check and r.returncode != 0:
            raise AssertionError(f"{tool} {' '.join(args)}: exit {r.returncode}\n{r.stdout}\n"
                                 f"{r.stderr}")
        return r

    def job_state(self, job_id):
        r = self.run("scontrol", "show", "job", job_id, check=False)
        state = re.search(r"JobState=(\S+)", r.stdout)
        code = re.search(r"\bExitCode=(\S+)", r.stdout)
        return (state.group(1) if state else None), (code.group(1) if code else None)

    def logs(self):
        out = []
        for name in ("slurmctld.log", "slurmd.log", "munged.log"):
            path = os.path.join(self.dir, "log", name)
            if os.path.exists(path):
                with open(path, errors="replace") as f:
                    out.append(f"----- {name}\n" + "".join(f.readlines()[-30:]))
        return "\n".join(out)

    def close(self):
        self.run("scancel", "--user=root", check=False)
        for p in reversed(self.procs):
            p.stop(timeout=5) if p.alive() else p.kill()


class SlurmTest(cluster.ClusterTestCase):
    def setUp(self):
        super().setUp()
        self.slurm = Slurm(os.path.join(self.new_cluster().dir, "slurm"))
        self.addCleanup(self.slurm.close)
        try:
            self.slurm.start()
        except AssertionError as e:
            # Slurm itself does not come up here (before the script under test is involved).
            self.skipTest(f"the test's own Slurm did not start: {e}")

    def test_sbatch_script_renders_a_job_and_stops_gracefully(self):
        c = self.new_cluster()
        c.start_server()
        scene = cluster.cornell_box()
        job = c.api.submit(scene, algorithm="pt", iterations=ITERATIONS, resolution=RESOLUTION,
                           seed=SEED, name="slurm")

        output = os.path.join(c.dir, "render-workers.out")
        script = os.path.join(cluster.SOURCE_DIR, "deploy", "slurm", "render-workers.sbatch")
        env_before = self.slurm.env
        self.slurm.env = {**env_before, "RENDER_SERVER": c.address,
                          "RENDER_WORKER_BIN": cluster.binary("worker"),
                          "RENDER_CACHE": os.path.join(c.dir, "slurm-cache")}
        try:
            r = self.slurm.run("sbatch", "--nodes=1", "--cpus-per-task=1", "--time=10",
                               f"--output={output}", f"--chdir={c.dir}", script)
        finally:
            self.slurm.env = env_before
        m = re.search(r"Submitted batch job (\d+)", r.stdout)
        self.assertTrue(m, r.stdout)
        slurm_job = m.group(1)

        def read_output():
            if not os.path.exists(output):
                return ""
            with open(output, errors="replace") as f:
                return f.read()

        def tail():
            text = read_output()
            return f"{text[-3000:]}\n{self.slurm.logs()}"

        try:
            c.api.wait_job(job.id, timeout=180, procs=[c.server])
        except AssertionError as e:
            raise AssertionError(f"{e}\n{tail()}")
        status = c.api.cluster_status()
        self.assertEqual(len(status.workers), 1, status)
        self.assertEqual(status.workers[0].threads, 1, "SLURM_CPUS_PER_TASK threads")
        out = c.api.fetch_to(job.id, c.path("slurm.exr"))
        print(self.assertImagesMatch(out, cluster.render_reference(
            scene, "pt", ITERATIONS, RESOLUTION, SEED)))

        # The graceful stop: SIGTERM to the batch shell, which forwards one to the workers.
        self.slurm.run("scancel", "--batch", "--signal=TERM", slurm_job)
        ended = wait_for("the Slurm job to end", lambda: (
            lambda s: s if s[0] not in (None, "PENDING", "RUNNING", "COMPLETING") else None)(
                self.slurm.job_state(slurm_job)), 90)
        self.assertEqual(ended, ("COMPLETED", "0:0"), tail())
        text = read_output()
        self.assertIn("stopping the workers", text, tail())
        self.assertIn("workers ended (srun status 0)", text, tail())
        self.assertIn("event=stop", text, tail())
        print(f"slurm job {slurm_job}: {ended[0]} {ended[1]}")


def main():
    reason = skip_reason()
    if reason:
        print(f"SKIP: {reason}")
        return 77
    parser = argparse.ArgumentParser(add_help=False)
    parser.add_argument("--bin-dir")
    parser.add_argument("--source-dir")
    args, rest = parser.parse_known_args()
    cluster.configure(args.bin_dir, args.source_dir)
    result = unittest.main(module="__main__", argv=[sys.argv[0]] + rest, verbosity=2,
                           exit=False).result
    if not result.wasSuccessful():
        return 1
    if result.skipped:
        print(f"SKIP: {result.skipped[0][1]}")
        return 77  # CTest's SKIP_RETURN_CODE
    return 0


if __name__ == "__main__":
    sys.exit(main())
