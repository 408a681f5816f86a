"""How the bundled motion library (:data:`library.BUNDLED`) was built: CMU clips, their activity
groups and held-out subjects.

The source BVH files are public conversions of the CMU Graphics Lab Motion Capture Database
(mocap.cs.cmu.edu; free for research and commercial use) and are not copied into the repository;
only silpose's derived form is (:mod:`.library`). Rebuild with checkouts of the two source
repositories::

    git clone https://github.com/DragonForgedTheArtist/IClone-CMU-Mocap   # commit 79529f9
    git clone https://github.com/yuki-koyama/bvh11                         # commit c907217
    python -m silpose.datagen.motion.cmu_library --iclone IClone-CMU-Mocap --bvh11 bvh11 --out LIBRARY_DIR

- ``IClone-CMU-Mocap`` (DragonForgedTheArtist): the AMC files converted to BVH (Credo LifeForms),
  a T-pose prepended (frame 0, dropped here), resampled to 60 fps and retargeted in iClone onto the
  Character Creator skeleton (``cc-base`` map, centimetres); its ``CMU data.csv`` is the CMU index
  (the descriptions below come from it). Subjects 1, 2, 3, 5, 6, 7 are in the repository.
- ``bvh11`` (Yuki Koyama, MIT): subject 131 from B. Hahne's 3dsMax-friendly BVH release
  (``hip-knee`` map, CMU units of 1/0.45 inch, 120 fps; frame 0 is a T-pose, dropped).

Groups follow the clip's CMU description (:data:`GROUP`); the splits hold out whole subjects
(:data:`TEST_SUBJECTS`): frames of one clip a few frames apart are near-copies, so a frame split
would measure memorisation.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

from .build import ClipSource, import_clips
from .config import CMU_SCALE
from .library import CMU_ACKNOWLEDGEMENT, CMU_LICENCE

ICLONE = ("DragonForgedTheArtist/IClone-CMU-Mocap", "79529f962ade3274163af53cd92179cee2ed9407")
BVH11 = ("yuki-koyama/bvh11", "c9072174fe89e0bf9776a092179b464ea39975e5")
#: Subjects held out for the test split (all their clips); every other subject is training.
TEST_SUBJECTS = frozenset({"2", "3", "131"})

#: Activity group of every clip that is not a plain walk (clip id -> group).
GROUP: dict[str, str] = {
    "01_01": "jump", "01_08": "sit", "01_14": "climb",
    "02_03": "run", "02_04": "balance", "02_05": "sports", "02_06": "bend", "02_07": "sports", "02_08": "sports",
    "02_09": "sports", "02_10": "everyday",
    **{f"05_{k:02d}": "dance" for k in range(2, 21)}, "05_12": "arms", "05_14": "balance", "05_15": "balance",
    **{f"06_{k:02d}": "sports" for k in range(2, 16)},
    "131_03": "jump",
}
#: Descriptions of subject 131 (the CMU index, as bvh11's resources/README.md quotes it).
DESC_131 = {"131_01": "Start Walk Stop", "131_02": "Start Walk Stop", "131_03": "Start Hop Stop"}


def cmu_sources(iclone: Path, bvh11: Path) -> list[ClipSource]:
    """The bundled library's clips (module docstring), in subject and trial order."""
    index = {}
    with open(iclone / "CMU data.csv", newline="") as f:
        for r in csv.DictReader(f):
            index[f"{int(r['Subject']):02d}_{int(r['Trial #']):02d}"] = r["Motion Description"].strip()
    out = []
    for p in sorted((iclone / "All_BVH" / "subjects").glob("*/*.bvh")):
        s, t = p.stem.split("_")
        cid = f"{int(s):02d}_{int(t):02d}"
        subject = str(int(s))
        out.append(ClipSource(
            path=p, id=f"cmu_{cid}", subject=subject, description=index.get(cid, "Unknown"),
            group=GROUP.get(cid, "walk"), split="test" if subject in TEST_SUBJECTS else "train",
            licence=CMU_LICENCE, source=f"github.com/{ICLONE[0]}@{ICLONE[1][:7]}:{p.relative_to(iclone)}",
            scale=0.01, joint_map="cc-base", first=1))
    for p in sorted((bvh11 / "resources").glob("131_0?.bvh")):
        out.append(ClipSource(
            path=p, id=f"cmu_{p.stem}", subject="131", description=DESC_131[p.stem], group=GROUP.get(p.stem, "walk"),
            split="test" if "131" in TEST_SUBJECTS else "train", licence=CMU_LICENCE,
            source=f"github.com/{BVH11[0]}@{BVH11[1][:7]}:{p.relative_to(bvh11)}", scale=CMU_SCALE,
            joint_map="hip-knee", first=1))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--iclone", type=Path, required=True, help="checkout of DragonForgedTheArtist/IClone-CMU-Mocap")
    ap.add_argument("--bvh11", type=Path, required=True, help="checkout of yuki-koyama/bvh11")
    ap.add_argument("--out", type=Path, required=True, help="library folder (new, or a silpose library)")
    ap.add_argument("--workers", type=int, default=None)
    args = ap.parse_args(argv)
    report = import_clips(cmu_sources(args.iclone, args.bvh11), args.out, workers=args.workers,
                          acknowledgement=CMU_ACKNOWLEDGEMENT)
    for line in report.skipped:
        print(line, file=sys.stderr)
    print(f"{len(report.added)} clips imported, {len(report.skipped)} skipped, into {args.out}")
    return 0 if report.added else 1


if __name__ == "__main__":
    raise SystemExit(main())
