"""The pods of deploy/kubernetes/bistable.yaml rehearsed on one machine (check_manifests.py --rehearse).

Two network namespaces stand in for two pods: `bk8s-coord` (10.98.0.1) runs bistable-coordinator with the
StatefulSet's args, `bk8s-worker` (10.98.0.2) runs bistable-worker with the Deployment's args and
resolves the Service name `bistable-coordinator` through its own /etc/hosts (`ip netns exec` mounts
/etc/netns/NAME/hosts), as cluster DNS would. Volume mount paths in the args are mapped to the files
make-secrets.sh wrote. Checks: the kubelet's probes (gRPC health on the --health port, from the other
namespace as the kubelet probes the pod IP), a sweep submitted with a client token over TLS completes,
the worker's metrics answer. Everything started here is stopped and removed at the end.
"""
import json
import os
import signal
import subprocess
import time

COORD_NS, WORKER_NS = "bk8s-coord", "bk8s-worker"
COORD_IP, WORKER_IP = "10.98.0.1", "10.98.0.2"
SPEC = """name = "kubernetes rehearsal"
model = "coupled"
[axes]
alpha = { linspace = [0.2, 2.0, 12] }
omega = { linspace = [0.2, 2.0, 12] }
[integration]
t_end = 200.0
t_keep = 100.0
"""


def sh(*args, check=True, **kw):
    return subprocess.run(list(args), check=check, capture_output=True, text=True, **kw)


def teardown():
    for ns in (COORD_NS, WORKER_NS):
        pids = sh("ip", "netns", "pids", ns, check=False).stdout.split()
        for p in pids:
            try:
                os.kill(int(p), signal.SIGKILL)
            except (ProcessLookupError, ValueError):
                pass
        sh("ip", "netns", "del", ns, check=False)
    sh("rm", "-rf", f"/etc/netns/{WORKER_NS}", f"/etc/netns/{COORD_NS}", check=False)


def mapped(args, tmp, secrets):
    """The container's args with its volume paths mapped to this machine's files."""
    out = []
    for a in args:
        a = a.replace("/var/lib/bistable", os.path.join(tmp, "data"))
        a = a.replace("/tls/", os.path.join(secrets, "tls") + "/")
        a = a.replace("/secrets/", secrets + "/")
        out.append(a)
    return out


def run(repo, build, tmp, pods, secrets):
    rows = []
    cli = os.path.join(build, "client", "bistable")
    teardown()
    procs = []
    try:
        sh("ip", "netns", "add", COORD_NS)
        sh("ip", "netns", "add", WORKER_NS)
        sh("ip", "link", "add", "bk8s-c", "netns", COORD_NS, "type", "veth", "peer", "name", "bk8s-w", "netns", WORKER_NS)
        for ns, dev, ip in ((COORD_NS, "bk8s-c", COORD_IP), (WORKER_NS, "bk8s-w", WORKER_IP)):
            sh("ip", "-n", ns, "addr", "add", ip + "/24", "dev", dev)
            sh("ip", "-n", ns, "link", "set", dev, "up")
            sh("ip", "-n", ns, "link", "set", "lo", "up")
        os.makedirs(f"/etc/netns/{WORKER_NS}", exist_ok=True)
        with open(f"/etc/netns/{WORKER_NS}/hosts", "w") as f:
            f.write(f"127.0.0.1 localhost\n{COORD_IP} bistable-coordinator bistable-coordinator.bistable.svc.cluster.local\n")
        os.makedirs(os.path.join(tmp, "data"), exist_ok=True)
        c_args = mapped(pods["coordinator"][2][1:], tmp, secrets)
        w_args = mapped(pods["worker"][2][1:], tmp, secrets)
        coord_log = open(os.path.join(tmp, "coord.log"), "w")
        procs.append(subprocess.Popen(["ip", "netns", "exec", COORD_NS, os.path.join(build, "server", "bistable-coordinator")] + c_args,
                                      stdout=coord_log, stderr=subprocess.STDOUT))
        worker_log = open(os.path.join(tmp, "worker.log"), "w")
        procs.append(subprocess.Popen(["ip", "netns", "exec", WORKER_NS, os.path.join(build, "worker", "bistable-worker")] + w_args,
                                      stdout=worker_log, stderr=subprocess.STDOUT))
        # The kubelet's probes: gRPC health on the pod IP's --health port, plaintext, from the other namespace.
        def probe(from_ns, ip, probe_spec):
            port, svc = probe_spec["grpc"]["port"], probe_spec["grpc"].get("service", "")
            for _ in range(100):
                r = sh("ip", "netns", "exec", from_ns, cli, "health", "--coordinator", f"{ip}:{port}", "--service", svc,
                       "--timeout", "1", check=False)
                if r.returncode == 0:
                    return r.stdout.strip(), f"{ip}:{port} {svc}"
                time.sleep(0.1)
            return None, f"{ip}:{port} {svc}"
        ready, where = probe(WORKER_NS, COORD_IP, pods["coordinator"][1]["readinessProbe"])
        rows.append(("rehearsal: coordinator readiness probe (gRPC health)", ready == "SERVING", f"{where}: {ready}"))
        live, where = probe(COORD_NS, WORKER_IP, pods["worker"][1]["livenessProbe"])
        rows.append(("rehearsal: worker liveness probe (gRPC health)", live == "SERVING", f"{where}: {live}"))
        # A client in the worker's namespace dials the Service name over TLS with its token.
        spec = os.path.join(tmp, "spec.toml")
        open(spec, "w").write(SPEC)
        remote = ["--coordinator", "bistable-coordinator:50051", "--tls-ca", os.path.join(secrets, "tls", "ca.pem"),
                  "--token-file", os.path.join(secrets, "alice.token")]
        sub = sh("ip", "netns", "exec", WORKER_NS, cli, "submit", spec, "--json", *remote, check=False)
        sid = json.loads(sub.stdout)["id"] if sub.returncode == 0 else ""
        st = sh("ip", "netns", "exec", WORKER_NS, cli, "status", sid or "0", "--watch", "--json", *remote, check=False, timeout=300)
        last = json.loads(st.stdout.strip().splitlines()[-1]) if st.returncode == 0 and st.stdout.strip() else {}
        rows.append(("rehearsal: sweep over TLS to the Service name completes", last.get("state") == "done" and last.get("items_done") == 144,
                     f"{last.get('state')} {last.get('items_done')}/144 {(sub.stderr + st.stderr).strip()[:160]}"))
        # Prometheus scrapes the pod IP's metrics port from elsewhere in the cluster.
        def scrape(from_ns, ip, metric, label):
            r = sh("ip", "netns", "exec", from_ns, "/usr/bin/python3", "-c",
                   f"import urllib.request;print(urllib.request.urlopen('http://{ip}:9090/metrics',timeout=5).read().decode())",
                   check=False)
            lines = [l for l in r.stdout.splitlines() if l.startswith(metric)]
            rows.append((label, bool(lines) and float(lines[0].split()[-1]) == 144, lines[0] if lines else r.stderr.strip()[:160]))
        scrape(COORD_NS, WORKER_IP, "bistable_worker_items_computed_total", "rehearsal: worker metrics scraped from the pod IP")
        scrape(WORKER_NS, COORD_IP, "bistable_items_done_total", "rehearsal: coordinator metrics scraped from the pod IP")
    finally:
        for p in procs:
            p.send_signal(signal.SIGTERM)
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
        teardown()
    leftovers = sh("ip", "netns", "list").stdout
    rows.append(("rehearsal: nothing left behind", COORD_NS not in leftovers and WORKER_NS not in leftovers, ""))
    return rows
