"""Error against time for NLGS and PCPG on a Siconos problem, from Python: the table of README's
"What accuracy costs in time" (iterations to each tolerance on the 7,002-contact file), and its
plot when matplotlib is installed.

    python python/examples/work_precision.py [PROBLEM.dat] [--plot work_precision.png]
"""

import argparse
from pathlib import Path

import numpy as np

import moreau

REPO = Path(__file__).resolve().parents[2]
DEFAULT = REPO.parent / "shared/data/siconos-fc2d/fc2d_granularflowonwall_07002_00801.dat"
TOLS = [1e-2, 1e-4, 1e-6, 1e-8]


def first_reaching(history, tol):
    """(iteration, seconds) of the first recorded error at or below tol, or None."""
    for iteration, seconds, error in history:
        if error <= tol:
            return iteration, seconds
    return None


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("problem", nargs="?", default=str(DEFAULT))
    parser.add_argument("--max-iter", type=int, default=20000)
    parser.add_argument("--plot", help="write the error-vs-time plot here (needs matplotlib)")
    args = parser.parse_args()

    problem = moreau.read_fc2d(args.problem)
    print(f"{Path(args.problem).name}: {problem.n_contacts} contacts")
    print("| solver | " + " | ".join(f"{t:.0e}" for t in TOLS) + " |")
    print("|---|" + "---|" * len(TOLS))
    curves = {}
    for solver in ["nlgs", "pcpg"]:
        result = moreau.solve(problem, solver=solver, tol=min(TOLS), max_iter=args.max_iter, history_every=1)
        curves[solver] = np.array(result.history)
        cells = []
        for tol in TOLS:
            hit = first_reaching(result.history, tol)
            cells.append("–" if hit is None else f"{hit[1]:.3f} s ({hit[0]:,} its)")
        print(f"| {solver} | " + " | ".join(cells) + " |")

    if args.plot:
        try:
            import matplotlib

            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
        except ImportError:
            print("matplotlib is not installed: no plot")
            return
        fig, ax = plt.subplots(figsize=(6, 4))
        for solver, h in curves.items():
            ax.loglog(h[1:, 1], h[1:, 2], label=solver)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("relative natural-map error")
        ax.set_title(Path(args.problem).name)
        ax.legend()
        fig.tight_layout()
        fig.savefig(args.plot, dpi=120)
        print(f"plot in {args.plot}")


if __name__ == "__main__":
    main()
