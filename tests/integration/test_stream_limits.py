"""The bulk streams and the asset store are bounded (docs/guide/reliability.md,
"Streams and the asset store").

A client that opens an UploadAsset stream and then sends nothing held a server thread for as
long as it liked. The server now cancels a stream that sent or took no chunk for
--stream-idle-timeout seconds, and admits at most --max-transfer-streams clients' UploadAsset
and FetchResult streams at once (RESOURCE_EXHAUSTED past it). The asset store refuses, before a
byte is written, an asset larger than a job may use (--max-job-assets) and one that would grow
the store past --max-store-size. Real server, real gRPC client (Python)."""

import hashlib
import sys
import threading

sys.dont_write_bytecode = True  # keep the source tree clean
import cluster  # noqa: E402

IDLE_SECONDS = 5


class StreamLimits(cluster.ClusterTestCase):
    def start(self):
        c = self.new_cluster(server_args=[
            "--stream-idle-timeout", str(IDLE_SECONDS), "--max-transfer-streams", "2",
            "--max-job-assets", "1K", "--max-store-size", "3K"])
        c.start_server()
        return c

    @staticmethod
    def idle_upload(api, first_chunk, release):
        """An UploadAsset stream that sends `first_chunk` (or nothing) and then waits for
        `release` without closing: a client holding the stream open."""
        def chunks():
            if first_chunk is not None:
                yield first_chunk
            release.wait()
        return api.jobs.UploadAsset.future(chunks(), metadata=api.metadata(), timeout=120)

    def test_idle_upload_streams_are_cancelled_and_bounded(self):
        import grpc
        P = cluster.pb()
        c = self.start()
        release = threading.Event()
        try:
            data = b"x" * 100
            digest = hashlib.sha256(data).hexdigest()
            # One stream sends half an asset then stalls; one never sends its first chunk.
            stalled = [
                self.idle_upload(c.api, P.AssetChunk(sha256=digest, size=100, data=data[:50]),
                                 release),
                self.idle_upload(c.api, None, release),
            ]
            # Both are open on the server (the third is refused) until the watchdog cancels
            # them; then the server's threads and places are free again.
            def third_refused():
                try:
                    c.api.upload_asset(b"third")
                except grpc.RpcError as e:
                    if e.code() == grpc.StatusCode.RESOURCE_EXHAUSTED:
                        return e
                    raise
                return None
            refused = cluster.wait_until(third_refused, timeout=30,
                                         what="a third stream refused while two are open")
            self.assertIn("more than 2 asset and result streams are open on this server "
                          "(server --max-transfer-streams 2)", refused.details())
            for f in stalled:
                # A bound for the test, not a measurement: the server cancels after IDLE_SECONDS.
                error = f.exception(timeout=60)
                self.assertIsNotNone(error, "an idle upload stream was not ended by the server")
                print(f"idle stream ended: {error.code()} {error.details()}")
                self.assertIn(error.code(), (grpc.StatusCode.CANCELLED,
                                             grpc.StatusCode.DEADLINE_EXCEEDED))
            c.server.wait_for_log("stream_idle_cancelled")
            # The places are free: an upload that sends its chunks goes through.
            reply = c.api.upload_asset(data)
            self.assertEqual(reply.sha256, digest)
            self.assertTrue(c.server.alive())
        finally:
            release.set()

    def test_asset_store_limits(self):
        import grpc
        c = self.start()
        # Per job (1 KiB): an asset of 1024 bytes is accepted, 1025 refused at its first chunk.
        c.api.upload_asset(b"a" * 1024)
        with self.assertRaises(grpc.RpcError) as too_big:
            c.api.upload_asset(b"b" * 1025)
        self.assertEqual(too_big.exception.code(), grpc.StatusCode.RESOURCE_EXHAUSTED)
        self.assertIn("asset of 1025 bytes exceeds the per-job size limit of 1024 bytes "
                      "(server --max-job-assets 1.0 KiB)", too_big.exception.details())
        # The whole store (3 KiB): two more assets of 1024 bytes fill it; one byte more is
        # refused, an asset it already holds is not.
        c.api.upload_asset(b"c" * 1024)
        c.api.upload_asset(b"d" * 1024)
        with self.assertRaises(grpc.RpcError) as full:
            c.api.upload_asset(b"e")
        self.assertEqual(full.exception.code(), grpc.StatusCode.RESOURCE_EXHAUSTED)
        print(full.exception.details())
        self.assertIn("the asset store is full: an asset of 1 B (1 bytes) does not fit beside "
                      "the 3.0 KiB stored", full.exception.details())
        self.assertIn("(server --max-store-size)", full.exception.details())
        c.api.upload_asset(b"c" * 1024)
        self.assertTrue(c.server.alive())


if __name__ == "__main__":
    cluster.main()
