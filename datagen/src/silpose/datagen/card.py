"""The dataset card ``README.md`` of a dataset folder (Hugging Face style front matter).

It documents the files, the schema, units and conventions, the camera rig, the subject and gait
distributions (documented and as measured), how to load the data with pyarrow, pandas, DuckDB,
Polars, Hugging Face ``datasets`` and silpose, embeds the preview contact sheet and (with both splits)
the train vs test characters picture (``silpose.datagen.character_sheet``), and carries the
license (CC BY 4.0), Hugging Face task and size categories and the paper's BibTeX.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from silpose.shared.atomic import write_text_atomic
from silpose.shared.camera import Rig
from silpose.shared.dataset import list_shards, load_split, read_metadata, rig_from_metadata
from silpose.shared.dataset_schema import TENSOR_DTYPES
from silpose.shared.rig_frame import Workspace

from .character_sheet import CHARACTERS_NAME
from .characters import measured_comparison, side_by_side
from .manifest import read_manifest
from .preview import PREVIEW_NAME
from .subjects import describe_distribution
from .walk import GAIT_FIELDS, gait_ranges

CARD = "README.md"


#: License of every generated dataset (synthetic data made by silpose); the code is MIT (LICENSE).
DATA_LICENSE = "cc-by-4.0"
#: Hugging Face task categories of the data: 2D silhouettes in, 3D joints (and keypoints) out.
TASK_CATEGORIES = ("image-to-3d", "keypoint-detection")
#: Hugging Face ``size_categories`` buckets: (upper bound on the row count, exclusive; label).
SIZE_BUCKETS = ((10**3, "n<1K"), (10**4, "1K<n<10K"), (10**5, "10K<n<100K"), (10**6, "100K<n<1M"),
                (10**7, "1M<n<10M"), (10**8, "10M<n<100M"), (10**9, "100M<n<1B"), (10**10, "1B<n<10B"),
                (10**11, "10B<n<100B"), (10**12, "100B<n<1T"))
#: The paper this dataset is made for (BibTeX, also in CITATION.cff at the repository root).
PAPER_BIBTEX = """@inproceedings{grauman2003inferring,
  author    = {Grauman, Kristen and Shakhnarovich, Gregory and Darrell, Trevor},
  title     = {Inferring {3D} Structure with a Statistical Image-Based Shape Model},
  booktitle = {Proceedings of the Ninth IEEE International Conference on Computer Vision (ICCV)},
  year      = {2003},
  pages     = {641--647}
}"""


def size_category(n_rows: int) -> str:
    """Hugging Face's ``size_categories`` label for a dataset of ``n_rows`` rows (all splits)."""
    for bound, label in SIZE_BUCKETS:
        if n_rows < bound:
            return label
    return "n>1T"


def _front_matter(name: str, splits: list[str], n_rows: int) -> str:
    lines = ["---", f"pretty_name: silpose {name}", f"license: {DATA_LICENSE}", "task_categories:",
             *[f"- {t}" for t in TASK_CATEGORIES], "size_categories:", f"- {size_category(n_rows)}", "tags:",
             "- silhouettes", "- multi-view", "- 3d-human-pose", "- synthetic", "configs:", "- config_name: default",
             "  data_files:"]
    for s in splits:
        lines += [f"  - split: {s}", f'    path: "{s}-*.parquet"']
    return "\n".join(lines + ["---", ""])


def _rig_table(meta: dict) -> str:
    rows = ["| camera | fx | fy | cx | cy | centre x, y, z (m) | image | dist |", "|---|---|---|---|---|---|---|---|"]
    for c in meta["cameras"]:
        K, R, t = np.array(c["K"]), np.array(c["R"]), np.array(c["t"])
        centre = -R.T @ t
        rows.append(
            f"| {c['name']} | {K[0, 0]:.2f} | {K[1, 1]:.2f} | {K[0, 2]:.2f} | {K[1, 2]:.2f} | "
            f"{centre[0]:.3f}, {centre[1]:.3f}, {centre[2]:.3f} | {c['width']}x{c['height']} | "
            f"{'zeros' if not np.any(c.get('dist', [])) else c['dist']}{' (fisheye)' if c.get('fisheye') else ''} |"
        )
    return "\n".join(rows)


def _schema_table(meta: dict, subject: list[str], gait: list[str]) -> str:
    K, (W, H), n = len(meta["cameras"]), meta["image_size"], meta["n_points"]
    shapes = {
        "joints": "19, 3", "masks": f"{K}, {H}, {W}", "contours": f"{K}, {n}, 2", "contour_centroid": f"{K}, 2",
        "contour_scale": f"{K}", "contour_length": f"{K}", "area": f"{K}", "n_blobs": f"{K}",
    }
    types = {
        "joints": "list<list<float32>[3]>[19]", "masks": f"list<image>[{K}] (1-bit PNG, {W}x{H})",
        "contours": f"list<list<list<float32>[2]>[{n}]>[{K}]", "contour_centroid": f"list<list<float32>[2]>[{K}]",
        "contour_scale": f"list<float32>[{K}]", "contour_length": f"list<float32>[{K}]",
        "area": f"list<int32>[{K}]", "n_blobs": f"list<int32>[{K}]",
    }
    units = meta["units"]
    rows = ["| column | type | per-row shape | unit / meaning |", "|---|---|---|---|",
            "| sample_id | int64 | | index within the split |", "| split | string | | train / test |",
            "| seed | int64 | | dataset seed |", "| redraws | int32 | | draws rejected (not fully visible) before this one |",
            f"| subject | struct of float32 | | {', '.join(subject)} |", f"| gait | struct of float32 | | {', '.join(gait)} |"]
    for col in TENSOR_DTYPES:
        rows.append(f"| {col} | {types[col]} | ({shapes[col]}) | {units.get(col, meta['conventions'].get(col, ''))} |")
    rows.append(f"| touches_border | list<bool>[{K}] | ({K}) | {meta['conventions'].get('touches_border', '')} |")
    rows.append("\n`list<T>[m]` is an Arrow/Parquet fixed-size list (Hugging Face `List(T, length=m)`); `image` is "
                "Hugging Face's `Image` storage, a struct `{bytes: PNG file, path: null}` (1 = person).")
    return "\n".join(rows)


def _distribution_section(split: str) -> str:
    try:
        d = describe_distribution(split)
    except Exception as exc:  # the card must still be written
        return f"(documented distribution unavailable: {exc})\n"
    lines = ["| field | distribution | low | high |", "|---|---|---|---|"]
    for key, spec in d.get("fields", {}).items():
        if "value" in spec:
            lines.append(f"| {key} | constant | {spec['value']} | {spec['value']} |")
        else:
            lines.append(f"| {key} | {spec.get('distribution', '')} | {spec.get('low', '')} | {spec.get('high', '')} |")
    for k, v in d.get("clothing_probability", {}).items():
        lines.append(f"\n- probability of {k}: {v}")
    for note in d.get("notes", []):
        lines.append(f"\n- {note}")
    return "\n".join(lines) + "\n"


def _rig_frame_section(rig: Rig, placement: Workspace) -> str:
    """The rig's workspace, where walkers were placed (``placement``), and the calibration -> world
    transform, in words and numbers."""
    ws, tr = rig.workspace, rig.transform
    (x0, x1), (y0, y1) = placement.bounds
    if placement.to_dict() == ws.to_dict():
        lines = [f"- **workspace** (walkers' pelvis positions, uniform): {ws.describe()}, i.e. x in "
                 f"[{x0:.3f}, {x1:.3f}] m, y in [{y0:.3f}, {y1:.3f}] m on the floor (z = 0)."]
    else:
        lines = [f"- **workspace** (the floor enough cameras see, not every one): {ws.describe()}; walkers' pelvis "
                 f"positions (uniform) are on its part every camera sees (config field `placement`): "
                 f"{placement.describe()}, i.e. x in [{x0:.3f}, {x1:.3f}] m, y in [{y0:.3f}, {y1:.3f}] m on the floor."]
    if tr.is_identity:
        lines.append("- **calibration frame**: the world frame itself (identity transform).")
    else:
        up = tr.up_in_calibration
        lines.append(
            "- **calibration frame -> world frame**: `X_world = scale * rotation @ X_calibration + offset` with "
            f"scale {tr.scale:g} m per calibration unit, rotation {np.round(tr.rotation, 6).tolist()}, offset "
            f"{np.round(tr.offset, 6).tolist()} m (world up is {np.round(up, 6).tolist()} in the calibration's "
            "axes); the inverse gives joints in the lab's own frame (`Rig.transform.to_calibration`).")
    return "\n".join(lines) + "\n"


def _gait_section(workspace: Workspace) -> str:
    rows = ["| field | distribution | low | high |", "|---|---|---|---|"]
    ranges = gait_ranges(workspace)
    for k in GAIT_FIELDS:
        lo, hi = ranges[k]
        rows.append(f"| {k} | uniform | {lo:.4g} | {hi:.4g} |")
    rows.append("\nSame for both splits; angles in radians, x and y in metres. A draw whose person is not fully "
                "inside every image is redrawn (counted in `redraws`), so the kept positions are not exactly uniform.")
    return "\n".join(rows) + "\n"


def _library_section(motion: dict, loaded: dict) -> str:
    """The clips of a motion-library dataset, by activity group: identity, split, licence, usage;
    then the library's acknowledgement."""
    clips = motion["clips"]
    lib = motion.get("library", {})
    counts = {s: np.bincount(np.asarray(d.gait["clip"], np.int64), minlength=len(clips)) for s, d in loaded.items()}
    groups = sorted({c["group"] for c in clips}, key=lambda g: (g != "walk", g))
    rows = ["| group | # | clip | subject | description | split | frames | weight per frame | licence | source | "
            + " | ".join(f"{s} samples" for s in loaded) + " |", "|" + "---|" * (10 + len(loaded))]
    summary = ["| group | train clips | test clips | " + " | ".join(f"{s} samples" for s in loaded) + " |",
               "|" + "---|" * (3 + len(loaded))]
    for g in groups:
        idx = [i for i, c in enumerate(clips) if c["group"] == g]
        summary.append(f"| {g} | {sum(clips[i]['split'] == 'train' for i in idx)} | "
                       f"{sum(clips[i]['split'] == 'test' for i in idx)} | "
                       + " | ".join(str(int(sum(counts[s][i] for i in idx))) for s in loaded) + " |")
        for i in idx:
            c = clips[i]
            rows.append(f"| {g} | {i} | {c['id']} | {c.get('subject', '-')} | {c.get('description', '') or '-'} | "
                        f"{c['split']} | {c['frames']} | {c['weight']:.3g} | {c['licence'] or '-'} | "
                        f"{('`' + c['source'] + '`') if c.get('source') else '-'} | "
                        + " | ".join(str(int(counts[s][i])) for s in loaded) + " |")
    weights = ", ".join(f"{k} {v:g}" for k, v in (motion.get("weights") or {}).items()) or "1 each"
    return "\n".join([
        "Poses come from silpose's motion library (per-frame bone directions and root motion of motion-capture "
        "clips, read once by Blender's BVH importer when the library was built; `silpose motions list`) mixed with "
        f"the procedural walk (share {motion.get('procedural_walk', 0):g}), retargeted onto every generated body: "
        "bone directions, pelvis and chest orientation from the clip, bone lengths from the subject's own "
        "proportions, feet put back on the floor (`silpose.datagen.motion.retarget`). Splits hold out subjects: "
        "train samples draw from the train clips, test samples from the test clips (other people). Each row's "
        "`gait` column holds `clip` (the # below; 0 = the procedural walk), `frame` (0-based BVH frame), `mirror`, "
        "and the walk's parameters (0 for a clip frame, except `heading`, `x`, `y`). A group is drawn with "
        f"probability proportional to its weight ({weights}; groups {', '.join(motion.get('groups') or ['all'])}), "
        f"then one of its frames uniformly. Mirror augmentation: {'on' if motion.get('mirror') else 'off'}. "
        + (f"Part mixing: {float(motion['part_mix']):g} of the train split's library frames take their hips and legs "
           "from a second train frame (`legs_clip`, `legs_frame`, `legs_mirror`; `legs_clip` -1: the frame's own legs). "
           if float(motion.get("part_mix") or 0) > 0 else "")
        + (f"Limb swing: {float(motion['limb_swing']):g} of the train split's library frames have each arm turned "
           f"about its shoulder and each leg about its hip by up to {float(motion.get('limb_swing_deg', 90)):g} degrees "
           "(`swing_<limb>_x|y|z`: rotation vectors, radians, world axes; all 0: not swung). "
           if float(motion.get("limb_swing") or 0) > 0 else "")
        + f"Library frames sha256 `{str(lib.get('frames_sha256', ''))[:16]}`, {lib.get('fps', '?')} fps.\n",
        *summary, "", *rows, "",
        *([f"**Acknowledgement.** {lib['acknowledgement']}\n"] if lib.get("acknowledgement") else []),
    ])


def _motion_section(motion: dict, loaded: dict) -> str:
    """The clips of a motion-capture dataset: identity, frames used, weights, licences, usage."""
    if motion.get("source") == "library":
        return _library_section(motion, loaded)
    clips = motion["clips"]
    rows = ["| # | clip | file | frames | fps | frames used (first, last, stride) | weight | joint map | "
            "vertical extent m | licence / source | note | sha256 | " + " | ".join(f"{s} samples" for s in loaded) + " |",
            "|" + "---|" * (12 + len(loaded))]
    counts = {s: np.bincount(np.asarray(d.gait["clip"], np.int64), minlength=len(clips)) for s, d in loaded.items()}
    for i, c in enumerate(clips):
        fps = 1.0 / c["frame_time"] if c["frame_time"] > 0 else float("nan")
        rows.append(f"| {i} | {c['name']} | `{c['file']}` | {c['frames']} | {fps:.1f} | {c['used_frames'][0]}, "
                    f"{c['used_frames'][1]}, {c['used_frames'][2]} ({c['n_used']}) | {c['weight']:g} | {c['joint_map']} | "
                    f"{c['vertical_extent_m']:.3f} | {c['licence'] or '-'} | {c['note'] or '-'} | `{c['sha256'][:12]}` | "
                    + " | ".join(str(int(counts[s][i])) for s in loaded) + " |")
    return "\n".join([
        "Poses come from motion-capture clips (BVH), imported by Blender's own importer and retargeted onto every "
        "generated body: bone directions, pelvis and chest orientation from the clip, bone lengths from the "
        "subject's own proportions, feet put back on the floor (`silpose.datagen.motion.retarget`). Each row's `gait` "
        "column holds `clip` (the # below), `frame` (0-based BVH frame), `mirror` (1: left/right mirrored), "
        f"`heading` (radians) and `x`, `y` (metres). Mirror augmentation: {'on' if motion.get('mirror') else 'off'}. "
        "A clip is drawn with probability proportional to weight x frames used, then one of its used frames "
        "uniformly; heading is uniform on [0, 2 pi) and x, y uniform on the workspace (redrawn when the person "
        "leaves an image). The vertical extent (metres, after `scale`) is a check of the clip's unit.\n",
        *rows, "",
    ])


def _measured_table(values: dict[str, np.ndarray]) -> str:
    rows = ["| field | mean | std | min | max |", "|---|---|---|---|---|"]
    for k, v in values.items():
        v = np.asarray(v, np.float64)
        rows.append(f"| {k} | {v.mean():.4g} | {v.std():.4g} | {v.min():.4g} | {v.max():.4g} |")
    return "\n".join(rows)


def _loading(name: str) -> str:
    return f"""```python
import glob, json
import numpy as np

# Hugging Face datasets (>= 4): masks come back as images (PIL, mode "1"), arrays as nested lists
from datasets import load_dataset
hf = load_dataset("{name}")   # this card's `configs`; or:
hf = load_dataset("parquet", data_files={{"train": "{name}/train-*.parquet", "test": "{name}/test-*.parquet"}})
sample = hf["train"].with_format("numpy")[0]   # joints (19, 3), contours (K, n, 2), masks (K, H, W)

# pyarrow: nested fixed-size lists flatten to numpy arrays without copying
import pyarrow.parquet as pq
files = sorted(glob.glob("{name}/train-*.parquet"))
table = pq.read_table(files, columns=["joints", "masks"])
joints = table["joints"].combine_chunks().flatten().flatten().to_numpy().reshape(-1, 19, 3)   # metres
meta = json.loads(pq.read_schema(files[0]).metadata[b"silpose"])  # cameras, joint names, conventions
import cv2   # or PIL: every mask is a PNG file
png = table["masks"].combine_chunks().flatten().field("bytes")[0].as_py()
mask = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_UNCHANGED) > 0   # (H, W) bool, first view

# pandas
df = pq.read_table(files, columns=["sample_id", "gait", "contour_scale"]).to_pandas()

# DuckDB
import duckdb
duckdb.sql("SELECT split, count(*), avg(gait.stride) FROM '{name}/*.parquet' GROUP BY split").show()

# Polars
import polars as pl
df = pl.read_parquet("{name}/train-*.parquet", columns=["sample_id", "joints"])

# silpose
from silpose.shared.dataset import load_split
train = load_split("{name}", "train", with_masks=True)   # numpy arrays (masks decoded), rig, metadata
```"""


def _citation() -> str:
    return (f"## License and citation\n\nThe data are synthetic, rendered by silpose, and licensed under "
            f"[CC BY 4.0](https://creativecommons.org/licenses/by/4.0/) (`license: {DATA_LICENSE}`); the silpose "
            "code is MIT. The shape+structure model these data are made for:\n\n```bibtex\n"
            f"{PAPER_BIBTEX}\n```\n")


def _characters_picture(root: Path) -> list[str]:
    """The card's lines embedding ``characters.png`` with a caption, or none when it was not written."""
    if not (root / CHARACTERS_NAME).is_file():
        return []
    return [f"![silhouettes of training characters (left) and test characters (right), each labelled with its "
            f"character kind]({CHARACTERS_NAME})\n",
            "*Training (left) vs test (right) characters: one mask per walker (the view where it covers most "
            "pixels), cropped and scaled to equal height, labelled with its kind (kinds explained under the measured "
            "table below), sample id and view. What differs: training skirts, dresses and coats are bell- or "
            "tulip-shaped (coats hang from the mid-torso), trousers flare or taper, hair falls 0.2-0.45 or 0.75-1.0 "
            "head radii behind the head and bulky jackets occur; test skirts are straight cones from the hips, "
            "trousers straight, hair 0.6 head radii behind, no jackets, and some test walkers wear nothing.*\n"]


def write_card(root: str | Path) -> Path:
    """Write ``root/README.md`` from the shards, the manifest and (if present) the preview."""
    root = Path(root)
    manifest = read_manifest(root)
    splits = [s for s in manifest["counts"] if list_shards(root, s)]
    meta = read_metadata(list_shards(root, splits[0])[0])
    rig = rig_from_metadata(meta)
    loaded = {s: load_split(root, s, columns=["subject", "gait", "contour_length", "area"]) for s in splits}
    first = loaded[splits[0]]
    subject, gait = list(first.subject), list(first.gait)
    cfg = manifest["config"]
    placement = Workspace.from_dict(cfg["placement"]) if "placement" in cfg else rig.workspace
    motion = cfg.get("motion")
    parts = [
        _front_matter(manifest["name"], splits, sum(int(manifest["counts"][s]) for s in splits)),
        f"# silpose dataset `{manifest['name']}`\n",
        f"Synthetic multi-view silhouettes of {'people posed from motion-capture clips' if motion else 'walking people'} "
        "with exact 3D joints, generated by "
        f"`silpose gen` ({meta['generator']['name']} {meta['generator']['version']}) for the shape+structure "
        "model of Grauman, Shakhnarovich & Darrell (ICCV 2003). Test subjects are drawn from a *different* "
        "distribution (other proportions, clothing, hair) than training subjects.\n",
        "## Files\n",
        "| split | samples | shards | redraws |\n|---|---|---|---|",
        *[f"| {s} | {manifest['counts'][s]} | {len(list_shards(root, s))} | {manifest['redraws'].get(s, 0)} |" for s in splits],
        f"\nShards `{{split}}-{{i:05d}}-of-{{n:05d}}.parquet` (zstd). `manifest.json` holds the config, seeds, "
        "counts, per-shard sha256 and timing. Config: "
        f"seed {cfg['seed']}, renderer `{cfg['renderer']}`"
        f"{' (' + cfg['blender_engine'] + ')' if cfg['renderer'] == 'blender' else ''}, "
        f"{cfg['n_points']} contour points, shard size {cfg['shard_size']}.\n",
    ]
    if (root / PREVIEW_NAME).is_file():
        parts.append(f"![mask, contour and projected joints of a few samples in every view]({PREVIEW_NAME})\n")
    parts += [
        "## Schema\n", _schema_table(meta, subject, gait),
        "\nEvery shard's Arrow schema metadata holds one JSON document under the key `silpose`: "
        "`format_version`, `cameras` (name, K, R, t, width, height, dist; `fisheye`: true for OpenCV's fisheye "
        "model), `joint_names`, `parents`, `terminal_joints`, `n_points`, `units`, `conventions`, `generator`, `config`.\n",
        "## Units and conventions\n",
        *[f"- **{k}**: {v}" for k, v in meta["conventions"].items()],
        f"\nJoints (`joint_names` order, parent in brackets): "
        + ", ".join(f"{i} {n} ({p})" for i, (n, p) in enumerate(zip(meta["joint_names"], meta["parents"]))) + "\n",
        "## Camera rig\n",
        "World->camera `x ~ K (R X + t)` (OpenCV axes); K, R, t of every camera are in the metadata.\n",
        _rig_table(meta), "",
        _rig_frame_section(rig, placement),
        "## Subjects and gait\n",
        *(["### motion-capture clips (both splits)\n", _motion_section(motion, loaded)] if motion else
          ["### documented gait distribution (both splits)\n", _gait_section(placement)]),
    ]
    if "train" in loaded and "test" in loaded:
        parts += ["### train vs test characters (documented)\n", *_characters_picture(root), side_by_side(),
                  "### train vs test characters (measured)\n",
                  measured_comparison(loaded["train"].subject, loaded["test"].subject)]
    for s in splits:
        parts += [f"### {s}: documented subject distribution\n", _distribution_section(s),
                  f"### {s}: measured subject parameters\n", _measured_table(loaded[s].subject), "",
                  f"### {s}: measured gait parameters\n", _measured_table(loaded[s].gait), "",
                  f"### {s}: measured silhouettes (mean over samples)\n",
                  "| view | contour length px | area px |\n|---|---|---|",
                  *[f"| {n} | {loaded[s].extra['contour_length'][:, k].mean():.1f} | "
                    f"{loaded[s].extra['area'][:, k].mean():.1f} |" for k, n in enumerate(first.rig.names)], ""]
    parts += ["## Loading\n", _loading(root.name), "", _citation()]
    return write_text_atomic(root / CARD, "\n".join(parts) + "\n")
