"""Subspace identification (N4SID-type) of an innovations state-space model.

Steps (Van Overschee & De Moor 1996, ch. 4; Verhaegen 1994 for the MOESP
weighting; Jansson 2003 and van der Veen et al. 2013 for the ARX-predictor
(SSARX / PBSID) weighting):

1. ``y`` and ``u`` scaled to unit RMS (the result does not depend on units);
2. MOESP: block Hankel matrices of past/future inputs and outputs, horizon
   ``i``; oblique projection ``O_i = Y_f /_{U_f} W_p`` by one QR; SVD weighted
   by the projection orthogonal to ``U_f``; ``A, C`` from the shift invariance
   of the observability matrix, ``K`` from the residual covariances.
   SSARX: a high-order ARX predictor (past data only, so unbiased with
   feedback) removes the future innovations' effect; the SVD of the
   predictor's state part gives the states; ``C`` then ``A, B, K`` by least
   squares on them.  The order is the largest gap of the log singular values
   when not given;
3. per candidate (weighting, horizon; with an unstable ``A`` also its twin
   with the unstable eigenvalues reflected), ``B, D`` and the initial state by
   linear least squares on the simulated output (scaled columns, FFT
   convolutions of ``C A^t`` with ``u``), through the stable one-step
   predictor when ``A`` is too unstable to simulate;
4. the candidate that simulates the estimation data best is kept; an
   unstable or degenerate result is said (``model.warnings``,
   :class:`sysid.SysidWarning`);
5. parameter covariance of the basis-independent ARMAX-equivalent
   coefficients (:attr:`IDSS.parameters`): ``sigma^2 (J^T J)^-1`` with ``J`` the
   exact prediction-error gradient at the estimate, as for the PEM models.
   A subspace estimate is not a minimiser of the prediction error and not
   efficient, so these bounds are somewhat optimistic for it (about 1.2x
   too small in simulation studies); :func:`sysid.ssest` refines the estimate
   by prediction-error minimisation, for which they hold.
"""
from __future__ import annotations

import numpy as np

from ._blas import one_blas_thread
from ._checks import check_data, check_flag, check_order, rms_scale
from ._diagnose import finish, growth_over, problems
from .data import IDData
from .errors import SysidError
from .polynomial import is_stable_poly
from .state_response import predict_states
from .statespace import IDSS

__all__ = ["N4SID", "n4sid"]


def _hankel(x: np.ndarray, start: int, rows: int, cols: int) -> np.ndarray:
    idx = start + np.arange(rows)[:, None] + np.arange(cols)[None, :]
    return x[idx]


class N4SID:
    """Subspace estimator; ``N4SID(nx).fit(data)`` returns an :class:`IDSS`.

    Parameters
    ----------
    nx : int or None
        State dimension; ``None`` picks it from the singular values (up to ``max_order``).
    horizon : int or None
        Past and future horizon ``i`` (default ``max(2 * nx_max, 10)`` capped by data length).
    feedthrough : bool
        Estimate ``D`` (MATLAB default: no, ``D = 0``).
    max_order : int
        Largest order considered when ``nx`` is None.
    method : {"shift", "states"}
        MOESP weighting only: ``A, C`` from the shift invariance of the observability
        matrix (default) or by regression on the estimated states.
    weighting : {"auto", "moesp", "ssarx"}
        MATLAB's ``N4Weight``.  ``"moesp"``: oblique projection along future inputs
        (Verhaegen), consistent for open-loop data only.  ``"ssarx"``: the future
        outputs are first corrected by a high-order ARX predictor (Jansson 2003;
        predictor-based, as PBSID), so feedback from the output to the input does not
        bias the estimate (closed-loop data).  ``"auto"`` (default) estimates both and
        keeps the one with the smaller one-step prediction error on the estimation data,
        preferring a model that is neither unstable nor degenerate.
    enforce_stability : bool or None
        MATLAB's ``EnforceStability``.  ``True``: eigenvalues of ``A`` outside the unit
        circle are reflected to ``1/conj(z)``.  ``False``: never (MATLAB's default).
        ``None`` (default): an unstable estimate and its reflected twin both compete
        (below), so ``A`` is stable unless the unstable model simulates the estimation
        data better, i.e. unless the data say it is unstable.

    With ``weighting="auto"`` and no ``horizon`` given, the horizons ``i`` and ``2 i``
    (at most 40) are tried as well.  After ``A, C`` (and ``K``) of each candidate, ``B``,
    ``D`` and the initial state ``x0`` are estimated by linear least squares on the
    simulated output (columns from FFT convolutions of ``C A^t`` with ``u``, scaled to
    unit norm, QR-based ``lstsq``); when ``A`` is so unstable that the simulation would
    grow by more than ``1e6`` over the record they are estimated through the (stable)
    one-step predictor instead.  The candidate with the smallest simulation error on the
    estimation data is returned (MATLAB's ``Focus='simulation'``); ``report`` lists
    them all.  An unstable or degenerate result is reported in ``model.warnings`` and
    as :class:`sysid.SysidWarning`.  The signals are scaled to unit RMS inside, so
    the result does not depend on their units.
    """

    def __init__(self, nx=None, horizon=None, feedthrough=False, max_order=10, method="shift",
                 weighting="auto", enforce_stability=None):
        self.method = method
        self.nx = nx
        self.horizon = horizon
        self.feedthrough = feedthrough
        self.max_order = max_order
        self.weighting = weighting
        self.enforce_stability = enforce_stability

    @one_blas_thread
    def fit(self, data: IDData) -> IDSS:
        """Estimate the model; sets ``model_`` and returns it."""
        data = check_data(data)
        N = data.N
        nmax = check_order(self.max_order, "max_order", 1)
        if self.nx is not None:
            nx = check_order(self.nx, "nx", 1)
            nmax = nx
        else:
            nx = None
        i = self.horizon if self.horizon is not None else max(2 * nmax, 10)
        i = check_order(i, "horizon", 1)
        j = N - 2 * i + 1
        if i <= nmax or j < 4 * i + 10:
            raise SysidError(f"orders are too high for the data: n4sid with nx = {nmax} needs horizon > nx and "
                             f"at least {2 * i + 4 * i + 9} samples, got horizon {i} and {N} samples.")
        if self.method not in ("shift", "states"):
            raise SysidError(f"method must be 'shift' or 'states', got {self.method!r}.")
        weighting = str(self.weighting).lower() if isinstance(self.weighting, str) else self.weighting
        if weighting not in ("auto", "moesp", "ssarx"):
            raise SysidError(f"weighting must be 'auto', 'moesp' or 'ssarx', got {self.weighting!r}.")
        check_flag(self.feedthrough, "feedthrough")
        if self.enforce_stability is not None and not isinstance(self.enforce_stability, (bool, np.bool_)):
            raise SysidError(f"enforce_stability must be True, False or None, got {self.enforce_stability!r}.")
        # work on signals of unit size: the result does not depend on the units (1e-3 m or 1e200)
        sy, su = rms_scale(data.y, "y"), rms_scale(data.u, "u")
        y, u = data.y / sy, data.u / su
        names = ["moesp", "ssarx"] if weighting == "auto" else [weighting]
        if self.horizon is None and weighting == "auto":
            i_max = (N - 9) // 6            # keeps j >= 4 i + 10
            horizons = sorted({i, max(i, min(2 * i, 40, i_max))})
        else:
            horizons = [i]
        enforce = self.enforce_stability
        cands = []
        for name in names:
            for h in horizons:
                try:
                    A, C, K, extra = (self._moesp(y, u, nx, nmax, h) if name == "moesp"
                                      else self._ssarx(y, u, nx, nmax, h))
                except (np.linalg.LinAlgError, SysidError):
                    if len(names) * len(horizons) == 1:
                        raise
                    continue
                extra["report"]["horizon"] = h
                unstable = bool(np.any(np.abs(np.linalg.eigvals(A)) > 1.0))
                variants = [True] if enforce is True else [False] if (enforce is False or not unstable) \
                    else [False, True]
                for reflect in variants:
                    cands.append(self._complete(name, A, C, K, y, u, extra, reflect))
        if not cands:
            raise SysidError("the data cannot support n4sid at this order: every weighting failed "
                             "(input not persistently exciting?).")
        # MATLAB's 'simulation' focus: the candidate that simulates the estimation data best
        # (estimated x0); a non-finite or degenerate one only if nothing else is left
        best = min(cands, key=lambda c: (c["degenerate"], c["sim_rss"], c["loss"]))
        A, B, Cm, D, K = best["A"], best["B"] * (sy / su), best["C"], best["D"] * (sy / su), best["K"]
        report = dict(method="n4sid", weighting=best["weighting"], stability_enforced=best["reflected"],
                      x0=best["x0"] * sy,
                      candidates=[dict(weighting=c["weighting"], horizon=c["extra_report"]["horizon"],
                                       stability_enforced=c["reflected"],
                                       simulation_fit_percent=float(c["sim_fit"])) for c in cands])
        report.update(best["extra_report"])
        model = IDSS(A, B, Cm, D, K, Ts=data.Ts, noise_variance=best["Svv"] * sy ** 2,
                     singular_values=best["s"], report=report)
        model.covariance, model.loss = _pem_covariance(model, data.y, data.u)
        if not np.isfinite(model.loss):
            model.loss = best["loss"] * sy ** 2
        if not np.isfinite(model.loss):   # a high-order polynomial form lost the poles: predict in state space
            with np.errstate(all="ignore"):
                eps = data.y - predict_states(A, B, Cm, D, K, data.y, data.u, 1)
            model.loss = float(eps @ eps) / N if np.all(np.isfinite(eps)) else float("inf")
        model.n_samples = N
        finish(model, data, f"n4sid model (nx = {A.shape[0]})", focus="simulation", fit=best["sim_fit"])
        self.model_ = model
        return model

    # ---------------------------------------------------------------- weightings
    def _moesp(self, y, u, nx, nmax, i):
        """MOESP: oblique projection of future outputs on the past along future inputs."""
        N = y.size
        j = N - 2 * i + 1
        Up, Uf = _hankel(u, 0, i, j), _hankel(u, i, i, j)
        Yp, Yf = _hankel(y, 0, i, j), _hankel(y, i, i, j)
        Wp = np.vstack([Up, Yp])
        # one QR (= LQ of [Uf; Wp; Yf]); then Yf = L31 Q1 + L32 Q2 + L33 Q3, Wp = L21 Q1 + L22 Q2
        L = np.linalg.qr(np.vstack([Uf, Wp, Yf]).T, mode="r").T
        L22 = L[i:3 * i, i:3 * i]
        L32 = L[3 * i:, i:3 * i]
        # oblique projection Oi = Yf /_Uf Wp = Lw Wp with Lw = L32 L22^+; weighted by the
        # projection orthogonal to Uf its column space is that of Lw L22 = L32
        Lw = L32 @ np.linalg.pinv(L22)
        Us, s, _ = np.linalg.svd(L32)
        s = s / np.sqrt(j)
        nx = _order(s, nx, nmax)
        U1 = Us[:, :nx]
        sq = np.sqrt(s[:nx])
        Gam = U1 * sq
        # states X(t), t = i .. i+j-1
        X = (U1.T / sq[:, None]) @ (Lw @ Wp)
        Xc, Xn = X[:, :-1], X[:, 1:]
        uc = u[i:i + j - 1]
        yc = y[i:i + j - 1]
        if self.method == "shift":
            A = np.linalg.lstsq(Gam[:-1], Gam[1:], rcond=None)[0]
            Cm = Gam[:1]
        else:
            reg = np.vstack([Xc, uc])
            th = np.linalg.lstsq(reg.T, np.vstack([Xn, yc[None, :]]).T, rcond=None)[0].T
            A, Cm = th[:nx, :nx], th[nx:, :nx]
        # input terms of the state and output equations given A, C; residuals -> K
        Rx = Xn - A @ Xc
        Ry = yc - (Cm @ Xc).ravel()
        bs = np.linalg.lstsq(uc[:, None], Rx.T, rcond=None)[0].T
        w = Rx - bs @ uc[None, :]
        v = Ry - (float(uc @ Ry) / float(uc @ uc)) * uc if self.feedthrough else Ry
        Svv = float(v @ v) / v.size
        noise = _noise_covariances(w, v)
        K = _kalman_gain(A, Cm, *noise)
        Bs = bs.reshape(nx, 1)
        Ds = float(uc @ Ry) / float(uc @ uc) if self.feedthrough else 0.0
        return A, Cm, K, dict(s=s, Svv=Svv, B=Bs, D=np.array([[Ds]]), noise=noise, report=dict(gamma=Gam))

    def _ssarx(self, y, u, nx, nmax, i):
        """ARX-predictor-based weighting (SSARX / PBSID): consistent with feedback in the data.

        A high-order ARX model ``y(t) = sum_k Xi_k z(t-k) + e(t)`` with ``z = [u; y]`` and
        ``k = 1..p`` estimates the Markov parameters ``Xi_k = [C Ab^(k-1) Bb, C Ab^(k-1) K]``
        of the one-step predictor (``Ab = A - K C``) from past data only, which stays
        unbiased in closed loop.  Row ``j`` of ``sum_{k>j} Xi_k z(t+j-k)`` is
        ``C Ab^j x(t)``; its SVD gives the state sequence, then ``C, D`` and ``A, B, K``
        follow by least squares on the states (van der Veen et al. 2013, PBSIDopt).
        """
        p = f = i
        N = y.size
        T = N - p
        Z = np.empty((T, 2 * p))
        for k in range(1, p + 1):
            Z[:, 2 * k - 2] = u[p - k:N - k]
            Z[:, 2 * k - 1] = y[p - k:N - k]
        reg = np.column_stack([Z, u[p:]]) if self.feedthrough else Z
        th = np.linalg.lstsq(reg, y[p:], rcond=None)[0]
        Xi = th[:2 * p]
        M = np.empty((f, T))
        for jj in range(f):
            M[jj] = Z[:, :2 * (p - jj)] @ Xi[2 * jj:]
        # SVD of the short, wide M through its f x f Gram matrix: M = U S V^T, V^T = S^-1 U^T M
        w, Us = np.linalg.eigh(M @ M.T)
        w, Us = w[::-1], Us[:, ::-1]
        s = np.sqrt(np.clip(w, 0.0, None))
        nx = _order(s / np.sqrt(T), nx, nmax)
        if not s[nx - 1] > 1e-12 * s[0]:
            raise SysidError(f"the data cannot support n4sid with nx = {nx}: the state sequence has rank "
                             f"{int(np.sum(s > 1e-12 * s[0]))} (input not persistently exciting?).")
        X = (Us[:, :nx].T @ M) / np.sqrt(s[:nx])[:, None]    # states x(t) = S^1/2 V^T, t = p .. N-1
        s = s / np.sqrt(T)
        yt, ut = y[p:], u[p:]
        reg1 = np.column_stack([X.T, ut]) if self.feedthrough else X.T
        th1 = np.linalg.lstsq(reg1, yt, rcond=None)[0]
        Cm = th1[:nx].reshape(1, nx)
        e = yt - reg1 @ th1
        reg2 = np.column_stack([X[:, :-1].T, ut[:-1], e[:-1]])
        th2 = np.linalg.lstsq(reg2, X[:, 1:].T, rcond=None)[0].T
        A, Bs, K = th2[:, :nx], th2[:, nx:nx + 1], th2[:, nx + 1:nx + 2]
        Ds = np.array([[th1[nx] if self.feedthrough else 0.0]])
        Svv = float(e @ e) / e.size
        w = X[:, 1:] - A @ X[:, :-1] - Bs @ ut[None, :-1]   # K e(t) is the process noise here
        return A, Cm, K, dict(s=s, Svv=Svv, B=Bs, D=Ds, noise=_noise_covariances(w, e[:-1]),
                              report=dict(arx_order=p))

    # --------------------------------------------------------------- completion
    def _complete(self, name, A, Cm, K, y, u, extra, reflect):
        """Stability enforcement, B, D, x0 by least squares, K check; one candidate model (scaled units)."""
        N = y.size
        nx = A.shape[0]
        if reflect:
            A = _reflect_unstable(A)
        if np.any(np.abs(np.linalg.eigvals(A - K @ Cm)) >= 1.0):
            K = _kalman_gain(A, Cm, *extra["noise"])      # the Kalman gain of this A: stable predictor
        if np.any(np.abs(np.linalg.eigvals(A - K @ Cm)) >= 1.0):
            K = np.zeros((nx, 1))  # keep the predictor stable; fall back to output error
        bdx = _input_matrices(A, Cm, K, y, u, self.feedthrough)
        if bdx is None:  # A unstable and no stable predictor: keep the regression's B, D
            B, D, x0, sim_rss = extra["B"], extra["D"], np.zeros(nx), float("inf")
        else:
            B, D, x0, sim_rss = bdx
        model = IDSS(A, B, Cm, D, K, Ts=1.0)
        p = model.to_idpoly()
        from .pem import prediction_errors
        with np.errstate(all="ignore"):
            eps = prediction_errors(p, y, u)[0] if is_stable_poly(p.C) else np.full(1, np.inf)
        loss = float(eps @ eps) / N if np.all(np.isfinite(eps)) else float("inf")
        degenerate = any("B = 0" in m or "non-finite" in m for m in problems(model, y, u, "model"))
        ny = float(np.linalg.norm(y - y.mean()))
        sim_fit = 100.0 * (1.0 - np.sqrt(sim_rss) / ny) if np.isfinite(sim_rss) else float("-inf")
        return dict(weighting=name, A=A, B=B, C=Cm, D=D, K=K, x0=x0, s=extra["s"], Svv=extra["Svv"],
                    loss=loss, sim_rss=sim_rss, sim_fit=sim_fit, degenerate=degenerate, reflected=bool(reflect),
                    extra_report=extra["report"])


def _noise_covariances(w, v):
    """``(Q, R, S)``: covariances of the state-equation residuals ``w`` (n x m), the output residuals ``v``."""
    m = v.size
    return (w @ w.T) / m, float(v @ v) / m, (w @ v / m).reshape(-1, 1)


def _kalman_gain(A, C, Q, R, S):
    """Steady-state Kalman gain for noise covariances ``Q = cov(w)``, ``R = var(v)``, ``S = cov(w, v)``.

    ``P`` from the discrete Riccati equation and ``K = (A P C^T + S)(C P C^T + R)^-1``
    (Van Overschee & De Moor 1996, sec. 4.3.3), which makes ``A - K C`` stable when a
    stabilising solution exists; otherwise ``S / R`` (``P = 0``).
    """
    from scipy.linalg import solve_discrete_are
    try:
        P = solve_discrete_are(A.T, C.T, Q, np.array([[R]]), s=S)
        K = (A @ P @ C.T + S) / ((C @ P @ C.T).item() + R)
        if np.all(np.isfinite(K)):
            return K
    except (np.linalg.LinAlgError, ValueError):
        pass
    return S / R


def _order(s: np.ndarray, nx, nmax: int) -> int:
    if nx is not None:
        return nx
    k = min(nmax, s.size - 1)
    gaps = np.log(s[:k] + 1e-300) - np.log(s[1:k + 1] + 1e-300)
    return int(np.argmax(gaps)) + 1


def _reflect_unstable(A: np.ndarray) -> np.ndarray:
    """``A`` with its eigenvalues ``|z| > 1`` reflected to ``1/conj(z)`` (MATLAB EnforceStability)."""
    lam, V = np.linalg.eig(A)
    out = np.abs(lam) > 1.0
    if not np.any(out):
        return A
    lam = lam.copy()
    lam[out] = 1.0 / np.conj(lam[out])
    return np.real(V @ np.diag(lam) @ np.linalg.inv(V))


SIMULATION_GROWTH_LIMIT = 1e6
"""Largest growth ``max|eig(A)|^N`` over the record for which B, D, x0 are fitted through the simulation."""


def _impulse_rows(F: np.ndarray, C: np.ndarray, N: int) -> np.ndarray:
    """``R[t] = C F^t``, shape (N, n); stops (zeros) once the rows have decayed below 1e-17 of their peak."""
    n = F.shape[0]
    R = np.zeros((N, n))
    r = C.ravel().astype(float).copy()
    peak = float(np.max(np.abs(r))) or 1.0
    for t in range(N):
        R[t] = r
        m = float(np.max(np.abs(r)))
        peak = max(peak, m)
        if m < 1e-17 * peak:
            break
        r = r @ F
    return R


def _input_matrices(A, C, K, y, u, feedthrough):
    """``B, D, x0`` by linear least squares, given ``A, C`` (and ``K``).

    Simulation form (``max|eig A|^N <= 1e6``)::

        y(t) = sum_j b_j [sum_{k<t} C A^(t-1-k) e_j u(k)] + D u(t) + C A^t x0

    otherwise the one-step predictor form with ``F = A - K C`` (stable) and
    ``Bb = B - K D``, whose output also carries ``sum_k C F^(t-1-k) K y(k)``.
    Columns come from FFT convolutions of the rows ``C F^t`` with ``u`` and are
    scaled to unit norm before ``lstsq``.  Returns ``(B, D, x0, rss)`` with ``rss`` the
    simulation residual sum of squares (inf in predictor form), or None when neither
    form is bounded.
    """
    from scipy.signal import fftconvolve
    n = A.shape[0]
    N = y.size
    r = float(np.max(np.abs(np.linalg.eigvals(A))))
    simulate = growth_over(r, N) <= SIMULATION_GROWTH_LIMIT
    F = A if simulate else A - K @ C
    if not simulate and growth_over(float(np.max(np.abs(np.linalg.eigvals(F)))), N) > 1.0 + 1e-9:
        return None
    R = _impulse_rows(F, C, N)
    cols = np.zeros((N, n))
    cols[1:] = fftconvolve(R, u[:, None], axes=0)[:N - 1]
    target = y.copy()
    if not simulate:
        g = R @ K[:, 0]
        target[1:] -= fftconvolve(g, y)[:N - 1]
    X = np.column_stack([cols] + ([u] if feedthrough else []) + [R])
    norms = np.sqrt(np.einsum("ij,ij->j", X, X))
    norms[norms == 0] = 1.0
    th = np.linalg.lstsq(X / norms, target, rcond=None)[0] / norms
    B = th[:n].reshape(n, 1)
    D = np.array([[th[n] if feedthrough else 0.0]])
    x0 = th[n + (1 if feedthrough else 0):]
    res = target - X @ th
    sim_rss = float(res @ res) if simulate else float("inf")
    if not simulate:
        B = B + K * D[0, 0]
    return B, D, x0, sim_rss


def _pem_covariance(model: IDSS, y, u):
    """``(sigma^2 (J^T J)^-1, V/N)`` of the ARMAX-equivalent parameters at ``model`` (None if undefined)."""
    from .pem import prediction_error_jacobian, prediction_errors
    p = model.to_idpoly()
    eps, v, w = prediction_errors(p, y, u)
    with np.errstate(over="ignore", invalid="ignore"):
        V = float(eps @ eps)
    if not np.isfinite(V):  # unstable predictor (or its polynomial form): no prediction-error covariance
        return None, float("nan")
    J = prediction_error_jacobian(p, y, u, eps, v, w)
    try:
        cov = V / max(y.size - p.n_parameters, 1) * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        cov = None
    return cov, V / y.size


def n4sid(data: IDData, nx=None, **options) -> IDSS:
    """MATLAB ``n4sid(data, nx)``; ``nx=None`` chooses the order from the singular values.

    Parameters
    ----------
    data : IDData
    nx : int or None
        State dimension.
    **options
        ``horizon``, ``feedthrough``, ``max_order``, ``method``, ``weighting``,
        ``enforce_stability`` (see :class:`N4SID`).

    Returns
    -------
    IDSS
    """
    return N4SID(nx, **options).fit(data)
