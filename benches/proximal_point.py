#!/usr/bin/env python3
"""A proximal point around moreau's interior point, measured on a problem file (an experiment,
not a solver of the crate).

Each outer iteration solves the problem with W + rho I and q - rho r_k (the proximal term
rho |r - r_k|^2 / 2 around the last answer) by `moreau solve` (the interior point unless told
otherwise) to a tolerance `fac` times the outer error, and judges the answer by the original
problem's error.
rho = alpha x mean diag W; alpha halves after a subproblem meets its tolerance (not below
alpha_min) and is multiplied by 4 after one that does not; an answer that missed its
tolerance is kept only if it lowers the error.

Needs Debian's python3-scipy and python3-siconos (the reader and the error come from
siconos_compare.py, which imports Siconos; run with /usr/bin/python3) and a release build of
moreau.

    /usr/bin/python3 benches/proximal_point.py FILE ALPHA OUTER FAC ALPHA_MIN [SOLVE_ARGS...]
    e.g. benches/proximal_point.py deposit.dat 1e-3 30 0.01 1e-6
         benches/proximal_point.py deposit.dat 1e-3 30 0.01 1e-6 --solver newton --newton-linear direct

SOLVE_ARGS go to `moreau solve` for each subproblem (default: --solver interior-point).
"""
import json, os, subprocess, sys, tempfile
import numpy as np
import scipy.sparse as sp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from siconos_compare import MOREAU, read_fc2d, error


def write_fc2d(path, W, q, mu):
    """The CSparse fc2d format that read_fc2d and moreau read, with 17 digits."""
    W = sp.csc_matrix(W); W.sort_indices(); n = W.shape[0]
    out = ["2", str(n // 2), "2", str(n), str(n), "2", "CSparse",
           f"{n}-by-{n}, nzmax: {W.nnz} nnz: {W.nnz}"]
    for j in range(n):
        a, b = W.indptr[j], W.indptr[j + 1]
        out.append(f"    col {j} : locations {a} to {b - 1}")
        out.extend(f"      {W.indices[k]} : {W.data[k]:.17e}" for k in range(a, b))
    out.append(" ".join(f"{v:.17e}" for v in q))
    out.append(" ".join(f"{v:.17e}" for v in mu))
    open(path, "w").write("\n".join(out) + "\n")


def solve_subproblem(path, tol, out, solve_args):
    subprocess.run([MOREAU, "solve", path, *solve_args, "--device", "cpu", "--threads", "1",
                    "--tol", str(tol), "--max-iter", "300", "--out", out],
                   check=True, capture_output=True)
    j = json.load(open(out))
    return np.array(j["r"]), j


def main():
    path, alpha, outer, fac, alpha_min = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), \
        float(sys.argv[4]), float(sys.argv[5])
    solve_args = sys.argv[6:] or ["--solver", "interior-point"]
    W, q, mu = read_fc2d(path)
    n = len(q); mean_diag = W.diagonal().mean()
    r = np.zeros(n); err = 1.0; seconds = 0.0
    print("| outer | alpha | subproblem: iterations, error / tolerance | error | seconds in solves |")
    print("|---:|---:|---|---:|---:|")
    with tempfile.TemporaryDirectory() as d:
        sub, out = os.path.join(d, "sub.dat"), os.path.join(d, "r.json")
        for k in range(outer):
            rho = alpha * mean_diag
            write_fc2d(sub, W + rho * sp.identity(n, format="csc"), q - rho * r, mu)
            tol = max(1e-11, fac * err)
            r_new, j = solve_subproblem(sub, tol, out, solve_args)
            seconds += j["seconds"]
            err_new = error(W, q, mu, r_new)
            met = j["error"] <= 10 * tol
            if met or err_new < err:
                r, err = r_new, err_new
            print(f"| {k} | {alpha:.1e} | {j['iterations']}, {j['error']:.1e} / {tol:.0e} | "
                  f"{err_new:.2e} | {seconds:.1f} |", flush=True)
            alpha = max(alpha_min, alpha / 2) if met else alpha * 4
            if err < 1e-8:
                break


if __name__ == "__main__":
    main()
