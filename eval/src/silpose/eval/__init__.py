"""silpose.eval — the paper's experiments (section 6) on our data.

The error measures live in :mod:`silpose.shared.metrics` (docs/conventions.md, "Evaluation protocol").

Modules (one concept each; import them directly, nothing heavy is imported here):

- ``noise``       segmentation-like noise on test contours (jitter, normal patches, mask corruption)
- ``baselines``   chance, kNN and ridge regression per view subset
- ``experiments`` E1-E4 as per-example result rows (``EvalConfig``, ``EvalData``, ``Evaluation``)
- ``tables``      summary statistics (mean, median, quartiles) and Markdown tables
- ``report``      summary.md with the paper's figures beside ours, headline numbers
- ``plots``       box plots in the paper's style
- ``e5_figures``     E5 example figures (paper Figs. 6 and 7)
- ``e6_inference`` E6, how honest the inference is: flips and top-K hypotheses, robust inference,
  missing-view contours, self-intersections, plausibility flags
- ``e6_figures`` E6 figures (a flip resolved, robust inference on a masked input, flagged garbage)
- ``e6_garbage``     inputs that are not a person, for E6's plausibility check
- ``frames_eval`` segmentation quality on a camera-frames dataset and what it costs the pose
- ``frames_figure`` its example figure (frames, silhouettes with reconstructions, stick figures; paper Fig. 9)
- ``errors``      ``EvalInputError``
- ``run``         load data + model, run, write ``reports/<preset>/``
- ``cli``         ``silpose eval [PRESET]``

Helpers that serve only tests and benchmarks live in ``benchmarks/`` (``frames_composite``: a Blender-free
frames dataset; ``recording_scores``: a recording's rows scored against its truth).
"""
