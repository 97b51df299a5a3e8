#!/usr/bin/env python3
"""The container and deployment files parse and say what docs/operations.md promises.

usage: deploy_files_test.py SOURCE_DIR MLSREG_BINARY
No Docker engine or cluster runs here, so the checks are static, plus the one image build step
that runs anywhere: scripts/runtime-packages.sh on the real binary.
"""
import os
import re
import subprocess
import sys

import yaml

src, binary = sys.argv[1], sys.argv[2]
failures = []
checks = 0


def check(condition, what):
    global checks
    checks += 1
    if not condition:
        failures.append(what)


def load(path):
    with open(os.path.join(src, path)) as f:
        return yaml.safe_load(f)


# Dockerfile: multi-stage, same scripts as CI, non-root, port, volume, health check.
dockerfile = open(os.path.join(src, "Dockerfile")).read()
check(len(re.findall(r"^FROM ", dockerfile, re.M)) == 2, "Dockerfile has two stages")
check("scripts/install-deps.sh" in dockerfile and "scripts/build.sh" in dockerfile,
      "Dockerfile builds with the README/CI scripts")
check(re.search(r"^USER mlsreg", dockerfile, re.M), "Dockerfile runs as a non-root user")
check(re.search(r"^EXPOSE 50051 9464$", dockerfile, re.M), "Dockerfile exposes 50051 and 9464")
check("MLSREG_METRICS_LISTEN=0.0.0.0:9464" in dockerfile, "Dockerfile serves /metrics on 9464")
check(re.search(r"^VOLUME /var/lib/mlsreg", dockerfile, re.M), "Dockerfile declares the data volume")
check(re.search(r"^HEALTHCHECK .*\n?.*mlsreg\", \"health\"", dockerfile, re.M),
      "Dockerfile health check uses mlsreg health")
check('ENTRYPOINT ["mlsreg", "serve"]' in dockerfile, "Dockerfile entrypoint is the server")
check(re.search(r"^COPY --from=build /build/libmlsreg_transport.so "
                r"/usr/local/lib/mlsreg/libmlsreg_transport.so$", dockerfile, re.M),
      "Dockerfile installs the transport module where /usr/local/bin/mlsreg looks (../lib/mlsreg)")

# docker-compose: port, volume, health check, grace period longer than the drain.
compose = load("deploy/docker-compose.yml")
svc = compose["services"]["mlsreg"]
check("50051:50051" in svc["ports"], "compose publishes 50051")
check("127.0.0.1:9464:9464" in svc["ports"], "compose publishes /metrics on the host's loopback")
check(svc["environment"]["MLSREG_METRICS_LISTEN"] == "0.0.0.0:9464", "compose turns /metrics on")
check(any(v.endswith(":/var/lib/mlsreg") for v in svc["volumes"]), "compose mounts the data volume")
check("mlsreg-data" in compose["volumes"], "compose declares the named volume")
check(svc["healthcheck"]["test"][1:3] == ["mlsreg", "health"], "compose health check")
drain = int(svc["command"][svc["command"].index("--drain-seconds") + 1])
check(int(svc["stop_grace_period"].rstrip("s")) > drain, "compose grace period > drain")

# Kubernetes: every kustomization resource exists and parses.
kustomization = load("deploy/k8s/kustomization.yaml")
docs = {}
for resource in kustomization["resources"]:
    doc = load(os.path.join("deploy/k8s", resource))
    docs[doc["kind"]] = doc
check(set(docs) == {"ConfigMap", "Service", "StatefulSet", "HorizontalPodAutoscaler"},
      f"k8s resources: {sorted(docs)}")
sts = docs["StatefulSet"]["spec"]
container = sts["template"]["spec"]["containers"][0]
check(container["ports"][0]["containerPort"] == 50051, "k8s container port 50051")
check({"name": "metrics", "containerPort": 9464, "protocol": "TCP"} in container["ports"],
      "k8s container exposes the metrics port")
annotations = sts["template"]["metadata"].get("annotations", {})
check(annotations.get("prometheus.io/scrape") == "true" and
      annotations.get("prometheus.io/port") == "9464" and
      annotations.get("prometheus.io/path") == "/metrics", "k8s pods carry the scrape annotations")
for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
    check(container[probe].get("grpc", {}).get("port") == 50051, f"k8s {probe} is a gRPC probe on 50051")
check(any(m["mountPath"] == "/var/lib/mlsreg" for m in container["volumeMounts"]), "k8s mounts the data volume")
check(sts["volumeClaimTemplates"][0]["metadata"]["name"] == "data", "k8s claims per-replica storage")
config = docs["ConfigMap"]["data"]
check(config.get("MLSREG_METRICS_LISTEN") == "0.0.0.0:9464", "k8s config turns /metrics on")
check(sts["template"]["spec"]["terminationGracePeriodSeconds"] > int(config["MLSREG_DRAIN_SECONDS"]),
      "k8s grace period > drain")
service = docs["Service"]["spec"]
check(service["clusterIP"] == "None" and service["ports"][0]["port"] == 50051, "k8s headless service on 50051")
hpa = docs["HorizontalPodAutoscaler"]["spec"]
check(hpa["scaleTargetRef"]["kind"] == "StatefulSet" and hpa["scaleTargetRef"]["name"] == "mlsreg",
      "HPA scales the StatefulSet")
overlay = load("deploy/k8s/overlays/tls/kustomization.yaml")
check(overlay["resources"] == ["../.."], "TLS overlay builds on the base")
for doc in yaml.safe_load_all(open(os.path.join(src, "deploy/k8s/secret.example.yaml"))):
    check(doc["kind"] == "Secret", "example secret parses")

# The runtime image installs exactly the packages owning the libraries of the binary and of the
# transport module beside it.
module = os.path.join(os.path.dirname(binary), "libmlsreg_transport.so")
packages = subprocess.run(["bash", os.path.join(src, "scripts/runtime-packages.sh"), binary, module],
                          check=True, capture_output=True, text=True).stdout.split()
check("libgrpc++1.51" in packages and "libprotobuf32" in packages,
      f"runtime packages include gRPC and protobuf: {packages}")
check("libcivetweb1" in packages, f"runtime packages include civetweb (/metrics): {packages}")

for f in failures:
    print("FAIL:", f)
print(f"{checks - len(failures)} passed, {len(failures)} failed")
sys.exit(1 if failures else 0)
