"""Integration test 6: an independent client that uses nothing but the stubs generated from
proto/ (and the standard grpc.health.v1 service): uploads the scene's assets by sha256, submits
a job, watches it with the WatchJob stream until it is done, fetches the EXR with FetchResult
chunks, and checks that the health service reports SERVING."""

import hashlib

import grpc

import sys

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

SEED = 21
ALGO = "vcm"
ITERATIONS = 32
RES = (32, 32)


class PythonClient(cluster.ClusterTestCase):
    def test_submit_watch_fetch_health(self):
        c = self.new_cluster(heartbeat=0.5)
        c.start_server()
        workers = c.start_workers(2, threads=1)
        s = cluster.stubs()
        P, H = s["pb"], s["hpb"]

        # Everything below talks to the server through a channel of its own.
        channel = grpc.insecure_channel(c.address)
        self.addCleanup(channel.close)
        jobs = s["rpc"].JobServiceStub(channel)
        health = s["hrpc"].HealthStub(channel)

        # Health.
        reply = health.Check(H.HealthCheckRequest(service=""), timeout=10)
        self.assertEqual(reply.status, H.HealthCheckResponse.SERVING)

        # Upload the bundle's assets (only the missing ones), then submit.
        scene = cluster.cornell_box()
        files, scene_path = cluster.scene_bundle_files(scene)
        hashes = {p: hashlib.sha256(d).hexdigest() for p, d in files.items()}
        missing = jobs.HasAssets(P.HasAssetsRequest(sha256=list(hashes.values())),
                                 timeout=10).missing
        for path, data in files.items():
            if hashes[path] not in missing:
                continue
            chunks = [P.AssetChunk(sha256=hashes[path], size=len(data),
                                   data=data[:cluster.CHUNK])]
            chunks += [P.AssetChunk(data=data[i:i + cluster.CHUNK])
                       for i in range(cluster.CHUNK, len(data), cluster.CHUNK)]
            stored = jobs.UploadAsset(iter(chunks), timeout=30)
            self.assertEqual(stored.sha256, hashes[path])
            self.assertEqual(stored.size, len(data))
        self.assertEqual(list(jobs.HasAssets(P.HasAssetsRequest(
            sha256=list(hashes.values())), timeout=10).missing), [])
        bundle = P.SceneBundle(scene_path=scene_path, files=[
            P.BundleFile(path=p, sha256=hashes[p], size=len(files[p])) for p in files])
        settings = P.RenderSettings(algorithm=ALGO, iterations=ITERATIONS, width=RES[0],
                                    height=RES[1], seed=SEED)
        job = jobs.SubmitJob(P.SubmitJobRequest(name="python-client", bundle=bundle,
                                                settings=settings), timeout=30)
        self.assertTrue(job.id)
        self.assertIn(job.state, (P.JOB_STATE_QUEUED, P.JOB_STATE_RUNNING))
        self.assertEqual(job.settings.algorithm, ALGO)
        self.assertEqual(job.settings.iterations, ITERATIONS)

        # Watch until the stream ends (the job is done); bounded by the call's deadline.
        events = []
        last_done = 0
        for event in jobs.WatchJob(P.WatchJobRequest(job_id=job.id), timeout=90):
            events.append(event)
            self.assertEqual(event.job.id, job.id)
            if event.job.frames:
                done = event.job.frames[0].iterations_done
                self.assertGreaterEqual(done, last_done, "progress went backwards")
                self.assertLessEqual(done, ITERATIONS)
                last_done = done
            if len(events) > 100000:
                self.fail("WatchJob sent an unbounded number of events")
        self.assertTrue(events, "WatchJob sent no event")
        final = events[-1].job
        self.assertEqual(final.state, P.JOB_STATE_DONE, str(final))
        self.assertEqual(final.frames[0].iterations_done, ITERATIONS)
        self.assertTrue(final.frames[0].done)
        print(f"{len(events)} WatchJob events; states "
              f"{sorted({P.JobState.Name(e.job.state) for e in events})}")

        # The job is listed.
        listed = jobs.ListJobs(P.ListJobsRequest(), timeout=10)
        self.assertIn(job.id, [j.id for j in listed.jobs])

        # Fetch the EXR in chunks.
        data = bytearray()
        total = None
        n = 0
        for chunk in jobs.FetchResult(P.FetchResultRequest(job_id=job.id, frame=0),
                                      timeout=60):
            n += 1
            self.assertLessEqual(len(chunk.data), cluster.CHUNK)
            if chunk.total_size:
                total = chunk.total_size
            data += chunk.data
        self.assertGreater(len(data), 0)
        if total is not None:
            self.assertEqual(total, len(data))
        self.assertEqual(bytes(data[:4]), b"\x76\x2f\x31\x01", "not an OpenEXR file")
        out = c.path("client.exr")
        with open(out, "wb") as f:
            f.write(data)
        print(f"fetched {len(data)} bytes in {n} chunks")
        ref = cluster.render_reference(scene, ALGO, ITERATIONS, RES, SEED)
        print(self.assertImagesMatch(out, ref))

        # Watching a finished job ends at once with its final state.
        again = list(jobs.WatchJob(P.WatchJobRequest(job_id=job.id), timeout=20))
        self.assertTrue(again and again[-1].job.state == P.JOB_STATE_DONE,
                        "WatchJob of a done job did not end with DONE")

        # Health once more after the work.
        reply = health.Check(H.HealthCheckRequest(service=""), timeout=10)
        self.assertEqual(reply.status, H.HealthCheckResponse.SERVING)
        for w in workers:
            self.assertTrue(w.alive(), f"{w.name} died")


if __name__ == "__main__":
    cluster.main()
