"""The Dirichlet distribution of the species model (paper §5.1): maximum-likelihood fit of a
set of tuples that each sum to 1 (Minka 2003, fixed-point precision with Newton steps), the
log-likelihood, and the inverse digamma it needs.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.special import digamma, gammaln, polygamma

MIN_VALUE = 1e-12                # zeros in a tuple are clipped to this before log (fallback)
MAX_PRECISION = 1e5              # cap of s = Σα (identical samples drive the ML s to ∞)
DEFAULT_PRECISION = 20.0         # s used when there is too little data to estimate it


# ============================================================================ Dirichlet

@dataclass
class DirichletFit:
    """A fitted Dirichlet ``D(z | α)``: ``alpha (K,)`` > 0; ``loglik`` mean log-likelihood per
    sample after the start and after every fixed-point iteration; ``fallback`` None for a clean
    maximum-likelihood fit, else why another estimate was used; ``n_samples`` rows used."""

    alpha: np.ndarray
    loglik: list = field(default_factory=list)
    fallback: str | None = None
    n_samples: int = 0
    iterations: int = 0

    @property
    def precision(self) -> float:
        """``s = Σ_k α_k``: large → samples close to the mean."""
        return float(np.sum(self.alpha))

    @property
    def mean(self) -> np.ndarray:
        """``m = α / s`` ``(K,)``."""
        return self.alpha / self.precision

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``(n, K)`` samples, every row positive and summing to 1."""
        z = rng.dirichlet(self.alpha, size=n)
        z = np.where(np.isfinite(z), z, 0.0)
        z = np.maximum(z, 1e-12)
        return z / z.sum(axis=1, keepdims=True)


def inv_digamma(y: np.ndarray, iterations: int = 5) -> np.ndarray:
    """``x`` with ``ψ(x) = y`` (elementwise) by Newton's method from Minka's (2003, App. C) start
    ``x0 = exp(y) + 1/2`` for ``y ≥ −2.22``, else ``−1 / (y − ψ(1))``; five steps reach 14 digits."""
    y = np.asarray(y, np.float64)
    x = np.where(y >= -2.22, np.exp(np.minimum(y, 700.0)) + 0.5, -1.0 / (y - digamma(1.0)))
    for _ in range(iterations):
        x = x - (digamma(x) - y) / polygamma(1, x)
        x = np.maximum(x, 1e-300)
    return x


def dirichlet_loglik(alpha: np.ndarray, mean_log: np.ndarray) -> float:
    """Mean log-likelihood per sample of Eq. 11:
    ``log Γ(Σα) − Σ log Γ(α_k) + Σ (α_k − 1) · mean_n log z_nk`` (``mean_log (K,)``)."""
    alpha = np.asarray(alpha, np.float64)
    return float(gammaln(alpha.sum()) - gammaln(alpha).sum() + np.dot(alpha - 1.0, mean_log))


def _best_precision(mean: np.ndarray, mean_log: np.ndarray) -> float:
    """Start for the precision: the best ``s`` on a log grid (0.1 … MAX_PRECISION) for α = s·m.
    (The moment estimate of s is thrown far off by one low-variance component, and the Newton
    step from there leaves the positive orthant.)"""
    grid = np.logspace(-1.0, np.log10(MAX_PRECISION), 81)
    ll = [dirichlet_loglik(g * mean, mean_log) for g in grid]
    return float(grid[int(np.argmax(ll))])


def _newton_step(alpha: np.ndarray, mean_log: np.ndarray) -> np.ndarray:
    """Newton direction ``H⁻¹ g`` for the mean log-likelihood (Minka eq. 15–18): the Hessian is
    ``diag(q) + z 11ᵀ`` with ``q_k = −ψ'(α_k)``, ``z = ψ'(Σα)``, so
    ``(H⁻¹g)_k = (g_k − b) / q_k``, ``b = Σ_j (g_j/q_j) / (1/z + Σ_j 1/q_j)``."""
    g = digamma(alpha.sum()) - digamma(alpha) + mean_log
    q = -polygamma(1, alpha)
    z = polygamma(1, alpha.sum())
    b = np.sum(g / q) / (1.0 / z + np.sum(1.0 / q))
    return (g - b) / q


def _fit_precision(mean: np.ndarray, mean_log: np.ndarray, max_iter: int) -> tuple[np.ndarray, list, bool]:
    """ML precision with the mean fixed (Minka §3.3): maximize
    ``f(s) = log Γ(s) − Σ log Γ(s m_k) + s Σ m_k mean_log_k`` by safeguarded Newton,
    ``f'(s) = ψ(s) − Σ m_k ψ(s m_k) + Σ m_k mean_log_k``, ``f''(s) = ψ'(s) − Σ m_k² ψ'(s m_k)``."""
    s = _best_precision(mean, mean_log)
    hist = [dirichlet_loglik(s * mean, mean_log)]
    for _ in range(max_iter):
        d1 = digamma(s) - np.dot(mean, digamma(s * mean)) + np.dot(mean, mean_log)
        d2 = polygamma(1, s) - np.dot(mean ** 2, polygamma(1, s * mean))
        step = -d1 / d2 if d2 < 0 else np.sign(d1) * s
        for t in (1.0, 0.5, 0.25, 0.125, 0.0625):
            cand = min(s + t * step, MAX_PRECISION)
            if cand > 0:
                ll = dirichlet_loglik(cand * mean, mean_log)
                if ll > hist[-1]:
                    break
        else:
            break
        if ll - hist[-1] <= 1e-12 * max(1.0, abs(ll)):
            break
        s = cand
        hist.append(ll)
        if s >= MAX_PRECISION:
            return s * mean, hist, True
    return s * mean, hist, False


def fit_dirichlet(X: np.ndarray, max_iter: int = 2000, fixed_mean: np.ndarray | None = None) -> DirichletFit:
    """Maximum-likelihood Dirichlet for rows ``X (S, K)`` of proportions (each row is normalized
    to sum 1 first).

    Minka's fixed point ``α_k ← ψ⁻¹(ψ(Σ_j α_j) + mean_n log z_nk)`` (Minka 2003 eq. 9; ψ⁻¹ by
    Newton, :func:`inv_digamma`), started from the sample mean with the best precision on a grid;
    each step maximizes a lower bound of the likelihood, so the log-likelihood never decreases.
    Where a (backtracked) Newton step on α raises the likelihood more than the fixed-point step it
    is taken instead (the fixed point alone needs thousands of steps when the precision is large);
    the history stays non-decreasing either way. Iteration stops when a step gains less than
    1e-12 (relative).

    ``fixed_mean``: keep the mean ``m (K,)`` (e.g. the sample mean) and fit only the precision
    by maximum likelihood (Minka §3.3).

    Degenerate data never gives NaN; ``fallback`` says what was done:

    * rows with non-finite entries or a non-positive sum are dropped; negative entries count as 0;
    * no usable row → ``α = 1`` (uniform);
    * fewer rows than dimensions (``S < K``) or a single row → the ML precision is not
      identifiable: ``α = DEFAULT_PRECISION · mean`` (mean of the rows, zeros clipped);
    * exact zeros → clipped to ``min(MIN_VALUE, smallest positive entry)`` and renormalized
      before the logarithm;
    * (nearly) identical rows → the precision is capped at ``MAX_PRECISION`` (the ML estimate is
      infinite): ``α = MAX_PRECISION · mean``.
    """
    X = np.asarray(X, np.float64)
    if X.ndim != 2 or X.shape[1] < 2:
        raise ValueError(f"fit_dirichlet needs (samples, K>=2) data, got shape {X.shape}")
    K = X.shape[1]
    notes = []
    X = X[np.all(np.isfinite(X), axis=1)]
    if (X < 0).any():
        notes.append("negative entries set to 0")
        X = np.maximum(X, 0.0)
    X = X[X.sum(axis=1) > 0]
    S = len(X)
    if S == 0:
        return DirichletFit(np.ones(K), [], "no usable samples: uniform α = 1", 0, 0)
    Z = X / X.sum(axis=1, keepdims=True)
    if (Z <= 0).any():
        floor = min(MIN_VALUE, float(Z[Z > 0].min()))
        notes.append(f"zeros clipped to {floor:.3g}")
        Z = np.maximum(Z, floor)
        Z /= Z.sum(axis=1, keepdims=True)
    mean = Z.mean(axis=0)
    if fixed_mean is not None:
        mean = np.maximum(np.asarray(fixed_mean, np.float64), MIN_VALUE)
        mean = mean / mean.sum()
    mean_log = np.log(Z).mean(axis=0)
    if S < max(K, 2):
        alpha = DEFAULT_PRECISION * mean
        notes.insert(0, f"{S} sample(s) for {K} dimensions: mean with precision {DEFAULT_PRECISION:g}")
        return DirichletFit(alpha, [dirichlet_loglik(alpha, mean_log)], "; ".join(notes), S, 0)
    if np.all(np.ptp(Z, axis=0) < 1e-9):
        alpha = MAX_PRECISION * mean
        notes.insert(0, f"identical samples: precision capped at {MAX_PRECISION:g}")
        return DirichletFit(alpha, [dirichlet_loglik(alpha, mean_log)], "; ".join(notes), S, 0)
    if fixed_mean is not None:
        alpha, hist, capped = _fit_precision(mean, mean_log, max_iter)
        if capped:
            notes.insert(0, f"precision capped at {MAX_PRECISION:g} (nearly identical samples)")
        return DirichletFit(alpha, hist, "; ".join(notes) or None, S, len(hist) - 1)
    alpha = _best_precision(mean, mean_log) * mean
    hist = [dirichlet_loglik(alpha, mean_log)]
    it = 0
    capped = False
    for it in range(1, max_iter + 1):  # noqa: B007  (read after the loop)
        # Minka's fixed point: α_k ← ψ⁻¹(ψ(Σα) + mean log z_k)  (never lowers the likelihood)
        new = inv_digamma(digamma(alpha.sum()) + mean_log)
        ll = dirichlet_loglik(new, mean_log)
        step = _newton_step(alpha, mean_log)
        for t in (1.0, 0.5, 0.25):
            nw = alpha - t * step
            if np.all(nw > 0) and np.all(np.isfinite(nw)):
                ll_n = dirichlet_loglik(nw, mean_log)
                if ll_n > ll:
                    new, ll = nw, ll_n
                break
        if new.sum() > MAX_PRECISION:               # the ML precision runs away: cap it
            new = new * (MAX_PRECISION / new.sum())
            ll = dirichlet_loglik(new, mean_log)
            if ll > hist[-1]:
                alpha = new
                hist.append(ll)
            capped = True
            break
        if ll - hist[-1] <= 1e-12 * max(1.0, abs(ll)):
            break                                    # converged (gain below round-off)
        alpha = new
        hist.append(ll)
    if capped:
        notes.insert(0, f"precision capped at {MAX_PRECISION:g} (nearly identical samples)")
    return DirichletFit(alpha, hist, "; ".join(notes) or None, S, it)
