#!/usr/bin/python3
"""Writes the seed corpora of the fuzz targets (tests/fuzz/corpus/NAME/seed-*) from the shipped
scenes (scenes/, tests/data/mitsuba/) and, for `request`, protobuf messages (Debian's python3
with python3-protobuf, and protoc). Run it from anywhere; it replaces the seed-* files and
leaves every other file (regression inputs, finding-*) alone.

A scene seed holds the scene and the files it reads, in the multi-file form of
tests/fuzz/fuzz_files.h ("@@@ NAME" lines). Files larger than MAX_ASSET bytes are replaced by a
tiny file of the same kind (a one-triangle PLY, a 2x2x2 .vol), so that seeds stay small but the
scene still loads; other missing files (textures) stay missing."""

import hashlib
import importlib
import pathlib
import re
import struct
import subprocess
import sys
import tempfile
import zlib

ROOT = pathlib.Path(__file__).resolve().parents[2]
CORPUS = ROOT / "tests" / "fuzz" / "corpus"
MAX_ASSET = 8 * 1024

XML_REF = re.compile(r'(?:filename"\s+value|<include\s+filename)="([^"$]+)"')
PBRT_REF = re.compile(r'(?:"string filename"\s*\[?\s*|Include\s+|Import\s+)"([^"]+)"')


def tiny_ply():
    header = ("ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
              "property float x\nproperty float y\nproperty float z\n"
              "element face 1\nproperty list uchar int vertex_indices\nend_header\n")
    body = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + struct.pack("<B3i", 3, 0, 1, 2)
    return header.encode() + body


def tiny_vol(channels=1):
    header = b"VOL" + bytes([3]) + struct.pack("<5i", 1, 2, 2, 2, channels)
    header += struct.pack("<6f", 0, 0, 0, 1, 1, 1)
    return header + struct.pack("<%df" % (8 * channels), *[0.5] * (8 * channels))


def tiny_serialized(version=4, double=False):
    """Two meshes in Mitsuba's serialized format: a quad with normals and uv, a triangle."""
    real = "d" if double else "f"
    meshes = [
        (0x1 | 0x2, b"quad", [0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0], [0, 0, 1] * 4,
         [0, 0, 1, 0, 1, 1, 0, 1], [0, 1, 2, 0, 2, 3]),
        (0x10, b"tri", [0, 0, 0, 1, 0, 0, 0, 1, 0], [], [], [0, 1, 2]),
    ]
    out, offsets = b"", []
    for flags, name, positions, normals, uvs, indices in meshes:
        raw = struct.pack("<I", flags | (0x2000 if double else 0x1000))
        if version == 4:
            raw += name + b"\0"
        raw += struct.pack("<QQ", len(positions) // 3, len(indices) // 3)
        values = positions + normals + uvs
        raw += struct.pack("<%d%s" % (len(values), real), *values)
        raw += struct.pack("<%dI" % len(indices), *indices)
        offsets.append(len(out))
        out += struct.pack("<HH", 0x041C, version) + zlib.compress(raw, 9)
    out += b"".join(struct.pack("<Q" if version == 4 else "<I", o) for o in offsets)
    return out + struct.pack("<I", len(offsets))


def scene_seed(main):
    """The multi-file seed of one scene file."""
    base = main.parent
    parts = [main.read_bytes()]
    seen = set()
    todo = [main]
    while todo:
        current = todo.pop()
        text = current.read_text(errors="replace")
        pattern = PBRT_REF if current.suffix == ".pbrt" else XML_REF
        for name in pattern.findall(text):
            path = (current.parent / name).resolve()
            if not path.is_file():  # Mitsuba looks in the main scene's folder next
                path = (base / name).resolve()
            try:
                rel = path.relative_to(base.resolve()).as_posix()
            except ValueError:
                continue
            if rel in seen or not path.is_file():
                continue
            seen.add(rel)
            data = path.read_bytes()
            if len(data) > MAX_ASSET:
                if path.suffix == ".ply":
                    data = tiny_ply()
                elif path.suffix == ".vol":
                    data = tiny_vol(3 if "radiance" in path.name else 1)
                else:
                    continue
            parts.append(b"@@@ " + rel.encode() + b"\n" + data)
            if path.suffix in (".xml", ".pbrt"):
                todo.append(path)
    return b"\n".join(parts)


def write(target, name, data):
    folder = CORPUS / target
    folder.mkdir(parents=True, exist_ok=True)
    (folder / ("seed-" + name)).write_bytes(data)


def seed_name(path):
    return "-".join(path.relative_to(ROOT).with_suffix("").parts[1:])


def main():
    for folder in CORPUS.glob("*"):
        for old in folder.glob("seed-*"):
            old.unlink()
    xml = sorted((ROOT / "scenes").rglob("*.xml")) + [ROOT / "tests/data/mitsuba/scene.xml"]
    for scene in xml:
        if "include" in scene.parent.name:
            continue
        write("mitsuba_xml", seed_name(scene) + ".xml", scene_seed(scene))
    for scene in sorted((ROOT / "scenes").rglob("*.pbrt")):
        write("pbrt", seed_name(scene) + ".pbrt", scene_seed(scene))
    for mesh in sorted((ROOT / "scenes").rglob("*.obj")) + [ROOT / "tests/data/mitsuba/assets/tri.obj"]:
        if "smallupbp" not in mesh.parts:  # smallvcm has the same meshes
            write("obj", seed_name(mesh) + ".obj", mesh.read_bytes())
    plys = [p for p in sorted((ROOT / "scenes").rglob("*.ply")) if p.stat().st_size <= MAX_ASSET]
    for mesh in plys[:6]:
        write("ply", seed_name(mesh) + ".ply", mesh.read_bytes())
    write("ply", "tiny-binary.ply", tiny_ply())
    write("ply", "tiny-ascii.ply", b"ply\nformat ascii 1.0\nelement vertex 4\n"
          b"property float x\nproperty float y\nproperty float z\nproperty float u\n"
          b"property float v\nelement face 1\nproperty list uchar int vertex_indices\n"
          b"end_header\n0 0 0 0 0\n1 0 0 1 0\n1 1 0 1 1\n0 1 0 0 1\n4 0 1 2 3\n")
    write("serialized", "two-meshes-v4.serialized", tiny_serialized(4))
    write("serialized", "two-meshes-v3-double.serialized", tiny_serialized(3, True))
    write("vol", "grey.vol", tiny_vol(1))
    write("vol", "rgb.vol", tiny_vol(3))

    # bundle_path: scenes with files (Mitsuba; pbrt when the input starts with '#') and paths.
    for name in ("smallupbp-isosph.xml", "data-mitsuba-scene.xml", "tests-flame.xml"):
        write("bundle_path", name, (CORPUS / "mitsuba_xml" / ("seed-" + name)).read_bytes())
    write("bundle_path", "cornell.pbrt", b"# a pbrt scene\n" +
          (CORPUS / "pbrt" / "seed-bitterli-pbrt-cornell-box-scene-v4.pbrt").read_bytes())
    for i, path in enumerate([b"meshes/floor.obj", b"a/../../b", b"./x", b"a//b", b"/etc/passwd"]):
        write("bundle_path", "path-%d" % i, path)

    request_seeds()


# The scene that request_fuzz.cpp puts in its asset store (kSceneXml there).
SCENE_XML = (
    '<scene version="3.0.0">\n'
    '  <sensor type="perspective">\n'
    '    <transform name="to_world"><lookat origin="0,0,5" target="0,0,0" up="0,1,0"/></transform>\n'
    '    <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/></film>\n'
    '  </sensor>\n'
    '  <shape type="sphere"/>\n'
    '  <emitter type="point"><point name="position" value="0,0,3"/></emitter>\n'
    '</scene>\n').encode()


def request_seeds():
    """One seed per message kind of request_fuzz.cpp: the kind byte, then the message."""
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(["protoc", "-I", str(ROOT / "proto"), "--python_out", tmp,
                        str(ROOT / "proto" / "render.proto")], check=True)
        sys.path.insert(0, tmp)
        pb = importlib.import_module("render_pb2")
    sha = hashlib.sha256(SCENE_XML).hexdigest()
    submit = pb.SubmitJobRequest(name="fuzz", priority=1)
    submit.bundle.scene_path = "scene.xml"
    submit.bundle.files.add(path="scene.xml", sha256=sha, size=len(SCENE_XML))
    submit.settings.algorithm = "pt"
    submit.settings.iterations = 4
    submit.settings.options["seed"] = "7"
    submit.frames.add().defines["x"] = "1"
    seeds = {
        "submit": (0, submit),
        "get": (1, pb.GetJobRequest(job_id="job-1")),
        "cancel": (2, pb.CancelJobRequest(job_id="job-1")),
        "has-assets": (3, pb.HasAssetsRequest(sha256=[sha, "00"])),
        "fetch": (4, pb.FetchResultRequest(job_id="job-1", frame=0, preview=True)),
        "register": (5, pb.RegisterWorkerRequest(host="h", threads=2, version="1")),
        "lease": (6, pb.LeaseRequest(worker_id="w-1")),
        "heartbeat": (7, pb.HeartbeatRequest(worker_id="w-1", lease_ids=["l-1"],
                                             failed_leases=[pb.LeaseFailure(lease_id="l-2",
                                                                            error="e")])),
        "report": (8, pb.ReportHeader(lease_id="l-1", count=2, odd_count=1, width=16,
                                      height=16)),
        "cluster": (9, pb.ClusterStatusRequest()),
        "delete": (10, pb.DeleteJobRequest(job_id="job-1")),
        "heartbeat-memory": (7, pb.HeartbeatRequest(
            worker_id="w-1", failed_leases=[pb.LeaseFailure(lease_id="l-2", error="e",
                                                            memory_needed=2 << 20,
                                                            memory_limit=1 << 20)])),
    }
    for name, (kind, message) in seeds.items():
        write("request", name, bytes([kind]) + message.SerializeToString())


if __name__ == "__main__":
    main()
