"""The silpose dataset schema: Arrow column types and the ``silpose`` metadata document.

A dataset is a folder of Parquet shards ``{split}-{i:05d}-of-{n:05d}.parquet`` (zstd). One row is
one sample seen by K calibrated cameras:

============================  ==========================================  =======================
column                        Arrow type                                  meaning
============================  ==========================================  =======================
``sample_id``                 int64                                       index within its split
``split``                     string                                      ``train`` / ``test``
``seed``                      int64                                       dataset seed
``redraws``                   int32                                       rejected draws before it
``subject``                   struct<name: float32, ...>                  body proportions
``gait``                      struct<name: float32, ...>                  walk-cycle parameters
``joints``                    fixed_shape_tensor<float32>[19, 3]          world, metres
``masks``                     fixed_shape_tensor<uint8>[K, H, W]          silhouettes, 0/1
``contours``                  fixed_shape_tensor<float32>[K, n, 2]        pixels (x right, y down)
``contour_centroid``          fixed_shape_tensor<float32>[K, 2]           pixels
``contour_scale``             fixed_shape_tensor<float32>[K]              pixels
``contour_length``            fixed_shape_tensor<float32>[K]              pixels
``area``                      fixed_shape_tensor<int32>[K]                pixels (mask sum)
``n_blobs``                   fixed_shape_tensor<int32>[K]                connected components
``touches_border``            fixed_size_list<bool>[K]                    mask touches the border
============================  ==========================================  =======================

The schema metadata holds one JSON document under the key ``silpose`` (see ``build_metadata``).
"""

from __future__ import annotations

import json
from importlib.metadata import PackageNotFoundError, version

import pyarrow as pa

from .camera import Rig, RigError
from .skeleton import JOINT_NAMES, N_JOINTS, PARENTS, TERMINAL_JOINTS

FORMAT_VERSION = 1
KNOWN_VERSIONS = (1,)
METADATA_KEY = b"silpose"
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
    "masks": "0/1 silhouette (uint8), one per view",
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


def per_view_fields(n_views: int, height: int, width: int, n_points: int) -> dict[str, pa.DataType]:
    """Arrow types of the tensor columns for K = ``n_views`` views of ``width`` x ``height``."""
    K = n_views
    return {
        "joints": pa.fixed_shape_tensor(pa.float32(), (N_JOINTS, 3)),
        "masks": pa.fixed_shape_tensor(pa.uint8(), (K, height, width)),
        "contours": pa.fixed_shape_tensor(pa.float32(), (K, n_points, 2)),
        "contour_centroid": pa.fixed_shape_tensor(pa.float32(), (K, 2)),
        "contour_scale": pa.fixed_shape_tensor(pa.float32(), (K,)),
        "contour_length": pa.fixed_shape_tensor(pa.float32(), (K,)),
        "area": pa.fixed_shape_tensor(pa.int32(), (K,)),
        "n_blobs": pa.fixed_shape_tensor(pa.int32(), (K,)),
        "touches_border": pa.list_(pa.bool_(), K),
    }


#: Numpy dtype of every tensor column.
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


def build_schema(metadata: dict, subject_fields: list[str], gait_fields: list[str]) -> pa.Schema:
    """The Arrow schema of a shard, with ``metadata`` serialised under the ``silpose`` key."""
    cams = metadata["cameras"]
    height, width = int(cams[0]["height"]), int(cams[0]["width"])
    fields = [pa.field(name, typ, nullable=False) for name, typ in SCALAR_COLUMNS.items()]
    fields.append(pa.field("subject", pa.struct([pa.field(f, pa.float32(), nullable=False) for f in subject_fields])))
    fields.append(pa.field("gait", pa.struct([pa.field(f, pa.float32(), nullable=False) for f in gait_fields])))
    for name, typ in per_view_fields(len(cams), height, width, int(metadata["n_points"])).items():
        fields.append(pa.field(name, typ, nullable=False))
    return pa.schema(fields, metadata={METADATA_KEY: json.dumps(metadata, sort_keys=True).encode()})


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
