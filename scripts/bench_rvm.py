"""Benchmark our kernel RVM against the RVMs a Python user would pick today, on the paper's split.

    python scripts/bench_rvm.py --data ../shared/data/ankur/ankurDataPoseSilhouette.mat [--point 8]

Peers (benchmark-only dependencies): sklearn-rvm's EMRVR and scikit-learn's ARDRegression on the
same Gaussian kernel design, one output at a time. They are fitted on the 3 outputs (x y z) of one
body point only; their fit time is extrapolated to all 63 outputs (labelled so). Errors are the
mean Euclidean error of that point on the test sequence. Same kernel, width and sqrt descriptors
for everyone; our hyperparameters are the ones scripts/reproduce_paper.py chose.
"""
from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
import scipy.io

from regressor.basis import default_width, gaussian_design
from regressor.rvm import RVMRegressor


def point_error(P: np.ndarray, T: np.ndarray) -> float:
    """Mean Euclidean error (T, 3) vs (T, 3)."""
    return float(np.linalg.norm(P - T, axis=1).mean())


def fit_per_output(make, Phi_or_X, Y):
    """Fit one single-output model per column of Y (N, 3); returns (models, seconds)."""
    start = time.perf_counter()
    models = [make().fit(Phi_or_X, Y[:, i]) for i in range(Y.shape[1])]
    return models, time.perf_counter() - start


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", required=True)
    ap.add_argument("--point", type=int, default=8, help="body point whose 3 outputs the peers fit")
    ap.add_argument("--width-scale", type=float, default=0.5)
    ap.add_argument("--noise", type=float, default=0.05)
    ap.add_argument("--min-gain", type=float, default=400.0)
    args = ap.parse_args()
    d = scipy.io.loadmat(args.data)
    X, Y, Xt, Yt = np.sqrt(d["Y"]), d["Z"], np.sqrt(d["Y_test"]), d["Z_test"]
    cols = slice(3 * args.point, 3 * args.point + 3)
    width = default_width(X, args.width_scale)
    rows = []

    start = time.perf_counter()
    ours = RVMRegressor("gaussian", noise=args.noise, width=width, output_scale="common",
                        min_gain=args.min_gain).fit(X, Y)
    ours_s = time.perf_counter() - start
    rows.append(("ours: RVMRegressor (all 63 outputs, measured)", point_error(ours.predict(Xt)[:, cols], Yt[:, cols]),
                 ours.n_basis_, ours_s))

    warnings.simplefilter("ignore")
    Phi, Phit = gaussian_design(X, X, width), gaussian_design(Xt, X, width)
    scale = Y.shape[1] / 3
    try:
        from sklearn_rvm import EMRVR
        models, s = fit_per_output(lambda: EMRVR(kernel="rbf", gamma=1.0 / width ** 2), X, Y[:, cols])
        P = np.column_stack([m.predict(Xt) for m in models])
        n_rv = len(set().union(*(map(tuple, m.relevance_vectors_) for m in models)))
        rows.append(("sklearn-rvm EMRVR (3 outputs; time x21 extrapolated)", point_error(P, Yt[:, cols]), n_rv, s * scale))
    except Exception as exc:  # report exactly why the peer could not run
        print(f"sklearn-rvm EMRVR unavailable: {type(exc).__name__}: {exc}")
    from sklearn.linear_model import ARDRegression
    models, s = fit_per_output(ARDRegression, Phi, Y[:, cols])
    P = np.column_stack([m.predict(Phit) for m in models])
    kept = np.any([np.abs(m.coef_) > 1e-12 * np.abs(m.coef_).max(initial=1) for m in models], axis=0).sum()
    rows.append(("scikit-learn ARDRegression (3 outputs; time x21 extrapolated)", point_error(P, Yt[:, cols]), int(kept), s * scale))

    print(f"test error of point {args.point} (data units), kept examples, fit seconds for 63 outputs (rough: shared 2-core machine)")
    print(f"{'method':64s} {'error':>6s} {'kept':>5s} {'fit s':>8s} {'x ours':>7s}")
    for name, err, kept, secs in rows:
        print(f"{name:64s} {err:6.3f} {kept:5d} {secs:8.1f} {secs / ours_s:7.1f}")


if __name__ == "__main__":
    main()
