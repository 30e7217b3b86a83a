"""The compiled physics is built by the package's build: one clear line without a compiler,
a portable build for wheels, the sources shipped with an sdist."""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib

from .conftest import ROOT


def test_a_machine_without_a_compiler_gets_one_line(tmp_path):
    env = {**os.environ, "CC": str(tmp_path / "no-such-cc"), "LDSHARED": str(tmp_path / "no-such-cc")}
    proc = subprocess.run([sys.executable, "setup.py", "-q", "build_ext", "--build-temp", str(tmp_path / "t"),
                           "--build-lib", str(tmp_path / "l")], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode != 0
    lines = [line for line in (proc.stdout + proc.stderr).splitlines() if "needs a C compiler" in line]
    assert len(lines) == 1, proc.stdout + proc.stderr
    assert lines[0].startswith("servo_toolkit: building the physics kernels needs a C compiler")
    assert not list(tmp_path.rglob("_kernels*.so"))  # nothing half-built left as if it were the extension


def test_wheels_are_built_for_the_platforms_baseline():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    wheel = config["tool"]["cibuildwheel"]
    assert wheel["environment"]["SERVO_TOOLKIT_CPU"] == "portable"
    assert "test_rhs_transcription.py" in wheel["test-command"]
    assert "Cython>=3.0" in config["build-system"]["requires"]
    assert not any(dep.startswith(("numba", "llvmlite")) for dep in config["project"]["dependencies"])


def test_the_sdist_carries_the_kernel_sources():
    manifest = (ROOT / "MANIFEST.in").read_text()
    assert "recursive-include servo_toolkit/_physics *.h *.c *.pyx *.pxi" in manifest
