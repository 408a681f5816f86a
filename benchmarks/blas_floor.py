"""The BLAS floor of each compute kernel: the matrix products it cannot avoid, timed with plain numpy.

A kernel row of the benchmark report carries ``blas_floor_s`` (the floor's seconds for the row's
shapes, measured in the same process a moment later) and ``over_floor`` (kernel seconds / floor
seconds). A ratio near 1 means the kernel is as fast as its unavoidable dense linear algebra on this
machine and BLAS; the excess is everything else (Python, element-wise passes, small factorisations).
The floor replaces the dense-conditioning copies the inference and EM benchmarks used to time: it
is a bound no implementation can beat, not a competitor (the dense reference lives in the tests).

Which products each kernel cannot avoid, and why (all float64; ``t(m x k x n)`` is the time of one
product A (m, k) @ B (k, n) of random operands):

**MPPCA EM iteration** (``silpose.model.MPPCA``; Tipping & Bishop 1999, Appendix C) on N rows of d
features, M components of q latent dims, model covariance C_i = W_i W_i^T + sigma_i^2 I:

- E-step: the responsibilities need log N(x_n | mu_i, C_i) for every row and component. C_i is
  rank q plus isotropic, so its Mahalanobis term is exactly (||e||^2 - z^T M_i^-1 z) / sigma_i^2 with
  z = W_i^T e (Woodbury); every exact evaluation needs those N M q inner products of length d:
  the product X (N, d) @ [W_1 .. W_M] (d, M q).
- M-step: the new W_i needs the d x q cross-moment sum_n R_ni x_n <z_ni>^T of every component:
  the product X^T (d, N) @ [R_1 <Z_1> .. R_M <Z_M>] (N, M q).

  floor = t(N x d x Mq) + t(d x N x Mq). Left out, as lower order when M, q << d: the row norms, the
  products with the means (M columns, not M q) and the O(N M q^2) latent algebra.

**Batched inference** (``ShapeStructureModel.infer``) of N frames with d_a observed dims (K views x n
points x 2) and all d dims returned (every view's reconstructed contour and the joints), same mixture:

- observed block: each component's latent posterior mean x_hat_ni = K_i^-1 W_a,i^T (a_n - mu_a,i) / D_i
  needs W_a,i^T a_n for every frame and component: the product A (N, d_a) @ [W_a,1 .. W_a,M] (d_a, M q);
- output: the mixture posterior mean of all d dims, sum_i r_ni (mu_i + W_i x_hat_ni), needs
  [r_1 x_hat_1 .. r_M x_hat_M] (N, M q) @ [W_1^T; ..; W_M^T] (M q, d).

  floor = t(N x d_a x Mq) + t(N x Mq x d). Left out: the normalisation of the contours, ||a||^2, the
  q x q algebra per component and the mixture's softmax (all O(N (d_a + M q^2))).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Product:
    """One matrix product A (m, k) @ B (k, n) of float64 operands; ``what`` says which product it is."""

    what: str
    m: int
    k: int
    n: int

    @property
    def flops(self) -> int:
        """Floating-point operations (multiply + add) of the product: 2 m k n."""
        return 2 * self.m * self.k * self.n

    def __str__(self) -> str:
        return f"{self.what} ({self.m}x{self.k})@({self.k}x{self.n})"


def em_iteration(n: int, d: int, m: int, q: int) -> tuple[Product, ...]:
    """The two products of one MPPCA EM iteration (module docstring): E-step X W, M-step X^T (R Z)."""
    return (Product("E-step X@W", n, d, m * q), Product("M-step X^T@RZ", d, n, m * q))


def inference(n: int, d_obs: int, d_out: int, m: int, q: int) -> tuple[Product, ...]:
    """The two products of batched inference (module docstring): observed block A W_a, output (r x_hat) W^T."""
    return (Product("observed A@W_a", n, d_obs, m * q), Product("output RZ@W^T", n, m * q, d_out))


def time_product(p: Product, repeats: int = 3, min_seconds: float = 0.05, seed: int = 0) -> float:
    """Best wall seconds of ``A @ B`` for random operands of the product's shapes.

    The operands are allocated once, before timing. The product runs at least ``repeats`` times and
    until ``min_seconds`` have passed (so microsecond products are timed often enough); the minimum
    is returned, the optimistic figure a floor should be.
    """
    rng = np.random.default_rng(seed)
    a = rng.standard_normal((p.m, p.k))
    b = rng.standard_normal((p.k, p.n))
    out = np.empty((p.m, p.n))
    best, spent, runs = float("inf"), 0.0, 0
    while runs < repeats or spent < min_seconds:
        t0 = time.perf_counter()
        np.matmul(a, b, out=out)
        dt = time.perf_counter() - t0
        best, spent, runs = min(best, dt), spent + dt, runs + 1
    return best


def floor_seconds(products: tuple[Product, ...], repeats: int = 3) -> float:
    """Sum over ``products`` of :func:`time_product`: the kernel's BLAS floor in seconds."""
    return float(sum(time_product(p, repeats) for p in products))


def floor_columns(kernel_seconds: float, products: tuple[Product, ...], repeats: int = 3) -> dict:
    """The floor columns of a kernel row: ``blas_floor_s``, ``over_floor`` (kernel / floor), ``floor_products``.

    ``kernel_seconds`` is the kernel's time for exactly the shapes of ``products``.
    """
    floor = floor_seconds(products, repeats)
    return {"blas_floor_s": floor, "over_floor": kernel_seconds / floor,
            "floor_products": " + ".join(str(p) for p in products)}


def shared_floor(rows: list[dict]) -> list[dict]:
    """``rows`` with one floor per shape: rows whose ``floor_products`` are equal take the smallest ``blas_floor_s``
    measured among them, and ``over_floor`` = ``seconds`` / that floor (in place; rows without a floor untouched).

    Each row times its floor right after its kernel, so on a shared machine the same products were measured
    up to 2x apart within one section (another process on a core halves a 2-thread BLAS); contention only ever
    slows a product down, so the fastest measurement is the floor's best estimate, and every kernel of the
    same shapes is held to it (the ratios can only grow)."""
    best: dict[str, float] = {}
    for r in rows:
        if "floor_products" in r and "blas_floor_s" in r:
            best[r["floor_products"]] = min(best.get(r["floor_products"], np.inf), float(r["blas_floor_s"]))
    for r in rows:
        if r.get("floor_products") in best:
            r["blas_floor_s"] = best[r["floor_products"]]
            r["over_floor"] = float(r["seconds"]) / r["blas_floor_s"]
    return rows

