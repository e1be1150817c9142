"""Offline schema check of deploy/kubernetes/**/*.yaml (the one-server manifests and the farm's
in deploy/kubernetes/farm/) against the Kubernetes API's object models.

No API server is needed: the models come from Debian's python3-kubernetes (the generated
client of the Kubernetes API; 22.6.0 in Debian 12 = the API of Kubernetes 1.22). Each model
class lists its fields with their JSON names and types (`attribute_map`, `openapi_types`), and
its constructor refuses a missing required field and, for some fields, values outside the
allowed set. For every document of every manifest this checks:
* apiVersion/kind name a known API object;
* every field name exists at its place (a typo like `containerport` or a field at the wrong
  level is an error), recursively through every nested object, list and map;
* every value has its field's type (string, integer, boolean, object, list, map);
* every required field is present (the model's constructor);
* enumerated strings (imagePullPolicy, protocol, Service type, ...; `ENUMS`) hold an allowed
  value.

Fields newer than Kubernetes 1.22 are checked against a hand-written definition taken from the
Kubernetes API reference (`NEWER_FIELDS`): only the gRPC probe (`grpc: {port, service}`,
Kubernetes 1.24+), which the server's probes use.

Not checked (what only an API server or a kubelet would tell): values' formats and ranges
(quantities like `512Mi`, port ranges, DNS names), defaulting, admission (pod security), that
referenced Secrets/PVCs exist, and anything at run time.

    /usr/bin/python3 tests/deploy/check_kubernetes_manifests.py --source-dir .
    /usr/bin/python3 tests/deploy/check_kubernetes_manifests.py --source-dir . --self-test

Exit status 0 when every manifest passes (with --self-test: when every planted error is
found), 1 otherwise, 77 (CTest's skip) without python3-kubernetes or python3-yaml.
"""

import argparse
import copy
import glob
import os
import re
import sys

try:
    import yaml
    from kubernetes import client as k8s
except ImportError as e:  # pragma: no cover - depends on the machine
    print(f"SKIP: {e} (Debian packages python3-kubernetes and python3-yaml; scripts/setup "
          "installs them)")
    sys.exit(77)

# apiVersion and kind of the objects the manifests may hold, and their model classes.
KINDS = {
    ("v1", "Namespace"): "V1Namespace",
    ("v1", "Secret"): "V1Secret",
    ("v1", "Service"): "V1Service",
    ("v1", "ConfigMap"): "V1ConfigMap",
    ("v1", "PersistentVolumeClaim"): "V1PersistentVolumeClaim",
    ("apps/v1", "StatefulSet"): "V1StatefulSet",
    ("apps/v1", "Deployment"): "V1Deployment",
}

# Fields added to the API after Kubernetes 1.22 (the models' version), from the API reference:
# model -> {JSON field: (type, required fields of a nested object or None)}.
NEWER_FIELDS = {
    # io.k8s.api.core.v1.Probe.grpc (Kubernetes 1.24 beta, 1.27 GA): GRPCAction
    "V1Probe": {"grpc": {"port": ("int", True), "service": ("str", False)}},
}


# Enumerated string fields (the API reference's allowed values; the 1.22 models check none of
# these): (model, JSON field) -> allowed values.
ENUMS = {
    ("V1Container", "imagePullPolicy"): {"Always", "IfNotPresent", "Never"},
    ("V1ContainerPort", "protocol"): {"TCP", "UDP", "SCTP"},
    ("V1ServicePort", "protocol"): {"TCP", "UDP", "SCTP"},
    ("V1ServiceSpec", "type"): {"ClusterIP", "NodePort", "LoadBalancer", "ExternalName"},
    ("V1PodSpec", "restartPolicy"): {"Always", "OnFailure", "Never"},
    ("V1DeploymentStrategy", "type"): {"RollingUpdate", "Recreate"},
    ("V1StatefulSetSpec", "podManagementPolicy"): {"OrderedReady", "Parallel"},
    ("V1StatefulSetUpdateStrategy", "type"): {"RollingUpdate", "OnDelete"},
    ("V1PersistentVolumeClaimSpec", "accessModes"):
        {"ReadWriteOnce", "ReadOnlyMany", "ReadWriteMany", "ReadWriteOncePod"},
    ("V1SeccompProfile", "type"): {"RuntimeDefault", "Unconfined", "Localhost"},
}


class Checker:
    def __init__(self):
        self.errors = []

    def error(self, where, message):
        self.errors.append(f"{where}: {message}")

    def check_document(self, doc, where):
        if not isinstance(doc, dict):
            self.error(where, "a document must be a mapping")
            return
        key = (doc.get("apiVersion"), doc.get("kind"))
        model = KINDS.get(key)
        if not model:
            self.error(where, f"unknown apiVersion/kind {key[0]}/{key[1]}")
            return
        name = (doc.get("metadata") or {}).get("name", "?")
        self.value(doc, model, f"{where} {key[1]}/{name}")

    def value(self, value, type_name, path):
        """Checks `value` against the model type `type_name`; returns a value for the
        parent's constructor (a model object for models, so required fields are checked)."""
        if type_name == "str" or type_name == "datetime":
            if not isinstance(value, str):
                self.error(path, f"expected a string, got {type(value).__name__} {value!r}")
            return value
        if type_name == "int":
            if not isinstance(value, int) or isinstance(value, bool):
                self.error(path, f"expected an integer, got {type(value).__name__} {value!r}")
            return value
        if type_name == "float":
            if not isinstance(value, (int, float)) or isinstance(value, bool):
                self.error(path, f"expected a number, got {type(value).__name__} {value!r}")
            return value
        if type_name == "bool":
            if not isinstance(value, bool):
                self.error(path, f"expected true/false, got {type(value).__name__} {value!r}")
            return value
        if type_name == "object":  # IntOrString and free-form values
            return value
        m = re.fullmatch(r"list\[(.+)\]", type_name)
        if m:
            if not isinstance(value, list):
                self.error(path, f"expected a list, got {type(value).__name__}")
                return value
            return [self.value(v, m.group(1), f"{path}[{i}]") for i, v in enumerate(value)]
        m = re.fullmatch(r"dict\(str, (.+)\)", type_name)
        if m:
            if not isinstance(value, dict):
                self.error(path, f"expected a mapping, got {type(value).__name__}")
                return value
            inner = m.group(1)
            out = {}
            for k, v in value.items():
                if not isinstance(k, str):
                    self.error(path, f"map key {k!r} is not a string")
                # Resource quantities (requests/limits) may be written as plain numbers.
                if inner == "str" and re.search(r"\.(limits|requests)$", path) and \
                        isinstance(v, (int, float)) and not isinstance(v, bool):
                    out[k] = str(v)
                    continue
                out[k] = self.value(v, inner, f"{path}.{k}")
            return out
        return self.model(value, type_name, path)

    def model(self, value, model_name, path):
        cls = getattr(k8s, model_name, None)
        if cls is None:
            self.error(path, f"no model {model_name} in python3-kubernetes")
            return None
        if not isinstance(value, dict):
            self.error(path, f"expected an object ({model_name}), got {type(value).__name__}")
            return None
        by_json = {j: p for p, j in cls.attribute_map.items()}
        newer = NEWER_FIELDS.get(model_name, {})
        kwargs = {}
        for key, v in value.items():
            here = f"{path}.{key}"
            if key in by_json:
                attr = by_json[key]
                kwargs[attr] = self.value(v, cls.openapi_types[attr], here)
                allowed = ENUMS.get((model_name, key))
                for item in (v if isinstance(v, list) else [v]):
                    if allowed and item not in allowed:
                        self.error(here, f"{item!r} is not one of {', '.join(sorted(allowed))}")
            elif key in newer:
                self.newer_field(v, newer[key], here)
            else:
                self.error(here, f"unknown field {key!r} of {model_name} (fields: "
                                 f"{', '.join(sorted(by_json))})")
        try:
            return cls(**kwargs)
        except (ValueError, TypeError) as e:
            self.error(path, f"{model_name}: {e}")
            return None

    def newer_field(self, value, fields, path):
        if not isinstance(value, dict):
            self.error(path, "expected an object")
            return
        for key, v in value.items():
            if key not in fields:
                self.error(f"{path}.{key}", f"unknown field {key!r} (fields: "
                                            f"{', '.join(sorted(fields))})")
                continue
            self.value(v, fields[key][0], f"{path}.{key}")
        for key, (_, required) in fields.items():
            if required and key not in value:
                self.error(path, f"required field {key!r} is missing")


def manifest_name(path, source_dir):
    """A manifest's path under deploy/kubernetes/ (farm/server-statefulset.yaml)."""
    return os.path.relpath(path, os.path.join(source_dir, "deploy", "kubernetes"))


def check_files(files, source_dir):
    checker = Checker()
    documents = 0
    for path in files:
        with open(path) as f:
            try:
                docs = [d for d in yaml.safe_load_all(f) if d is not None]
            except yaml.YAMLError as e:
                checker.error(manifest_name(path, source_dir), f"not YAML: {e}")
                continue
        for i, doc in enumerate(docs):
            documents += 1
            checker.check_document(doc, f"{manifest_name(path, source_dir)}#{i}")
    return checker.errors, documents


def self_test(files, source_dir):
    """Plants one error at a time into the manifests; each must be reported."""
    loaded = {p: [d for d in yaml.safe_load_all(open(p)) if d] for p in files}
    def container(doc):
        return doc["spec"]["template"]["spec"]["containers"][0]

    # A server's StatefulSet (the one with gRPC probes), and a Deployment.
    sts = next(d for ds in loaded.values() for d in ds
               if d["kind"] == "StatefulSet" and "livenessProbe" in container(d))
    dep = next(d for ds in loaded.values() for d in ds if d["kind"] == "Deployment")

    plants = {
        "misspelt field": lambda: container(sts)["ports"][0].update(containerport=1),
        "field at the wrong level": lambda: sts["spec"].update(containers=[]),
        "string for an integer": lambda: sts["spec"].update(replicas="1"),
        "integer for a string": lambda: container(dep).update(image=5),
        "mapping for a list": lambda: container(dep).update(args={"a": "b"}),
        "missing required container name": lambda: container(dep).pop("name"),
        "missing required selector": lambda: dep["spec"].pop("selector"),
        "unknown kind": lambda: dep.update(kind="Deploymnet"),
        "bad gRPC probe field": lambda: container(sts)["livenessProbe"]["grpc"].update(prot=1),
        "gRPC probe without port": lambda: container(sts)["readinessProbe"]["grpc"].pop("port"),
        "bad enum value": lambda: container(dep).update(imagePullPolicy="Sometimes"),
    }
    failures = 0
    for name, plant in plants.items():
        original = (copy.deepcopy(sts), copy.deepcopy(dep))
        plant()
        checker = Checker()
        for path, docs in loaded.items():
            for i, doc in enumerate(docs):
                checker.check_document(doc, f"{manifest_name(path, source_dir)}#{i}")
        sts.clear(), sts.update(original[0])
        dep.clear(), dep.update(original[1])
        if checker.errors:
            print(f"found  {name}: {checker.errors[0]}")
        else:
            print(f"MISSED {name}")
            failures += 1
    return failures


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source-dir", default=".")
    parser.add_argument("--self-test", action="store_true")
    args = parser.parse_args()
    files = sorted(glob.glob(os.path.join(args.source_dir, "deploy", "kubernetes", "**", "*.yaml"),
                             recursive=True))
    if not files:
        print("no manifests in deploy/kubernetes/")
        return 1
    print(f"python3-kubernetes {getattr(k8s, '__version__', '?')} models")
    if args.self_test:
        failures = self_test(files, args.source_dir)
        print(f"{failures} planted errors missed")
        return 1 if failures else 0
    errors, documents = check_files(files, args.source_dir)
    for e in errors:
        print(e)
    print(f"{len(files)} files, {documents} documents, {len(errors)} errors")
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
