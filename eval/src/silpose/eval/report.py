"""Tables and headline numbers from the per-example rows of :mod:`silpose.eval.experiments`.

Every table gives mean, median and quartiles (Q1, Q3). Pose error: cm, root-relative, no other
alignment (paper §6); "PA" columns are a labelled extra (similarity Procrustes). Contour error:
one-sided Chamfer D(true clean -> reconstruction) in px (paper eq. 5), mean over the views that
get a reconstruction; "sym" is the mean of both directions.
"""

from __future__ import annotations

import json

import numpy as np

from .experiments import E1_PER_VIEW, REGRESSORS as BASELINES
from .tables import QUARTILE_HEADERS, fmt, fmt_stats, markdown_table, select, stats

__all__ = ["PAPER", "stats", "e1_comparison", "noise_comparison", "headline", "pct_per_px", "markdown_summary"]

#: The paper's figures (Grauman et al. 2003, §6).
#: Table names of the regression baselines.
BASELINE_NAMES = {"knn": "kNN regression", "ridge": "ridge regression", "mlp": "MLP regression"}

PAPER = {
    "pose_4_views_cm": 3.0,
    "pose_1_view_cm": 15.0,
    "chance_cm": 29.0,
    "multi_view_pose_improvement_pct": 24.0,
    "multi_view_contour_improvement_pct": 16.0,
}


def _pct_better(multi: float, single: float) -> float:
    """Improvement of multi over single in % of the single-view error: 100 (1 - multi / single)."""
    return float(100.0 * (1.0 - multi / single)) if single and np.isfinite(single) else float("nan")


def e1_comparison(df, single: str = "single-view") -> dict:
    """E1 means: pose (pooled over views) and per-view contours, single- vs multi-view training.

    ``single``: the single-view models' ``training`` label: ``"single-view"`` (equal q, the keys at the
    top level) or :data:`~silpose.eval.experiments.E1_PER_VIEW` (q / K latent dimensions per view; with
    the default label its comparison is nested under ``"equal_q_per_view"`` when those rows exist).
    """
    e1 = select(df, experiment="E1")
    if e1.empty:
        return {}
    sv = select(e1, training=single)
    if sv.empty:
        return {}
    mv = select(e1, training="multi-view")
    views = sorted(int(v) for v in sv["trained_views"].unique())
    sv_c = np.concatenate([select(sv, trained_views=str(k))[f"chamfer_v{k}"].to_numpy() for k in views])
    mv_c = np.concatenate([mv[f"chamfer_v{k}"].to_numpy() for k in views])
    out = {
        "single_view_pose_cm": stats(sv["pose_cm"])["mean"],
        "multi_view_pose_cm": stats(mv["pose_cm"])["mean"],
        "single_view_chamfer_px": stats(sv_c)["mean"],
        "multi_view_chamfer_px": stats(mv_c)["mean"],
    }
    e2 = select(df, experiment="E2")
    if not e2.empty:  # the 4-view model given the single-view models' input (view k alone): same inputs
        one = [select(e2, input_views=str(k)) for k in views]
        if all(len(g) for g in one):
            out["multi_view_model_one_view_input_pose_cm"] = stats(np.concatenate([g["pose_cm"] for g in one]))["mean"]
            out["multi_view_model_one_view_input_chamfer_px"] = stats(
                np.concatenate([g[f"chamfer_v{k}"] for k, g in zip(views, one)]))["mean"]
    out["pose_improvement_pct"] = _pct_better(out["multi_view_pose_cm"], out["single_view_pose_cm"])
    out["contour_improvement_pct"] = _pct_better(out["multi_view_chamfer_px"], out["single_view_chamfer_px"])
    out["_sv_chamfer"], out["_mv_chamfer"] = sv_c, mv_c
    if single == "single-view":
        per_view = e1_comparison(df, E1_PER_VIEW)
        if per_view:
            out["equal_q_per_view"] = per_view
    return out


def headline(df) -> dict:
    """The numbers the issue asks for, with the paper's beside them (JSON-friendly)."""
    h: dict = {"paper": PAPER}
    e2 = select(df, experiment="E2")
    if not e2.empty:
        h["pose_cm_by_n_views"] = {int(n): stats(g["pose_cm"]) for n, g in e2.groupby("n_input_views")}
        h["chamfer_px_by_n_views"] = {int(n): stats(g["chamfer_px"]) for n, g in e2.groupby("n_input_views")}
        h["chamfer_sym_px_by_n_views"] = {int(n): stats(g["chamfer_sym_px"])["mean"] for n, g in e2.groupby("n_input_views")}
    e1 = e1_comparison(df)
    if e1:
        h["e1"] = {k: v for k, v in e1.items() if not k.startswith("_") and k != "equal_q_per_view"}
        h["e1"]["capacity"] = "equal q (the single-view models have the 4-view model's q)"
        if "equal_q_per_view" in e1:
            h["e1_equal_q_per_view"] = {k: v for k, v in e1["equal_q_per_view"].items() if not k.startswith("_")}
            h["e1_equal_q_per_view"]["capacity"] = "equal latent dimensions per view (single-view q = q / K)"
    by_noise = noise_comparison(df)
    if by_noise:
        h["pose_mean_cm_by_noise_all_views"] = by_noise
    e4 = select(df, experiment="E4")
    if not e4.empty:
        h["chance_cm"] = stats(select(e4, method="chance")["pose_cm"])
        cmp: dict = {}
        for n, g in e4[e4["method"] != "chance"].groupby("n_input_views"):
            cmp[int(n)] = {m: stats(gg["pose_cm"])["mean"] for m, gg in g.groupby("method")}
            if not e2.empty:
                cmp[int(n)]["mppca"] = stats(select(e2, n_input_views=n)["pose_cm"])["mean"]
        robust = _robust_by_n_views(df, e2)
        for n, v in robust.items():
            cmp.setdefault(n, {})["mppca robust"] = v
        h["pose_mean_cm_by_method_and_n_views"] = cmp
        if not e2.empty:
            ahead = []
            for views, g in e2.groupby("input_views"):
                m = g["pose_cm"].mean()
                others = {k: float(select(e4, input_views=views, method=k)["pose_cm"].mean()) for k in BASELINES}
                ahead.append({"views": views, "mppca": float(m), **others,
                              "mppca_best": bool(m < np.nanmin(list(others.values())))})
            h["mppca_vs_baselines_by_subset"] = ahead
    return h


def _robust_by_n_views(df, e2) -> dict:
    """{n views: mean pose cm of robust inference (E6's E3 rows) with E2's noise}, for n = all views and n = 1 (the
    mean over every view alone, as kNN's one-view figure is; only when E6 scored each view alone)."""
    e3 = select(df, experiment="E3", method="mppca robust")
    if e3.empty or e2.empty:
        return {}
    e3 = select(e3, noise=str(e2["noise"].iloc[0]))
    K = int(e2["n_input_views"].max())
    out = {}
    every = select(e3, n_input_views=K)
    if len(every):
        out[K] = float(every["pose_cm"].mean())
    alone = select(e3, n_input_views=1)
    if alone["input_views"].nunique() == K:
        out[1] = float(alone["pose_cm"].mean())
    return out


def noise_comparison(df) -> dict:
    """E3 with every view given: {noise label: {"mppca", "mppca robust", "knn", "ridge": mean pose cm (the
    methods with rows), "x_clean" / "x_clean_robust": the MPPCA mean / its clean mean}} in the sweep's order
    (empty without E3 rows)."""
    e3 = select(df, experiment="E3")
    if e3.empty:
        return {}
    all_views = "".join(str(k) for k in range(int(e3["n_input_views"].max())))
    e3 = select(e3, input_views=all_views)
    out: dict = {}
    for noise in dict.fromkeys(e3["noise"]):
        g = select(e3, noise=noise)
        out[noise] = {m: float(select(g, method=m)["pose_cm"].mean()) for m in ("mppca", "mppca robust", *BASELINES)
                      if len(select(g, method=m))}
    for method, key in (("mppca", "x_clean"), ("mppca robust", "x_clean_robust")):
        clean = out.get("clean", {}).get(method)
        for v in out.values():
            if method in v:
                v[key] = v[method] / clean if clean else float("nan")
    return out


def _headline_md(df) -> list[str]:
    """The headline table: pose error by number of views (standard noise) and by noise kind (all views)."""
    h = headline(df)
    rows = []
    paper = {4: f"{PAPER['pose_4_views_cm']:.0f}", 1: f"{PAPER['pose_1_view_cm']:.0f}"}
    for n, st in sorted(h.get("pose_cm_by_n_views", {}).items(), key=lambda t: -t[0]):
        by = h.get("pose_mean_cm_by_method_and_n_views", {}).get(n, {})
        rows.append([f"{n} view{'s' if n > 1 else ''}, standard contour noise", fmt(st["mean"]), "–",
                     fmt(by.get("mppca robust", float("nan"))), "–",
                     fmt(by.get("knn", float("nan"))), fmt(by.get("mlp", float("nan"))), paper.get(n, "–")])
    n_all = max(h.get("pose_cm_by_n_views", {0: None}))
    for noise, v in h.get("pose_mean_cm_by_noise_all_views", {}).items():
        if noise == "clean" or noise.startswith("mask") or noise == "standard":
            rows.append([f"{n_all or 'all'} views, noise '{noise}'", fmt(v.get("mppca", float("nan"))),
                         f"{fmt(v.get('x_clean', float('nan')))}×", fmt(v.get("mppca robust", float("nan"))),
                         f"{fmt(v.get('x_clean_robust', float('nan')))}×", fmt(v.get("knn", float("nan"))),
                         fmt(v.get("mlp", float("nan"))), "–"])
    if "chance_cm" in h:
        rows.append(["chance (random training pose)", fmt(h["chance_cm"]["mean"]), "–", "–", "–", "–", "–",
                     f"{PAPER['chance_cm']:.0f}"])
    if not rows:
        return []
    return ["## Headline", "",
            "Mean pose error (cm). 'standard' contour noise: E2's inputs; 'mask mild'/'mask strong' corrupt the "
            "silhouette (holes, blobs, a shadow) and re-extract the contour (E3, every view given). 'robust': "
            "the same inputs with robust inference (`silpose infer`'s default; E6).", "",
            markdown_table(["condition", "MPPCA (cm)", "× clean", "MPPCA robust (cm)", "× clean (robust)", "kNN (cm)",
                            "MLP (cm)", "paper (cm)"], rows), ""]


def _e1_md(df) -> list[str]:
    e1 = select(df, experiment="E1")
    if e1.empty:
        return []
    c = e1_comparison(df)
    rows = []
    for (training, tv), g in e1.groupby(["training", "trained_views"], sort=False):
        views = [int(v) for v in tv] if training == "multi-view" else [int(tv)]
        ch = np.concatenate([g[f"chamfer_v{k}"].to_numpy() for k in views])
        rows.append([training, tv, tv, str(len(g)), fmt_stats(stats(g["pose_cm"])), fmt_stats(stats(ch)), fmt(stats(g["pose_pa_cm"])["mean"])])
    rows.append(["single-view (all views pooled)", "k", "k", str(len(select(e1, training="single-view"))),
                 fmt_stats(stats(select(e1, training="single-view")["pose_cm"])), fmt_stats(stats(c["_sv_chamfer"])), ""])
    pv = c.get("equal_q_per_view")
    if pv:
        rows.append([f"{E1_PER_VIEW} (all views pooled)", "k", "k", str(len(select(e1, training=E1_PER_VIEW))),
                     fmt_stats(stats(select(e1, training=E1_PER_VIEW)["pose_cm"])), fmt_stats(stats(pv["_sv_chamfer"])), ""])
    e2 = select(df, experiment="E2")
    one = [(int(k), select(e2, input_views=k)) for k in sorted(select(e1, training="single-view")["trained_views"].unique())]
    if not e2.empty and all(len(g) for _, g in one):
        pose = np.concatenate([g["pose_cm"] for _, g in one])
        ch = np.concatenate([g[f"chamfer_v{k}"] for k, g in one])
        rows.append(["multi-view, given view k only (from E2; extra)", "0123", "k", str(len(pose)), fmt_stats(stats(pose)),
                     fmt_stats(stats(ch)), fmt(np.concatenate([g["pose_pa_cm"] for _, g in one]).mean())])
    out = ["## E1 — single-view vs multi-view training (paper Fig. 5)", "",
           "Same noisy test examples for both. A single-view model k (trained on view k alone) gets the noisy contour "
           "of view k; the 4-view model gets the noisy contours of all 4 views. Contour error per view: single-view "
           "model k in view k vs the 4-view model in view k. The extra last row gives the 4-view model exactly the "
           "single-view models' input (view k alone), separating the effect of training from that of the input.", "",
           markdown_table(["training", "trained views", "input views", "n", *[f"pose {h} (cm)" for h in QUARTILE_HEADERS],
                   *[f"Chamfer {h} (px)" for h in QUARTILE_HEADERS], "PA pose mean (cm, extra)"], rows), "",
           markdown_table(["multi-view improvement", "ours, equal q", "ours, equal q per view", "paper"], [
               ["pose (mean)", f"{fmt(c['pose_improvement_pct'], 1)} %",
                f"{fmt(pv['pose_improvement_pct'], 1)} %" if pv else "–", f"{PAPER['multi_view_pose_improvement_pct']:.0f} %"],
               ["contours (mean Chamfer)", f"{fmt(c['contour_improvement_pct'], 1)} %",
                f"{fmt(pv['contour_improvement_pct'], 1)} %" if pv else "–",
                f"{PAPER['multi_view_contour_improvement_pct']:.0f} %"],
           ]), "",
           "Capacity: 'equal q' gives each single-view model the 4-view model's latent dimension q (so K times its "
           "latent dimensions per view); 'equal q per view' gives it q / K (the 4-view model's share per view). "
           "The paper does not say which it used.", ""]
    return out


def pct_per_px(settings: dict) -> float:
    """The paper's normalisation of a Chamfer distance: % error per px = 100 * contour length / area."""
    length, area = settings.get("test_contour_length_px_mean"), settings.get("test_area_px_mean")
    return 100.0 * length / area if length and area else float("nan")


def _e2_md(df, settings: dict) -> list[str]:
    e2 = select(df, experiment="E2")
    if e2.empty:
        return []
    per_px = pct_per_px(settings)
    paper = {4: f"{PAPER['pose_4_views_cm']:.0f}", 1: f"{PAPER['pose_1_view_cm']:.0f}"}
    rows = []
    for n, g in sorted(e2.groupby("n_input_views"), key=lambda t: -t[0]):
        rows.append([str(n), str(len(g)), fmt_stats(stats(g["pose_cm"])), paper.get(int(n), "–"), fmt_stats(stats(g["chamfer_px"])),
                     fmt(per_px * g["chamfer_px"].mean(), 1),
                     fmt(g["chamfer_observed_px"].mean()), fmt(g["chamfer_missing_px"].mean()), fmt(g["chamfer_sym_px"].mean()),
                     fmt(g["pose_pa_cm"].mean())])
    detail = [[v, str(len(g)), fmt_stats(stats(g["pose_cm"])), fmt(g["chamfer_px"].mean()), fmt(g["chamfer_missing_px"].mean())]
              for v, g in sorted(e2.groupby("input_views"), key=lambda t: (-len(t[0]), t[0]))]
    return ["## E2 — the 4-view model given 4, 3, 2, 1 views (paper Fig. 8)", "",
            "Every non-empty subset of views on every example (3 views: each left out in turn; 2 and 1: all combinations). "
            "Chamfer: one-sided true clean -> reconstruction, mean over all 4 views; 'observed'/'missing' split it by "
            "whether the view was an input; 'sym' is the symmetric mean.", "",
            markdown_table(["input views", "n", *[f"pose {h} (cm)" for h in QUARTILE_HEADERS], "paper pose mean (cm)",
                    *[f"Chamfer {h} (px)" for h in QUARTILE_HEADERS], "≈ % (paper's normalisation)", "Chamfer observed",
                    "Chamfer missing", "Chamfer sym", "PA pose mean (cm, extra)"], rows), "",
            f"Paper's normalisation (§6): % ≈ Chamfer × contour length / area. Our test silhouettes average "
            f"{fmt(settings.get('test_contour_length_px_mean') or float('nan'), 0)} px of contour and "
            f"{fmt(settings.get('test_area_px_mean') or float('nan'), 0)} px of area, so 1 px ≈ {fmt(per_px, 1)} % "
            f"(paper: 850 px, 30,000 px, 1 px ≈ 2.8 %). Our figures are smaller, so equal pixel errors mean more here.", "",
            "Per subset:", "",
            markdown_table(["views", "n", *[f"pose {h} (cm)" for h in QUARTILE_HEADERS], "Chamfer mean (px)", "Chamfer missing (px)"], detail), ""]


def _e3_md(df) -> list[str]:
    e3 = select(df, experiment="E3")
    if e3.empty:
        return []
    rows = [[noise, method, views, str(len(g)), fmt_stats(stats(g["pose_cm"])),
             fmt(g["chamfer_px"].mean()) if "chamfer_px" in g and g["chamfer_px"].notna().any() else "–"]
            for (noise, method, views), g in e3.groupby(["noise", "method", "input_views"], sort=False)]
    return ["## E3 — noise types and magnitudes", "",
            "Noise definitions and magnitudes: see 'Settings' below and `silpose.eval.noise`. kNN/ridge/MLP get all views.", "",
            markdown_table(["noise", "method", "input views", "n", *[f"pose {h} (cm)" for h in QUARTILE_HEADERS], "Chamfer mean (px)"], rows), ""]


def _e4_md(df, timing: dict | None = None) -> list[str]:
    e4 = select(df, experiment="E4")
    if e4.empty:
        return []
    e2 = select(df, experiment="E2")
    ch = stats(select(e4, method="chance")["pose_cm"])
    rows = [["chance (random training pose)", "–", fmt_stats(ch), f"{PAPER['chance_cm']:.0f}"]]
    for n in sorted(e4["n_input_views"].unique(), reverse=True):
        if n == 0:
            continue
        if not e2.empty:
            rows.append(["MPPCA (ours)", str(n), fmt_stats(stats(select(e2, n_input_views=n)["pose_cm"])), ""])
        for m in BASELINES:
            g = select(e4, n_input_views=n, method=m)
            if len(g):
                rows.append([BASELINE_NAMES[m], str(n), fmt_stats(stats(g["pose_cm"])), ""])
    out = ["## E4 — chance and baselines", "",
           "kNN (k=5, distance-weighted) and ridge (penalty by leave-one-out, as RidgeCV) regress root-relative joints "
           "on the observed views' normalised contours; one fitted per view subset on the clean training data (ridge "
           "and the MLP on at most `baseline_rows` training samples, settings); same noisy inputs as E2. "
           "When the MPPCA models joints per measured stature, so do they (joints / (stature / 1.75 m), "
           "prediction times the stature measured from the observed views). The MLP (scikit-learn MLPRegressor, "
           "hidden layers 512, 512) is ONE network for every view subset (absent views zeroed, presence flags), "
           "trained on the clean training contours and noisy copies of them (the test noise model, other seeds), "
           "inputs scaled by one global factor, early stopping on a validation split by walker.", "",
           markdown_table(["method", "input views", *[f"pose {h} (cm)" for h in QUARTILE_HEADERS], "paper mean (cm)"], rows), ""]
    h = headline(df).get("mppca_vs_baselines_by_subset", [])
    if h:
        out += ["Pose mean (cm) per view subset:", "",
                markdown_table(["views", "MPPCA", "kNN", "ridge", "MLP", "MPPCA best"],
                       [[r["views"], fmt(r["mppca"]), *(fmt(r.get(k, float("nan"))) for k in BASELINES),
                         "yes" if r["mppca_best"] else "no"] for r in h]),
                ""]
    if timing:
        out += ["Baseline cost (fitting: all view subsets' regressors, or the one MLP with its noisy training copies; "
                "prediction: per test frame, over every E3/E4/E6 call):", "",
                markdown_table(["method", "fitting (s)", "prediction (ms / frame)"],
                               [[BASELINE_NAMES[k], fmt(v["fit_s"]), fmt(v.get("ms_per_frame", float("nan")))]
                                for k, v in timing.items()]), ""]
    return out


def markdown_summary(df, settings: dict, title: str, figures: list[str] | None = None, notes: list[str] | None = None,
                     sections: list[str] | None = None, baseline_timing: dict | None = None) -> str:
    """The whole ``summary.md``: one table per experiment, paper figures beside ours, settings; ``sections``
    (Markdown lines, e.g. E6's) go after E4."""
    from silpose.shared.version import silpose_version

    parts = [f"# {title}", "", f"silpose {silpose_version()}.", "",
             "Pose error: mean Euclidean distance over the 19 joints, cm, root-relative, no other alignment "
             "(PA = similarity-Procrustes-aligned, a labelled extra, not the paper's measure). Contour error: "
             "one-sided Chamfer distance D(true clean contour -> reconstruction), px (paper eq. 5), via an exact "
             "Euclidean distance transform; missing views are placed with their true normalisation.", ""]
    parts += _headline_md(df) + _e1_md(df) + _e2_md(df, settings) + _e3_md(df) + _e4_md(df, baseline_timing)
    parts += list(sections or [])
    if figures:
        parts += ["## Figures", ""] + [f"![{f}]({f})" for f in figures] + [""]
    if notes:
        parts += ["## Notes", ""] + [f"- {n}" for n in notes] + [""]
    parts += ["## Settings", "", "```json", json.dumps(settings, indent=2, default=str), "```", ""]
    return "\n".join(parts)
