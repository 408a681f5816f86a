"""The silpose dataset schema: Arrow column types and the ``silpose`` metadata document.

A dataset is a folder of Parquet shards ``{split}-{i:05d}-of-{n:05d}.parquet`` (zstd). One row is
one sample seen by K calibrated cameras. Format version 2 stores every array as nested
fixed-size lists (``list<T>[m]`` below; one nesting level per axis, outermost first) and every
silhouette as a 1-bit PNG image, so Hugging Face ``datasets``, pyarrow, pandas, DuckDB and Polars
all read it without silpose code:

=====================  =======================================  ==========  ========================
column                 Arrow type (version 2)                   row shape   meaning
=====================  =======================================  ==========  ========================
``sample_id``          int64                                                index within its split
``split``              string                                               ``train`` / ``test``
``seed``               int64                                                dataset seed
``redraws``            int32                                                rejected draws before it
``subject``            struct<name: float32, ...>                           body proportions
``gait``               struct<name: float32, ...>                           motion parameters
``joints``             list<list<float32>[3]>[19]               (19, 3)     world, metres
``masks``              list<struct<bytes: binary, path: str>>[K]  (K,)      1-bit PNG per view
``contours``           list<list<list<float32>[2]>[n]>[K]       (K, n, 2)   pixels (x right, y down)
``contour_centroid``   list<list<float32>[2]>[K]                (K, 2)      pixels
``contour_scale``      list<float32>[K]                         (K,)        pixels
``contour_length``     list<float32>[K]                         (K,)        pixels
``area``               list<int32>[K]                           (K,)        pixels (mask sum)
``n_blobs``            list<int32>[K]                           (K,)        connected components
``touches_border``     list<bool>[K]                            (K,)        mask touches the border
=====================  =======================================  ==========  ========================

``masks`` is Hugging Face's ``Image`` storage, one struct ``{bytes: PNG file, path: null}`` per view
(H x W, 1-bit greyscale, 1 = person; see ``silpose.shared.mask_png``); silpose's readers decode it
to (K, H, W) uint8 0/1. Every field is nullable in the Arrow schema, because ``datasets`` applies a
declared feature only to a nullable field, but the readers reject null values. The schema
metadata holds two JSON documents: ``silpose`` (see ``build_metadata``) and ``huggingface``
(``{"info": {"features": ...}}``, see ``hf_features``), which tells ``datasets`` that ``masks`` is a
list of K images.

Format version 1 stored the same arrays as ``arrow.fixed_shape_tensor`` extension columns
(``masks`` a uint8 (K, H, W) tensor). The readers still accept it (``per_view_fields(...,
version=1)``); Hugging Face ``datasets`` cannot load it: regenerate with ``silpose gen``.
"""

from __future__ import annotations

import json
from importlib.metadata import PackageNotFoundError, version

import numpy as np
import pyarrow as pa

from .camera import Rig, RigError
from .skeleton import JOINT_NAMES, N_JOINTS, PARENTS, TERMINAL_JOINTS

#: Version written; see the module docstring. Readers accept every version in ``KNOWN_VERSIONS``.
FORMAT_VERSION = 2
KNOWN_VERSIONS = (1, 2)
METADATA_KEY = b"silpose"
#: Schema metadata key Hugging Face ``datasets`` reads its features from.
HF_METADATA_KEY = b"huggingface"
GENERATOR_NAME = "silpose-datagen"

class DatasetError(ValueError):
    """A dataset file or record is malformed; the message names the file and the field."""


#: Metadata fields a reader requires.
REQUIRED_METADATA = (
    "format_version",
    "cameras",
    "joint_names",
    "parents",
    "n_points",
    "units",
    "conventions",
    "generator",
    "config",
)

UNITS = {
    "joints": "metres, world frame",
    "masks": "1-bit PNG silhouette per view (1 = person); silpose reads (K, H, W) uint8 0/1",
    "contours": "pixels",
    "contour_centroid": "pixels",
    "contour_scale": "pixels",
    "contour_length": "pixels",
    "area": "pixels",
    "cameras.K": "pixels",
    "cameras.t": "metres",
}

DEFAULT_CONVENTIONS = {
    "world_frame": "right-handed, metres, z up, floor at z = 0, workspace a 3 m x 3 m square centred at the origin",
    "camera_frame": "OpenCV: x right, y down, z forward; x ~ K (R X + t), then OpenCV distortion `dist`",
    "pixel_frame": "x right, y down, pixel centres at integer coordinates, origin at the centre of the top-left pixel",
    "joints": "19 joints in `joint_names` order, `parents` gives each joint's parent (-1 for the root, pelvis); "
    "the structure target is joints - joints[pelvis] in world orientation",
    "contours": "outer boundary of the largest 8-connected silhouette blob (holes ignored), traced through the "
    "centres of its boundary pixels (cv2.findContours), resampled to n_points equally spaced in arc length",
    "contour_orientation": "clockwise on screen: positive shoelace area 1/2 sum(x_i y_{i+1} - x_{i+1} y_i) "
    "in (x right, y down) pixel coordinates",
    "contour_start": "where the upward vertical ray from the blob's area centroid leaves the outline for the last "
    "time (the top of the head for a standing person)",
    "contour_normalisation": "contour_centroid c = mean of the n points; contour_scale s = sqrt(mean ||p_i - c||^2) "
    "(RMS distance); normalised = (contours - c) / s; pixels = normalised * s + c",
    "contour_length": "perimeter of the raw boundary polyline (cv2.arcLength), pixels",
    "area": "pixels in the largest blob",
    "touches_border": "the largest blob has a pixel on the image border",
    "n_blobs": "8-connected foreground components in the mask",
    "views": "the K views are in `cameras` order in every per-view column",
}


#: Numpy dtype of every per-view array column (``touches_border`` is bool).
TENSOR_DTYPES = {
    "joints": "float32",
    "masks": "uint8",
    "contours": "float32",
    "contour_centroid": "float32",
    "contour_scale": "float32",
    "contour_length": "float32",
    "area": "int32",
    "n_blobs": "int32",
}
TENSOR_COLUMNS = tuple(TENSOR_DTYPES)
SCALAR_COLUMNS = {"sample_id": pa.int64(), "split": pa.string(), "seed": pa.int64(), "redraws": pa.int32()}
STRUCT_COLUMNS = ("subject", "gait")
ALL_COLUMNS = tuple(SCALAR_COLUMNS) + STRUCT_COLUMNS + TENSOR_COLUMNS + ("touches_border",)


def column_shapes(n_views: int, height: int, width: int, n_points: int) -> dict[str, tuple[int, ...]]:
    """Per-row array shape of every per-view column for K = ``n_views`` views of ``width`` x ``height``."""
    K = n_views
    return {
        "joints": (N_JOINTS, 3),
        "masks": (K, height, width),
        "contours": (K, n_points, 2),
        "contour_centroid": (K, 2),
        "contour_scale": (K,),
        "contour_length": (K,),
        "area": (K,),
        "n_blobs": (K,),
        "touches_border": (K,),
    }


#: Hugging Face ``datasets.Image`` storage: one PNG file per struct (``path`` stays null).
MASK_IMAGE_TYPE = pa.struct([pa.field("bytes", pa.binary()), pa.field("path", pa.string())])


def nested_list_type(value_type: pa.DataType, shape: tuple[int, ...]) -> pa.DataType:
    """``fixed_size_list`` nested once per axis of ``shape``, outermost first: (19, 3) -> list<list<v>[3]>[19]."""
    typ = value_type
    for size in reversed(shape):
        typ = pa.list_(typ, int(size))
    return typ


def per_view_fields(
    n_views: int, height: int, width: int, n_points: int, version: int = FORMAT_VERSION
) -> dict[str, pa.DataType]:
    """Arrow types of the per-view columns of format ``version`` (see the module docstring)."""
    if version not in KNOWN_VERSIONS:
        raise ValueError(f"format version {version!r} unknown (known: {list(KNOWN_VERSIONS)})")
    shapes = column_shapes(n_views, height, width, n_points)
    if version == 1:
        types = {name: pa.fixed_shape_tensor(pa.from_numpy_dtype(np.dtype(dt)), shapes[name])
                 for name, dt in TENSOR_DTYPES.items()}
        types["touches_border"] = pa.list_(pa.bool_(), n_views)
        return types
    types = {name: nested_list_type(pa.from_numpy_dtype(np.dtype(dt)), shapes[name])
             for name, dt in TENSOR_DTYPES.items() if name != "masks"}
    types["masks"] = pa.list_(MASK_IMAGE_TYPE, n_views)
    types["touches_border"] = pa.list_(pa.bool_(), n_views)
    return {name: types[name] for name in shapes}


def build_schema(metadata: dict, subject_fields: list[str], gait_fields: list[str]) -> pa.Schema:
    """The Arrow schema of a shard (format ``FORMAT_VERSION``), with ``metadata`` serialised under the
    ``silpose`` key and the Hugging Face features (``hf_features``) under ``huggingface``."""
    cams = metadata["cameras"]
    height, width = int(cams[0]["height"]), int(cams[0]["width"])
    fields = [pa.field(name, typ) for name, typ in SCALAR_COLUMNS.items()]
    fields.append(pa.field("subject", pa.struct([pa.field(f, pa.float32()) for f in subject_fields])))
    fields.append(pa.field("gait", pa.struct([pa.field(f, pa.float32()) for f in gait_fields])))
    for name, typ in per_view_fields(len(cams), height, width, int(metadata["n_points"])).items():
        fields.append(pa.field(name, typ))
    features = hf_features(len(cams), int(metadata["n_points"]), subject_fields, gait_fields)
    return pa.schema(fields, metadata={
        METADATA_KEY: json.dumps(metadata, sort_keys=True).encode(),
        HF_METADATA_KEY: json.dumps({"info": {"features": features}}).encode(),
    })


def _hf_value(dtype: str) -> dict:
    return {"dtype": dtype, "_type": "Value"}


def _hf_list(feature: dict, shape: tuple[int, ...]) -> dict:
    for size in reversed(shape):
        feature = {"feature": feature, "length": int(size), "_type": "List"}
    return feature


def hf_features(n_views: int, n_points: int, subject_fields: list[str], gait_fields: list[str]) -> dict:
    """The Hugging Face ``datasets.Features`` of a version-2 shard, as ``Features.to_dict()`` writes it.

    Nested ``List(..., length=...)`` for the arrays and ``List(Image(), length=K)`` for ``masks``
    (``datasets`` >= 4 understands this form). ``datasets`` applies a declared feature only where its
    Arrow type equals the column's, which ``tests/shared/test_dataset_hf.py`` checks.
    """
    shapes = column_shapes(n_views, 1, 1, n_points)  # image size does not enter the features
    features = {name: _hf_value(str(typ)) for name, typ in SCALAR_COLUMNS.items()}  # "int64", "string", ...
    features["subject"] = {f: _hf_value("float32") for f in subject_fields}
    features["gait"] = {f: _hf_value("float32") for f in gait_fields}
    for name, dt in TENSOR_DTYPES.items():
        if name == "masks":
            features[name] = _hf_list({"_type": "Image"}, (n_views,))
        else:
            features[name] = _hf_list(_hf_value(dt), shapes[name])
    features["touches_border"] = _hf_list(_hf_value("bool"), (n_views,))
    return features


#: Optional metadata fields: the rig's ``transform`` (calibration frame -> this dataset's world frame)
#: and ``workspace`` (where walkers stand), written only for rigs that have them
#: (``silpose.shared.rig_frame``); absent means identity and the 3 m x 3 m square centred at the origin.
RIG_FRAME_METADATA = ("transform", "workspace")


def build_metadata(cameras: list[dict], config: dict, n_points: int, generator_version: str | None = None,
                   rig_frame: dict | None = None) -> dict:
    """The ``silpose`` metadata document of a dataset.

    Args:
        cameras: ``Rig.to_dict()["cameras"]`` (name, K, R, t, width, height, dist per camera).
        config: the generator configuration (JSON-serialisable).
        n_points: contour points per view.
        generator_version: defaults to the installed silpose-datagen version.
        rig_frame: ``transform`` and/or ``workspace`` dicts of the rig (``Rig.to_dict()`` holds them only
            when they differ from the defaults); stored as top-level fields of the same names.
    """
    if generator_version is None:
        generator_version = _installed_version(GENERATOR_NAME)
    conventions = dict(DEFAULT_CONVENTIONS)
    extra = {k: v for k, v in (rig_frame or {}).items() if k in RIG_FRAME_METADATA}
    if "workspace" in extra:
        conventions["world_frame"] = "right-handed, metres, z up, floor at z = 0, workspace: metadata field 'workspace'"
    if any(isinstance(c, dict) and c.get("fisheye") for c in cameras):
        conventions["camera_frame"] = (DEFAULT_CONVENTIONS["camera_frame"] + "; a camera with `fisheye`: true has "
                                       "OpenCV's fisheye model instead (cv2.fisheye; `dist` = k1, k2, k3, k4)")
    if "transform" in extra:
        conventions["calibration_frame"] = (
            "metadata field 'transform' maps the rig's calibration frame to the world frame: "
            "X_world = scale * rotation @ X_calibration + offset")
    return {
        **extra,
        "format_version": FORMAT_VERSION,
        "generator": {"name": GENERATOR_NAME, "version": generator_version},
        "cameras": cameras,
        "n_views": len(cameras),
        "image_size": [int(cameras[0]["width"]), int(cameras[0]["height"])],
        "n_points": int(n_points),
        "joint_names": list(JOINT_NAMES),
        "parents": list(PARENTS),
        "terminal_joints": list(TERMINAL_JOINTS),
        "units": dict(UNITS),
        "conventions": conventions,
        "config": config,
    }


def _installed_version(dist: str) -> str:
    try:
        return version(dist)
    except PackageNotFoundError:
        return "unknown"


def check_metadata(meta: dict, source: str) -> None:
    """Raise DatasetError (naming ``source`` and the field) unless ``meta`` is a valid document."""
    if not isinstance(meta, dict):
        raise DatasetError(f"{source}: metadata 'silpose' must be a JSON object")
    for key in REQUIRED_METADATA:
        if key not in meta:
            raise DatasetError(f"{source}: metadata field {key!r} missing")
    if meta["format_version"] not in KNOWN_VERSIONS:
        raise DatasetError(
            f"{source}: metadata field 'format_version': unknown version {meta['format_version']!r} "
            f"(this reader knows {list(KNOWN_VERSIONS)})"
        )
    if list(meta["joint_names"]) != list(JOINT_NAMES):
        raise DatasetError(f"{source}: metadata field 'joint_names' differs from silpose's 19-joint skeleton")
    try:
        rig_from_metadata(meta, source=f"{source}: metadata")
    except RigError as exc:
        raise DatasetError(str(exc)) from None
    if not isinstance(meta["n_points"], int) or meta["n_points"] < 3:
        raise DatasetError(f"{source}: metadata field 'n_points': expected an integer >= 3")


def rig_from_metadata(meta: dict, source: str | None = None) -> Rig:
    """The dataset's rig: its cameras plus the optional ``transform`` and ``workspace`` fields."""
    d = {"cameras": meta["cameras"], **{k: meta[k] for k in RIG_FRAME_METADATA if k in meta}}
    return Rig.from_dict(d, source=source)
