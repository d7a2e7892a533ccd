#!/usr/bin/env python3
"""Side-by-side comparison with Siconos' fc2d NSGS (sparse-block storage) on the same problems.

Needs Debian's python3-siconos and python3-scipy (run with /usr/bin/python3) and a release build of
moreau (cargo build --release). Every answer, Siconos' and moreau's, is judged by the same error:
the natural-map residual with De Saxcé's correction normalised by max(|q|, |r|, |u|), recomputed
here from r. Prints a markdown table; the ratio is Siconos time / moreau time (> 1: moreau faster).

    /usr/bin/python3 benches/siconos_compare.py [--tols 1e-4,1e-6,1e-8] [FILES...]
"""
import argparse, json, os, subprocess, sys, tempfile, time
import numpy as np
import scipy.sparse as sp
import siconos.numerics as sn

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MOREAU = os.path.join(ROOT, "target", "release", "moreau")
DATA = os.path.join(ROOT, "..", "shared", "data", "siconos-fc2d")


def read_fc2d(path):
    """Reads dense (tag 0) and CSparse (tag 2) fc2d files."""
    lines = open(path).read().split("\n")
    nc = int(lines[1]); n = 2 * nc; tag = int(lines[2])
    if tag == 0:
        vals = " ".join(lines[6:]).split()
        W = np.array([float(v) for v in vals[: n * n]]).reshape((n, n)).T
        rest = vals[n * n:]
        return sp.csc_matrix(W), np.array(rest[:n], float), np.array(rest[n:n + nc], float)
    rows, cols, data = [], [], []
    i = 8
    while lines[i].strip().startswith("col"):
        p = lines[i].split(); j, a, b = int(p[1]), int(p[4]), int(p[6]); i += 1
        for _ in range(b - a + 1):
            r, v = lines[i].split(":"); rows.append(int(r)); cols.append(j); data.append(float(v)); i += 1
    W = sp.csc_matrix((data, (rows, cols)), shape=(n, n))
    q = np.array(lines[i].split(), float); mu = np.array(lines[i + 1].split(), float)
    return W, q, mu


def proj(xn, xt, m):
    if abs(xt) <= m * xn: return xn, xt
    if m * abs(xt) <= -xn: return 0.0, 0.0
    rn = (xn + m * abs(xt)) / (1 + m * m); return rn, np.copysign(m * rn, xt)


def error(W, q, mu, r):
    u = W @ r + q
    s = 0.0
    for a, m in enumerate(mu):
        rn, rt, un, ut = r[2 * a], r[2 * a + 1], u[2 * a], u[2 * a + 1]
        pn, pt = proj(rn - (un + m * abs(ut)), rt - ut, m)
        s += (rn - pn) ** 2 + (rt - pt) ** 2
    scale = max(np.linalg.norm(q), np.linalg.norm(r), np.linalg.norm(u))
    return np.sqrt(s) / scale if scale > np.finfo(float).eps else np.sqrt(s)


def siconos_nsgs(W, q, mu, tol, max_iter):
    n = len(q)
    Wi = sp.csc_matrix(W); Wi.indices = Wi.indices.astype(np.int64); Wi.indptr = Wi.indptr.astype(np.int64)
    info, sbm = sn.SBM_from_csparse(2, Wi)
    M = sn.NumericsMatrix(sbm) if hasattr(sn, "NumericsMatrix") else None
    prob = sn.FrictionContactProblem(2, M, q, mu)
    o = sn.SolverOptions(sn.SICONOS_FRICTION_2D_NSGS)
    o.iparam[sn.SICONOS_IPARAM_MAX_ITER] = max_iter
    o.dparam[sn.SICONOS_DPARAM_TOL] = tol
    r = np.zeros(n); u = np.zeros(n)
    t = time.perf_counter(); info = sn.fc2d_driver(prob, r, u, o); t = time.perf_counter() - t
    return t, o.iparam[sn.SICONOS_IPARAM_ITER_DONE], error(W, q, mu, r)


def moreau(path, solver, tol, max_iter, extra=()):
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "r.json")
        subprocess.run([MOREAU, "solve", path, "--solver", solver, "--device", "cpu", "--tol", str(tol),
                        "--max-iter", str(max_iter), "--out", out, *extra], check=True, capture_output=True)
        j = json.load(open(out))
    return j["seconds"], j["iterations"], j["error"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--tols", default="1e-4,1e-6,1e-8")
    ap.add_argument("--max-iter", type=int, default=100000)
    ap.add_argument("--repeat", type=int, default=3, help="best of N runs for each timing")
    ap.add_argument("files", nargs="*")
    a = ap.parse_args()
    files = a.files or [os.path.join(DATA, f) for f in sorted(os.listdir(DATA)) if f.endswith(".dat")]
    print("| problem | tol | Siconos NSGS s (sweeps, error) | moreau nlgs s (sweeps, error) | ratio | moreau pcpg s (iter, error) | ratio |")
    print("|---|---|---|---|---|---|---|")
    for path in files:
        W, q, mu = read_fc2d(path)
        for tol in [float(t) for t in a.tols.split(",")]:
            s = min((siconos_nsgs(W, q, mu, tol, a.max_iter) for _ in range(a.repeat)), key=lambda x: x[0])
            m = min((moreau(path, "nlgs", tol, a.max_iter) for _ in range(a.repeat)), key=lambda x: x[0])
            c = min((moreau(path, "pcpg", tol, a.max_iter) for _ in range(a.repeat)), key=lambda x: x[0])
            fmt = lambda x: f"{x[0]:.4f} ({x[1]}, {x[2]:.1e})"
            ratio = lambda x: f"{s[0] / x[0]:.1f}x" if x[0] > 0 else "-"
            print(f"| {os.path.basename(path)} | {tol:.0e} | {fmt(s)} | {fmt(m)} | {ratio(m)} | {fmt(c)} | {ratio(c)} |", flush=True)


if __name__ == "__main__":
    sys.exit(main())
