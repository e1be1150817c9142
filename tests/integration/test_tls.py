"""Integration test: transport security (docs/guide/service.md, "Transport security").

A CA and a server certificate for 127.0.0.1 are made with `openssl` in a temporary folder
(without openssl every case is skipped with a message and CTest reports the test as Skipped,
never Passed; scripts/setup installs openssl). Checked:
  * a server with --tls-cert/--tls-key and a token, two workers with --tls-ca: a job submitted
    with `client --tls-ca ... submit --out` equals `render`'s image;
  * a client trusting another CA is refused (certificate verify failed), and so is a client
    that checks the certificate for another name;
  * a plaintext client (C++ and Python) against the TLS server fails;
  * the plaintext rule: a server with a token and no TLS refuses to start off loopback, with
    or without --insecure, and on loopback without --insecure; --insecure contradicts TLS;
    --http off loopback with a token is refused; a client or worker refuses to send a token in
    clear to a non-loopback address; unreadable certificate files are named;
  * --health-listen serves the health service, not the render API, in plaintext beside the
    TLS port.
"""

import os
import shutil
import subprocess
import sys
import tempfile
import unittest

sys.dont_write_bytecode = True  # keep the source tree clean
import grpc  # noqa: E402

import cluster  # noqa: E402

TOKEN = "tls-token"
SEED = 17
RES = (32, 32)


def run(args, timeout=90):
    """Runs a program of ours without RENDER_* variables from the caller's environment."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("RENDER_")}
    return subprocess.run([str(a) for a in args], capture_output=True, text=True,
                          timeout=timeout, env=env, stdin=subprocess.DEVNULL,
                          start_new_session=True)


class Tls(cluster.ClusterTestCase):
    @classmethod
    def setUpClass(cls):
        if not cluster.openssl():
            raise unittest.SkipTest("openssl is not installed (scripts/setup installs it): "
                                    "the TLS test needs it to make certificates")
        cls.dir = tempfile.mkdtemp(prefix="render-it-tls-")
        cls.files = cluster.make_tls_files(cls.dir, "ca")
        cls.other = cluster.make_tls_files(cls.dir, "other")  # a CA the server does not use

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.dir, ignore_errors=True)

    def client(self, c, *args, ca=None, token=TOKEN):
        cmd = [cluster.binary("client"), "--server", c.address]
        if token:
            cmd += ["--token", token]
        if ca:
            cmd += ["--tls-ca", ca]
        return run(cmd + list(args))

    def server(self, *args):
        store = tempfile.mkdtemp(prefix="render-it-tls-store-")
        try:
            return run([cluster.binary("server"), "--store", store, *args], timeout=30)
        finally:
            shutil.rmtree(store, ignore_errors=True)

    def test_job_over_tls_equals_render(self):
        c = self.new_cluster(token=TOKEN, tls=self.files, heartbeat=0.5)
        c.start_server()
        workers = c.start_workers(2, threads=1)
        c.wait_workers_registered(2)
        scene = cluster.cornell_box()
        out = c.path("tls.exr")
        r = self.client(c, "submit", scene, "--algo", "pt", "--iterations", 16, "--resolution",
                        f"{RES[0]}x{RES[1]}", "--seed", SEED, "--out", out, ca=self.files.ca)
        self.assertEqual(r.returncode, 0, f"client exited {r.returncode}:\n{r.stdout}\n{r.stderr}")
        print(self.assertImagesMatch(out, cluster.render_reference(scene, "pt", 16, RES, SEED)))
        for w in workers:
            self.assertTrue(w.alive(), f"{w.name} died:\n{w.log_tail()}")
        with open(c.server.log_path) as f:
            self.assertIn("transport=tls", f.read())

        # The health service answers over TLS without the token (for probes).
        P = cluster.stubs()
        reply = c.api.health.Check(P["hpb"].HealthCheckRequest(service=""), timeout=10)
        self.assertEqual(reply.status, P["hpb"].HealthCheckResponse.SERVING)

    def test_wrong_ca_wrong_name_and_plaintext_are_refused(self):
        P = cluster.pb()
        c = self.new_cluster(token=TOKEN, tls=self.files)
        c.start_server()

        # The right CA works (the control for the refusals below).
        r = self.client(c, "list", ca=self.files.ca)
        self.assertEqual(r.returncode, 0, r.stderr)

        # Another CA: the handshake fails, and the client says why.
        r = self.client(c, "list", ca=self.other.ca)
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertIn("UNAVAILABLE", r.stderr)
        self.assertIn("certificate verify failed", r.stderr)
        self.assertIn("with --tls-ca the server must serve TLS", r.stderr)
        other = cluster.Api(c.address, TOKEN, ca=self.other.ca)
        try:
            self.assertStatus(grpc.StatusCode.UNAVAILABLE, other.call, other.jobs.ListJobs,
                              P.ListJobsRequest(), timeout=10, what="a client of another CA")
        finally:
            other.close()

        # The right CA, but the certificate checked for a name it does not carry.
        r = run([cluster.binary("client"), "--server", c.address, "--token", TOKEN, "--tls-ca",
                 self.files.ca, "--tls-server-name", "elsewhere.example", "list"])
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertIn("elsewhere.example", r.stderr)
        renamed = cluster.Api(c.address, TOKEN, ca=self.files.ca, server_name="localhost")
        try:  # ... and one it does carry.
            renamed.call(renamed.jobs.ListJobs, P.ListJobsRequest(), timeout=10)
        finally:
            renamed.close()

        # Plaintext against the TLS port: refused (the C++ client hints at --tls-ca).
        r = self.client(c, "list")
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertIn("UNAVAILABLE", r.stderr)
        self.assertIn("give --tls-ca FILE", r.stderr)
        plain = cluster.Api(c.address, TOKEN)
        try:
            self.assertStatus(grpc.StatusCode.UNAVAILABLE, plain.call, plain.jobs.ListJobs,
                              P.ListJobsRequest(), timeout=10, what="a plaintext client")
        finally:
            plain.close()

    def test_plaintext_token_rule(self):
        server, files = cluster.binary("server"), self.files
        cases = [
            # (what, args, text the error must hold)
            ("token, no TLS, off loopback", ["--listen", "0.0.0.0:0", "--token", TOKEN],
             "give --tls-cert FILE --tls-key FILE"),
            ("token, no TLS, off loopback, --insecure",
             ["--listen", "0.0.0.0:0", "--token", TOKEN, "--insecure"],
             "--insecure is only accepted on a loopback --listen address"),
            ("--insecure off loopback without a token", ["--listen", "0.0.0.0:0", "--insecure"],
             "--insecure is only accepted on a loopback --listen address"),
            ("token, no TLS, loopback, no --insecure",
             ["--listen", "127.0.0.1:0", "--token", TOKEN], "or --insecure"),
            ("TLS and --insecure", ["--listen", "127.0.0.1:0", "--token", TOKEN, "--insecure",
                                    "--tls-cert", files.cert, "--tls-key", files.key],
             "--insecure contradicts --tls-cert"),
            ("--http off loopback with a token",
             ["--listen", "127.0.0.1:0", "--token", TOKEN, "--tls-cert", files.cert,
              "--tls-key", files.key, "--http", "0.0.0.0:0"],
             "--http 0.0.0.0:0: the dashboard's /api/ takes the token over plain HTTP"),
            ("--tls-cert without --tls-key", ["--listen", "127.0.0.1:0", "--tls-cert",
                                              files.cert], "--tls-cert needs --tls-key"),
            ("a missing certificate file",
             ["--listen", "127.0.0.1:0", "--tls-cert", os.path.join(self.dir, "missing.crt"),
              "--tls-key", files.key],
             f"--tls-cert {os.path.join(self.dir, 'missing.crt')}: cannot read"),
            ("a key given as the certificate",
             ["--listen", "127.0.0.1:0", "--tls-cert", files.key, "--tls-key", files.key],
             "not a PEM file with a CERTIFICATE"),
        ]
        for what, args, expected in cases:
            with self.subTest(what):
                r = self.server(*args)
                self.assertEqual(r.returncode, 2, f"{what}: {server} {args}:\n{r.stderr}")
                self.assertIn(expected, r.stderr)
                self.assertNotIn("listening on", r.stdout)

        # Clients and workers never send a token in clear off loopback (checked before any
        # connection: 192.0.2.1 is TEST-NET-1, never reached).
        for program, args in (("client", ["--server", "192.0.2.1:50051", "--token", TOKEN,
                                          "list"]),
                              ("worker", ["--server", "192.0.2.1:50051", "--token", TOKEN])):
            with self.subTest(f"{program} sends no token in clear"):
                r = run([cluster.binary(program), *args], timeout=30)
                self.assertEqual(r.returncode, 2, r.stderr)
                self.assertIn("refusing to send the token in clear to 192.0.2.1:50051", r.stderr)
                self.assertIn("--tls-ca FILE", r.stderr)
            with self.subTest(f"{program} names an unreadable --tls-ca"):
                missing = os.path.join(self.dir, "no-ca.crt")
                r = run([cluster.binary(program), "--tls-ca", missing, *args], timeout=30)
                self.assertEqual(r.returncode, 2, r.stderr)
                self.assertIn(f"--tls-ca {missing}: cannot read", r.stderr)

    def test_plaintext_health_port(self):
        P = cluster.stubs()
        c = self.new_cluster(token=TOKEN, tls=self.files,
                             server_args=["--health-listen", "127.0.0.1:0"])
        c.start_server()
        health_address = c.http_addresses["health"]
        channel = grpc.insecure_channel(health_address)
        try:
            health = P["hrpc"].HealthStub(channel)
            reply = health.Check(P["hpb"].HealthCheckRequest(service=""), timeout=10)
            self.assertEqual(reply.status, P["hpb"].HealthCheckResponse.SERVING)
            # The render API is not there.
            jobs = P["rpc"].JobServiceStub(channel)
            self.assertStatus(grpc.StatusCode.UNIMPLEMENTED, jobs.ListJobs,
                              P["pb"].ListJobsRequest(),
                              metadata=[("authorization", f"Bearer {TOKEN}")], timeout=10,
                              what="the render API on the health port")
            # Server reflection (every gRPC server of the process gets it) lists the health
            # service there, and nothing of the render API.
            reflection = channel.stream_stream(
                "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
                request_serializer=lambda b: b, response_deserializer=lambda b: b)
            list_services = b"\x3a\x01*"  # ServerReflectionRequest{list_services: "*"}
            listed = b"".join(reflection(iter([list_services]), timeout=10))
            self.assertIn(b"grpc.health.v1.Health", listed)
            self.assertNotIn(b"render.v1", listed)
        finally:
            channel.close()


if __name__ == "__main__":
    cluster.main()
