"""A synthetic lab recording: people walking in front of a four-camera rig along one wall (tests, benchmarks).

What a lab brings to ``silpose infer --videos`` is one video per camera plus its own calibration. This
module makes such a recording with silpose's own renderer, so the recordings workflow can be tested
end to end against known joints:

- :func:`lab_rig`: four 644x486 cameras mounted 2.3 m high along one wall of a 6 m x 8 m room, all
  seeing the 3 m x 3 m workspace in the room's middle, in silpose's frame (metres, z up, origin at the
  workspace centre), with the :class:`~silpose.shared.rig_frame.WorldTransform` from the lab's own
  calibration frame: millimetres, z pointing into the floor, origin at a floor corner of the room
  (:data:`LAB_TRANSFORM`). :func:`write_lab_calibration` writes that calibration as one OpenCV
  ``cv2.FileStorage`` file per camera, the way a lab would bring it
  (``silpose rig import`` reads it).
- :class:`Walker`: a person walking back and forth between two floor points at constant speed; its
  build and gait style are those of test sample ``index`` (:func:`silpose.datagen.scene.draw_sample_parameters`,
  so test-split builds and clothing), its stature its own (:func:`walker_stature`: adults' statures, not the
  test split's uniform range -- the first four test samples of seed 0 are all 1.91-1.93 m tall, which made
  every walker of a recording look alike), its clothing colours those of test sample ``index``'s frames
  (:func:`walker_clothing_bgr`, for colour videos composited from the masks), its pose at time ``t`` the
  procedural walk (:class:`silpose.datagen.motion.source.WalkMotion`) at the phase its travelled distance gives.
- :func:`render_lab`: the spawned-worker entry point (Blender): every frame, each walker is rendered
  ALONE through the renderer registry (``raster`` by default), and the cameras' masks are the OR of
  the walkers' masks. Written: ``masks/<camera>.mp4`` (the OR, 0/255, each frame through JPEG at quality
  :data:`MASK_JPEG_QUALITY` and then MPEG-4 part 2 ``mp4v``: lossy, as labs' mask videos often are; OpenCV's
  FFmpeg writer has no quality setting, so the JPEG pass is what smears the edges: ~0.4 % of the pixels end
  up mid-grey, 30..225, with ~220 grey levels in all) and ``truth.npz`` (joints, roots, and every walker's own clean
  masks, bit-packed).
- :func:`make_lab_recording`: the driver (never imports bpy): calibration files, then
  :func:`render_lab` in one spawned process (:func:`silpose.datagen.executor.spawned_map`: a worker that dies
  -- a crash in Blender, the OOM killer -- is reported at once with its exit code, never waited for).

Walkers' subjects and gaits come from the sample-draw stream of the test split (docs/conventions.md,
"Seeds"): walker ``index`` i is test sample i's first draw, so a recording is a pure function of
``(seed, walkers, n_frames, fps)``. Statures come from their own stream, ``derive_rng(seed,
stream_code("lab stature"), index)`` (:mod:`silpose.shared.seeds`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import cv2
import numpy as np

from silpose.shared.atomic import atomic_open, atomic_path
from silpose.shared.camera import Camera, Rig, look_at
from silpose.shared.rig_frame import Workspace, WorldTransform
from silpose.shared.seeds import derive_rng, stream_code

from .executor import WorkerDied, spawned_map
from .motion.source import WALK
from .render import rendering
from .renderers import renderer_from_config
from .scene import SampleScene, draw_sample_parameters

#: (width, height) of the lab's cameras, pixels
LAB_SIZE = (644, 486)
#: frames per second of the lab recording
LAB_FPS = 25.0
#: focal length, pixels: the whole workspace up to 2 m is seen by every camera (>= 19 px from the border)
LAB_FOCAL_PX = 420.0
#: the lab's calibration frame -> silpose's: mm -> m, z down -> z up (a half turn about x), origin at the
#: floor corner (x, y) = (-3, 3.8) m of silpose's frame; the camera wall is the room's far side y = -4.2 m
LAB_TRANSFORM = WorldTransform(rotation=np.diag([1.0, -1.0, -1.0]), scale=0.001, offset=np.array([-3.0, 3.8, 0.0]))
#: the walking area, silpose's frame: 3 m x 3 m centred in the room (what the cameras all see)
LAB_WORKSPACE = Workspace(center=np.zeros(2), size=np.array([3.0, 3.0]))
#: gait cycle length in metres travelled (two steps) and duration in seconds of the walkers
STRIDE_M, CYCLE_S = 1.3, 1.1
#: mask video codec (lossy) and suffix
MASK_FOURCC, MASK_SUFFIX = "mp4v", ".mp4"
#: JPEG quality every mask frame goes through before the video encoder (module docstring)
MASK_JPEG_QUALITY = 15
#: metres: mean and standard deviation of the walkers' statures (adults of both sexes: about 1.78 m and 1.65 m
#: means, 7 cm within each), clipped to the test split's stature range (:mod:`silpose.datagen.subjects`)
STATURE_MEAN_M, STATURE_STD_M, STATURE_RANGE_M = 1.71, 0.09, (1.50, 1.98)


def lab_rig(focal_px: float = LAB_FOCAL_PX) -> Rig:
    """The lab's rig in silpose's frame (module docstring): cameras ``cam0..cam3`` from left to right.

    Cameras sit at x = -2.25, -0.75, 0.75, 2.25 m on the wall y = -4.2 m, 2.3 m high, each aimed at
    (0.35 x, 0, 0.8) so the outer ones look inwards. A 1.75 m person in the centre is ~150 px tall.
    """
    w, h = LAB_SIZE
    K = np.array([[focal_px, 0.0, (w - 1) / 2], [0.0, focal_px, (h - 1) / 2], [0.0, 0.0, 1.0]])
    cams = []
    for i, x in enumerate((-2.25, -0.75, 0.75, 2.25)):
        R, t = look_at((x, -4.2, 2.3), (0.35 * x, 0.0, 0.8))
        cams.append(Camera(name=f"cam{i}", K=K, R=R, t=t, width=w, height=h))
    return Rig(tuple(cams))


def calibration_camera(cam: Camera, transform: WorldTransform) -> Camera:
    """``cam`` (silpose's frame) expressed in a calibration frame scaled to metres.

    With ``X = s A X_c + b`` (silpose from calibration units) and ``X_m = s X_c``:
    ``x_cam = R X + t = (R A) X_m + (R b + t)``.
    """
    return Camera(name=cam.name, K=cam.K, R=cam.R @ transform.rotation, t=cam.R @ transform.offset + cam.t,
                  width=cam.width, height=cam.height, dist=cam.dist)


def write_opencv_file(path: Path, cam: Camera, unit: float) -> None:
    """One camera as an OpenCV FileStorage YAML file, the way ``cv2.calibrateCamera`` users store it:
    ``camera_matrix``, ``distortion_coefficients``, ``rvec`` (Rodrigues), ``tvec`` in calibration
    units (metres / ``unit``), ``image_width``, ``image_height``. ``silpose rig import`` reads it."""
    rvec, _ = cv2.Rodrigues(np.asarray(cam.R, np.float64))
    with atomic_path(path) as tmp:
        fs = cv2.FileStorage(str(tmp), cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_FORMAT_YAML)
        try:
            fs.write("camera_matrix", np.asarray(cam.K, np.float64))
            fs.write("distortion_coefficients", np.asarray(cam.dist, np.float64).reshape(-1, 1))
            fs.write("rvec", rvec.reshape(3, 1))
            fs.write("tvec", (np.asarray(cam.t, np.float64) / unit).reshape(3, 1))
            fs.write("image_width", int(cam.width))
            fs.write("image_height", int(cam.height))
        finally:
            fs.release()


def write_lab_calibration(folder: Path, rig: Rig, transform: WorldTransform = LAB_TRANSFORM) -> list[Path]:
    """One OpenCV FileStorage file per camera, ``<folder>/<camera>.yml``, in the calibration frame's units
    (millimetres for :data:`LAB_TRANSFORM`): ``camera_matrix``, ``distortion_coefficients``, ``rvec``, ``tvec``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for cam in rig:
        p = folder / f"{cam.name}.yml"
        write_opencv_file(p, calibration_camera(cam, transform), unit=transform.scale)
        paths.append(p)
    return paths


@dataclass(frozen=True)
class Walker:
    """A person walking back and forth between two floor points (silpose's frame, metres).

    index: test sample whose subject and gait style the walker has; start, end: (x, y) metres;
    speed: metres per second; delay: seconds of walking already done at t = 0 (where the walker is when
    the recording starts); stature: metres (None: :func:`walker_stature`'s draw).
    """

    index: int
    start: tuple[float, float]
    end: tuple[float, float]
    speed: float = 1.2
    delay: float = 0.0
    stature: float | None = None


#: two walkers crossing in front of the rig: one near the cameras walking right, one farther walking left
DEFAULT_WALKERS = (
    Walker(index=0, start=(-1.35, -0.55), end=(1.35, -0.45), speed=1.15),
    Walker(index=1, start=(1.35, 0.6), end=(-1.35, 0.5), speed=1.05),
)


#: four walkers crossing in front of the rig (the identities benchmark): two along the width at different
#: depths in opposite directions, one diagonal through the others' paths, one along the back
FOUR_WALKERS = (
    Walker(index=0, start=(-1.35, -0.9), end=(1.35, -0.7), speed=1.15),
    Walker(index=1, start=(1.35, -0.1), end=(-1.35, -0.35), speed=1.0),
    Walker(index=2, start=(-0.7, 1.3), end=(0.8, -1.3), speed=0.9, delay=0.5),
    Walker(index=3, start=(1.3, 0.95), end=(-1.3, 0.7), speed=1.1, delay=1.0),
)


#: the same four paths timed so that nobody walks through anybody: the walkers' pelvises stay at least 0.56 m apart
#: over the first 8 s (:func:`closest_approach`; ``FOUR_WALKERS`` pass within a centimetre of each other, which real
#: people never do, and walker 2 is within 0.3 m of another in 23 % of its 200 frames)
FOUR_WALKERS_APART = (
    FOUR_WALKERS[0],
    Walker(index=1, start=(1.35, -0.1), end=(-1.35, -0.35), speed=1.0, delay=1.5),
    Walker(index=2, start=(-0.7, 1.3), end=(0.8, -1.3), speed=1.2, delay=2.75),
    Walker(index=3, start=(1.3, 0.95), end=(-1.3, 0.7), speed=1.1, delay=2.5),
)


def closest_approach(walkers, n_frames: int, fps: float = LAB_FPS) -> float:
    """Metres: the smallest floor distance between two walkers' positions (:func:`walker_state`) over the frames."""
    if len(walkers) < 2:
        return float("inf")
    t = np.arange(int(n_frames)) / float(fps)
    xy = np.array([[walker_state(w, ti)[:2] for w in walkers] for ti in t])  # (T, P, 2)
    d = np.linalg.norm(xy[:, :, None] - xy[:, None], axis=3)
    d[:, np.arange(len(walkers)), np.arange(len(walkers))] = np.inf
    return float(d.min())


def walker_stature(seed: int, walker: Walker) -> float:
    """Metres: ``walker.stature``, or a draw from N(:data:`STATURE_MEAN_M`, :data:`STATURE_STD_M`) clipped to
    :data:`STATURE_RANGE_M`, from ``derive_rng(seed, stream_code("lab stature"), walker.index)``."""
    if walker.stature is not None:
        return float(walker.stature)
    rng = derive_rng(seed, stream_code("lab stature"), walker.index)
    return float(np.clip(rng.normal(STATURE_MEAN_M, STATURE_STD_M), *STATURE_RANGE_M))


def walker_clothing_bgr(seed: int, walker: Walker) -> np.ndarray:
    """(2, 3) uint8: the walker's shirt and trousers colours, sRGB BGR (test sample ``walker.index``'s
    clothing, :func:`silpose.datagen.frames.scene.draw_appearance`, linear RGB encoded with the sRGB curve)."""
    from .frames.scene import draw_appearance

    look = draw_appearance(seed, walker.index)
    lin = np.array([look["shirt"], look["trousers"]], float)
    srgb = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * np.power(lin, 1 / 2.4) - 0.055)
    return np.round(255 * np.clip(srgb, 0, 1))[:, ::-1].astype(np.uint8)


def walker_state(walker: Walker, t: float) -> tuple[float, float, float, float]:
    """(x, y, heading, travelled metres) of ``walker`` at time ``t`` seconds (ping-pong between the ends)."""
    a, b = np.asarray(walker.start, float), np.asarray(walker.end, float)
    length = float(np.linalg.norm(b - a))
    travelled = walker.speed * (t + walker.delay)
    u = travelled % (2 * length)
    forward = u <= length
    s = u if forward else 2 * length - u
    p = a + (b - a) * (s / length)
    d = (b - a) if forward else (a - b)
    return float(p[0]), float(p[1]), float(np.arctan2(d[1], d[0])), travelled


def walker_scene(seed: int, walker: Walker, t: float, rig: Rig) -> SampleScene:
    """The scene of ``walker`` at time ``t``: test sample ``walker.index``'s subject (its stature
    :func:`walker_stature`'s) and gait style, placed and phased by :func:`walker_state`."""
    subject, gait = draw_sample_parameters(seed, "test", walker.index, 0)
    subject = dict(subject, height=walker_stature(seed, walker))
    x, y, heading, travelled = walker_state(walker, t)
    gait = dict(gait, x=x, y=y, heading=heading, phase=(gait["phase"] + travelled / STRIDE_M) % 1.0)
    return SampleScene(split="test", index=walker.index, redraw=0, subject=subject, motion=gait,
                       pose=WALK.pose(subject, gait), rig=rig)


def lossy(mask: np.ndarray, quality: int = MASK_JPEG_QUALITY) -> np.ndarray:
    """(H, W) uint8 0/255 mask after a JPEG round trip at ``quality`` (smeared edges, ringing)."""
    ok, buf = cv2.imencode(".jpg", mask, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise RuntimeError("OpenCV cannot encode JPEG")
    return cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)


def _video_writer(path: Path, fps: float, size: tuple[int, int]) -> cv2.VideoWriter:
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*MASK_FOURCC), fps, size, isColor=False)
    if not w.isOpened():
        raise RuntimeError(f"{path}: OpenCV cannot write {MASK_FOURCC} video")
    return w


def render_lab(config: dict, out: str) -> dict:
    """Render the recording (call in a spawned worker: Blender). See the module docstring.

    Args:
        config: ``seed``, ``rig`` (``Rig.to_dict()``), ``walkers`` (list of :class:`Walker` fields),
            ``n_frames``, ``fps``, ``renderer`` (registry name, default ``raster``).
        out: folder; gets ``masks/<camera>.mp4`` and ``truth.npz`` (``joints`` (T, P, 19, 3) metres,
            ``heading`` (T, P), ``masks`` bit-packed per-walker masks with ``mask_shape`` (T, P, K, H, W),
            ``fps``, ``cameras``, ``stature`` (P,) metres, ``clothing_bgr`` (P, 2, 3) uint8 shirt and trousers).
    Returns:
        ``{"frames": T, "walkers": P, "empty_views": (P,) count of (frame, camera) where a walker is not rendered}``.
    """
    rig = Rig.from_dict(config["rig"])
    walkers = [Walker(**{k: tuple(v) if isinstance(v, list) else v for k, v in w.items()}) for w in config["walkers"]]
    n, fps, seed = int(config["n_frames"]), float(config["fps"]), int(config["seed"])
    w, h = rig.image_size
    out = Path(out)
    (out / "masks").mkdir(parents=True, exist_ok=True)
    P, K = len(walkers), len(rig)
    joints = np.zeros((n, P, 19, 3))
    heading = np.zeros((n, P))
    packed = []
    writers = {cam.name: _video_writer(out / "masks" / f"{cam.name}{MASK_SUFFIX}", fps, (w, h)) for cam in rig}
    empty = np.zeros(P, int)
    try:
        with rendering(renderer_from_config({"renderer": config.get("renderer", "raster")}), rig) as renderer:
            for f in range(n):
                masks = np.zeros((P, K, h, w), np.uint8)
                for p, walker in enumerate(walkers):
                    scene = walker_scene(seed, walker, f / fps, rig)
                    result = renderer.render(scene)
                    joints[f, p] = result.joints
                    heading[f, p] = scene.motion["heading"]
                    if result.masks is None:  # the body leaves some image: render what each camera sees
                        raise RuntimeError(f"walker {p} leaves a camera's image at frame {f}; keep walkers in the workspace")
                    masks[p] = result.masks
                    empty[p] += int((masks[p].reshape(K, -1).max(axis=1) == 0).sum())
                union = masks.max(axis=0)
                for k, cam in enumerate(rig):
                    writers[cam.name].write(lossy((union[k] * 255).astype(np.uint8)))
                packed.append(np.packbits(masks.astype(bool), axis=-1))
    finally:
        for wr in writers.values():
            wr.release()
    with atomic_open(out / "truth.npz", "wb") as fh:
        np.savez_compressed(fh, joints=joints, heading=heading, masks=np.stack(packed), mask_shape=np.array([n, P, K, h, w]),
                            fps=np.array(fps), cameras=np.array(rig.names),
                            stature=np.array([walker_stature(seed, w) for w in walkers]),
                            clothing_bgr=np.stack([walker_clothing_bgr(seed, w) for w in walkers]))
    return {"frames": n, "walkers": P, "empty_views": empty.tolist()}


def unpack_masks(truth) -> np.ndarray:
    """(T, P, K, H, W) bool per-walker masks of a loaded ``truth.npz``."""
    shape = tuple(int(v) for v in truth["mask_shape"])
    return np.unpackbits(truth["masks"], axis=-1, count=shape[-1]).astype(bool).reshape(shape)


def make_lab_recording(out: Path, *, walkers=DEFAULT_WALKERS, n_frames: int = 75, fps: float = LAB_FPS, seed: int = 0,
                       renderer: str = "raster", rig: Rig | None = None) -> Path:
    """Write a lab recording to ``out`` (the driver; never imports bpy). Returns ``out``.

    ``out/calibration/<camera>.yml`` (mm, z down, origin at a floor corner), ``out/rig.json`` (the same rig
    in silpose's frame), ``out/masks/<camera>.mp4`` and ``out/truth.npz`` (:func:`render_lab`, in a spawned worker).
    ``rig``: other cameras than :func:`lab_rig`'s (the same walkers seen through them); a rig with fisheye lenses
    gets no ``calibration/`` (OpenCV's files do not say that a lens is a fisheye).

    Raises:
        LabRenderError: the rendering raised (the message names ``out`` and the error) or its worker died (its
            exit code).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rig = lab_rig() if rig is None else rig
    if not any(cam.fisheye for cam in rig):
        write_lab_calibration(out / "calibration", rig)
    with atomic_path(out / "rig.json") as tmp:
        tmp.write_text(rig.to_json())
    config = {"seed": seed, "rig": rig.to_dict(), "walkers": [asdict(w) for w in walkers], "n_frames": int(n_frames),
              "fps": float(fps), "renderer": renderer}
    try:
        for _, error in spawned_map(render_lab_job, [(0, (config, str(out)))], workers=1):
            if error is not None:
                raise LabRenderError(f"{out}: rendering the lab recording failed: {error}")
    except WorkerDied as died:
        raise LabRenderError(f"{out}: rendering the lab recording failed: {died}") from None
    return out


class LabRenderError(RuntimeError):
    """The lab recording could not be rendered (:func:`make_lab_recording`)."""


def render_lab_job(message: tuple[dict, str]) -> str | None:
    """Worker side of :func:`make_lab_recording`: :func:`render_lab` of ``(config, out)``; returns None, or the
    error it raised as ``"<type>: <message>"`` (``spawned_map``'s calls return their errors)."""
    try:
        render_lab(*message)
    except Exception as exc:  # noqa: BLE001 - reported by the driver, with the recording's folder
        return f"{type(exc).__name__}: {exc}"
    return None
