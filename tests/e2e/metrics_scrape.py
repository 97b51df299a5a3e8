#!/usr/bin/env python3
"""End-to-end: `mlsreg serve --metrics-listen` on 127.0.0.1, scraped with a real HTTP client
(urllib) before, during and after a registration run by the real CLI client.

Checks: the exposition parses as Prometheus text (every sample of a declared family, histogram
buckets cumulative with +Inf = _count); while the registration runs the scrape sees it
(active_jobs, open_streams, in-flight bytes); after it the request, registration, latency and
target-build counters have moved by exactly what was done; other paths are 404, POST 405.
Usage: metrics_scrape.py MLSREG_BINARY SOURCE_DIR"""

import re
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request

MLSREG, SRC = sys.argv[1], sys.argv[2]
SAMPLE = re.compile(r'^([a-zA-Z_:][a-zA-Z0-9_:]*)(\{([^}]*)\})? (\S+)$')


def fail(message):
    print("FAIL:", message, file=sys.stderr)
    sys.exit(1)


def parse(text):
    """{(name, labels-tuple): value}, checking the text format as it goes."""
    families, samples = {}, {}
    for line in text.splitlines():
        if line.startswith("# HELP "):
            continue
        if line.startswith("# TYPE "):
            _, _, name, kind = line.split(" ")
            families[name] = kind
            continue
        m = SAMPLE.match(line)
        if not m:
            fail(f"not a sample line: {line!r}")
        name, labels, value = m.group(1), m.group(3) or "", float(m.group(4))
        base = re.sub(r"_(bucket|sum|count)$", "", name)
        if name not in families and base not in families:
            fail(f"sample of an undeclared family: {line!r}")
        key = tuple(sorted(re.findall(r'(\w+)="([^"]*)"', labels)))
        samples[(name, key)] = value
    for (name, key), value in samples.items():  # histograms: cumulative, +Inf == _count
        if name.endswith("_bucket") and dict(key).get("le") == "+Inf":
            rest = tuple(kv for kv in key if kv[0] != "le")
            if samples.get((name[:-len("_bucket")] + "_count", rest)) != value:
                fail(f"{name}{rest}: +Inf bucket != _count")
    return families, samples


def get(samples, name, **labels):
    return samples.get((name, tuple(sorted(labels.items()))), 0.0)


def scrape(url):
    with urllib.request.urlopen(url, timeout=10) as response:
        if response.status != 200:
            fail(f"status {response.status}")
        if not response.headers["Content-Type"].startswith("text/plain; version=0.0.4"):
            fail(f"content type {response.headers['Content-Type']}")
        return parse(response.read().decode())


# A --metrics-listen that is not HOST:PORT with a port up to 65535 is bad usage (exit 2, naming
# the flag); one that cannot be bound stops the server at start (exit 1), naming the setting.
for bad in ["nonsense", "127.0.0.1:99999"]:
    done = subprocess.run([MLSREG, "serve", "--listen", "127.0.0.1:0", "--metrics-listen", bad],
                          capture_output=True, text=True, timeout=60)
    if done.returncode != 2 or "metrics_listen (--metrics-listen): " not in done.stderr:
        fail(f"--metrics-listen {bad}: exit {done.returncode}: {done.stderr}{done.stdout}")
done = subprocess.run([MLSREG, "serve", "--listen", "127.0.0.1:0", "--metrics-listen",
                       "192.0.2.1:9464"], capture_output=True, text=True, timeout=60)
if done.returncode != 1 or "metrics_listen: cannot listen on 192.0.2.1:9464" not in done.stderr + done.stdout:
    fail(f"--metrics-listen 192.0.2.1:9464: exit {done.returncode}: {done.stderr}{done.stdout}")

with tempfile.TemporaryDirectory() as work:
    log_path = f"{work}/server.log"
    log = open(log_path, "w")
    server = subprocess.Popen([MLSREG, "serve", "--listen", "127.0.0.1:0", "--workers", "1",
                               "--metrics-listen", "127.0.0.1:0"], stdout=log,
                              stderr=subprocess.STDOUT)
    try:
        grpc_address = metrics_url = None
        for _ in range(200):
            text = open(log_path).read()
            g = re.search(r"listening on ([0-9.]+:[0-9]+)", text)
            m = re.search(r"metrics on (http://[0-9.]+:[0-9]+/metrics)", text)
            if g and m:
                grpc_address, metrics_url = g.group(1), m.group(1)
                break
            if server.poll() is not None:
                fail("server exited: " + text)
            time.sleep(0.05)
        if not metrics_url:
            fail("no metrics address in the log: " + open(log_path).read())

        taken = metrics_url.split("//")[1].split("/")[0]
        done = subprocess.run([MLSREG, "serve", "--listen", "127.0.0.1:0", "--metrics-listen",
                               taken], capture_output=True, text=True, timeout=60)
        if done.returncode != 1 or "metrics_listen: cannot listen" not in done.stderr + done.stdout:
            fail(f"a taken metrics port: exit {done.returncode}: {done.stderr}{done.stdout}")

        families, before = scrape(metrics_url)
        for family, kind in [("mlsreg_requests_total", "counter"),
                             ("mlsreg_request_duration_seconds", "histogram"),
                             ("mlsreg_registrations_total", "counter"),
                             ("mlsreg_registration_duration_seconds", "histogram"),
                             ("mlsreg_queue_depth", "gauge"), ("mlsreg_queue_capacity", "gauge"),
                             ("mlsreg_active_jobs", "gauge"), ("mlsreg_cache_bytes", "gauge"),
                             ("mlsreg_cache_budget_bytes", "gauge"),
                             ("mlsreg_cache_entries", "gauge"),
                             ("mlsreg_cache_hits_total", "counter"),
                             ("mlsreg_cache_misses_total", "counter"),
                             ("mlsreg_cache_evictions_total", "counter"),
                             ("mlsreg_target_builds_total", "counter"),
                             ("mlsreg_target_build_seconds_total", "counter"),
                             ("mlsreg_inflight_bytes", "gauge")]:
            if families.get(family) != kind:
                fail(f"{family}: declared {families.get(family)}, expected {kind}")
        if get(before, "mlsreg_cache_entries") != 0 or get(before, "mlsreg_serving") != 1:
            fail("a fresh server has entries or is not serving")

        subprocess.run([MLSREG, "targets", "upload", "--server", grpc_address, "--id", "bun045",
                        f"{SRC}/data/bunny/bun045.ply"], check=True, stdout=subprocess.DEVNULL)
        # A registration that keeps running: 300 iterations, no convergence test.
        register = subprocess.Popen(
            [MLSREG, "register", "--server", grpc_address, "--target", "bun045", "--source",
             f"{SRC}/data/bunny/bun000.ply", "--method", "mls-sicp", "--max-iterations", "300",
             "--convergence", "0", "--stall", "0", "--stall-noise", "0"], stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE)
        seen_running = False
        while register.poll() is None:
            _, during = scrape(metrics_url)
            if (get(during, "mlsreg_active_jobs") == 1 and get(during, "mlsreg_open_streams") >= 1
                    and get(during, "mlsreg_inflight_bytes") > 0):
                seen_running = True
            time.sleep(0.05)
        if register.returncode != 0:
            fail("register: " + register.stderr.read().decode())
        if not seen_running:
            fail("no scrape saw the registration running")

        _, after = scrape(metrics_url)
        moved = {
            ("mlsreg_requests_total", (("code", "OK"), ("rpc", "CreateTarget"))): 1,
            ("mlsreg_requests_total", (("code", "OK"), ("rpc", "Register"))): 1,
            ("mlsreg_registration_duration_seconds_count", (("method", "mls-sicp"),)): 1,
            ("mlsreg_request_duration_seconds_count", (("rpc", "Register"),)): 1,
            ("mlsreg_target_builds_total", ()): 1,
            ("mlsreg_cache_entries", ()): 1,
        }
        for key, delta in moved.items():
            if after.get(key, 0.0) - before.get(key, 0.0) != delta:
                fail(f"{key}: {before.get(key, 0.0)} -> {after.get(key, 0.0)}, expected +{delta}")
        runs = {k: v for k, v in after.items() if k[0] == "mlsreg_registrations_total"}
        if list(runs.values()) != [1.0] or dict(next(iter(runs))[1])["method"] != "mls-sicp":
            fail(f"registrations by method and termination: {runs}")
        if not (get(after, "mlsreg_cache_bytes") > 0 and
                get(after, "mlsreg_target_build_seconds_total") > 0 and
                get(after, "mlsreg_inflight_bytes") == 0 and get(after, "mlsreg_active_jobs") == 0):
            fail("cache bytes, build seconds or the idle gauges are wrong after the run")

        for path, method, status in [("/other", "GET", 404), ("/", "GET", 404),
                                     ("/metrics/", "GET", 404), ("/a/b/../c", "GET", 404),
                                     ("/metrics", "POST", 405), ("/metrics", "DELETE", 405)]:
            try:
                urllib.request.urlopen(urllib.request.Request(
                    metrics_url.replace("/metrics", path), method=method,
                    data=b"" if method == "POST" else None), timeout=10)
                fail(f"{method} {path} answered 200")
            except urllib.error.HTTPError as e:
                if e.code != status:
                    fail(f"{method} {path}: {e.code}, expected {status}")
        # Junk on the socket, then a scrape: the endpoint and the server keep working.
        host, port = metrics_url.split("//")[1].split("/")[0].split(":")
        for junk in [b"GARBAGE\r\n\r\n", b"GET /metrics HTTP/1.1\r\nX: " + b"a" * 100000,
                     b"\x00\xff" * 1000, b"GET " + b"/x" * 5000 + b" HTTP/1.1\r\n\r\n"]:
            with socket.create_connection((host, int(port)), timeout=10) as s:
                try:  # the endpoint may answer 4xx and close before it has read it all
                    s.sendall(junk)
                    s.shutdown(socket.SHUT_WR)
                    while s.recv(65536):
                        pass
                except (ConnectionResetError, BrokenPipeError, OSError):
                    pass
        scrape(metrics_url)
        if server.poll() is not None:
            fail("the server died on bad HTTP requests")
    finally:
        server.terminate()
        if server.wait(timeout=30) != 0:
            fail("server exit code " + str(server.returncode) + ": " + open(log_path).read())
print("metrics scrape: ok")
