"""Fuzz: malformed rig files (JSON rigs) and calibrations (OpenCV XML/YAML, read by ``silpose rig import``).

``load_rig`` / ``read_calibrations`` either return or raise ``RigError`` (a ValueError) whose message
names the file -- never another exception type, never a hang, never a crash of the interpreter.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from silpose.app.rig.calibration import CalibratedCamera
from silpose.app.rig.formats import read_calibrations
from silpose.app.rig.opencv import write_opencv_camera
from silpose.shared.camera import Rig, RigError, default_rig, load_rig

FUZZ = settings(max_examples=80, deadline=2000, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

_json_scalars = st.one_of(
    st.none(), st.booleans(), st.integers(-10**12, 10**12), st.text(max_size=6),
    st.floats(allow_nan=True, allow_infinity=True),
)
json_values = st.recursive(_json_scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=4), inner, max_size=3)), max_leaves=12)
CAMERA_KEYS = ("name", "K", "R", "t", "width", "height", "dist")


def _check(path) -> Rig | list | None:
    try:
        return load_rig(path) if str(path).endswith(".json") else read_calibrations([path]).cameras
    except RigError as exc:
        assert str(path) in str(exc), str(exc)
        assert "\n" not in str(exc)
        return None


@st.composite
def mutated_rig(draw):
    """The default rig's JSON with a few fields deleted, replaced by random JSON, or re-shaped."""
    d = default_rig().to_dict()
    for _ in range(draw(st.integers(1, 3))):
        cams = d.get("cameras") if isinstance(d, dict) else None
        op = draw(st.sampled_from(["delete", "replace", "reshape", "nan", "camera", "top"]))
        if op == "top":
            d = draw(json_values)
            continue
        if not isinstance(cams, list) or not cams:
            continue
        i = draw(st.integers(0, len(cams) - 1))
        if op == "camera":
            cams[i] = draw(json_values)
            continue
        if not isinstance(cams[i], dict):
            continue
        key = draw(st.sampled_from(CAMERA_KEYS))
        if op == "delete":
            cams[i].pop(key, None)
        elif op == "replace":
            cams[i][key] = draw(json_values)
        elif op == "reshape" and key in cams[i]:
            flat = np.asarray(cams[i][key], dtype=object).ravel().tolist()
            cams[i][key] = flat[: draw(st.integers(0, len(flat)))]
        elif op == "nan" and key in ("K", "R", "t", "dist"):
            arr = np.array(cams[i][key], dtype=np.float64)
            arr.flat[draw(st.integers(0, arr.size - 1))] = draw(st.sampled_from([math.nan, math.inf, -math.inf]))
            cams[i][key] = arr.tolist()
    return d


@FUZZ
@given(rig=mutated_rig())
def test_malformed_json_rig_loads_or_raises_rig_error_naming_the_file(tmp_path_factory, rig):
    path = tmp_path_factory.mktemp("rig") / "rig.json"
    path.write_text(json.dumps(rig))  # NaN / Infinity literals included: json.loads accepts them
    loaded = _check(path)
    if loaded is not None:
        for cam in loaded:
            for arr in (cam.K, cam.R, cam.t, cam.dist):
                assert np.all(np.isfinite(arr)), cam.name


@FUZZ
@given(data=st.binary(max_size=300))
def test_garbage_bytes_as_json_rig(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("rig") / "rig.json"
    path.write_bytes(data)
    _check(path)


# ------------------------------------------------------------------ OpenCV FileStorage files


@pytest.fixture(scope="module")
def opencv_texts(tmp_path_factory):
    """A valid calibration of the default rig's first camera, as YAML and XML text."""
    tmp = tmp_path_factory.mktemp("cv")
    texts = {}
    for suffix, rotation in ((".yml", "rvec"), (".xml", "matrix")):
        p = tmp / f"cam{suffix}"
        c = default_rig()[0]
        write_opencv_camera(p, CalibratedCamera(c.name, c.K, c.dist, c.R, c.t, (c.width, c.height), ""), rotation=rotation)
        texts[suffix] = p.read_text()
    return texts


_JUNK = st.sampled_from(["nan", ".nan", "inf", "-.Inf", "abc", "1e999", "", "[", "]", "{", "}", ":", "!!opencv-matrix",
                         "<data>", "</data>", "<", ">", "rows: 9", "dt: z", "\x00", "'", '"', "%YAML:1.0", "---", "-1",
                         "0", "1e-320", "<rows>0</rows>", "  ", "\n"])


@st.composite
def mutated_opencv(draw, texts):
    suffix = draw(st.sampled_from(sorted(texts)))
    tokens = texts[suffix].replace("\n", " \n ").split(" ")
    for _ in range(draw(st.integers(1, 4))):
        i = draw(st.integers(0, len(tokens) - 1))
        op = draw(st.sampled_from(["replace", "delete", "insert", "truncate"]))
        if op == "replace":
            tokens[i] = draw(_JUNK)
        elif op == "delete":
            del tokens[i]
        elif op == "insert":
            tokens.insert(i, draw(_JUNK))
        else:
            tokens = tokens[:i]
        if not tokens:
            tokens = [""]
    return suffix, " ".join(tokens)


@settings(max_examples=120, deadline=3000, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(data=st.data())
def test_malformed_opencv_calibration_loads_or_raises_rig_error_naming_the_file(tmp_path_factory, opencv_texts, data):
    suffix, text = data.draw(mutated_opencv(opencv_texts))
    path = tmp_path_factory.mktemp("cv") / f"cam{suffix}"
    path.write_text(text)
    loaded = _check(path)
    if loaded is not None:
        cam = loaded[0]
        assert all(np.all(np.isfinite(a)) for a in (cam.K, cam.R, cam.t, cam.dist))


@settings(max_examples=60, deadline=3000, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(suffix=st.sampled_from([".yml", ".yaml", ".xml"]), data=st.binary(max_size=200))
def test_garbage_bytes_as_opencv_calibration(tmp_path_factory, suffix, data):
    path = tmp_path_factory.mktemp("cv") / f"cam{suffix}"
    path.write_bytes(data)
    _check(path)


_CRASH_CHECK = r"""
import sys
from pathlib import Path
from silpose.app.rig.formats import read_calibrations
from silpose.shared.camera import RigError
for p in sorted(Path(sys.argv[1]).iterdir()):
    try:
        read_calibrations([p])
    except RigError:
        pass
print("survived", flush=True)
"""


def test_odd_calibration_files_do_not_crash_the_interpreter(tmp_path, opencv_texts):
    """cv2.FileStorage is C++: run a batch of nasty files in a child and require a normal exit."""
    yml, xml = opencv_texts[".yml"], opencv_texts[".xml"]
    nasty = {
        "deep.yml": "%YAML:1.0\n" + "a: [" * 2000 + "]" * 2000 + "\n",
        "deep.xml": "<?xml version=\"1.0\"?><opencv_storage>" + "<a>" * 2000 + "</a>" * 2000 + "</opencv_storage>",
        "huge_rows.yml": yml.replace("rows: 3", "rows: 2000000000", 1),
        "huge_rows.xml": xml.replace("<rows>3</rows>", "<rows>2000000000</rows>", 1),
        "neg_cols.yml": yml.replace("cols: 3", "cols: -3", 1),
        "bad_dt.yml": yml.replace("dt: d", "dt: \"9q\"", 1),
        "nul.yml": yml[:40] + "\x00" * 50 + yml[40:],
        "half.xml": xml[: len(xml) // 2],
        "empty.yml": "",
        "header_only.xml": "<?xml version=\"1.0\"?>",
        "bom.yml": "\ufeff" + yml,
        "long_line.yml": "%YAML:1.0\nK: " + "1," * 200000 + "\n",
    }
    folder = tmp_path / "nasty"
    folder.mkdir()
    for name, text in nasty.items():
        (folder / name).write_text(text)
    r = subprocess.run([sys.executable, "-c", _CRASH_CHECK, str(folder)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "survived" in r.stdout, (r.returncode, r.stderr[-3000:])
    for p in sorted(folder.iterdir()):  # and in this process: the documented error, naming the file
        _check(p)
