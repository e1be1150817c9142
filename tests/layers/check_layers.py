#!/usr/bin/env python3
"""Checks that every #include follows the layer order of docs/design/architecture.md.

A file may include headers of its own layer or of a lower one, never of a higher one; the
applications at the top (tools, server, worker, client, bench) may not include one another.
Run from anywhere:  check_layers.py --source-dir DIR   (exit 1 and one line per violation)
                    check_layers.py --source-dir DIR --self-test
The self-test plants wrong includes (in memory) and fails unless each one is reported.
"""
import argparse
import os
import re
import sys

# (folder prefix, layer). The longest matching prefix decides. Keep in step with
# docs/design/architecture.md.
LAYERS = [
    ("core/util/", 0, "util"),
    ("core/math/", 0, "math"),
    ("core/sampling/", 1, "sampling"),
    ("core/base/", 2, "base"),
    ("core/image/", 2, "image"),
    ("core/camera/", 3, "plugins"),
    ("core/materials/", 3, "plugins"),
    ("core/lights/", 3, "plugins"),
    ("core/media/", 3, "plugins"),
    ("core/shapes/", 3, "plugins"),
    ("core/mesh_io/", 3, "plugins"),
    ("core/textures/", 3, "plugins"),
    ("core/scene/", 4, "scene"),
    ("core/integrators/", 5, "integrators"),
    ("core/render/", 6, "render"),
    ("<generated>/", 7, "proto"),
    ("service/", 7, "service"),
    ("tools/", 8, "app:tools"),
    ("server/", 8, "app:server"),
    ("worker/", 8, "app:worker"),
    ("client/", 8, "app:client"),
    ("bench/", 8, "app:bench"),
    ("tests/", 9, "tests"),
]
SOURCE_FOLDERS = ["core", "service", "tools", "server", "worker", "client", "bench", "tests"]
EXTENSIONS = (".h", ".hpp", ".cpp", ".cc")
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')


def layer_of(path):
    best = None
    for prefix, level, name in LAYERS:
        if path.startswith(prefix) and (best is None or len(prefix) > len(best[0])):
            best = (prefix, level, name)
    return best


def resolve(include, including_file, files):
    """The repository path an include names: root-relative, or next to the including file;
    a bare name that is not a file of the tree is generated code (the protobuf stubs)."""
    if include in files:
        return include
    sibling = os.path.normpath(os.path.join(os.path.dirname(including_file), include))
    if sibling in files:
        return sibling
    if "/" not in include and include.endswith((".pb.h", ".grpc.pb.h")):
        return "<generated>/" + include
    return None


def collect(source_dir):
    files = {}
    for folder in SOURCE_FOLDERS:
        for root, _, names in os.walk(os.path.join(source_dir, folder)):
            for name in names:
                if name.endswith(EXTENSIONS):
                    full = os.path.join(root, name)
                    rel = os.path.relpath(full, source_dir).replace(os.sep, "/")
                    with open(full, encoding="utf-8", errors="replace") as f:
                        files[rel] = [m.group(1) for m in map(INCLUDE.match, f) if m]
    return files


def violations(files):
    found = []
    for path, includes in sorted(files.items()):
        here = layer_of(path)
        if here is None:
            found.append(f"{path}: not in any layer of check_layers.py (add its folder)")
            continue
        for include in includes:
            target = resolve(include, path, files)
            if target is None:
                continue  # a system or third-party header written with quotes
            there = layer_of(target)
            if there is None:
                found.append(f"{path}: includes {include}, which is in no layer")
            elif there[1] > here[1]:
                found.append(f"{path} ({here[2]}, layer {here[1]}) includes {include} "
                             f"({there[2]}, layer {there[1]}): a lower layer may not use a "
                             f"higher one")
            elif there[1] == here[1] and here[2].startswith("app:") and there[2] != here[2]:
                found.append(f"{path} ({here[2]}) includes {include} ({there[2]}): applications "
                             f"share code through service/ or core/, not each other")
    return found


def self_test(files):
    plants = [
        ("core/math/vec.h", "core/scene/scene.h"),  # upward, across several layers
        ("core/media/medium.h", "core/integrators/integrator.h"),  # plugin -> integrators
        ("core/integrators/integrator.h", "core/render/render_options.h"),  # one layer up
        ("client/main.cpp", "worker/worker.h"),  # application -> application
    ]
    ok = True
    for file, include in plants:
        if file not in files or include not in files:
            print(f"self-test: {file} or {include} does not exist; update the plants")
            ok = False
            continue
        planted = dict(files)
        planted[file] = files[file] + [include]
        found = [v for v in violations(planted) if v.startswith(file) and include in v]
        print(f"self-test: planted {include} in {file}: "
              f"{'reported' if found else 'NOT REPORTED'}")
        ok &= bool(found)
    return ok


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--source-dir", default=os.path.join(os.path.dirname(__file__), "..", ".."))
    parser.add_argument("--self-test", action="store_true")
    args = parser.parse_args()
    files = collect(os.path.abspath(args.source_dir))
    if args.self_test:
        clean = violations(files)
        for v in clean:
            print("self-test: the tree itself has a violation:", v)
        ok = self_test(files) and not clean
        print("self-test", "passed" if ok else "FAILED")
        return 0 if ok else 1
    found = violations(files)
    for v in found:
        print(v)
    print(f"{len(files)} files checked, {len(found)} layer violations")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
