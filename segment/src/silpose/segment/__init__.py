"""silpose.segment: background subtraction for real camera frames (paper section 6).

>>> model = BackgroundModel().fit(background_frames)      # (N, H, W[, 3]) uint8, N >= 2
>>> mask = model.segment(frame)                           # (H, W) bool, one frame at a time
>>> masks = model.segment_batch(frames)                   # (M, H, W) bool

Modules: :mod:`.background` (the model), :mod:`.validate` (input checks,
:class:`SegmentError`), :mod:`.ncc` (local normalised correlation with box
filters), :mod:`.chroma` (colour shadow growth from the NCC's seeds), :mod:`.align` (registering a plate to the
recording it is the background of), :mod:`.cleanup` (median,
open/close, largest blob), :mod:`.synthetic` (scenes with known masks). A library on arrays:
reading image folders, videos and frames folders is ``silpose.app.inputs``. The throughput
benchmark is ``benchmarks/segmentation.py`` at the repository root.
"""

from .validate import SegmentError
from .background import STAGES, BackgroundModel, Candidates
from .align import plate_alignment, plate_mismatch_std, warp_plate

__all__ = ["STAGES", "BackgroundModel", "Candidates", "SegmentError", "plate_alignment", "plate_mismatch_std", "warp_plate"]
