"""The lock file (requirements.lock, what `make` installs) against pyproject.toml (the ranges library users get) and
against the environment the tests run in: a dependency added to one and not the other, an unhashed pin, or an
environment that is not the lock's, is what made two machines write different bytes."""

from __future__ import annotations

import re
import sys
import tomllib
from importlib import metadata
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

from stages.common import REPO

LOCK = REPO / "requirements.lock"
PIN = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==(\S+)")


def _lock() -> dict[str, tuple[Version, list[str]]]:
    """{canonical name: (version, sha256 hashes)} from the lock's pins and their ``--hash`` continuation lines."""
    pins: dict[str, tuple[Version, list[str]]] = {}
    name = None
    for line in LOCK.read_text().splitlines():
        if m := PIN.match(line):
            name = canonicalize_name(m.group(1))
            assert name not in pins, f"requirements.lock: {name} pinned twice"
            pins[name] = (Version(m.group(2)), [])
        elif name and (h := re.search(r"--hash=sha256:([0-9a-f]{64})", line)):
            pins[name][1].append(h.group(1))
        elif not line.startswith(" "):
            name = None
    return pins


def _declared() -> list[Requirement]:
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    return [Requirement(r) for r in project["dependencies"] + project["optional-dependencies"]["test"]]


def test_every_declared_dependency_is_locked_within_its_range_and_hashed():
    pins = _lock()
    assert len(pins) > 50, "requirements.lock holds the whole dependency tree, not only the direct dependencies"
    for name, (version, hashes) in pins.items():
        assert hashes, f"requirements.lock: {name}=={version} without a --hash"
    for req in _declared():
        name = canonicalize_name(req.name)
        assert name in pins, f"pyproject.toml names {req}, requirements.lock has no {name} (run `make lock`)"
        assert req.specifier.contains(pins[name][0], prereleases=True), (
            f"requirements.lock pins {name}=={pins[name][0]}, outside pyproject.toml's {req}")


def test_torch_is_the_cpu_build_pinned_exactly():
    version, _ = _lock()["torch"]
    assert version.public == "2.13.0" and version.local == "cpu", f"torch {version}: a range fetches a CUDA build"


@pytest.mark.skipif(Path(sys.prefix).resolve() != (REPO / ".venv").resolve(),
                    reason="not the project's .venv, which `make` installs from the lock")
def test_the_installed_environment_is_the_lock():
    """In the environment `make` installed (CI's): every locked package is installed at its locked version."""
    wrong = {}
    for name, (version, _) in _lock().items():
        try:
            found = Version(metadata.version(name))
        except metadata.PackageNotFoundError:
            found = None
        if found != version:
            wrong[name] = (str(version), str(found))
    assert not wrong, f"installed versions differ from requirements.lock (locked, installed): {wrong}"


OPENBLAS_CORE = ("import ctypes; lib = ctypes.CDLL(next(l.split()[-1] for l in open('/proc/self/maps') "
                 "if 'openblas' in l)); f = next(getattr(lib, n) for n in ('scipy_openblas_get_corename64_', "
                 "'openblas_get_corename64_', 'openblas_get_corename') if hasattr(lib, n)); "
                 "f.restype = ctypes.c_char_p; core = f().decode(); ")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the loaded OpenBLAS from /proc/self/maps")
def test_a_stage_process_runs_the_pinned_cpu_code_paths_unless_the_user_set_them():
    """MKL, ATen and OpenBLAS pick their kernels by CPU; unpinned, an AVX-512 machine wrote other bytes than an AVX2
    one. OpenBLAS reads its pin when numpy loads, so a stage must set it before: importing ``stages`` loads no numpy."""
    import os
    import subprocess

    probe = ("import os, sys, stages; early = 'numpy' in sys.modules; import numpy, torch; torch.ones(3).sum(); "
             + OPENBLAS_CORE + "print(early, torch.backends.cpu.get_cpu_capability(), os.environ['MKL_CBWR'], "
             "os.environ['OPENBLAS_CORETYPE'], core)")
    env = {k: v for k, v in os.environ.items() if k not in ("MKL_CBWR", "ATEN_CPU_CAPABILITY", "OPENBLAS_CORETYPE")}

    def run(**chosen: str) -> list[str]:
        return subprocess.run([sys.executable, "-c", probe], env={**env, **chosen}, cwd=REPO, capture_output=True,
                              text=True, check=True).stdout.split()

    assert run() == ["False", "AVX2", "AVX2", "Haswell", "Haswell"]  # (Haswell is also what AMD Zen picks)
    assert run(ATEN_CPU_CAPABILITY="default", MKL_CBWR="COMPATIBLE", OPENBLAS_CORETYPE="Sandybridge") == [
        "False", "DEFAULT", "COMPATIBLE", "Sandybridge", "Sandybridge"]
