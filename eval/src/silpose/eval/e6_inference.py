"""E6 — how honest the inference is: flips and top-K hypotheses, robust inference under
mask noise, missing-view contours against a nearest-neighbour baseline, self-intersecting
reconstructions, plausibility flags on inputs that are not a person.

All on the test split, deterministic per evaluation seed. Pose errors are root-relative cm,
contour errors one-sided Chamfer D(true clean -> reconstruction) in px (:mod:`silpose.eval.report`).

- **Flips** (:mod:`silpose.model.hypotheses`): a pose faces the wrong way when its heading (the
  forward direction of the hip + shoulder axes in the floor plane) is more than 90 deg from the
  truth's. For each condition: the posterior mean (the headline answer of E2), the most probable
  hypothesis, the *single answer* ``silpose infer`` writes for a lone frame
  (:func:`silpose.model.hypotheses.single_answer` with the most probable hypothesis: the posterior
  mean unless that hypothesis faces the other way), the view-pair *consensus* among the top 3
  (``infer(consensus=True)``, off by default) and best-of-3 (an oracle: the hypothesis nearest the
  truth; a frame counts as flipped only if all 3 are).
- **Robust inference** (:mod:`silpose.model.robust`): E3 rows with method ``mppca robust`` (clean,
  the standard noise and the two mask-level settings; all views and view 0 alone, and with the standard noise
  every view alone, for the one-view headline beside kNN's mean over the views), added to E3's table.
- **Missing-view contours**: for each view left out, the 4-view model's reconstruction of that view
  from the other three (standard noise) against the nearest training sample's contour of that view
  (Euclidean distance of the observed views' normalised contours), both placed with the view's
  true normalisation. The ratio is MPPCA / nearest neighbour (issue 12 target: <= 0.8), with the
  Gaussian posterior mean and with robust inference (``silpose infer``'s default), which conditions
  on down-weighted, trimmed inputs and so reconstructs the missing view from less of the noise.
- **Self-intersections** (:mod:`silpose.model.untangle`): share of reconstructed contours whose
  polygon crosses itself, as inferred and after ``infer(untangle=True)``; the noisy inputs' share
  for reference.
- **Plausibility** (:mod:`silpose.model.plausibility`, :mod:`silpose.eval.e6_garbage`): share of each
  garbage kind flagged implausible (all 4 views), and of genuine test inputs (clean and with the
  standard noise, per number of views).
"""

from __future__ import annotations


import numpy as np
from sklearn.neighbors import NearestNeighbors

from silpose.model.hypotheses import is_flip, single_answer
from silpose.model.plausibility import CONVEX_SOLIDITY, view_subsets
from silpose.model.untangle import self_intersecting, untangle
from silpose.shared.contours import denormalise, normalise
from silpose.shared.metrics import chamfer_errors, pose_error_cm

from .e6_garbage import GARBAGE_KINDS, garbage_masks, masks_to_contours
from .tables import fmt, markdown_table

__all__ = ["ROBUST_SPECS", "N_GARBAGE", "run_e6", "e6_markdown"]

#: E3 settings also scored with robust inference
ROBUST_SPECS = ("clean", "standard", "mask mild", "mask strong")
#: inputs per garbage kind
N_GARBAGE = 50
#: hypotheses returned per frame
TOP_K = 3


def _label(views) -> str:
    return "".join(str(int(v)) for v in views)


def _present(n: int, k: int, views) -> np.ndarray:
    p = np.zeros((n, k), dtype=bool)
    p[:, list(views)] = True
    return p


def _flip_row(name: str, res, truth: np.ndarray) -> dict:
    """Flip rates (%) and pose errors (cm) of one condition's result (with hypotheses)."""
    hyp = res.hypotheses
    rows = np.arange(len(truth))
    top1 = hyp.joints[:, 0]
    oracle = hyp.best_of(truth)
    best = hyp.joints[rows, oracle]
    single = single_answer(res.joints, hyp, chosen=np.zeros(len(truth), dtype=np.intp))
    all_flipped = np.all(np.where(hyp.component >= 0, is_flip(hyp.joints, truth[:, None]), True), axis=1)
    return {
        "condition": name, "n": int(len(truth)),
        "posterior_mean_flips_pct": 100.0 * float(is_flip(res.joints, truth).mean()),
        "posterior_mean_pose_cm": float(pose_error_cm(res.joints, truth).mean()),
        "top1_flips_pct": 100.0 * float(is_flip(top1, truth).mean()),
        "single_answer_flips_pct": 100.0 * float(is_flip(single, truth).mean()),
        "single_answer_pose_cm": float(pose_error_cm(single, truth).mean()),
        "consensus_flips_pct": 100.0 * float(is_flip(hyp.best_joints, truth).mean()),
        "consensus_pose_cm": float(pose_error_cm(hyp.best_joints, truth).mean()),
        "best_of_3_flips_pct": 100.0 * float(all_flipped.mean()),
        "best_of_3_pose_cm": float(pose_error_cm(best, truth).mean()),
        "changed_by_consensus_pct": 100.0 * float((hyp.chosen != 0).mean()),
    }


def flips(ev) -> list[dict]:
    """Flip table rows: standard noise with 4, 3 (each left out, pooled) and 1 view(s); robust inference
    under the mask-level settings with all views."""
    d, model = ev.data, ev.model
    K, n = d.n_views, len(d.test_ids)
    out = []
    noisy = ev.noisy(ev.config.noise)
    sizes = sorted({K, K - 1, 1} - {0}, reverse=True)
    for size in sizes:
        subsets = [s for s in view_subsets(K) if len(s) == size]
        if size == K - 1 and K > 1:
            subsets = [tuple(v for v in range(K) if v != k) for k in range(K)]  # each view left out in turn
        name = f"{size} view{'s' if size > 1 else ''}, {ev.config.noise.label}"
        parts = [model.infer(noisy, _present(n, K, s), hypotheses=TOP_K, consensus=True) for s in subsets]
        out.append(_pooled_flip_row(name, parts, d.test_joints))
    specs = {s.label: s for s in ev.config.sweep}
    for label in ("clean", "standard before issue 12"):
        if label in specs and specs[label] != ev.config.noise:
            res = model.infer(ev.noisy(specs[label]), hypotheses=TOP_K, consensus=True)
            out.append(_flip_row(f"{K} views, {label}", res, d.test_joints))
    for label in ("mask mild", "mask strong"):
        spec = specs.get(label)
        if spec is None or (spec.needs_masks and d.test_masks is None):
            continue
        res = model.infer(ev.noisy(spec), hypotheses=TOP_K, robust=True, consensus=True)
        out.append(_flip_row(f"{K} views, {label}, robust", res, d.test_joints))
    return out


def _pooled_flip_row(name: str, parts: list, truth: np.ndarray) -> dict:
    rows = [_flip_row(name, r, truth) for r in parts]
    merged = {"condition": name, "n": int(sum(r["n"] for r in rows))}
    for key in rows[0]:
        if key not in ("condition", "n"):
            merged[key] = float(np.mean([r[key] for r in rows]))
    return merged


def robust_rows(ev) -> dict:
    """Score robust inference on :data:`ROBUST_SPECS` (all views and view 0; with the evaluation's own noise every
    view alone); adds E3 rows. Returns the mean 4-view pose error per (setting, method) and the kNN baseline's, for
    the headline ratios."""
    d, K = ev.data, ev.data.n_views
    specs = {s.label: s for s in ev.config.sweep}
    specs.setdefault(ev.config.noise.label, ev.config.noise)
    summary: dict = {}
    for label in ROBUST_SPECS:
        spec = specs.get(label)
        if spec is None or (spec.needs_masks and d.test_masks is None):
            continue
        noisy = ev.noisy(spec)
        alone = range(K) if label == ev.config.noise.label else range(1)
        for views in (tuple(range(K)),) + tuple((k,) for k in alone):
            s = ev.score_model(ev.model, noisy, views, robust=True)
            ev._add(dict(experiment="E3", method="mppca robust", training="multi-view", trained_views=_label(range(K)),
                         input_views=_label(views), n_input_views=len(views), noise=spec.label), **s)
            if len(views) == K:
                summary.setdefault(label, {})["mppca robust"] = float(np.mean(s["pose_cm"]))
        summary.setdefault(label, {})["mppca"] = float(np.mean(ev.score_model(ev.model, noisy, tuple(range(K)))["pose_cm"]))
        for kind in ("knn", "mlp"):
            summary[label][kind] = float(np.mean(ev.score_regressor(kind, tuple(range(K)), noisy)["pose_cm"]))
    return summary


def missing_view_vs_nn(ev) -> list[dict]:
    """Per left-out view: mean Chamfer (px) of the MPPCA reconstruction (as inferred and untangled) and of
    the nearest training sample's contour; standard noise on the three observed views."""
    d, model = ev.data, ev.model
    K, n = d.n_views, len(d.test_ids)
    if K < 2:
        return []
    noisy = ev.noisy(ev.config.noise)
    train_norm = ev.train_normalised()
    test_norm = normalise(noisy)[0].astype(train_norm.dtype)  # one dtype: no float64 copy of the training rows
    out = []
    for k in range(K):
        obs = [v for v in range(K) if v != k]
        res = model.infer(noisy, _present(n, K, obs), centroid=d.test_centroid, scale=d.test_scale)
        rec = np.full(d.test_contours.shape, np.nan)
        rec[:, list(res.views)] = res.contours_px
        _, rec_untangled = untangle(rec[:, k], rec[:, k])
        robust = model.infer(noisy, _present(n, K, obs), centroid=d.test_centroid, scale=d.test_scale, robust=True)
        rec_robust = np.full(d.test_contours.shape, np.nan)
        rec_robust[:, list(robust.views)] = robust.contours_px
        nn = NearestNeighbors(n_neighbors=1).fit(train_norm[:, obs].reshape(len(train_norm), -1))
        idx = nn.kneighbors(test_norm[:, obs].reshape(n, -1), return_distance=False)[:, 0]
        nn_px = denormalise(train_norm[idx, k], d.test_centroid[:, k], d.test_scale[:, k])
        both = np.stack([rec[:, k], rec_untangled, rec_robust[:, k], nn_px], axis=1)  # (n, 4, P, 2) as four "views"
        truth = np.repeat(d.test_contours[:, k : k + 1], 4, axis=1)
        size = np.repeat(d.image_size[k : k + 1], 4, axis=0)
        one, _ = chamfer_errors(truth, both, size)
        m = np.nanmean(one, axis=0)
        out.append({"missing_view": k, "n": n, "mppca_px": float(m[0]), "mppca_untangled_px": float(m[1]),
                    "mppca_robust_px": float(m[2]), "nearest_neighbour_px": float(m[3]), "ratio": float(m[0] / m[3]),
                    "ratio_untangled": float(m[1] / m[3]), "ratio_robust": float(m[2] / m[3])})
    return out


def self_intersections(ev) -> list[dict]:
    """Share (%) of self-intersecting contours: inputs and reconstructions (standard noise)."""
    d, model = ev.data, ev.model
    K, n = d.n_views, len(d.test_ids)
    noisy = ev.noisy(ev.config.noise)
    rows = [{"contours": "true clean contours", "n": n * K, "raw_pct": 100.0 * float(self_intersecting(d.test_contours).mean()),
             "untangled_pct": float("nan")},
            {"contours": f"noisy inputs ({ev.config.noise.label})", "n": n * K,
             "raw_pct": 100.0 * float(self_intersecting(noisy).mean()), "untangled_pct": float("nan")}]
    for name, subsets in ((f"{K} views given: every view's reconstruction", [tuple(range(K))]),
                          (f"{K - 1} views given: the missing view's reconstruction",
                           [tuple(v for v in range(K) if v != k) for k in range(K)] if K > 1 else [])):
        raw, fixed = [], []
        for s in subsets:
            res = model.infer(noisy, _present(n, K, s))
            sel = np.ones(K, bool) if len(s) == K else ~np.isin(np.arange(K), s)
            recon = res.contours_norm[:, sel]
            raw.append(self_intersecting(recon).reshape(-1))
            fixed.append(self_intersecting(untangle(recon)[0]).reshape(-1))
        if raw:
            raw_a, fixed_a = np.concatenate(raw), np.concatenate(fixed)
            rows.append({"contours": name, "n": int(raw_a.size), "raw_pct": 100.0 * float(raw_a.mean()),
                         "untangled_pct": 100.0 * float(fixed_a.mean())})
    return rows


def plausibility(ev) -> dict:
    """Flagged shares (%) of garbage kinds and of genuine test inputs; {} when the model is not calibrated."""
    d, model = ev.data, ev.model
    cal = getattr(model, "plausibility_", None)
    if cal is None:
        return {}
    K, n = d.n_views, len(d.test_ids)
    n_pts = d.test_contours.shape[2]
    garbage = []
    examples = {}
    for kind in GARBAGE_KINDS:
        if kind == "two people merged" and d.test_masks is None:
            continue
        masks = garbage_masks(kind, N_GARBAGE, d.rig, seed=ev.config.seed, person_masks=d.test_masks)
        contours, present = masks_to_contours(masks, n_pts)
        usable = present.any(axis=1)
        flagged = ~usable  # no silhouette in any view: silpose infer reports it, nothing to infer
        pct = np.full(len(masks), np.nan)
        if usable.any():
            res = model.infer(contours[usable], present[usable])
            flagged[usable] = res.implausible
            pct[usable] = res.plausibility
        garbage.append({"kind": kind, "n": len(masks), "flagged_pct": 100.0 * float(flagged.mean()),
                        "no_silhouette_pct": 100.0 * float((~usable).mean()),
                        "median_percentile": float(np.nanmedian(pct)) if np.isfinite(pct).any() else float("nan")})
        examples[kind] = (masks[:1], contours[:1], present[:1])
    genuine = []
    specs = {s.label: s for s in ev.config.sweep}
    inputs = [("clean", d.test_contours), (ev.config.noise.label, ev.noisy(ev.config.noise))]
    for label in ("mask mild", "mask strong"):
        if label in specs and not (specs[label].needs_masks and d.test_masks is None):
            inputs.append((label, ev.noisy(specs[label])))
    for label, contours in inputs:
        for nv in range(K, 0, -1):
            subsets = [s for s in view_subsets(K) if len(s) == nv]
            flagged = np.concatenate([model.infer(contours, _present(n, K, s)).implausible for s in subsets])
            genuine.append({"input": f"test, {label}", "n_views": nv, "n": int(flagged.size),
                            "flagged_pct": 100.0 * float(flagged.mean())})
    ev.e6_garbage_examples = examples
    return {"flag_percentile": cal.flag_percentile, "calibration": {"n_inputs": cal.n_inputs, "n_draws": cal.n_draws,
                                                                    "noise_variance": cal.noise_variance},
            "garbage": garbage, "genuine": genuine}




def run_e6(ev) -> dict:
    """Run every E6 part on an :class:`~silpose.eval.experiments.Evaluation`; returns (and stores in
    ``ev.extra["E6"]``) a JSON-friendly dict."""
    out: dict = {}
    steps = (("flips", flips), ("robust", robust_rows), ("missing_view", missing_view_vs_nn),
             ("self_intersection", self_intersections), ("plausibility", plausibility))
    for i, (name, fn) in enumerate(steps):
        ev._tick(f"E6: {name.replace('_', ' ')}", i, len(steps))
        out[name] = fn(ev)
    ev._tick("E6", len(steps), len(steps))
    ev.extra["E6"] = out
    return out


def e6_markdown(e6: dict) -> list[str]:
    """The E6 section of ``summary.md``."""
    if not e6:
        return []
    lines = ["## E6 — hypotheses, flips, robust inference, missing views, plausibility (issue 12)", ""]
    fl = e6.get("flips") or []
    if fl:
        lines += ["A pose is *flipped* when its facing direction (hip + shoulder axes, floor plane) is more than 90° from "
                  "the truth's. Single answer: what `silpose infer` writes for a lone frame, the posterior mean unless the "
                  "most probable of the top-3 hypotheses faces the other way (`silpose.model.hypotheses.single_answer`); "
                  "consensus: the vote of the view pairs among the top 3 (`infer(consensus=True)`, off by default); "
                  "best of 3: the hypothesis nearest the truth (an oracle).", "",
                  markdown_table(["condition", "n", "posterior mean: flips %", "pose (cm)", "top-1 flips %",
                                  "single answer: flips %", "pose (cm)", "consensus: flips %", "pose (cm)",
                                  "best of 3: flips %", "pose (cm)", "consensus changed %"],
                                 [[r["condition"], str(r["n"]), fmt(r["posterior_mean_flips_pct"], 1),
                                   fmt(r["posterior_mean_pose_cm"]), fmt(r["top1_flips_pct"], 1),
                                   fmt(r["single_answer_flips_pct"], 1), fmt(r["single_answer_pose_cm"]),
                                   fmt(r["consensus_flips_pct"], 1), fmt(r["consensus_pose_cm"]),
                                   fmt(r["best_of_3_flips_pct"], 1), fmt(r["best_of_3_pose_cm"]),
                                   fmt(r["changed_by_consensus_pct"], 1)] for r in fl]), ""]
    rb = e6.get("robust") or {}
    if rb:
        clean = rb.get("clean", {})
        rows = []
        for label, v in rb.items():
            rows.append([label, fmt(v.get("mppca")), fmt(v.get("mppca robust")), fmt(v.get("knn")), fmt(v.get("mlp")),
                         fmt(v.get("mppca", np.nan) / clean.get("mppca", np.nan)),
                         fmt(v.get("mppca robust", np.nan) / clean.get("mppca robust", np.nan))])
        lines += ["Robust inference (`silpose.model.robust`: Tukey-weighted contour points, iteratively reweighted "
                  "conditioning), all views; its rows are also in E3's table as `mppca robust`.", "",
                  markdown_table(["noise", "MPPCA pose (cm)", "MPPCA robust pose (cm)", "kNN pose (cm)", "MLP pose (cm)",
                                  "MPPCA / its clean", "robust / its clean"], rows), ""]
    mv = e6.get("missing_view") or []
    if mv:
        cols = ("mppca_px", "mppca_untangled_px", "mppca_robust_px", "nearest_neighbour_px")
        means = {c: float(np.mean([r[c] for r in mv])) for c in cols}
        nn = means["nearest_neighbour_px"]
        lines += ["Missing-view contours: the 4-view model given the other three views vs the nearest training "
                  "sample's contour of the missing view (same observed views, normalised); both placed with the true "
                  "normalisation; one-sided Chamfer true -> contour. Robust: `silpose infer`'s default inference.", "",
                  markdown_table(["missing view", "n", "MPPCA (px)", "MPPCA untangled (px)", "MPPCA robust (px)",
                                  "nearest neighbour (px)", "ratio", "ratio untangled", "ratio robust"],
                                 [[str(r["missing_view"]), str(r["n"]), *(fmt(r[c]) for c in cols),
                                   fmt(r["ratio"]), fmt(r["ratio_untangled"]), fmt(r["ratio_robust"])] for r in mv]
                                 + [["mean", "", *(fmt(means[c]) for c in cols),
                                     *(fmt(means[c] / nn) for c in cols[:3])]]), ""]
    si = e6.get("self_intersection") or []
    if si:
        lines += ["Self-intersecting contours (a polygon edge crosses another); untangled: after `infer(untangle=True)` "
                  "(`silpose.model.untangle`, 2-opt moves).", "",
                  markdown_table(["contours", "n", "self-intersecting %", "after untangling %"],
                                 [[r["contours"], str(r["n"]), fmt(r["raw_pct"], 1), fmt(r["untangled_pct"], 1)] for r in si]),
                  ""]
    pl = e6.get("plausibility") or {}
    if pl:
        cal = pl["calibration"]
        lines += [f"Plausibility (`silpose.model.plausibility`): a frame is flagged when its log marginal likelihood is "
                  f"below the {pl['flag_percentile']:g} % percentile of held-out training inputs with the same views "
                  f"({cal['n_inputs']} walkers x {cal['n_draws']} draws of the model's observation noise, "
                  f"s² = {cal['noise_variance']:g}), or when every observed view is convex (solidity >= "
                  f"{CONVEX_SOLIDITY:g}: a smooth blob is more likely than any person). Garbage inputs: "
                  f"`silpose.eval.e6_garbage`, all views.", "",
                  markdown_table(["garbage input", "n", "flagged %", "of which no silhouette %", "median percentile"],
                                 [[g["kind"], str(g["n"]), fmt(g["flagged_pct"], 1), fmt(g["no_silhouette_pct"], 1),
                                   fmt(g["median_percentile"], 1)] for g in pl["garbage"]]), "",
                  markdown_table(["genuine input", "views given", "n", "flagged %"],
                                 [[g["input"], str(g["n_views"]), str(g["n"]), fmt(g["flagged_pct"], 1)]
                                  for g in pl["genuine"]]), ""]
    return lines
