"""Benchmark: 393 independent GPs of 13 points (3-D inputs), batched vs a scikit-learn loop.

Run from the repository root::

    python benchmarks/bench_gp.py [--outputs 393] [--points 13] [--restarts 2]

The data imitate the chapter-5 use: one GP per FRF bin (131 bins x 3 directions) over 13 poses;
each target is the log-compliance of a pose-dependent single mode at that bin's frequency.

Printed: wall time of each fit and their ratio (goal: >= 20x), the mean log marginal likelihood
(Eq. 33, data units, same constant-mean SE + noise model) of each, and the latency of predicting
all outputs (mean and std) at one new pose (goal: < 100 µs per call on one core).
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np


def make_data(n_outputs: int, n_points: int, rng: np.random.Generator):
    poses = rng.uniform([2100.0, -300.0, 0.0], [2700.0, 600.0, 180.0], (n_points, 3))
    fn = 8.0 + 4.0 * (2700.0 - poses[:, 0]) / 600.0 + 0.5 * np.cos(np.radians(2 * poses[:, 2]))
    k = 1.0e6 * (1.0 + 0.3 * poses[:, 1] / 600.0)
    zeta = 0.08
    freqs = np.linspace(2.0, 70.0, n_outputs)
    r = freqs[None, :] / fn[:, None]
    compliance = 1.0 / (k[:, None] * np.abs(1.0 - r**2 + 2j * zeta * r))
    y = np.log10(compliance) + 0.01 * rng.normal(size=compliance.shape)
    return poses, y


def sklearn_loop(X, Y, n_restarts, seed):
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, WhiteKernel
    from sklearn.gaussian_process.kernels import ConstantKernel as C

    from robovib.gp import GPHyperparameters

    x_loc, x_scale = X.mean(axis=0), X.std(axis=0)
    Xs = (X - x_loc) / x_scale
    sf, ls, sn, mean = [], [], [], []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        for b in range(Y.shape[1]):
            kernel = C(1.0, (1e-6, 1e4)) * RBF(1.0, (1e-2, 1e3)) + WhiteKernel(1e-2, (1e-8, 1e2))
            gp = GaussianProcessRegressor(
                kernel, normalize_y=True, n_restarts_optimizer=n_restarts, random_state=seed
            ).fit(Xs, Y[:, b])
            std_y = Y[:, b].std()
            params = gp.kernel_.get_params()
            sf.append(np.sqrt(params["k1__k1__constant_value"]) * std_y)
            ls.append(params["k1__k2__length_scale"] * x_scale)
            sn.append(np.sqrt(params["k2__noise_level"]) * std_y)
            mean.append(Y[:, b].mean())
    return GPHyperparameters(np.array(sf), np.array(ls), np.array(sn), np.array(mean))


def main() -> None:
    from robovib.gp import BatchedGPRegressor

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--outputs", type=int, default=393)
    parser.add_argument("--points", type=int, default=13)
    parser.add_argument("--restarts", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    rng = np.random.default_rng(args.seed)
    X, Y = make_data(args.outputs, args.points, rng)
    print(f"{args.outputs} GPs x {args.points} points, 3-D inputs, {args.restarts} restarts each")

    t0 = time.perf_counter()
    ours = BatchedGPRegressor(kernel="isotropic", n_restarts=args.restarts, rng=args.seed).fit(X, Y)
    t_ours = time.perf_counter() - t0

    t0 = time.perf_counter()
    hp_sk = sklearn_loop(X, Y, args.restarts, args.seed)
    t_sk = time.perf_counter() - t0
    lml_ours = ours.log_marginal_likelihood_value_
    lml_sk = ours.log_marginal_likelihood(hp_sk)

    print(f"fit  robovib batched BFGS : {t_ours:8.3f} s   mean LML {lml_ours.mean():9.3f}")
    print(f"fit  scikit-learn loop    : {t_sk:8.3f} s   mean LML {lml_sk.mean():9.3f}")
    print(f"speed-up                  : {t_sk / t_ours:8.1f} x   (goal >= 20 x)")
    print(
        f"LML ours >= sklearn - 1e-3 on {np.mean(lml_ours >= lml_sk - 1e-3) * 100:.1f} % of outputs"
    )
    print(f"iterations per output     : mean {ours.n_iter_.mean():.1f}, max {ours.n_iter_.max()}")

    x_new = np.array([2450.0, 120.0, 60.0])
    ours.predict_one(x_new)
    n_calls = 2000
    t0 = time.perf_counter()
    for _ in range(n_calls):
        ours.predict_one(x_new)
    t_one = (time.perf_counter() - t0) / n_calls
    t0 = time.perf_counter()
    for _ in range(200):
        ours.predict(x_new[None], return_std=True)
    t_gen = (time.perf_counter() - t0) / 200
    print(
        f"predict_one, {args.outputs} outputs (mean+std): {t_one * 1e6:8.1f} µs/call  (goal < 100 µs)"
    )
    print(f"predict(return_std=True), 1 pose           : {t_gen * 1e6:8.1f} µs/call")


if __name__ == "__main__":
    main()
