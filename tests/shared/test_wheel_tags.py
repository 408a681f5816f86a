"""silpose.shared.wheel_tags: installed WHEEL tags that contradict the locked wheel's file name are
corrected (the cause of uv reinstalling bpy on every call), and a second ``uv sync`` installs nothing."""

from __future__ import annotations

import base64
import hashlib
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from packaging.tags import Tag

from silpose.shared.wheel_tags import find_mismatches, repair

ROOT = Path(__file__).resolve().parents[2]
SUPPORTED = [Tag("cp311", "cp311", "manylinux_2_28_x86_64"), Tag("cp311", "abi3", "manylinux_2_28_x86_64"),
             Tag("py3", "none", "any")]
LOCK = """version = 1
requires-python = "==3.11.*"

[[package]]
name = "demo-pkg"
version = "1.0"
source = { registry = "https://pypi.org/simple" }
wheels = [
    { url = "https://files.example/p/demo_pkg-1.0-cp311-cp311-macosx_11_0_arm64.whl", hash = "sha256:00" },
    { url = "https://files.example/p/demo_pkg-1.0-cp311-cp311-manylinux_2_28_x86_64.whl", hash = "sha256:01" },
    { url = "https://files.example/p/demo_pkg-1.0-cp311-cp311-win_amd64.whl", hash = "sha256:02" },
]

[[package]]
name = "good"
version = "2.0"
source = { registry = "https://pypi.org/simple" }
wheels = [{ url = "https://files.example/p/good-2.0-py3-none-any.whl", hash = "sha256:03" }]
"""


def _dist(site: Path, name: str, version: str, tags: list[str]) -> Path:
    info = site / f"{name}-{version}.dist-info"
    info.mkdir(parents=True)
    wheel = "Wheel-Version: 1.0\nGenerator: setuptools (80.9.0)\nRoot-Is-Purelib: false\n"
    wheel += "".join(f"Tag: {t}\n" for t in tags) + "\n"
    (info / "WHEEL").write_text(wheel)
    (info / "METADATA").write_text(f"Metadata-Version: 2.4\nName: {name}\nVersion: {version}\n")
    (info / "RECORD").write_text(f"{name}/__init__.py,sha256=abc,3\n{info.name}/WHEEL,sha256=old,{len(wheel)}\n"
                                 f"{info.name}/RECORD,,\n")
    return info


@pytest.fixture
def env(tmp_path):
    site = tmp_path / "site-packages"
    lock = tmp_path / "uv.lock"
    lock.write_text(LOCK)
    bad = _dist(site, "demo_pkg", "1.0", ["cp39-cp39-manylinux_2_28_x86_64"])  # like bpy 5.0.1
    good = _dist(site, "good", "2.0", ["py3-none-any"])
    orphan = _dist(site, "orphan", "0.1", ["cp39-cp39-manylinux_2_28_x86_64"])  # not in the lock: left alone
    return site, lock, bad, good, orphan


def test_wheel_tags_are_rewritten_to_the_locked_file_name(env):
    site, lock, bad, good, orphan = env
    before = {p: (p / "WHEEL").read_bytes() for p in (good, orphan)}
    found = repair(site, lock, SUPPORTED)
    assert [(r.name, r.version, r.installed_tags) for r in found] == [
        ("demo_pkg", "1.0", ("cp39-cp39-manylinux_2_28_x86_64",))]
    assert found[0].wheel_file == "demo_pkg-1.0-cp311-cp311-manylinux_2_28_x86_64.whl"
    text = (bad / "WHEEL").read_text()
    assert text == ("Wheel-Version: 1.0\nGenerator: setuptools (80.9.0)\nRoot-Is-Purelib: false\n"
                    "Tag: cp311-cp311-manylinux_2_28_x86_64\n\n")  # only the Tag line changed, in place
    digest = base64.urlsafe_b64encode(hashlib.sha256(text.encode()).digest()).rstrip(b"=").decode()
    assert f"demo_pkg-1.0.dist-info/WHEEL,sha256={digest},{len(text)}" in (bad / "RECORD").read_text().splitlines()
    assert (bad / "RECORD").read_text().startswith("demo_pkg/__init__.py,sha256=abc,3\n")
    assert {p: (p / "WHEEL").read_bytes() for p in (good, orphan)} == before


def test_a_second_repair_changes_nothing(env):
    site, lock, bad, *_ = env
    assert len(repair(site, lock, SUPPORTED)) == 1
    stamps = {p: p.stat().st_mtime_ns for p in site.rglob("*")}
    assert repair(site, lock, SUPPORTED) == [] and find_mismatches(site, lock, SUPPORTED) == []
    assert {p: p.stat().st_mtime_ns for p in site.rglob("*")} == stamps


def test_no_lock_or_nothing_compatible_means_no_change(env, tmp_path):
    site, lock, bad, *_ = env
    assert repair(site, tmp_path / "missing.lock", SUPPORTED) == []  # nothing to compare with
    other = [Tag("cp312", "cp312", "win_arm64")]  # no locked wheel fits this interpreter: nothing to choose
    assert repair(site, lock, other) == []
    assert "cp39-cp39" in (bad / "WHEEL").read_text()


def test_the_project_environment_is_stable_under_uv_sync():
    """The root cause is gone from this checkout's .venv, and ``uv sync`` would change nothing.

    CI runs ``just test`` in a fresh clone: ``just setup`` synced and repaired, so a second sync must
    install nothing (before the fix, it reinstalled bpy's 2,621 files every time). Only a workspace
    member whose pyproject.toml was touched after the last sync may be rebuilt (editable, harmless).
    """
    if Path(sys.prefix).resolve() != (ROOT / ".venv").resolve():
        pytest.skip("not running in the project's .venv")
    assert find_mismatches(lock=ROOT / "uv.lock") == []
    uv = shutil.which("uv")
    if uv is None:
        if os.environ.get("CI"):
            pytest.fail("uv is not on PATH in CI")
        pytest.skip("uv is not on PATH")
    env = {k: v for k, v in os.environ.items() if not k.startswith("UV_")}
    out = subprocess.run([uv, "sync", "--all-extras", "--frozen", "--dry-run"], cwd=ROOT, env=env,
                         capture_output=True, text=True, timeout=300)
    text = out.stdout + out.stderr
    assert out.returncode == 0, text
    changes = re.findall(r"^ [~+-] (.+)$", text, re.M)
    # a workspace member (editable, from this checkout) is reinstalled when its pyproject.toml was touched
    # since the last sync; every other package must stay as it is
    foreign = [c for c in changes if f"file://{ROOT}/" not in c]
    assert foreign == [], text
    assert changes or "Would make no changes" in text, text
