"""The Python package against the command line and the Rust library: the same answers on the
same inputs, the same messages on bad ones, arrays of the documented shapes, the GIL released
during solves."""

import csv
import json
import math
import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

import moreau

REPO = Path(__file__).resolve().parents[2]
SEED = REPO / "fuzz/seeds/problem_parser/FC2D_SliderCrankLagrangian00000.dat"
SHARED = REPO.parent / "shared/data/siconos-fc2d"
PILE = REPO / "scenes/pile.toml"


def cli():
    """The `moreau` binary built beside this package (MOREAU_BIN overrides)."""
    path = Path(os.environ.get("MOREAU_BIN", REPO / "target/release/moreau"))
    if not path.exists():
        pytest.fail(f"{path} not found: build it with `cargo build --release` (or set MOREAU_BIN)")
    return str(path)


def problem_files():
    files = [SEED]
    files += [SHARED / n for n in ("fc2d_granularflowonwall_00667_00000.dat", "fc2d_granularflowonwall_02020_00213.dat")]
    return [f for f in files if f.exists()]


@pytest.mark.parametrize("path", problem_files(), ids=lambda p: p.name)
@pytest.mark.parametrize("solver", ["nlgs", "pcpg"])
def test_python_and_the_command_line_give_the_same_r(tmp_path, path, solver):
    out = tmp_path / "solve.json"
    args = [cli(), "solve", str(path), "--solver", solver, "--tol", "1e-7", "--max-iter", "3000", "--threads", "1"]
    subprocess.run(args + ["--device", "cpu", "--out", str(out)], check=True, capture_output=True)
    from_cli = json.loads(out.read_text())
    result = moreau.solve(moreau.read_fc2d(path), solver=solver, tol=1e-7, max_iter=3000, threads=1)
    r_cli = np.array(from_cli["r"])
    assert result.r.shape == r_cli.shape == (2 * from_cli["contacts"],)
    assert np.linalg.norm(result.r - r_cli) <= 1e-12 * max(np.linalg.norm(r_cli), 1e-300)
    assert result.iterations == from_cli["iterations"] and result.converged == from_cli["converged"]
    assert result.error == pytest.approx(from_cli["error"], rel=1e-9, abs=1e-300)


def test_anderson_acceleration_from_python_matches_the_command_line(tmp_path):
    out = tmp_path / "solve.json"
    args = [cli(), "solve", str(SEED), "--solver", "nlgs", "--tol", "1e-10", "--max-iter", "5000", "--threads", "1"]
    args += ["--anderson", "5"]
    subprocess.run(args + ["--device", "cpu", "--out", str(out)], check=True, capture_output=True)
    from_cli = json.loads(out.read_text())
    plain = moreau.solve(moreau.read_fc2d(SEED), tol=1e-10, max_iter=5000, threads=1)
    mixed = moreau.solve(moreau.read_fc2d(SEED), tol=1e-10, max_iter=5000, threads=1, anderson=5)
    assert mixed.converged and mixed.iterations == from_cli["iterations"]
    assert np.linalg.norm(mixed.r - np.array(from_cli["r"])) <= 1e-12 * np.linalg.norm(mixed.r)
    assert plain.converged and plain.iterations != mixed.iterations


def test_over_relaxed_nlgs_from_python_is_the_command_lines_and_stays_in_the_cone(tmp_path):
    out = tmp_path / "solve.json"
    args = [cli(), "solve", str(SEED), "--solver", "nlgs", "--tol", "1e-8", "--max-iter", "5000", "--threads", "1"]
    subprocess.run(args + ["--omega", "1.3", "--device", "cpu", "--out", str(out)], check=True, capture_output=True)
    from_cli = json.loads(out.read_text())
    problem = moreau.read_fc2d(SEED)
    relaxed = moreau.solve(problem, tol=1e-8, max_iter=5000, threads=1, omega=1.3)
    plain = moreau.solve(problem, tol=1e-8, max_iter=5000, threads=1)
    assert relaxed.converged and relaxed.iterations == from_cli["iterations"]
    assert np.linalg.norm(relaxed.r - np.array(from_cli["r"])) <= 1e-12 * np.linalg.norm(relaxed.r)
    assert plain.iterations != relaxed.iterations
    # Each contact's impulse in its cone, the normal one never pulling.
    r = relaxed.r.reshape(-1, 2)
    assert (r[:, 0] >= 0.0).all()
    # A simulation takes it too, and reports it.
    sim = moreau.Simulation.from_scene(PILE)
    sim.set_solver(omega=1.2)
    assert sim.solver_settings()["omega"] == 1.2


def test_a_gpu_solve_below_the_f32_floor_lists_its_parts_as_the_command_line_does(tmp_path):
    problem = moreau.read_fc2d(SEED)
    try:
        result = moreau.solve(problem, tol=1e-9, max_iter=20_000, device="gpu", threads=1)
    except moreau.MoreauError as e:
        if os.environ.get("MOREAU_REQUIRE_GPU") == "1":
            raise
        pytest.skip(f"no GPU adapter: {e}")
    out = tmp_path / "solve.json"
    args = [cli(), "solve", str(SEED), "--solver", "nlgs", "--tol", "1e-9", "--max-iter", "20000", "--threads", "1"]
    subprocess.run(args + ["--device", "gpu", "--out", str(out)], check=True, capture_output=True)
    from_cli = json.loads(out.read_text())
    assert result.converged and result.error <= 1e-9
    assert [p[0] for p in result.parts] == [p["device"] for p in from_cli["parts"]] == ["gpu", "cpu"]
    assert sum(p[1] for p in result.parts) == result.iterations
    assert result.gpu_iterations == result.parts[0][1] > 0
    assert result.parts[0][3] > 1e-9, "the f32 part alone should not reach 1e-9"
    on_cpu = moreau.solve(problem, tol=1e-9, max_iter=20_000, device="cpu", threads=1)
    assert on_cpu.parts == [] and on_cpu.gpu_iterations == 0


def test_a_problem_from_scipy_and_from_a_dense_matrix_solves_to_tolerance():
    sparse = pytest.importorskip("scipy.sparse")
    rng = np.random.default_rng(3)
    n = 40
    B = rng.normal(size=(2 * n, 3 * n))
    W = B @ B.T / (3 * n) + 0.1 * np.eye(2 * n)
    q = rng.normal(size=2 * n)
    mu = np.full(n, 0.4)
    for matrix in (W, sparse.csr_matrix(W), sparse.coo_matrix(W)):
        problem = moreau.Problem(matrix, q, mu)
        result = moreau.solve(problem, tol=1e-10, max_iter=20000)
        assert result.converged and result.error <= 1e-10
        np.testing.assert_allclose(problem.velocity(result.r), W @ result.r + q, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(result.u, W @ result.r + q, rtol=1e-12, atol=1e-12)
        rn, rt = result.r[0::2], result.r[1::2]
        assert np.all(rn >= 0) and np.all(np.abs(rt) <= mu * rn * (1 + 1e-12) + 1e-300)
    warm = moreau.solve(problem, tol=1e-10, r0=result.r)
    assert warm.iterations <= 1 and warm.converged


def test_a_problem_with_no_answer_comes_back_unconverged_and_says_why():
    # One disk pressed from opposite sides at once: u_n1 + u_n2 = -2 whatever the impulses.
    W = np.array([[1.0, 0, -1, 0], [0, 1, 0, -1], [-1, 0, 1, 0], [0, -1, 0, 1]])
    problem = moreau.Problem(W, [-1.0, 0.0, -1.0, 0.0], [0.5, 0.5])
    for solver in ("nlgs", "interior-point"):
        result = moreau.solve(problem, solver=solver, tol=1e-4, max_iter=20000)
        assert not result.converged, (solver, result.error)
        assert result.stop == "unbounded" and "may have no answer" in result.stop_reason
    answered = moreau.solve(moreau.Problem(W, [-1.0, 0.0, 1.5, 0.0], [0.5, 0.5]), tol=1e-4)
    assert answered.converged and answered.stop == "converged"
    # The same disk a million times heavier, by projected Jacobi: the natural-map error passes
    # while the pressed contact still closes at a third of the largest free velocity.
    heavy = moreau.solve(moreau.Problem(1e-6 * W, [-1.0, 0.0, 1.5, 0.0], [0.5, 0.5]), solver="jacobi", tol=1e-4)
    assert heavy.converged and heavy.error <= 1e-4 and heavy.velocity_error > 0.1
    held = moreau.solve(moreau.Problem(1e-6 * W, [-1.0, 0.0, 1.5, 0.0], [0.5, 0.5]), solver="jacobi", tol=1e-4,
                        criterion="velocity", max_iter=100000)
    assert held.converged and held.velocity_error == held.judged_error <= 1e-4


def test_a_problem_written_from_python_reads_back_the_same(tmp_path):
    problem = moreau.read_fc2d(SEED)
    for sparse in (True, False):
        path = tmp_path / f"p_{sparse}.dat"
        problem.write_fc2d(path, sparse=sparse)
        again = moreau.read_fc2d(path)
        np.testing.assert_array_equal(again.q, problem.q)
        np.testing.assert_array_equal(again.mu, problem.mu)
        r = np.linspace(0.0, 1.0, 2 * problem.n_contacts)
        np.testing.assert_array_equal(again.velocity(r), problem.velocity(r))


def test_a_deposit_built_from_python_is_the_command_lines_and_the_interior_point_solves_it(tmp_path):
    """The deposit family of BENCHMARKS ("The frictional deposit as a family") from Python: the
    problem `moreau generate deposit` writes, to the byte; on the 100-disk deposit of seed 7 the
    interior point reaches 1e-8 in tens of iterations where 2,000 NLGS sweeps do not."""
    problem = moreau.deposit(100, mu=0.3, seed=7)
    problem.write_fc2d(tmp_path / "python.dat")
    args = [cli(), "generate", "deposit", "--n", "100", "--mu", "0.3", "--seed", "7", "--out", str(tmp_path / "cli.dat")]
    subprocess.run(args, check=True, capture_output=True)
    assert (tmp_path / "python.dat").read_bytes() == (tmp_path / "cli.dat").read_bytes()
    assert problem.n_contacts == 184 and np.all(problem.mu == 0.3)
    ip = moreau.solve(problem, solver="interior-point", tol=1e-8, max_iter=2000, threads=1)
    sweeps = moreau.solve(problem, solver="nlgs", tol=1e-8, max_iter=2000, threads=1)
    assert ip.converged and ip.error <= 1e-8 and ip.iterations <= 100, (ip.iterations, ip.error)
    assert not sweeps.converged and sweeps.error > 1e-6, sweeps.error


def read_steps(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def test_a_scene_stepped_from_python_matches_the_command_line_step_by_step(tmp_path):
    steps = 40
    scene = tmp_path / "pile.toml"
    scene.write_text(PILE.read_text().replace("[output]\n", f"[output]\ncheckpoint_every = {steps}\n"))
    args = [cli(), "run", str(scene), "--steps", str(steps), "--threads", "1", "--device", "cpu", "--quiet"]
    subprocess.run(args + ["--out", str(tmp_path)], check=True, capture_output=True)
    rows = read_steps(tmp_path / "steps.csv")
    sim = moreau.Simulation.from_scene(scene)
    assert sim.set_device("cpu", threads=1).startswith("cpu")
    for row in rows:
        report = sim.step()
        assert report["step"] == int(row["step"])
        assert report["contacts"] == int(row["contacts"]) and report["iterations"] == int(row["iterations"])
        assert report["kinetic_energy"] == pytest.approx(float(row["kinetic_energy"]), rel=1e-12, abs=0.0)
        assert report["dissipated_energy"] == pytest.approx(float(row["dissipated_energy"]), rel=1e-12, abs=1e-300)
        assert report["max_penetration"] == pytest.approx(float(row["max_penetration"]), rel=1e-12, abs=1e-300)
        assert report["velocity_scale"] == pytest.approx(float(row["velocity_scale"]), rel=1e-12, abs=1e-300)
        measures = sim.measures()
        for name in ("packing_fraction", "coordination", "stress_yy", "fabric_xy", "anisotropy"):
            assert measures[name] == pytest.approx(float(row[name]), rel=1e-12, abs=1e-300), name
    assert sim.steps_done == steps and sim.time == pytest.approx(steps * 2e-3)
    # The command line's state after the last step, from its checkpoint: the same bits.
    end = json.loads((tmp_path / f"checkpoint_{steps:06d}.json").read_text())
    np.testing.assert_array_equal(sim.positions, np.array(end["position"]))
    np.testing.assert_array_equal(sim.velocities, np.array(end["velocity"]))
    np.testing.assert_array_equal(sim.spins, np.array(end["spin"]))


def test_a_scene_given_another_solver_from_python_steps_as_the_command_lines_overrides_do(tmp_path):
    # The work list and the velocity test, the settings of a settled pile's steps, set on a
    # loaded scene as `moreau run --ordering worklist --criterion velocity` sets them.
    steps = 30
    args = [cli(), "run", str(PILE), "--steps", str(steps), "--threads", "1", "--device", "cpu", "--quiet"]
    overrides = ["--ordering", "worklist", "--criterion", "velocity", "--tol", "1e-5"]
    subprocess.run(args + overrides + ["--out", str(tmp_path / "list")], check=True, capture_output=True)
    subprocess.run(args + ["--out", str(tmp_path / "scene")], check=True, capture_output=True)
    listed, scene = read_steps(tmp_path / "list/steps.csv"), read_steps(tmp_path / "scene/steps.csv")
    assert [r["iterations"] for r in listed] != [r["iterations"] for r in scene]
    sim = moreau.Simulation.from_scene(PILE)
    sim.set_device("cpu", threads=1)
    before = sim.solver_settings()
    sim.set_solver(ordering="worklist", criterion="velocity", tol=1e-5)
    after = sim.solver_settings()
    assert (after["ordering"], after["criterion"], after["tol"]) == ("worklist", "velocity", 1e-5)
    assert {k: after[k] for k in ("solver", "max_iter", "anderson")} == {k: before[k] for k in ("solver", "max_iter", "anderson")}
    for row in listed:
        report = sim.step()
        assert report["iterations"] == int(row["iterations"]) and report["converged"] == (row["converged"] == "true")
        assert report["kinetic_energy"] == pytest.approx(float(row["kinetic_energy"]), rel=1e-12, abs=0.0)
    # Refused settings change nothing.
    with pytest.raises(moreau.MoreauError, match="max_iter 0: must be at least 1"):
        sim.set_solver(max_iter=0, ordering="forward")
    with pytest.raises(moreau.MoreauError, match="block_sweeps 65: a block is swept at most 64 times a dispatch"):
        sim.set_solver(block_sweeps=65)
    assert sim.solver_settings() == after
    # The GPU's block sweeps are a setting like the others (the CPU sweeps as its ordering says).
    sim.set_solver(block_sweeps=4)
    assert sim.solver_settings() == {**after, "block_sweeps": 4}


def test_a_scene_given_another_time_step_from_python_steps_as_the_command_line_does(tmp_path):
    steps = 20
    args = [cli(), "run", str(PILE), "--steps", str(steps), "--threads", "1", "--device", "cpu", "--quiet"]
    subprocess.run(args + ["--time-step", "5e-4", "--out", str(tmp_path / "half")], check=True, capture_output=True)
    rows = read_steps(tmp_path / "half/steps.csv")
    sim = moreau.Simulation.from_scene(PILE)
    sim.set_device("cpu", threads=1)
    assert sim.time_step != 5e-4
    sim.set_time_step(5e-4)
    assert sim.time_step == 5e-4
    for row in rows:
        report = sim.step()
        assert report["iterations"] == int(row["iterations"])
        assert report["kinetic_energy"] == pytest.approx(float(row["kinetic_energy"]), rel=1e-12, abs=0.0)
    assert sim.time == pytest.approx(steps * 5e-4, rel=1e-12)
    # Refused steps change nothing.
    for bad in (0.0, -1e-3, float("nan"), float("inf")):
        with pytest.raises(moreau.MoreauError, match="must be finite and > 0"):
            sim.set_time_step(bad)
    assert sim.time_step == 5e-4


def test_every_criterion_python_names_is_one_the_library_takes():
    # CRITERIA is written by hand: each name must set that criterion, and a name outside it is refused.
    sim = moreau.Simulation.from_scene(PILE)
    for criterion in moreau.CRITERIA:
        sim.set_solver(criterion=criterion)
        assert sim.solver_settings()["criterion"] == criterion
    with pytest.raises(moreau.MoreauError, match="step-velocity"):
        sim.set_solver(criterion="gravity")


def test_a_solve_judged_by_the_velocity_test_from_python_matches_the_command_line(tmp_path):
    out = tmp_path / "solve.json"
    args = [cli(), "solve", str(SEED), "--solver", "nlgs", "--tol", "1e-6", "--criterion", "velocity", "--threads", "1"]
    subprocess.run(args + ["--device", "cpu", "--out", str(out)], check=True, capture_output=True)
    from_cli = json.loads(out.read_text())
    result = moreau.solve(moreau.read_fc2d(SEED), tol=1e-6, threads=1, criterion="velocity")
    natural = moreau.solve(moreau.read_fc2d(SEED), tol=1e-6, threads=1)
    assert result.converged and result.iterations == from_cli["iterations"] != natural.iterations
    assert result.judged_error == pytest.approx(from_cli["judged_error"], rel=1e-12) and result.judged_error <= 1e-6
    assert natural.judged_error == natural.error


def test_a_checkpoint_written_from_python_restarts_bit_for_bit_here_and_on_the_command_line(tmp_path):
    scene = tmp_path / "pile.toml"
    scene.write_text(PILE.read_text().replace("[output]\n", "[output]\ncheckpoint_every = 30\n"))
    straight = moreau.Simulation.from_scene(scene)
    straight.set_device("cpu", threads=1)
    for _ in range(20):
        straight.step()
    straight.write_checkpoint(tmp_path / "at_20.json", scene=scene)
    for _ in range(10):
        straight.step()
    again = moreau.Simulation.from_scene(scene)
    again.set_device("cpu", threads=1)
    again.restore(tmp_path / "at_20.json", scene=scene)
    assert again.steps_done == 20
    for _ in range(10):
        again.step()
    np.testing.assert_array_equal(again.positions, straight.positions)
    np.testing.assert_array_equal(again.spins, straight.spins)
    # The command line goes on from the same file to the same state at step 30.
    args = [cli(), "run", str(scene), "--restart", str(tmp_path / "at_20.json"), "--steps", "10"]
    subprocess.run(args + ["--threads", "1", "--device", "cpu", "--quiet", "--out", str(tmp_path)], check=True, capture_output=True)
    end = json.loads((tmp_path / "checkpoint_000030.json").read_text())
    np.testing.assert_array_equal(straight.positions, np.array(end["position"]))
    # A checkpoint of another scene file is refused by name.
    other = tmp_path / "other.toml"
    other.write_text(scene.read_text() + "\n# changed\n")
    with pytest.raises(moreau.MoreauError, match="fingerprint"):
        again.restore(tmp_path / "at_20.json", scene=other)


def test_state_and_contacts_come_back_as_arrays_of_the_documented_shapes():
    sim = moreau.Simulation.from_scene(PILE)
    for _ in range(30):
        assert sim.step()["converged"]
    n = sim.body_count
    assert sim.positions.shape == (n, 2) and sim.velocities.shape == (n, 2)
    assert sim.angles.shape == (n,) and sim.spins.shape == (n,)
    c = sim.contacts()
    k = len(c["body"])
    assert k > 0
    for name, shape in [("other", (k,)), ("point", (k, 2)), ("normal", (k, 2)), ("impulse", (k, 2)), ("gap", (k,)), ("status", (k,))]:
        assert c[name].shape == shape, name
    assert np.all(c["body"] < n) and np.all(c["impulse"][:, 0] >= 0.0) and np.all(c["status"] <= 3)
    assert np.all(c["other"][~c["other_is_wall"]] < n) and np.all(c["other"][c["other_is_wall"]] < 3)
    np.testing.assert_allclose(np.linalg.norm(c["normal"], axis=1), 1.0, rtol=1e-12)


def test_a_world_built_from_python_lets_a_grain_land_and_rest():
    world = moreau.World([("glass", 2500.0)], friction=0.3, gravity=(0.0, -9.81))
    world.add_wall((-1.0, 0.0), (1.0, 0.0), "glass")
    world.add_disk((0.0, 0.05), 0.05, "glass")
    sim = moreau.Simulation(world, h=1e-3)
    grain = sim.add_disk((0.0, 0.2), 0.05, "glass")
    for _ in range(200):
        assert sim.step()["converged"]
    assert abs(sim.positions[grain, 1] - 0.15) < 1e-3 and np.linalg.norm(sim.velocities[grain]) < 1e-2
    sim.keep_problems()
    sim.step()
    problem = sim.last_problem()
    assert problem.matrix_free and problem.n_contacts == len(sim.contacts()["body"])
    assert moreau.solve(problem, tol=1e-10).error <= 1e-10
    focused = moreau.solve(problem, tol=1e-10, focus=3)
    assert focused.error <= 1e-10 and any(n.startswith("focused sweeps: ") for n in focused.notes), focused.notes


def test_a_stack_hangs_its_weight_on_the_floor_and_a_driven_wall_goes_where_python_sends_it():
    world = moreau.World([("glass", 2500.0)], friction=0.3, gravity=(0.0, -9.81), moving_walls=True)
    world.add_wall((-1.0, 0.0), (1.0, 0.0), "glass")
    world.add_wall((0.5, 0.0), (0.5, 0.5), "glass")
    for k in range(3):
        world.add_disk((0.0, 0.05 + 0.1 * k), 0.05, "glass")
    # The column's alignment below is asked to 1e-6 m: a natural-map tol of 1e-4 (the default)
    # lets the bottom disk fall 5.5e-6 m behind the others over the 600 sliding steps.
    sim = moreau.Simulation(world, h=1e-3, tol=1e-6)
    for _ in range(100):
        assert sim.step()["converged"]
    weight = 3 * 2500.0 * np.pi * 0.05**2 * 9.81
    walls, bodies = sim.wall_loads(), sim.body_loads()
    assert walls["force"].shape == (2, 2) and walls["moment"].shape == (2,) and bodies["force"].shape == (3, 2)
    np.testing.assert_allclose(walls["force"][0], [0.0, -weight], atol=1e-6 * weight)
    np.testing.assert_allclose(walls["force"][1], [0.0, 0.0], atol=1e-12)
    # At rest the contacts on each disk hold up its own weight.
    np.testing.assert_allclose(bodies["force"][:, 1], weight / 3, rtol=1e-6)
    np.testing.assert_allclose(bodies["force"].sum(axis=0), -walls["force"].sum(axis=0), atol=1e-9 * weight)
    # The side wall sent left at 1 m/s for 0.5 s, then stopped.
    sim.set_wall_motion(1, (-1.0, 0.0))
    for k in range(600):
        if k == 500:
            sim.set_wall_motion(1, (0.0, 0.0))
        sim.step()
    w = sim.walls()
    np.testing.assert_allclose(w["center"][1], [0.0, 0.25], atol=1e-12)
    assert w["velocity"][1].tolist() == [0.0, 0.0] and w["spin"].tolist() == [0.0, 0.0]
    # Pushed past where the wall stopped (they slide on after it), the stack in one column.
    x = sim.positions[:, 0]
    assert x.max() < -0.05 + 1e-6 and np.ptp(x) < 1e-6, x
    with pytest.raises(moreau.MoreauError, match="wall 2 does not exist"):
        sim.set_wall_motion(2, (1.0, 0.0))
    world = moreau.World([("glass", 1.0)])
    world.add_wall((-1.0, 0.0), (1.0, 0.0), "glass")
    with pytest.raises(moreau.MoreauError, match="wall 0: a wall with a velocity or a spin needs the effect moving_walls"):
        moreau.Simulation(world, h=1e-3).set_wall_motion(0, (1.0, 0.0))


def test_a_turning_drum_and_a_polygon_wall_built_from_python_step_as_the_scene_file_describing_them(tmp_path):
    disks = [(0.02 * (k % 5) - 0.04, -0.06 + 0.02 * (k // 5)) for k in range(15)]
    scene = tmp_path / "drum.toml"
    scene.write_text(
        'effects = ["gravity", "friction", "rotation", "moving_walls"]\n[time]\nstep = 1e-3\nsteps = 1\n'
        '[contact]\nfriction = 0.5\n[[material]]\nname = "grain"\ndensity = 2500.0\n'
        '[[wall]]\ndrum = { center = [0.0, 0.0], radius = 0.1, sides = 24 }\nmaterial = "grain"\nangular_velocity = 2.0\n'
        '[[wall]]\npolygon = [[-0.02, -0.1], [0.02, -0.1], [0.0, -0.08]]\nmaterial = "grain"\n'
        + "".join(f"[[body]]\ndisk = {{ center = [{x!r}, {y!r}], radius = 0.009 }}\n" for x, y in disks)
    )
    world = moreau.World([("grain", 2500.0)], friction=0.5, gravity=(0.0, -9.81), rotation=True, moving_walls=True)
    assert world.add_drum((0.0, 0.0), 0.1, 24, "grain", spin=2.0) == list(range(24))
    assert world.add_polygon_wall([(-0.02, -0.1), (0.02, -0.1), (0.0, -0.08)], "grain") == 24
    for x, y in disks:
        world.add_disk((x, y), 0.009, "grain")
    ours, theirs = moreau.Simulation(world, h=1e-3), moreau.Simulation.from_scene(scene)
    for sim in (ours, theirs):
        sim.set_device("cpu", threads=1)
        for _ in range(200):
            sim.step()
    np.testing.assert_array_equal(ours.positions, theirs.positions)
    np.testing.assert_array_equal(ours.walls()["angle"], theirs.walls()["angle"])
    np.testing.assert_allclose(ours.walls()["angle"][:24], 0.4, rtol=1e-12)
    with pytest.raises(moreau.MoreauError, match="3 <= sides"):
        world.add_drum((0.0, 0.0), 0.1, 2, "grain")
    with pytest.raises(moreau.MoreauError, match="a polygon needs at least 3 vertices, got 2"):
        world.add_polygon_wall([(0.0, 0.0), (1.0, 0.0)], "grain")


def test_a_periodic_cell_built_from_python_steps_as_the_scene_file_describing_it(tmp_path):
    # Grains sliding right along a floor leave the cell at x = 0.2 and come back at 0; the last
    # one is given beyond the cell, where both bring it in.
    disks = [(0.01 + 0.021 * k, 0.01 + 0.02 * (k % 2)) for k in range(9)] + [(0.25, 0.05)]
    scene = tmp_path / "cell.toml"
    scene.write_text(
        'effects = ["gravity", "friction", "rotation"]\n[time]\nstep = 1e-3\nsteps = 1\n'
        '[contact]\nfriction = 0.1\n[[material]]\nname = "grain"\ndensity = 2500.0\n[periodic]\nx = [0.0, 0.2]\n'
        '[[wall]]\nsegment = [[-0.1, 0.0], [0.3, 0.0]]\nmaterial = "grain"\n'
        + "".join(f"[[body]]\ndisk = {{ center = [{x!r}, {y!r}], radius = 0.009 }}\nvelocity = [1.0, 0.0]\n" for x, y in disks)
    )
    world = moreau.World([("grain", 2500.0)], friction=0.1, gravity=(0.0, -9.81), rotation=True)
    assert world.periodic is None
    world.add_wall((-0.1, 0.0), (0.3, 0.0), "grain")
    for x, y in disks[:5]:
        world.add_disk((x, y), 0.009, "grain", velocity=(1.0, 0.0))
    world.set_periodic(0.0, 0.2)
    for x, y in disks[5:]:
        world.add_disk((x, y), 0.009, "grain", velocity=(1.0, 0.0))
    assert world.periodic == (0.0, 0.2)
    ours, theirs = moreau.Simulation(world, h=1e-3), moreau.Simulation.from_scene(scene)
    np.testing.assert_allclose(ours.positions[-1], (0.05, 0.05), rtol=1e-12)
    for sim in (ours, theirs):
        sim.set_device("cpu", threads=1)
        for _ in range(300):
            sim.step()
    np.testing.assert_array_equal(ours.positions, theirs.positions)
    assert ours.positions[:, 0].min() >= 0.0 and ours.positions[:, 0].max() < 0.2
    assert (ours.velocities[:, 0] > 0.3).all(), "still sliding right, through the boundary"
    profile = ours.height_profile()
    assert profile["grains"].sum() == 10 and profile["y_low"][0] == 0.0, "from the floor up"
    filled = profile["grains"] > 0
    np.testing.assert_allclose(profile["vx"][filled].min(), ours.velocities[:, 0].min(), rtol=0.2)
    assert ((profile["solid_fraction"] > 0) & (profile["solid_fraction"] < 1)).all()
    with pytest.raises(moreau.MoreauError, match="thickness 0 must be finite and > 0"):
        ours.height_profile(0.0)
    # A grain added to the running cell comes in too; one wider than a quarter of it is refused.
    k = ours.add_disk((0.45, 0.1), 0.009, "grain")
    np.testing.assert_allclose(ours.positions[k, 0], 0.05, rtol=1e-12)
    with pytest.raises(moreau.MoreauError, match="at least 4 of its widest bodies"):
        ours.add_disk((0.1, 0.2), 0.03, "grain")
    assert len(ours.positions) == k + 1
    with pytest.raises(moreau.MoreauError, match=r"periodic cell x: \[0.2, 0.1\] must be finite with x0 < x1"):
        world.set_periodic(0.2, 0.1)


def test_a_fixed_plate_given_a_velocity_from_python_carries_a_grain_as_a_belt_does():
    world = moreau.World([("rubber", 1000.0)], friction=0.2, gravity=(0.0, -9.81))
    plate = world.add_polygon((0.0, -0.05), [(-5.0, -0.05), (5.0, -0.05), (5.0, 0.05), (-5.0, 0.05)], "rubber",
                              fixed=True, velocity=(1.0, 0.0))
    grain = world.add_disk((0.0, 0.1), 0.1, "rubber")
    sim = moreau.Simulation(world, h=1e-3, tol=1e-10)
    for _ in range(300):
        sim.step()
    # Dragged at mu g until it moves with the belt at 1 m/s (0.51 s); the belt is never pushed.
    assert abs(sim.velocities[grain, 0] - 0.2 * 9.81 * 0.3) < 1e-5
    assert tuple(sim.velocities[plate]) == (1.0, 0.0)
    sim.set_velocity(plate, (-1.0, 0.0))
    for _ in range(100):
        sim.step()
    assert tuple(sim.velocities[plate]) == (-1.0, 0.0)
    assert abs(sim.velocities[grain, 0] - 0.2 * 9.81 * 0.2) < 1e-5, "now braked at mu g"
    with pytest.raises(moreau.MoreauError, match="is fixed: it takes no force or impulse"):
        sim.apply_force(plate, (1.0, 0.0))
    # A fixed bar added to a running simulation whose bodies turn: it turns at its spin, a paddle.
    turning = moreau.Simulation(moreau.World([("rubber", 1000.0)], gravity=(0.0, -9.81), rotation=True), h=1e-3)
    bar = turning.add_polygon((0.0, 2.0), [(-0.5, -0.05), (0.5, -0.05), (0.5, 0.05), (-0.5, 0.05)], "rubber",
                              fixed=True, spin=2.0)
    turning.step()
    assert turning.spins[bar] == 2.0 and abs(turning.angles[bar] - 2e-3) < 1e-15
    with pytest.raises(moreau.MoreauError, match="polygon vertex 1"):
        turning.add_polygon((0.0, 3.0), [(0.0, 0.0), (float("inf"), 0.0), (0.0, 1.0)], "rubber")
    with pytest.raises(moreau.MoreauError, match="spin 1 needs the effect rotation"):
        sim.add_disk((0.0, 3.0), 0.1, "rubber", spin=1.0)


def test_a_block_held_along_x_from_python_slides_at_its_velocity_pressed_by_its_force():
    # A scene's piston keywords from Python: a 100 kg block (its mass given: density x area is 500 kg) held
    # along x at 1 m/s on a fixed floor, pressed down by 400 N with its angle kept. Friction drags
    # it with 0.3 times its load and does not slow it; along y it rests on the floor.
    world = moreau.World([("steel", 2500.0)], friction=0.3, gravity=(0.0, -9.81), rotation=True)
    world.add_polygon((0.0, -0.05), [(-50.0, -0.05), (50.0, -0.05), (50.0, 0.05), (-50.0, 0.05)], "steel", fixed=True)
    block = world.add_polygon((0.0, 0.1), [(-0.5, -0.1), (0.5, -0.1), (0.5, 0.1), (-0.5, 0.1)], "steel",
                              velocity=(1.0, 0.0), force=(0.0, -400.0), lock_rotation=True, mass=100.0,
                              hold_velocity=("x",))
    sim = moreau.Simulation(world, h=1e-3, tol=1e-10)
    load = 100.0 * 9.81 + 400.0
    for _ in range(200):
        assert sim.step()["converged"]
        assert sim.velocities[block, 0] == 1.0 and sim.angles[block] == 0.0
        np.testing.assert_allclose(sim.body_loads()["force"][block], [-0.3 * load, load], rtol=1e-6)
    assert abs(sim.positions[block, 1] - 0.1) < 1e-6
    # Free along x, the same block slows at 0.3 (g + 4 m/s²) and stops.
    world = moreau.World([("steel", 2500.0)], friction=0.3, gravity=(0.0, -9.81))
    world.add_polygon((0.0, -0.05), [(-50.0, -0.05), (50.0, -0.05), (50.0, 0.05), (-50.0, 0.05)], "steel", fixed=True)
    free = moreau.Simulation(world, h=1e-3, tol=1e-10)
    block = free.add_polygon((0.0, 0.1), [(-0.5, -0.1), (0.5, -0.1), (0.5, 0.1), (-0.5, 0.1)], "steel",
                             velocity=(1.0, 0.0), force=(0.0, -400.0), mass=100.0)
    for _ in range(100):
        free.step()
    assert abs(free.velocities[block, 0] - (1.0 - 0.3 * (9.81 + 4.0) * 0.1)) < 1e-6
    with pytest.raises(moreau.MoreauError, match="hold_velocity: unknown axis 'z'"):
        free.add_disk((0.0, 3.0), 0.1, "steel", hold_velocity=["z"])
    with pytest.raises(moreau.MoreauError, match="along x, where the body holds its velocity"):
        free.add_disk((0.0, 3.0), 0.1, "steel", force=(1.0, 0.0), hold_velocity=["x"])
    with pytest.raises(moreau.MoreauError, match="mass"):
        free.add_clump((0.0, 3.0), [(0.0, 0.0, 0.1)], "steel", mass=-1.0)


def test_a_clump_from_python_topples_and_lies_on_both_disks_with_its_centre_falling_straight():
    # A dimer (two disks of radius 0.1, centres 0.16 apart) standing tilted by 0.05 rad on a
    # frictionless floor: no horizontal force, so its centre falls straight down as it topples.
    world = moreau.World([("rubber", 1000.0)], gravity=(0.0, -9.81), rotation=True)
    world.add_wall((-2.0, 0.0), (2.0, 0.0), "rubber")
    axis = (-math.sin(0.05), math.cos(0.05))
    dimer = world.add_clump((0.0, 0.1), [(0.0, 0.0, 0.1), (0.16 * axis[0], 0.16 * axis[1], 0.1)], "rubber")
    sim = moreau.Simulation(world, h=1e-3, tol=1e-8)
    x0 = sim.positions[dimer, 0]
    for _ in range(2500):
        sim.step()
    assert abs(sim.positions[dimer, 0] - x0) < 1e-9
    assert abs(sim.positions[dimer, 1] - 0.1) < 1e-5, "lying on both disks"
    with pytest.raises(moreau.MoreauError, match="clump disk 1 neither overlaps nor touches"):
        sim.add_clump((1.0, 1.0), [(0.0, 0.0, 0.1), (0.5, 0.0, 0.1)], "rubber")


def test_a_concave_cup_from_python_holds_a_disk_in_its_notch_and_a_crossed_outline_is_refused():
    # A 2 x 1 cup with a 1.6 x 0.8 notch on a floor: the disk rests on the notch's bottom
    # (y = 0.2 + r), where the cup's convex hull would hold it at y = 1 + r.
    world = moreau.World([("wood", 1000.0)], friction=0.5, gravity=(0.0, -9.81), rotation=True)
    world.add_wall((-3.0, 0.0), (3.0, 0.0), "wood")
    cup = [(-1.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.8, 1.0), (0.8, 0.2), (-0.8, 0.2), (-0.8, 1.0), (-1.0, 1.0)]
    world.add_polygon((0.0, 0.0), cup, "wood")
    disk = world.add_disk((0.05, 0.8), 0.3, "wood")
    sim = moreau.Simulation(world, h=1e-3, tol=1e-8)
    for _ in range(500):
        assert sim.step()["converged"]
    assert abs(sim.positions[disk, 1] - 0.5) < 1e-6
    with pytest.raises(moreau.MoreauError, match="cross or touch"):
        sim.add_polygon((3.0, 3.0), [(0.0, 0.0), (1.0, 1.0), (1.0, 0.0), (0.0, 1.0)], "wood")


def test_a_shuffled_packing_read_from_python_is_numbered_in_rows_and_each_row_finds_its_body(tmp_path):
    # 40 x 10 disks touching on a square lattice, written shuffled.
    rows = [(0.05 + 0.1 * j, 0.05 + 0.1 * i) for i in range(10) for j in range(40)]
    shuffled = np.random.default_rng(4).permutation(len(rows))
    path = tmp_path / "packing.csv"
    path.write_text("x,y,r,tag\n" + "".join(f"{rows[k][0]!r},{rows[k][1]!r},0.05,{k}\n" for k in shuffled))
    for order in ["auto", "space", "file"]:
        world = moreau.World([("glass", 2500.0)], friction=0.3, gravity=(0.0, -9.81))
        world.add_wall((0.0, 0.0), (4.0, 0.0), "glass")
        body_of = world.add_grains(path, "glass", order=order)
        assert sorted(body_of) == list(range(len(rows))) and world.body_count == len(rows)
        sim = moreau.Simulation(world, h=1e-3)
        # Row n of the file is the body the call says.
        np.testing.assert_array_equal(sim.positions[body_of], np.array([rows[k] for k in shuffled]))
        if order == "file":
            assert body_of == list(range(len(rows)))
        else:
            # In rows: body k is the lattice's k-th grain, row-major.
            np.testing.assert_array_equal(sim.positions, np.array(rows))
    with pytest.raises(moreau.MoreauError, match='unknown order "random"'):
        world.add_grains(path, "glass", order="random")
    bad = tmp_path / "bad.csv"
    bad.write_text("x,y,r\n0,0,1\n1,zz,1\n")
    with pytest.raises(moreau.MoreauError, match=r"line 3, column 2 \(y\)"):
        world.add_grains(bad, "glass")


def test_a_projection_slack_of_zero_from_python_stops_a_loosely_solved_stack_sinking():
    def deepest(**slack):
        world = moreau.World([("g", 1.0)], friction=0.5, gravity=(0.0, -9.81))
        world.add_wall((-1.0, 0.0), (4.0, 0.0), "g")
        for k in range(4):
            world.add_disk((0.0, 0.5 + k), 0.5, "g")
        # Every contact within 0.5 g h: up to 4.9e-6 m of overlap a step, below the default
        # slack (1e-4 of the 0.5 m radius), so it accumulates unless the slack is 0.
        sim = moreau.Simulation(world, 1e-3, tol=0.5, criterion="step-velocity", ordering="worklist", **slack)
        return max(sim.step()["max_penetration"] for _ in range(200))

    default, zero = deepest(), deepest(projection_slack=0.0)
    assert default > 1e-5, default
    assert zero < 1e-12, zero


def test_rolling_resistance_from_python_stops_a_rolling_disk_after_three_v0_squared_over_four_eta_g():
    eta, v0, radius = 0.1, 1.0, 0.05
    world = moreau.World([("steel", 7800.0)], friction=0.5, gravity=(0.0, -9.81), rotation=True, rolling_resistance=eta)
    world.add_wall((-1.0, 0.0), (5.0, 0.0), "steel")
    disk = world.add_disk((0.0, radius), radius, "steel", velocity=(v0, 0.0), spin=-v0 / radius)
    sim = moreau.Simulation(world, h=1e-3, tol=1e-10)
    for _ in range(1800):  # it stops after 1.53 s
        assert sim.step()["converged"]
    assert sim.positions[disk, 0] == pytest.approx(3.0 * v0**2 / (4.0 * eta * 9.81), rel=1e-3)
    assert np.linalg.norm(sim.velocities[disk]) < 1e-9


def test_a_body_removed_from_python_leaves_the_others_renumbered():
    sim = moreau.Simulation.from_scene(PILE)
    for _ in range(10):
        sim.step()
    before = sim.positions
    sim.remove_body(0)
    assert sim.body_count == len(before) - 1
    np.testing.assert_array_equal(sim.positions, before[1:])
    assert sim.step()["converged"]
    with pytest.raises(moreau.MoreauError, match="does not exist"):
        sim.remove_body(sim.body_count)


def test_a_force_and_a_velocity_set_from_python_act_on_the_next_step():
    world = moreau.World([("steel", 7800.0)], gravity=(0.0, 0.0))
    body = world.add_disk((0.0, 0.0), 0.1, "steel")
    sim = moreau.Simulation(world, h=1e-2)
    mass = 7800.0 * np.pi * 0.1**2
    sim.apply_force(body, (mass * 2.0, 0.0))
    sim.step()
    assert sim.velocities[body, 0] == pytest.approx(2.0 * 1e-2, rel=1e-12)
    sim.set_velocity(body, (0.0, 1.0))
    sim.step()
    assert sim.positions[body, 1] > 0.0 and sim.velocities[body, 0] == 0.0


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: moreau.read_fc2d("/no/such/problem.dat"), "/no/such/problem.dat: No such file"),
        (lambda: moreau.solve(moreau.read_fc2d(SEED), tol=-1.0), "tol -1: must be finite and > 0"),
        (lambda: moreau.solve(moreau.read_fc2d(SEED), max_iter=0), "max_iter 0: must be at least 1"),
        (lambda: moreau.solve(moreau.read_fc2d(SEED), solver="gauss"), 'unknown solver "gauss" (one of: nlgs,'),
        (lambda: moreau.solve(moreau.read_fc2d(SEED), device="tpu"), 'unknown device "tpu"'),
        (lambda: moreau.solve(moreau.read_fc2d(SEED), r0=[1.0]), "r0 has 1 entries, expected"),
        (lambda: moreau.solve(moreau.read_fc2d(SEED), anderson=51), "anderson 51: Anderson acceleration keeps at most 50"),
        (lambda: moreau.solve(moreau.read_fc2d(SEED), anderson=-1), "anderson -1: must be a whole number >= 0"),
        (lambda: moreau.Simulation(moreau.World([("glass", 2500.0)]), 1e-3, anderson=51), "anderson 51"),
        (lambda: moreau.Simulation(moreau.World([("glass", 2500.0)]), 1e-3, focus=101), "focus 101: at most 100"),
        (lambda: moreau.Simulation(moreau.World([("glass", 2500.0)]), 1e-3, projection_slack=-1.0),
         "projection_slack -1 must lie in [0, 1)"),
        (lambda: moreau.solve(moreau.read_fc2d(SEED), focus=-1), "focus -1: must be a whole number >= 0"),
        (lambda: moreau.solve(moreau.read_fc2d(SEED), omega=2.5), "omega 2.5: the NLGS relaxation must lie in (0, 2)"),
        (lambda: moreau.Simulation(moreau.World([("glass", 2500.0)]), 1e-3, omega=0.0), "omega 0: the NLGS relaxation"),
        (lambda: moreau.Simulation.from_scene(PILE).set_solver(omega=2.0), "omega 2: the NLGS relaxation"),
        (lambda: moreau.solve(moreau.read_fc2d(SEED), criterion="l2"), 'unknown criterion "l2" (one of: natural,'),
        (lambda: moreau.solve(moreau.read_fc2d(SEED), ordering="random"), 'unknown ordering "random" (one of: forward,'),
        (lambda: moreau.Simulation(moreau.World([("glass", 2500.0)]), 1e-3, ordering="random"), 'unknown ordering "random"'),
        (lambda: moreau.Simulation.from_scene(PILE).set_solver(criterion="l2"), 'unknown criterion "l2"'),
        (lambda: moreau.Simulation.from_scene(PILE).set_solver(tol=0.0), "tol 0: must be finite and > 0"),
        (lambda: moreau.Simulation.from_scene(PILE).set_solver(anderson=-2), "anderson -2: must be a whole number >= 0"),
        (lambda: moreau.deposit(0), "a deposit of 0 disks: give 1 to 200000"),
        (lambda: moreau.deposit(-3), "a deposit of -3 disks: give 1 to 200000"),
        (lambda: moreau.deposit(50, mu=-0.1), "friction -0.1: must be finite and >= 0"),
        (lambda: moreau.Problem(np.eye(2), [0.0, float("nan")], [0.1]), "q[1] is not finite"),
        (lambda: moreau.Problem(np.eye(2), [0.0, 0.0], [-0.1]), "mu[0] = -0.1 is not a friction coefficient"),
        (lambda: moreau.Problem(np.eye(3), [0.0, 0.0], [0.1]), "W has shape (3, 3), expected (2, 2)"),
        (lambda: moreau.Simulation.from_scene("/no/such/scene.toml"), "/no/such/scene.toml"),
        (lambda: moreau.World([("glass", -1.0)]), "density -1 must be finite and > 0"),
        (lambda: moreau.World([("glass", 1.0), ("glass", 2.0)]), 'material "glass" is defined twice'),
        (lambda: moreau.World([("glass", 1.0)], restitution=2.0), "restitution 2 must be <= 1"),
        (lambda: moreau.World([("glass", 1.0)], gravity=(float("nan"), 0.0)), "gravity [NaN, 0] must be finite"),
        (lambda: moreau.World([("glass", 1.0)]).set_interaction("glass", "glass", restitution=1.5),
         "restitution 1.5 must be <= 1"),
        (lambda: moreau.World([("glass", 1.0)]).add_wall((0.0, 0.0), (0.0, 0.0), "glass"),
         "wall 0: segment endpoints must be finite and distinct"),
        (lambda: moreau.World([("glass", 1.0)]).add_wall((0.0, float("nan")), (1.0, 0.0), "glass"),
         "wall 0: segment endpoints must be finite and distinct"),
        (lambda: moreau.World([("glass", 1.0)]).add_wall((0.0, 0.0), (1.0, 0.0), "glass", velocity=(1.0, 0.0)),
         "needs the effect moving_walls"),
        (lambda: moreau.World([("glass", 1.0)]).add_disk((0.0, 1.0), 0.1, "glass", spin=1.0),
         "spin 1 needs the effect rotation"),
        (lambda: moreau.World([("glass", 1.0)]).add_disk((float("nan"), 1.0), 0.1, "glass"),
         "position [NaN, 1] must be finite"),
        (lambda: moreau.World([("glass", 1.0)]).add_polygon((0.0, 0.0), [(0.0, 0.0), (1.0, 0.0), (float("nan"), 1.0)], "glass"),
         "polygon vertex 2 [NaN, 1] is not finite"),
        (lambda: moreau.Simulation.from_scene(PILE).set_velocity(10_000, (0.0, 0.0)), "body 10000 does not exist"),
        (lambda: moreau.Simulation.from_scene(PILE).apply_force(0, (float("inf"), 0.0)), "force of body 0 must be finite"),
        (lambda: moreau.Simulation.from_scene(PILE).add_disk((0.0, 0.1), 0.01, "wood"), 'material "wood" does not exist'),
    ],
)
def test_bad_input_raises_a_moreau_error_naming_the_problem(call, message):
    with pytest.raises(moreau.MoreauError) as e:
        call()
    assert message in str(e.value)


def test_python_and_the_command_line_word_a_missing_file_alike():
    out = subprocess.run([cli(), "solve", "/no/such/problem.dat"], capture_output=True, text=True)
    assert out.returncode != 0
    with pytest.raises(moreau.MoreauError) as e:
        moreau.read_fc2d("/no/such/problem.dat")
    assert str(e.value) in out.stderr


def test_a_solve_releases_the_gil():
    sparse = pytest.importorskip("scipy.sparse")
    n = 30_000
    W = sparse.diags([np.full(2 * n, 4.0), np.full(2 * n - 2, 1.0), np.full(2 * n - 2, 1.0)], [0, 2, -2], format="csr")
    problem = moreau.Problem(W, -np.ones(2 * n), np.full(n, 0.3))
    done = []
    worker = threading.Thread(target=lambda: done.append(moreau.solve(problem, tol=1e-300, max_iter=300, threads=1)))
    worker.start()
    ticks = 0
    while worker.is_alive():
        ticks += 1
    worker.join()
    assert done and done[0].iterations == 300
    # Holding the GIL for the whole solve would leave this thread a handful of ticks.
    assert ticks > 1000, ticks


def test_the_warnings_and_notes_of_the_command_line_reach_python_once(tmp_path):
    import random
    import warnings

    # Grains in no spatial order (numbered in rows: a note), with spins but no effect rotation
    # (the scene's warning), one of them 0.04 m into the floor (the start's warning).
    rows = [(0.05 + 0.1 * j, 0.05 + 0.1 * i) for i in range(20) for j in range(40)]
    rows[0] = (0.05, 0.01)
    order = list(range(len(rows)))
    random.Random(3).shuffle(order)
    (tmp_path / "grains.csv").write_text("x,y,r,spin\n" + "".join(f"{rows[k][0]},{rows[k][1]},0.05,1.0\n" for k in order))
    scene = tmp_path / "shuffled.toml"
    scene.write_text(
        'name = "shuffled"\neffects = ["gravity", "friction"]\n[time]\nstep = 1e-3\nsteps = 2\n[contact]\nfriction = 0.3\n'
        '[[material]]\nname = "glass"\ndensity = 2500.0\n'
        "[[wall]]\ncontainer = { min = [0.0, 0.0], max = [4.0, 3.0] }\n"
        '[[grains]]\nfile = "grains.csv"\nmaterial = "glass"\n'
    )
    sim = moreau.Simulation.from_scene(scene)
    assert any("800 grains of" in n and "numbered in rows" in n for n in sim.notes), sim.notes
    with pytest.warns(UserWarning) as record:
        sim.step()
    said = [str(r.message) for r in record]
    assert len(said) == 2 and "spins but the effect `rotation`" in said[0] and "overlapping a wall" in said[1], said
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sim.step()
        assert sim.check() == said
    # `moreau check` prints the same lines.
    out = subprocess.run([cli(), "check", str(scene)], capture_output=True, text=True, check=True).stdout
    assert all(f"warning: {w}" in out for w in said) and all(f"note: {n}" in out for n in sim.notes), out

    # A simulation built from a World: the start's warnings, from check(), issued once.
    world = moreau.World([("g", 1.0)], friction=0.3, gravity=(0.0, -9.81))
    world.add_wall((-1.0, 0.0), (1.0, 0.0), "g")
    world.add_disk((0.0, 0.2), 0.5, "g")
    sim = moreau.Simulation(world, h=1e-3)
    with pytest.warns(UserWarning, match="overlapping a wall") as record:
        found = sim.check()
    assert [str(r.message) for r in record] == found and sim.notes == []
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sim.step()


def test_the_biaxial_example_holds_its_confining_stress_and_drives_its_plate_while_the_sample_resists():
    # python/examples/biaxial.py at 64 grains (tol 1e-3): isotropic compression at 1e4 N/m until
    # at rest, then 200 steps of shear. The right piston, free along x only and loaded by sigma3 times the
    # sample's height each step, keeps sigma3 within 2 %; the top plate, driven at 0.01 m/s,
    # shortens the sample in proportion to the steps; a frictional packing resists shear with a
    # mobilised friction sin(phi) between 0.2 and 0.7 (disk packings at mu 0.5: about 0.3-0.5).
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))
    import biaxial

    rows = biaxial.run(grains=64, steps=200, every=25)
    first, shear = rows[0], rows[1:]
    assert abs(first["sigma1"] / 1e4 - 1) < 1e-3 and abs(first["sigma3"] / 1e4 - 1) < 1e-3, first
    assert 0.75 < first["packing_fraction"] < 0.9, first
    for r in shear:
        assert abs(r["sigma3"] / 1e4 - 1) < 0.02, r
        assert abs(r["axial_strain"] / r["step"] - shear[0]["axial_strain"] / shear[0]["step"]) < 1e-9, r
    peak = max(r["sin_phi"] for r in shear)
    assert 0.2 < peak < 0.7, [r["sin_phi"] for r in shear]
    assert max(r["max_overlap"] for r in shear) < 5e-3, [r["max_overlap"] for r in shear]


def test_a_grain_flung_by_a_finite_but_huge_force_stops_the_step_with_an_error():
    # A force of 1e308 N sends the grain some 1e300 m in a step: the next detection once made a
    # cell count overflow (a panic); the step now reports the grain that ran away.
    world = moreau.World([("glass", 2500.0)], friction=0.3, gravity=(0.0, -9.81))
    world.add_wall((-1.0, 0.0), (1.0, 0.0), "glass")
    for k in range(5):
        world.add_disk((-0.4 + 0.2 * k, 0.05), 0.05, "glass")
    sim = moreau.Simulation(world, h=1e-3)
    sim.apply_force(1, (0.0, 1e308))
    with pytest.raises(moreau.MoreauError, match="ran away"):
        sim.step()
