"""The dense reference of Gaussian conditioning (the one in the repository; tests only).

``silpose.model.conditioning`` never forms a d x d matrix; this reference does everything the
straightforward way (full covariances per component, ``np.linalg.solve``, scipy's Gaussian
log-density), so the tests compare two independent implementations of the same maths.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import logsumexp
from scipy.stats import multivariate_normal


def dense_conditioning(p, X_obs, obs, noise=0.0) -> dict:
    """Posterior of the missing dims of a PPCA mixture ``p`` (weights_, means_, components_,
    noise_variance_) given X_obs (N, d_obs) at dims ``obs`` (index array, column order) with
    observation-noise variance ``noise`` (scalar or (d_obs,)). Returns a dict of mean, best_mean,
    component_means, responsibilities, log_marginal, cov, component_cov, variance (missing dims in
    increasing order) and reconstruction (N, d): E[x | a] at every dim."""
    obs = np.asarray(obs)
    d = p.means_.shape[1]
    miss = np.setdiff1d(np.arange(d), obs)
    noise = np.broadcast_to(np.asarray(noise, float), (obs.size,))
    logp, cmeans, ccovs, recs = [], [], [], []
    for w, mu, W, s2 in zip(p.weights_, p.means_, p.components_, p.noise_variance_):
        C = W @ W.T + s2 * np.eye(d)
        Caa = C[np.ix_(obs, obs)] + np.diag(noise)
        Cba = C[np.ix_(miss, obs)]
        logp.append(np.log(w) + multivariate_normal(mu[obs], Caa).logpdf(X_obs).reshape(-1))
        sol = np.linalg.solve(Caa, (X_obs - mu[obs]).T).T  # C_aa^-1 (a - mu_a)
        cmeans.append(mu[miss] + sol @ Cba.T)
        ccovs.append(C[np.ix_(miss, miss)] - Cba @ np.linalg.solve(Caa, Cba.T))
        # reconstruction of every dim: mu + W E[z | a], E[z | a] = W_a^T C_aa^-1 (a - mu_a)
        recs.append(mu + (sol @ W[obs]) @ W.T)
    logp = np.array(logp).T
    log_marg = logsumexp(logp, axis=1)
    resp = np.exp(logp - log_marg[:, None])
    cmeans = np.stack(cmeans, axis=1)  # (N, M, dm)
    mean = np.einsum("nm,nmk->nk", resp, cmeans)
    dev = cmeans - mean[:, None]
    cov = np.einsum("nm,mij->nij", resp, np.array(ccovs)) + np.einsum("nm,nmi,nmj->nij", resp, dev, dev)
    return dict(mean=mean, component_means=cmeans, responsibilities=resp, log_marginal=log_marg, cov=cov,
                component_cov=np.array(ccovs), variance=np.einsum("nii->ni", cov),
                best_mean=cmeans[np.arange(len(mean)), resp.argmax(1)],
                reconstruction=np.einsum("nm,mnd->nd", resp, np.array(recs)), missing=miss)


@pytest.fixture
def dense_reference():
    """:func:`dense_conditioning`, the dense reference of Gaussian conditioning."""
    return dense_conditioning


@pytest.fixture
def moved_in_place():
    """f(clean (n, 2) outline) -> (jittered, patched): 1 px Gaussian jitter (seed 3), and points 40..69 pushed
    8 px out along the normals with a half-sine profile. Both move points without sliding them along the
    outline (the evaluation's contour noise), which outline repairs must leave alone."""
    from silpose.shared.contours import outward_normals

    def make(clean: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        jittered = clean + np.random.default_rng(3).normal(0, 1.0, clean.shape)
        patched = clean.copy()
        profile = np.sin(np.pi * (np.arange(30) + 0.5) / 30)
        patched[40:70] += 8.0 * profile[:, None] * outward_normals(clean)[40:70]
        return jittered, patched

    return make
