"""silpose.eval — the paper's experiments (section 6) on our data.

Modules (one concept each; import them directly, nothing heavy is imported here):

- ``noise``       segmentation-like noise on test contours (jitter, normal patches, mask corruption)
- ``metrics``     pose error (cm, root-relative), Procrustes extra, image Chamfer distance (paper eq. 5)
- ``baselines``   chance, kNN and ridge regression per view subset
- ``experiments`` E1-E4 as per-example result rows (``EvalConfig``, ``EvalData``, ``Evaluation``)
- ``report``      tables (mean, median, quartiles) with the paper's figures, headline numbers
- ``plots``       box plots in the paper's style
- ``figures``     E5 example figures (paper Figs. 6 and 7)
- ``run``         load data + model, run, write ``reports/<preset>/``
- ``cli``         ``silpose eval [PRESET]``
"""
