"""A biaxial test, the classic of 2D granular mechanics (LMGC90's, Radjai & Dubois's): disks in a
box of two fixed walls (left, bottom) and two pistons, compressed isotropically at a pressure
sigma3, then sheared by the top plate at a constant speed while the right piston keeps sigma3.

The pistons are bodies with a mass, the load of the stress each step (`apply_force`), and an
axis held (`hold_velocity`): the right piston moves only along x, the top one only along y, so
neither tilts or drifts. The steel parts pass through each other (`set_pass_through`) where they
cross at the corners. Prints, per saved step, the axial strain, the volumetric strain, the
stresses and the mobilised friction sin(phi) = (sigma1 - sigma3) / (sigma1 + sigma3).

    python python/examples/biaxial.py [--grains 400] [--steps 1000] [--tol 1e-3] [--solver nlgs] [--csv biaxial.csv]

At tol 1e-4 the interior point (--solver interior-point) leaves far fewer steps unconverged than
NLGS on these dense sheared packings (BENCHMARKS, "A biaxial test").
"""

import argparse
import csv

import numpy as np

import moreau

THICKNESS = 0.01  # plates' thickness (m)


def build(grains, mu, seed, tol, solver="nlgs"):
    """The sample on a loose lattice, the walls and the two pistons; returns the simulation
    (every contact solved to `tol` times the step's largest free velocity), the grains' area,
    their mean diameter and the pistons' indices (right, top)."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(grains)))
    r_max, spacing = 1.2e-3, 2.5e-3
    width = height = side * spacing
    world = moreau.World([("glass", 2500.0), ("steel", 7800.0)], friction=mu, rotation=True)
    world.set_interaction("glass", "steel", friction=0.0)  # frictionless boundaries
    world.set_pass_through("steel", "steel")
    world.add_wall((0.0, 0.0), (0.0, 3 * height), "steel")
    world.add_wall((0.0, 0.0), (3 * width, 0.0), "steel")
    radii = rng.uniform(0.8e-3, r_max, grains)
    for k, r in enumerate(radii):
        world.add_disk(((k % side + 0.5) * spacing, (k // side + 0.5) * spacing), r, "glass")
    mass = 2500.0 * np.pi * 1e-6 * grains / 10  # a tenth of the sample's mass
    t = THICKNESS / 2
    plate = lambda half_w, half_h: [(-half_w, -half_h), (half_w, -half_h), (half_w, half_h), (-half_w, half_h)]
    right = world.add_polygon((width + t, 1.5 * height), plate(t, 1.5 * height), "steel", lock_rotation=True,
                              mass=mass, hold_velocity=("y",))
    top = world.add_polygon((1.5 * width, height + t), plate(1.5 * width, t), "steel", lock_rotation=True,
                            mass=mass, hold_velocity=("x",))
    mixing = {"anderson": 5} if solver == "nlgs" else {}
    sim = moreau.Simulation(world, h=2e-4, solver=solver, tol=tol, criterion="velocity", **mixing)
    return sim, np.pi * np.sum(radii**2), 2 * radii.mean(), right, top


def sample_size(sim, right, top):
    """The sample's width and height: from the left wall to the right piston's face, from the
    floor to the top plate's face."""
    p = sim.positions
    return p[right, 0] - THICKNESS / 2, p[top, 1] - THICKNESS / 2


def run(grains=400, steps=1000, sigma3=1e4, speed=0.01, mu=0.5, seed=1, every=50, tol=1e-3, solver="nlgs", out=None):
    """Isotropic compression to sigma3 (N/m) until the sample's size and the pistons' loads hold
    still, then shear at `speed` (m/s) for `steps` steps; returns the saved rows (dicts): the
    first is the isotropic state, the others every `every` steps of the shear."""
    sim, area, diameter, right, top = build(grains, mu, seed, tol, solver)
    sizes = []
    for k in range(20000):
        w, h = sample_size(sim, right, top)
        sim.apply_force(right, (-sigma3 * h, 0.0))
        sim.apply_force(top, (0.0, -sigma3 * w))
        sim.step()
        w, h = sample_size(sim, right, top)
        sizes.append((w, h))
        loads = sim.body_loads()["force"]
        balanced = abs(loads[right, 0] / (sigma3 * h) - 1) < 1e-3 and abs(loads[top, 1] / (sigma3 * w) - 1) < 1e-3
        # At rest: 100 steps without the sample's size moving by 1e-5 of itself (a rattler, free
        # of contacts without gravity, may drift on).
        if balanced and k >= 100 and np.abs(np.array(sizes[-100]) / (w, h) - 1).max() < 1e-5:
            break
    w0, h0 = sample_size(sim, right, top)
    loads = sim.body_loads()["force"]
    rows = [row(0, 0.0, 0.0, loads[top, 1] / w0, loads[right, 0] / h0, area / (w0 * h0), 0.0)]
    # Shear: the top piston replaced by a plate of the same shape driven down at `speed` (a fixed
    # body: it moves at its velocity whatever the grains do); the right piston keeps sigma3.
    centre = tuple(sim.positions[top])
    half_w, t = centre[0], THICKNESS / 2  # the plate spans x from 0 to twice its centre's
    sim.remove_body(top)
    top = sim.add_polygon(centre, [(-half_w, -t), (half_w, -t), (half_w, t), (-half_w, t)], "steel", fixed=True,
                          velocity=(0.0, -speed))
    unconverged, overlap = 0, 0.0
    for k in range(1, steps + 1):
        w, h = sample_size(sim, right, top)
        sim.apply_force(right, (-sigma3 * h, 0.0))
        report = sim.step()
        unconverged += not report["converged"]
        overlap = max(overlap, report["max_penetration"] / diameter)
        if k % every == 0:
            w, h = sample_size(sim, right, top)
            loads = sim.body_loads()["force"]
            strains = (1 - h / h0, 1 - w * h / (w0 * h0))
            rows.append(row(k, *strains, loads[top, 1] / w, loads[right, 0] / h, area / (w * h), overlap))
            overlap = 0.0
    if unconverged:
        print(f"{unconverged} of {steps} shear steps did not converge")
    if out:
        with open(out, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    return rows


def row(step, axial, volumetric, sigma1, sigma3, packing, overlap):
    """A saved state: strains (compression positive), stresses (N/m), sin(phi), packing fraction,
    and the largest overlap of the steps since the last row over the mean diameter."""
    return {
        "step": step,
        "axial_strain": axial,
        "volumetric_strain": volumetric,
        "sigma1": sigma1,
        "sigma3": sigma3,
        "sin_phi": (sigma1 - sigma3) / (sigma1 + sigma3),
        "packing_fraction": packing,
        "max_overlap": overlap,
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grains", type=int, default=400)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--tol", type=float, default=1e-3,
                        help="every contact within tol times the step's largest free velocity")
    parser.add_argument("--solver", default="nlgs", help="nlgs (with Anderson 5), interior-point, pcpg, ...")
    parser.add_argument("--csv", help="write the saved rows here")
    args = parser.parse_args()
    rows = run(args.grains, args.steps, tol=args.tol, solver=args.solver, out=args.csv)
    print("| axial strain | volumetric strain | sigma1 (N/m) | sigma3 (N/m) | sin phi | packing | max overlap / d |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['axial_strain']:.4f} | {r['volumetric_strain']:+.4f} | {r['sigma1']:.0f} | {r['sigma3']:.0f} "
              f"| {r['sin_phi']:.3f} | {r['packing_fraction']:.3f} | {r['max_overlap']:.1e} |")


if __name__ == "__main__":
    main()
