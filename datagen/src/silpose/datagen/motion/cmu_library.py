"""How the bundled motion library (:data:`library.BUNDLED`) was built: CMU clips, their activity
groups and held-out subjects.

The source BVH files are public conversions of the CMU Graphics Lab Motion Capture Database
(mocap.cs.cmu.edu; free for research and commercial use) and are not copied into the repository;
only silpose's derived form is (:mod:`.library`). Rebuild with checkouts of the source repositories
at these commits (files of 4 MiB and more were not fetched here and are not used: e.g.
``001_02`` ... ``001_13`` of IClone-CMU-Mocap, ``13_20``, ``13_29``, ``14_*`` of cookbook)::

    git clone https://github.com/DragonForgedTheArtist/IClone-CMU-Mocap    # commit 79529f9
    git clone https://github.com/yuki-koyama/bvh11                          # commit c907217
    git clone https://github.com/jaanga/cookbook                            # commit 87b8826
    git clone https://github.com/AmmarkoV/RGBDAcquisition                   # commit 22ae26c
    git clone https://github.com/beemsoft/webxr-handtracking-playground     # commit c75be06
    git clone https://github.com/makehumancommunity/makehuman && git -C makehuman checkout 49101a4
    git clone https://github.com/lawrennd/mocap                             # commit 7e19233
    python -m silpose.datagen.motion.cmu_library --iclone IClone-CMU-Mocap --bvh11 bvh11 --cookbook cookbook \\
        --rgbd RGBDAcquisition --salsa webxr-handtracking-playground --makehuman makehuman --lawrence mocap \\
        --out LIBRARY_DIR

- ``IClone-CMU-Mocap`` (DragonForgedTheArtist): the AMC files converted to BVH (Credo LifeForms),
  a T-pose prepended (frame 0, dropped here), resampled to 60 fps and retargeted in iClone onto the
  Character Creator skeleton (``cc-base`` map, centimetres); its ``CMU data.csv`` is the CMU index
  (the descriptions below come from it). Subjects 1, 2, 3, 5, 6, 7 are in the repository.
- ``bvh11`` (Yuki Koyama, MIT): subject 131 from B. Hahne's 3dsMax-friendly BVH release
  (``hip-knee`` map, CMU units of 1/0.45 inch, 120 fps; frame 0 is a T-pose, dropped).
- ``cookbook`` (jaanga): ``bvh-reader/bvh-cmu-daz``, the DAZ-friendly BVH release (``daz`` map,
  centimetres, 120 fps; frame 0 a T-pose, dropped); only the subjects not in ``IClone-CMU-Mocap``
  (8, 10, 13, 16) are used, so no CMU trial appears twice.
- ``RGBDAcquisition`` (Ammar Qammaz, the MocapNET author's renderer): ``Motions/49_04.bvh``, the
  DAZ-friendly conversion of trial 49_04 re-exported on the MakeHuman skeleton at 25 fps
  (``mocapnet`` map, centimetres; frame 0 a rest pose, dropped). Its ``102_01cc.bvh`` is not used:
  a test file of another hierarchy whose neck and lower-back bones have zero length.
- ``webxr-handtracking-playground`` (beemsoft; its READMEs credit "The BVH Conversion Release of
  CMU's Motion Capture Database" with CMU's use terms): ``public/shared/bvh/60``, ``61``, the salsa
  subjects 60 (lead) and 61 (follow) in the DAZ-friendly conversion shrunk 128 times (``daz`` map,
  :data:`SALSA_SCALE`, 120 fps, no T-pose). 60 and 61 dance together in each trial, so only
  disjoint trials are taken from the two (:data:`SALSA_CLIPS`).
- ``makehuman`` at commit 49101a4 (the files were removed later): ``makehuman/data/bvhs``, trials
  03_03 (DAZ-friendly) and 12_03 (the MotionBuilder-friendly conversion, ``cmu`` map, CMU units;
  its LowerBack and Neck start where their parents do). Its 10_01 (another hierarchy, 30 fps) is
  not used: ``mocap`` has the DAZ-friendly one.
- ``mocap`` (Neil Lawrence's MOCAP toolbox): ``python/files``, the DAZ-friendly trials 10_01,
  10_03, 11_01 (soccer kicks) and 14_19 (laugh) (``daz`` map, centimetres, 120 fps; frame 0 a
  T-pose, dropped).

Groups follow the clip's CMU description (:data:`GROUP`); the splits hold out whole subjects
(:data:`TEST_SUBJECTS`): frames of one clip a few frames apart are near-copies, so a frame split
would measure memorisation. The test subjects are chosen so that every group has training and test
clips.
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
COOKBOOK = ("jaanga/cookbook", "87b8826d2367248bd7a88d083d5531017a216e97")
COOKBOOK_SUBJECTS = frozenset({"8", "10", "13", "16"})
RGBD = ("AmmarkoV/RGBDAcquisition", "22ae26cb6f9a8e6c2900a828aa520bfcc7fd6723")
RGBD_DIR = "opengl_acquisition_shared_library/opengl_depth_and_color_renderer/Motions"
#: The RGBDAcquisition clip used (file -> metres per BVH unit: the DAZ-friendly skeleton, centimetres).
RGBD_SCALE = {"49_04.bvh": 0.01}
SALSA = ("beemsoft/webxr-handtracking-playground", "c75be0627feb6cd30ed1e269a7b4a32f26e99404")
SALSA_DIR = "public/shared/bvh"
#: The salsa files are the DAZ-friendly conversion shrunk 128 times (thigh 0.2877 units, DAZ 36.82 cm).
SALSA_SCALE = 1.28
#: The salsa trials used: subject 60 leads, 61 follows in the same trials; disjoint trials are taken from each.
SALSA_CLIPS = ("60_01", "60_02", "60_03", "60_04", "61_10", "61_11")
MAKEHUMAN = ("makehumancommunity/makehuman", "49101a4709fb2ede938390c71b78cf3e2636923c")
#: The MakeHuman clips used (path -> joint map, metres per BVH unit); its 02_02 and 10_01 are taken elsewhere.
MAKEHUMAN_FILES = {"makehuman/data/bvhs/03_03.bvh": ("daz", 0.01),
                   "makehuman/data/bvhs/cmu/12_03.bvh": ("cmu", CMU_SCALE)}
LAWRENCE = ("lawrennd/mocap", "7e192332050e0be6ccc5d45c3fb762b6f5da8fac")
#: The CMU trials of the MOCAP toolbox's ``python/files`` used (DAZ-friendly; 14_06, 14_10 are over 4 MiB).
LAWRENCE_CLIPS = ("10_01", "10_03", "11_01", "14_19")
#: Subjects held out for the test split (all their clips); every other subject is training. Chosen so
#: that every group has clips of a training subject and of a test subject.
TEST_SUBJECTS = frozenset({"2", "3", "8", "11", "49", "61", "131"})

#: Activity group of every clip that is not a plain walk (clip id -> group), from its CMU description:
#: ``bend`` bending over, sitting down and climbing (the trunk bent, the body lowered); ``leap`` a
#: travelling jump from a run (run and leap, grand jete); ``kick`` kicking a soccer ball; ``sports``
#: basketball, punching, swordplay; ``dance`` ballet (subject 5) and salsa (60, 61); ``everyday``
#: washing, laughing.
GROUP: dict[str, str] = {
    "01_01": "jump", "01_08": "bend", "01_14": "bend",
    "02_03": "run", "02_04": "balance", "02_05": "sports", "02_06": "bend", "02_07": "sports", "02_08": "sports",
    "02_09": "sports", "02_10": "everyday",
    **{f"05_{k:02d}": "dance" for k in range(2, 21)}, "05_14": "balance", "05_15": "balance", "05_17": "leap",
    **{f"06_{k:02d}": "sports" for k in range(2, 16)},
    "10_01": "kick", "10_02": "kick", "10_03": "kick", "11_01": "kick",
    "13_14": "everyday", "13_32": "jump", "14_19": "everyday", "16_36": "run", "49_04": "leap",
    **{f"{s}_{k:02d}": "dance" for s in (60, 61) for k in range(1, 16)},
    "131_03": "jump",
}
#: Descriptions of subject 131 (the CMU index, as bvh11's resources/README.md quotes it).
DESC_131 = {"131_01": "Start Walk Stop", "131_02": "Start Walk Stop", "131_03": "Start Hop Stop"}


def _source(repo: tuple[str, str], checkout: Path, path: Path, cid: str, description: str, joint_map: str,
            scale: float, first: int = 1) -> ClipSource:
    subject = str(int(cid.split("_")[0]))
    return ClipSource(
        path=path, id=f"cmu_{cid}", subject=subject, description=description, group=GROUP.get(cid, "walk"),
        split="test" if subject in TEST_SUBJECTS else "train", licence=CMU_LICENCE,
        source=f"github.com/{repo[0]}@{repo[1][:7]}:{path.relative_to(checkout)}", scale=scale, joint_map=joint_map,
        first=first)


def _cid(stem: str) -> str:
    """``001_01`` / ``08_08`` / ``60_01_scaled`` / ``102_01cc`` -> the CMU trial id ``01_01`` ... ``102_01``."""
    s, t = stem.split("_")[:2]
    return f"{int(s):02d}_{int(t[:2]):02d}"


def cmu_index(iclone: Path) -> dict[str, str]:
    """The CMU index (``CMU data.csv`` of ``IClone-CMU-Mocap``): trial id -> motion description."""
    index = {}
    with open(iclone / "CMU data.csv", newline="") as f:
        for r in csv.DictReader(f):
            index[f"{int(r['Subject']):02d}_{int(r['Trial #']):02d}"] = r["Motion Description"].strip()
    return index


def cmu_sources(iclone: Path, bvh11: Path, cookbook: Path | None = None, rgbd: Path | None = None,
                salsa: Path | None = None, makehuman: Path | None = None, lawrence: Path | None = None
                ) -> list[ClipSource]:
    """The bundled library's clips (module docstring), source by source, in subject and trial order."""
    index = cmu_index(iclone)
    out = [_source(ICLONE, iclone, p, _cid(p.stem), index.get(_cid(p.stem), "Unknown"), "cc-base", 0.01)
           for p in sorted((iclone / "All_BVH" / "subjects").glob("*/*.bvh"))]
    out += [_source(BVH11, bvh11, p, p.stem, DESC_131[p.stem], "hip-knee", CMU_SCALE)
            for p in sorted((bvh11 / "resources").glob("131_0?.bvh"))]
    if cookbook is not None:
        out += [_source(COOKBOOK, cookbook, p, _cid(p.stem), index[_cid(p.stem)], "daz", 0.01)
                for p in sorted((cookbook / "bvh-reader" / "bvh-cmu-daz").glob("*.bvh"))
                if str(int(p.stem.split("_")[0])) in COOKBOOK_SUBJECTS]
    if rgbd is not None:
        out += [_source(RGBD, rgbd, rgbd / RGBD_DIR / name, _cid(Path(name).stem), index[_cid(Path(name).stem)],
                        "mocapnet", RGBD_SCALE[name])
                for name in sorted(RGBD_SCALE)]
    if salsa is not None:
        out += [_source(SALSA, salsa, salsa / SALSA_DIR / f"{cid[:2]}/{cid}_scaled.bvh", cid, index[cid], "daz",
                        SALSA_SCALE, first=0)
                for cid in SALSA_CLIPS]
    if makehuman is not None:
        out += [_source(MAKEHUMAN, makehuman, makehuman / name, _cid(Path(name).stem), index[_cid(Path(name).stem)],
                        jmap, scale)
                for name, (jmap, scale) in sorted(MAKEHUMAN_FILES.items())]
    if lawrence is not None:
        out += [_source(LAWRENCE, lawrence, lawrence / "python" / "files" / f"{cid}.bvh", cid, index[cid], "daz", 0.01)
                for cid in LAWRENCE_CLIPS]
    return sorted(out, key=lambda c: (int(c.subject), c.id))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--iclone", type=Path, required=True, help="checkout of DragonForgedTheArtist/IClone-CMU-Mocap")
    ap.add_argument("--bvh11", type=Path, required=True, help="checkout of yuki-koyama/bvh11")
    ap.add_argument("--cookbook", type=Path, default=None, help="checkout of jaanga/cookbook")
    ap.add_argument("--rgbd", type=Path, default=None, help="checkout of AmmarkoV/RGBDAcquisition")
    ap.add_argument("--salsa", type=Path, default=None, help="checkout of beemsoft/webxr-handtracking-playground")
    ap.add_argument("--makehuman", type=Path, default=None,
                    help=f"checkout of makehumancommunity/makehuman at commit {MAKEHUMAN[1][:8]}")
    ap.add_argument("--lawrence", type=Path, default=None, help="checkout of lawrennd/mocap")
    ap.add_argument("--out", type=Path, required=True, help="library folder (new, or a silpose library)")
    ap.add_argument("--workers", type=int, default=None)
    args = ap.parse_args(argv)
    report = import_clips(cmu_sources(args.iclone, args.bvh11, args.cookbook, args.rgbd, args.salsa, args.makehuman,
                                     args.lawrence), args.out, workers=args.workers,
                          acknowledgement=CMU_ACKNOWLEDGEMENT)
    for line in report.skipped:
        print(line, file=sys.stderr)
    print(f"{len(report.added)} clips imported, {len(report.skipped)} skipped, into {args.out}")
    return 0 if report.added else 1


if __name__ == "__main__":
    raise SystemExit(main())
