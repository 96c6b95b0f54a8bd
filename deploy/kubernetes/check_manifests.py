#!/usr/bin/env python3
"""Checks deploy/kubernetes without a cluster, as far as can be.

1. Static: every manifest parses; pods run as non-root (runAsNonRoot, a non-zero runAsUser equal to the
   image's USER uid) with a read-only root filesystem, no privilege escalation, all capabilities dropped;
   the coordinator's data volume gets an fsGroup; readiness/liveness (and startup) probes use the gRPC
   health protocol on the port the container's --health flag serves; workers take their threads from
   their CPU limit (no --threads, a cpu limit set); workers dial a Service of their namespace whose port
   exists; every flag in the args is one the binary's --help lists; `kubectl kustomize` renders it.
2. Certificates: make-secrets.sh writes a certificate that verifies (openssl verify -verify_hostname)
   for the host the workers dial and for the Service's FQDN.
3. Rehearsal (root only, --rehearse): the coordinator and a worker are started with the manifests' own
   args (paths of mounted volumes mapped to a temp dir) in two network namespaces, the worker resolving
   `bistable-coordinator` through the namespace's /etc/hosts as cluster DNS would; the probes' gRPC health
   checks answer SERVING, a sweep submitted with a client token completes over TLS, and the worker's
   metrics endpoint answers.

Usage: check_manifests.py REPO BUILD_DIR [--rehearse]   (exit 0: all checks pass; 77: skipped)
"""
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

try:
    import yaml
except ImportError:
    print("SKIP: python3-yaml is not installed (scripts/setup.sh installs it)")
    sys.exit(77)

repo, build = sys.argv[1], sys.argv[2]
rehearse = "--rehearse" in sys.argv[3:]
kdir = os.path.join(repo, "deploy", "kubernetes")
bin_cli = os.path.join(build, "client", "bistable")
bins = {"coordinator": os.path.join(build, "server", "bistable-coordinator"),
        "worker": os.path.join(build, "worker", "bistable-worker")}
rows = []


def check(name, ok, detail=""):
    rows.append((name, bool(ok), detail))
    return ok


docs = [d for d in yaml.safe_load_all(open(os.path.join(kdir, "bistable.yaml"))) if d]
check("manifests parse", len(docs) >= 5, f"{len(docs)} objects")
by_kind = {}
for d in docs:
    by_kind.setdefault(d["kind"], []).append(d)
services = {(s["metadata"].get("namespace", "default"), s["metadata"]["name"]): s for s in by_kind.get("Service", [])}

m = re.search(r"^USER\s+(\S+)", open(os.path.join(repo, "deploy", "container", "Containerfile")).read(), re.M)
image_user = m.group(1).split(":")[0] if m else None

help_text = {role: subprocess.run([b, "--help"], capture_output=True, text=True).stdout for role, b in bins.items()}


def flag_value(args, flag):
    return args[args.index(flag) + 1] if flag in args else None


workloads = by_kind.get("StatefulSet", []) + by_kind.get("Deployment", [])
pods = {}
for w in workloads:
    name = w["metadata"]["name"]
    ns = w["metadata"].get("namespace", "default")
    spec = w["spec"]["template"]["spec"]
    psc = spec.get("securityContext", {})
    c = spec["containers"][0]
    args = c.get("args", [])
    role = args[0] if args else ""
    pods[role] = (w, c, args)
    csc = c.get("securityContext", {})
    check(f"{name}: runs as non-root", psc.get("runAsNonRoot") is True and psc.get("runAsUser", 0) != 0,
          f"runAsUser {psc.get('runAsUser')}")
    check(f"{name}: runAsUser is the image's USER", image_user is None or str(psc.get("runAsUser")) == image_user,
          f"image USER {image_user}")
    check(f"{name}: read-only root, no escalation, no capabilities",
          csc.get("readOnlyRootFilesystem") is True and csc.get("allowPrivilegeEscalation") is False
          and csc.get("capabilities", {}).get("drop") == ["ALL"])
    check(f"{name}: no service account token", spec.get("automountServiceAccountToken") is False)
    check(f"{name}: entrypoint role", role in ("coordinator", "worker"), role)
    unknown = [a for a in args if a.startswith("--") and not re.search(r"(^|\s)" + re.escape(a) + r"\b", help_text.get(role, ""))]
    check(f"{name}: every flag exists in bistable-{role} --help", not unknown, ", ".join(unknown))
    health = flag_value(args, "--health")
    hport = int(health.rsplit(":", 1)[1]) if health else None
    for probe in ("livenessProbe", "readinessProbe", "startupProbe"):
        p = c.get(probe)
        if p is None:
            continue
        check(f"{name}: {probe} is a gRPC health probe on the --health port",
              "grpc" in p and p["grpc"]["port"] == hport, f"port {p.get('grpc', {}).get('port')} vs --health {health}")
    check(f"{name}: liveness probe", "livenessProbe" in c)
    if role == "coordinator":
        check(f"{name}: readiness probe", "readinessProbe" in c)
        claims = [t["metadata"]["name"] for t in w["spec"].get("volumeClaimTemplates", [])]
        data_mount = [v for v in c.get("volumeMounts", []) if v["name"] in claims]
        check(f"{name}: data volume with fsGroup", data_mount and psc.get("fsGroup") not in (None, 0),
              f"fsGroup {psc.get('fsGroup')}")
        check(f"{name}: --data is the volume", data_mount and flag_value(args, "--data") == data_mount[0]["mountPath"])
    if role == "worker":
        check(f"{name}: threads from the CPU limit (no --threads, a cpu limit)",
              "--threads" not in args and "cpu" in c.get("resources", {}).get("limits", {}),
              f"limit {c.get('resources', {}).get('limits', {}).get('cpu')}")
        target = flag_value(args, "--coordinator") or ""
        host, port = target.rsplit(":", 1)
        svc = services.get((ns, host.split(".")[0]))
        check(f"{name}: dials a Service of its namespace on a port it has",
              svc is not None and any(p["port"] == int(port) for p in svc["spec"]["ports"]), target)
        vols = {v["name"]: v for v in spec.get("volumes", [])}
        leaked = [v for v in vols.values() if v.get("secret", {}).get("secretName") == "bistable-tls"
                  and [i["key"] for i in v["secret"].get("items", [])] != ["ca.pem"]]
        check(f"{name}: sees the CA only, never the server key", not leaked)

kubectl = shutil.which("kubectl")
if kubectl:
    r = subprocess.run([kubectl, "kustomize", kdir], capture_output=True, text=True)
    check("kubectl kustomize renders", r.returncode == 0 and "kind: StatefulSet" in r.stdout, r.stderr.strip()[:200])
else:
    rows.append(("kubectl kustomize renders", None, "kubectl not installed: skipped"))

# ---- certificates: make-secrets.sh names what the workers dial ----
tmp = tempfile.mkdtemp(prefix="bistable-k8s-")
try:
    env = dict(os.environ, BISTABLE=bin_cli)
    r = subprocess.run([os.path.join(kdir, "make-secrets.sh"), os.path.join(tmp, "s"), "--client", "alice"],
                       capture_output=True, text=True, env=env)
    check("make-secrets.sh", r.returncode == 0, (r.stderr or r.stdout).strip()[:200])
    secrets = [d for d in yaml.safe_load_all(open(os.path.join(tmp, "s", "secrets.yaml"))) if d]
    names = {s["metadata"]["name"] for s in secrets}
    wanted = set()
    for w in workloads:
        for v in w["spec"]["template"]["spec"].get("volumes", []):
            if "secret" in v:
                wanted.add(v["secret"]["secretName"])
    check("every Secret the pods mount is written", wanted <= names, ", ".join(sorted(wanted - names)))
    w_args = pods["worker"][2]
    host = (flag_value(w_args, "--coordinator") or "").rsplit(":", 1)[0]
    ns = pods["worker"][0]["metadata"].get("namespace", "default")
    tls = os.path.join(tmp, "s", "tls")
    for h in (host, f"bistable-coordinator.{ns}.svc.cluster.local"):
        r = subprocess.run(["openssl", "verify", "-CAfile", os.path.join(tls, "ca.pem"), "-verify_hostname", h,
                            os.path.join(tls, "server.pem")], capture_output=True, text=True)
        check(f"certificate verifies for {h}", r.returncode == 0, (r.stdout + r.stderr).strip()[:200])

    # ---- rehearsal: the pods' own args, two network namespaces, DNS by /etc/hosts ----
    if rehearse:
        if os.geteuid() != 0 or not shutil.which("ip"):
            rows.append(("rehearsal", None, "needs root and iproute2: skipped"))
        else:
            sys.path.insert(0, kdir)
            import rehearse
            rows.extend(rehearse.run(repo, build, tmp, pods, os.path.join(tmp, "s")))
finally:
    subprocess.run(["rm", "-rf", tmp])

width = max(len(r[0]) for r in rows)
failed = 0
for name, ok, detail in rows:
    mark = "PASS" if ok else ("SKIP" if ok is None else "FAIL")
    failed += ok is False
    print(f"| {name:<{width}} | {mark} | {detail} |")
print(f"{len(rows)} checks, {failed} failed")
sys.exit(1 if failed else 0)
