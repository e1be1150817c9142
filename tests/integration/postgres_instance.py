"""A PostgreSQL server of a test's own: initdb in a temporary folder, started on a free port of
127.0.0.1 with trust authentication, stopped and removed by close(). PostgreSQL refuses to run
as root, so under root it runs as the `postgres` user (runuser). `PostgresInstance.start()`
returns (instance, None), or (None, reason) when the binaries (env RENDER_PG_BIN, else
/usr/lib/postgresql/*/bin, else PATH) or a user to run them as are missing: the test then skips
with the reason (scripts/setup installs postgresql-15). The C++ tests' twin is
tests/unit/server/postgres_instance.h."""

import glob
import os
import pwd
import shlex
import shutil
import socket
import subprocess
import tempfile

import cluster


def _bin_dir():
    env = os.environ.get("RENDER_PG_BIN")
    if env and os.path.exists(os.path.join(env, "initdb")):
        return env
    found = [d for d in glob.glob("/usr/lib/postgresql/*/bin")
             if os.path.exists(os.path.join(d, "initdb"))]
    if found:
        return max(found, key=lambda d: int(d.split("/")[-2]) if d.split("/")[-2].isdigit()
                   else 0)
    initdb = shutil.which("initdb")
    return os.path.dirname(initdb) if initdb else None


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class PostgresInstance:
    def __init__(self, bin_dir, user):
        self.bin_dir = bin_dir
        self.user = user  # None: this process's user
        self.dir = tempfile.mkdtemp(prefix="render-pg-")
        self.port = None
        if user:
            pw = pwd.getpwnam(user)
            os.chown(self.dir, pw.pw_uid, pw.pw_gid)

    @classmethod
    def start(cls, options=""):
        """`options`: more server settings ("-c name=value ..."), e.g. for measurements."""
        bin_dir = _bin_dir()
        if not bin_dir or not os.path.exists(os.path.join(bin_dir, "pg_ctl")):
            return None, ("PostgreSQL's initdb and pg_ctl not found (RENDER_PG_BIN, "
                          "/usr/lib/postgresql/*/bin, PATH); scripts/setup installs postgresql-15")
        user = None
        if os.geteuid() == 0:
            try:
                pwd.getpwnam("postgres")
            except KeyError:
                return None, "running as root (PostgreSQL refuses to) and no `postgres` user"
            user = "postgres"
        pg = cls(bin_dir, user)
        try:
            pg._run([os.path.join(bin_dir, "initdb"), "-D", pg.data, "-A", "trust", "-U",
                     "render", "-E", "UTF8", "--no-sync"])
            for attempt in range(5):  # a port found free may be taken before the server binds
                port = _free_port()
                options = (f"-p {port} -k {pg.dir} -c listen_addresses=127.0.0.1 -c fsync=off "
                           f"{options}")
                try:
                    pg._run([os.path.join(bin_dir, "pg_ctl"), "-D", pg.data, "-l", pg.log, "-o",
                             options, "-w", "-t", "60", "start"])
                    pg.port = port
                    break
                except RuntimeError:
                    if attempt == 4:
                        raise
        except Exception:
            log = pg.log_tail()
            pg.close()
            raise RuntimeError(f"PostgreSQL did not start:\n{log}")
        return pg, None

    @property
    def data(self):
        return os.path.join(self.dir, "data")

    @property
    def log(self):
        return os.path.join(self.dir, "log")

    def url(self, database="postgres"):
        return f"postgresql://render@127.0.0.1:{self.port}/{database}"

    def _run(self, args):
        if self.user:
            args = ["runuser", "-u", self.user, "--"] + args
        r = subprocess.run(args, capture_output=True, text=True, timeout=120)
        if r.returncode != 0:
            raise RuntimeError(f"{shlex.join(args)} failed ({r.returncode}): {r.stderr}")
        return r.stdout

    def psql(self, sql):
        """The rows of `sql` (psql's unaligned tuples, one per line)."""
        r = subprocess.run([os.path.join(self.bin_dir, "psql"), "-h", "127.0.0.1", "-p",
                            str(self.port), "-U", "render", "-d", "postgres", "-At",
                            "-v", "ON_ERROR_STOP=1", "-c", sql],
                           capture_output=True, text=True, timeout=60)
        if r.returncode != 0:
            raise RuntimeError(f"psql failed: {r.stderr}")
        return r.stdout.splitlines()

    def log_tail(self, n=4000):
        try:
            with open(self.log, errors="replace") as f:
                return f.read()[-n:]
        except OSError:
            return "(no log)"

    def close(self):
        if self.port:
            try:
                self._run([os.path.join(self.bin_dir, "pg_ctl"), "-D", self.data, "-m",
                           "immediate", "-w", "stop"])
            except RuntimeError:
                pass
            self.port = None
        shutil.rmtree(self.dir, ignore_errors=True)



class PostgresClusterTestCase(cluster.ClusterTestCase):
    """ClusterTestCase whose tests each get self.pg, a PostgreSQL of their own, or skip (with
    the reason) where PostgreSQL is not installed."""

    def setUp(self):
        super().setUp()
        self.pg, reason = PostgresInstance.start()
        if reason:
            self.skipTest(reason)
        # Cleanups run last-in first-out: the servers stop before their database.
        self.addCleanup(self.pg.close)
        self.addCleanup(lambda: [c.close() for c in self._clusters])
