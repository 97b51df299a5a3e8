"""Fixtures of the Python package's tests: the bundled bunny scans, their ground truth, and a
locally started `mlsreg serve` (the CLI binary named by MLSREG_CLI)."""

import os
import pathlib
import re
import subprocess
import time

import numpy as np
import pytest

import mlsreg

SOURCE_DIR = pathlib.Path(__file__).resolve().parents[2]
BUNNY = SOURCE_DIR / "data" / "bunny"


def ground_truth(pair_id: str) -> np.ndarray:
    for line in (BUNNY / "pairs.csv").read_text().splitlines()[1:]:
        fields = line.split(",")
        if fields[0] == pair_id:
            return np.array([float(v) for v in fields[3].split()]).reshape(4, 4)
    raise KeyError(pair_id)


def perturbed(gt: np.ndarray, angle_deg: float, translation: np.ndarray) -> np.ndarray:
    """gt composed with a rotation of angle_deg about a fixed oblique axis and a translation."""
    axis = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    a = np.radians(angle_deg)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    m = np.eye(4)
    m[:3, :3] = np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * k @ k
    m[:3, 3] = translation
    return m @ gt


@pytest.fixture(scope="session")
def bun000():
    return mlsreg.read_cloud(BUNNY / "bun000.ply")


@pytest.fixture(scope="session")
def bun045():
    return mlsreg.read_cloud(BUNNY / "bun045.ply")


@pytest.fixture(scope="session")
def bunny_target(bun045):
    return mlsreg.Target(bun045.points)


@pytest.fixture(scope="session")
def gt():
    return ground_truth("bun000_bun045")


@pytest.fixture(scope="session")
def near_start(gt, bunny_target):
    d = bunny_target.sampling_distance
    return perturbed(gt, 8.0, np.array([5 * d, -4 * d, 3 * d]))


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """A real server on 127.0.0.1 (an ephemeral port); yields its address."""
    cli = os.environ.get("MLSREG_CLI")
    if not cli:
        pytest.skip("MLSREG_CLI (the mlsreg binary) is not set")
    log = tmp_path_factory.mktemp("server") / "server.log"
    with open(log, "w") as out:
        process = subprocess.Popen([cli, "serve", "--listen", "127.0.0.1:0", "--workers", "2"],
                                   stdout=out, stderr=subprocess.STDOUT)
    try:
        address = None
        for _ in range(200):
            match = re.search(r"listening on ([0-9.]+:[0-9]+)", log.read_text())
            if match:
                address = match.group(1)
                break
            assert process.poll() is None, log.read_text()
            time.sleep(0.05)
        assert address, "the server did not start: " + log.read_text()
        yield address
    finally:
        process.terminate()
        assert process.wait(timeout=30) == 0, log.read_text()
