"""Integration test 5: bad requests get the right gRPC status, the server keeps serving, and a
following good job still completes.

The status families asserted (the ones this test considers right):
  * no token / wrong token (server started with --token)  -> UNAUTHENTICATED
  * unknown algorithm                                      -> INVALID_ARGUMENT
  * an asset of the bundle never uploaded                  -> FAILED_PRECONDITION (the client
    must upload first) or NOT_FOUND
  * malformed scene XML                                    -> INVALID_ARGUMENT
  * a negative time budget                                -> INVALID_ARGUMENT
  * zero iterations without a time budget -> INVALID_ARGUMENT, or (tolerated) a job whose
    target is the scene's sample count, as `render` does
  * "negative" iterations (-1 sent as uint64 = 2^64-1), huge iterations, huge resolution
                          -> INVALID_ARGUMENT, OUT_OF_RANGE or RESOURCE_EXHAUSTED (a limit)
  * asset path "../../etc/passwd", an absolute path, a scene_path not in the bundle
                                                           -> INVALID_ARGUMENT
  * an upload whose bytes do not match its sha256 or size  -> INVALID_ARGUMENT (or DATA_LOSS)
  * GetJob / CancelJob / FetchResult of an unknown job     -> NOT_FOUND
  * a well-formed scene that cannot be loaded (unknown shape type): INVALID_ARGUMENT at submit,
    or else the job must end FAILED with an error message (never hang, never crash a worker)
"""

import hashlib

import grpc

import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

TOKEN = "integration-secret-token"
SEED = 9
RES = (32, 32)
S = grpc.StatusCode
LIMIT = {S.INVALID_ARGUMENT, S.OUT_OF_RANGE, S.RESOURCE_EXHAUSTED}


class BadRequests(cluster.ClusterTestCase):
    def submit_raw(self, api, files, scene_path, upload=True, bundle_files=None, **settings):
        """SubmitJob with an explicit bundle: files {path: bytes} uploaded (if `upload`), and
        the bundle listing `bundle_files` {path: bytes} (default: files)."""
        P = cluster.pb()
        if upload:
            for data in files.values():
                api.upload_asset(data)
        listed = files if bundle_files is None else bundle_files
        bundle = P.SceneBundle(scene_path=scene_path, files=[
            P.BundleFile(path=p, sha256=hashlib.sha256(d).hexdigest(), size=len(d))
            for p, d in listed.items()])
        rs = dict(algorithm="pt", iterations=8, width=RES[0], height=RES[1], seed=SEED)
        rs.update(settings)
        return api.call(api.jobs.SubmitJob, P.SubmitJobRequest(
            name="bad", bundle=bundle, settings=P.RenderSettings(**rs)))

    def test_bad_requests(self):
        P = cluster.pb()
        c = self.new_cluster(token=TOKEN, heartbeat=0.5, lease_timeout=5)
        c.start_server()
        api = c.api
        scene = cluster.cornell_box()
        files, scene_name = cluster.scene_bundle_files(scene)
        scene_bytes = files[scene_name]

        # -- authentication
        for label, token in (("no token", ""), ("wrong token", "not-the-token")):
            other = cluster.Api(c.address, token=None)
            md = [("authorization", f"Bearer {token}")] if token else None
            try:
                with self.subTest(auth=label, rpc="ListJobs"):
                    self.assertStatus(S.UNAUTHENTICATED, other.jobs.ListJobs,
                                      P.ListJobsRequest(), metadata=md, timeout=10, what=label)
                with self.subTest(auth=label, rpc="SubmitJob"):
                    self.assertStatus(S.UNAUTHENTICATED, other.jobs.SubmitJob,
                                      P.SubmitJobRequest(name="x"), metadata=md, timeout=10,
                                      what=label)
                with self.subTest(auth=label, rpc="HasAssets"):
                    self.assertStatus(S.UNAUTHENTICATED, other.jobs.HasAssets,
                                      P.HasAssetsRequest(sha256=["00" * 32]), metadata=md,
                                      timeout=10, what=label)
                with self.subTest(auth=label, rpc="RegisterWorker"):
                    self.assertStatus(S.UNAUTHENTICATED, other.workers.RegisterWorker,
                                      P.RegisterWorkerRequest(host="x", threads=1), metadata=md,
                                      timeout=10, what=label)
            finally:
                other.close()
        # A token that is right but sent without "Bearer " is not accepted either.
        with self.subTest(auth="token without Bearer"):
            self.assertStatus(S.UNAUTHENTICATED, api.jobs.ListJobs, P.ListJobsRequest(),
                              metadata=[("authorization", TOKEN)], timeout=10,
                              what="token without Bearer")
        # The right token works.
        api.call(api.jobs.ListJobs, P.ListJobsRequest())

        # -- settings
        cases = [
            ("unknown algorithm", {S.INVALID_ARGUMENT}, dict(algorithm="no-such-algorithm")),
            ("negative time budget", {S.INVALID_ARGUMENT},
             dict(iterations=0, time_budget_seconds=-5.0)),
            ("negative iterations (-1 as uint64)", LIMIT, dict(iterations=2**64 - 1)),
            ("huge iterations", LIMIT, dict(iterations=10**15)),
            ("huge resolution", LIMIT, dict(width=100000, height=100000)),
            ("huge width", LIMIT, dict(width=10**9, height=32)),
        ]
        for label, expected, settings in cases:
            with self.subTest(case=label):
                self.assertStatus(expected, self.submit_raw, api, files, scene_name,
                                  what=label, **settings)

        # Zero iterations without a time budget: proto/render.proto says "0 = use the time
        # budget only", which leaves no stopping rule, so INVALID_ARGUMENT is right; the server
        # may instead take the scene's own sample count (as `render` does), which is accepted
        # here if the job then has that finite target.
        with self.subTest(case="zero iterations and no time budget"):
            try:
                zero = self.submit_raw(api, files, scene_name, iterations=0,
                                       time_budget_seconds=0)
            except grpc.RpcError as e:
                self.assertEqual(e.code(), S.INVALID_ARGUMENT, e.details())
            else:
                target = zero.frames[0].iterations_target if zero.frames else 0
                api.call(api.jobs.CancelJob, P.CancelJobRequest(job_id=zero.id))
                self.assertEqual(target, 64, "iterations=0 without a budget accepted, but the "
                                 "job's target is not the scene's sample count (64)")
                print("note: iterations=0 without a time budget was accepted with the scene's "
                      "sample count as target (the proto says 0 = time budget only)")

        # -- bundles and assets
        never_uploaded = b"<!-- an asset nobody uploaded " + hashlib.sha256(
            b"salt-for-missing").hexdigest().encode() + b" -->"
        with self.subTest(case="missing asset"):
            self.assertStatus({S.FAILED_PRECONDITION, S.NOT_FOUND}, self.submit_raw, api,
                              files, scene_name,
                              bundle_files=dict(files, **{"extra/missing.obj": never_uploaded}),
                              what="missing asset")
        with self.subTest(case="missing scene file"):
            lonely = b'<scene version="3.0.0"><!-- never uploaded --></scene>'
            self.assertStatus({S.FAILED_PRECONDITION, S.NOT_FOUND}, self.submit_raw, api,
                              {"lonely.xml": lonely}, "lonely.xml", upload=False,
                              what="missing scene file")
        with self.subTest(case="malformed scene XML"):
            broken = b'<scene version="3.0.0">\n  <shape type="rectangle">\n    <ref id="x"'
            self.assertStatus(S.INVALID_ARGUMENT, self.submit_raw, api, {"broken.xml": broken},
                              "broken.xml", what="malformed scene XML")
        with self.subTest(case="not XML at all"):
            self.assertStatus(S.INVALID_ARGUMENT, self.submit_raw, api,
                              {"garbage.xml": bytes(range(256)) * 4}, "garbage.xml",
                              what="binary garbage as scene")
        passwd = b"root:x:0:0:root:/root:/bin/sh\n"
        for label, path in (("../../etc/passwd", "../../etc/passwd"),
                            ("absolute path", "/etc/passwd"),
                            ("escape in the middle", "meshes/../../../etc/passwd"),
                            ("backslash escape", "..\\..\\etc\\passwd")):
            with self.subTest(case=f"asset path {label}"):
                self.assertStatus(S.INVALID_ARGUMENT, self.submit_raw, api,
                                  {scene_name: scene_bytes, path: passwd}, scene_name,
                                  what=f"asset path {path}")
        with self.subTest(case="scene path escapes"):
            self.assertStatus(S.INVALID_ARGUMENT, self.submit_raw, api,
                              {"../scene.xml": scene_bytes}, "../scene.xml",
                              what="scene_path ../scene.xml")
        with self.subTest(case="scene_path not in the bundle"):
            self.assertStatus(S.INVALID_ARGUMENT, self.submit_raw, api, files, "other.xml",
                              what="scene_path not among files")
        with self.subTest(case="upload with a wrong hash"):
            self.assertStatus({S.INVALID_ARGUMENT, S.DATA_LOSS}, api.upload_asset,
                              b"some bytes", "0" * 64, what="upload with a wrong sha256")
        with self.subTest(case="upload with a wrong size"):
            data = b"some other bytes"
            self.assertStatus({S.INVALID_ARGUMENT, S.DATA_LOSS}, api.upload_asset, data,
                              hashlib.sha256(data).hexdigest(), len(data) + 7,
                              what="upload with a wrong size")

        # -- unknown jobs
        for label, fn, req in (
                ("GetJob", api.jobs.GetJob, P.GetJobRequest(job_id="no-such-job")),
                ("CancelJob", api.jobs.CancelJob, P.CancelJobRequest(job_id="no-such-job"))):
            with self.subTest(case=f"{label} of an unknown job"):
                self.assertStatus(S.NOT_FOUND, api.call, fn, req, what=label)
        with self.subTest(case="FetchResult of an unknown job"):
            self.assertStatus(S.NOT_FOUND, lambda: api.fetch("no-such-job"),
                              what="FetchResult of an unknown job")

        self.assertTrue(c.server.alive(), "the server died of a bad request:\n"
                        + c.server.log_tail())
        c.api.call(api.health.Check, cluster.stubs()["hpb"].HealthCheckRequest(service=""))

        # -- a following good job completes (workers with the token)
        workers = c.start_workers(2, threads=1)
        job = api.submit(scene, algorithm="vcm", iterations=16, resolution=RES, seed=SEED,
                         name="good-after-bad")
        api.wait_job(job.id, timeout=60, procs=[c.server] + workers)
        out = api.fetch_to(job.id, c.path("good.exr"))
        print(self.assertImagesMatch(
            out, cluster.render_reference(scene, "vcm", 16, RES, SEED)))

        # -- a well-formed scene that cannot be loaded: rejected, or a FAILED job
        with self.subTest(case="unloadable scene"):
            bad_scene = (b'<scene version="3.0.0">\n  <shape type="no-such-shape-type">\n'
                         b'  </shape>\n</scene>\n')
            try:
                bad = self.submit_raw(api, {"bad.xml": bad_scene}, "bad.xml")
            except grpc.RpcError as e:
                self.assertEqual(e.code(), S.INVALID_ARGUMENT, e.details())
            else:
                failed = api.wait_job(bad.id, states=[P.JOB_STATE_FAILED], timeout=30)
                self.assertTrue(failed.error, "a FAILED job without an error message")
        for w in workers:
            self.assertTrue(w.alive(), f"{w.name} died:\n{w.log_tail()}")
        self.assertTrue(c.server.alive(), "the server died")
        # And the queue still moves.
        job2 = api.submit(scene, algorithm="pt", iterations=8, resolution=RES, seed=SEED,
                          name="good-after-unloadable")
        api.wait_job(job2.id, timeout=60, procs=[c.server] + workers)


if __name__ == "__main__":
    cluster.main()
