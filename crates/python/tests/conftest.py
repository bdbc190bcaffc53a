"""Shared fixtures: the bundled faces and the shapespace binary the package is compared with."""

import os
import pathlib
import shutil
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[3]
FACES = ROOT / "datasets" / "faces"


def face(name: str) -> str:
    return str(FACES / f"{name}.obj")


@pytest.fixture(scope="module")
def shapespace_bin() -> str:
    """The command-line binary: $SHAPESPACE_BIN, else the release build in the target folder
    ($CARGO_TARGET_DIR or target/), else `shapespace` on the PATH. Missing is a failure (the
    comparisons with the command are the point of these tests)."""
    candidates = [os.environ.get("SHAPESPACE_BIN")]
    target = os.environ.get("CARGO_TARGET_DIR") or str(ROOT / "target")
    candidates.append(os.path.join(target, "release", "shapespace"))
    candidates.append(shutil.which("shapespace"))
    for c in candidates:
        if c and os.path.isfile(c) and os.access(c, os.X_OK):
            return c
    pytest.fail("no shapespace binary: build it (cargo build --release -p shapespace-cli) or set SHAPESPACE_BIN")


def run_distances(binary: str, files, out, *flags) -> None:
    result = subprocess.run(
        [binary, "distances", *files, "--out", str(out), "--quiet", *flags], capture_output=True, text=True
    )
    assert result.returncode == 0, result.stderr


def read_matrix(path):
    """distances.csv as (names, rows of floats; empty cells NaN)."""
    lines = pathlib.Path(path).read_text().splitlines()
    names = lines[0].split(",")[1:]
    rows = [[float(c) if c else float("nan") for c in line.split(",")[1:]] for line in lines[1:]]
    return names, rows
