#!/usr/bin/env python3
"""Siconos' 3D frictional-contact solvers on moreau's 2D problems, for what Siconos' fc2d lacks
(Newton, proximal point, ADMM, VI methods).

Each 2D contact becomes a 3D one: the 2D block fills rows and columns 0-1 of a 3x3 block, the
second tangent is decoupled with W_zz = W_tt of the same contact and q_z = 0, so its reaction
stays 0 and the 3D problem's solutions are the 2D problem's. The answer (its 2D part) is judged
by the same error as every moreau answer (benches/siconos_compare.py's `error`).

--dense hands Siconos W as a dense matrix instead of sparse blocks. Needs Debian's
python3-siconos and python3-scipy (run with /usr/bin/python3).

    /usr/bin/python3 benches/siconos_fc3d.py FILE TOL MAX_ITER SOLVER[,SOLVER...] [--dense]
    e.g. benches/siconos_fc3d.py deposit.dat 1e-8 1000 PROX,ADMM,NSN_AC,NSGS
"""
import os, sys, time
import numpy as np
import scipy.sparse as sp
import siconos.numerics as sn

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from siconos_compare import read_fc2d, error


def embed_in_3d(W, q):
    """W and q of the 3D problem whose solutions are the 2D problem's."""
    nc = len(q) // 2
    W = sp.coo_matrix(W)
    rows = list(3 * (W.row // 2) + W.row % 2)
    cols = list(3 * (W.col // 2) + W.col % 2)
    data = list(W.data)
    diag = W.diagonal()
    for a in range(nc):
        rows.append(3 * a + 2); cols.append(3 * a + 2); data.append(diag[2 * a + 1])
    W3 = sp.csc_matrix((data, (rows, cols)), shape=(3 * nc, 3 * nc))
    W3.indices = W3.indices.astype(np.int64); W3.indptr = W3.indptr.astype(np.int64)
    q3 = np.zeros(3 * nc)
    q3[0::3] = q[0::2]; q3[1::3] = q[1::2]
    return W3, q3


def solve(W3, q3, mu, name, tol, max_iter, dense=False):
    """Siconos' solver `name` on the embedded problem; its answer's 2D part, with the run's
    info, seconds and iterations."""
    if dense:
        matrix = sn.NumericsMatrix(W3.toarray())
    else:
        _, sbm = sn.SBM_from_csparse(3, W3)
        matrix = sn.NumericsMatrix(sbm)
    prob = sn.FrictionContactProblem(3, matrix, q3, mu)
    o = sn.SolverOptions(getattr(sn, "SICONOS_FRICTION_3D_" + name))
    o.iparam[sn.SICONOS_IPARAM_MAX_ITER] = max_iter
    o.dparam[sn.SICONOS_DPARAM_TOL] = tol
    r3 = np.zeros(len(q3)); u3 = np.zeros(len(q3))
    t = time.perf_counter(); info = sn.fc3d_driver(prob, r3, u3, o); t = time.perf_counter() - t
    r = np.zeros(2 * len(mu)); r[0::2] = r3[0::3]; r[1::2] = r3[1::3]
    return r, info, t, o.iparam[sn.SICONOS_IPARAM_ITER_DONE]


def main():
    dense = "--dense" in sys.argv
    args = [a for a in sys.argv[1:] if a != "--dense"]
    path, tol, max_iter, names = args[0], float(args[1]), int(args[2]), args[3]
    W, q, mu = read_fc2d(path)
    W3, q3 = embed_in_3d(W, q)
    print(f"{path}: {len(q) // 2} contacts, tol {tol:g}, at most {max_iter} iterations")
    print("| Siconos fc3d solver | info | iterations | seconds | error |")
    print("|---|---:|---:|---:|---:|")
    for name in names.split(","):
        r, info, t, its = solve(W3, q3, mu, name, tol, max_iter, dense)
        print(f"| {name} | {info} | {its} | {t:.3g} | {error(W, q, mu, r):.2e} |", flush=True)


if __name__ == "__main__":
    main()
