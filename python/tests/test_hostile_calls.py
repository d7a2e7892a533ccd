"""Random hostile calls into the Python API, from fixed seeds: worlds built from NaN, infinite,
huge, tiny, negative and zero values, then stepped, and random sequences of a simulation's
methods with such arguments. Every call must either work or raise one of the errors a caller can
handle (MoreauError, or Python's own ValueError, TypeError, OverflowError, IndexError): a Rust
panic (pyo3's PanicException) is a failure. Runs like these found a grain flung by a force of
1e308 N overflowing the broad phase's grid and a polygon vertex at 1e308 m crashing the f32 hull.
"""

import math
import random

import numpy as np
import pytest

import moreau

HANDLED = (moreau.MoreauError, ValueError, TypeError, OverflowError, IndexError)
VALUES = [0.0, -0.0, -1.0, 1.0, 0.05, 3.0, 1e-9, 1e-300, 1e17, 1e308, -1e308, math.nan, math.inf, -math.inf]
INTEGERS = [0, 1, 2, 5, -1, 10**6, 2**31, 2**63 - 1]


class Hostile:
    def __init__(self, seed):
        self.rng = random.Random(seed)

    def f(self):
        return self.rng.choice(VALUES)

    def i(self):
        return self.rng.choice(INTEGERS)

    def v(self):
        return (self.f(), self.f()) if self.rng.random() < 0.6 else (self.rng.uniform(-1, 1), self.rng.uniform(-1, 1))


def failures_of(calls, rng, count):
    """Runs `count` calls picked by `rng`; returns (call, exception) for each unhandled one."""
    failures = []
    for _ in range(count):
        name, call = rng.choice(calls)
        try:
            call()
        except HANDLED:
            pass
        except BaseException as e:  # pyo3's PanicException derives from BaseException
            if isinstance(e, KeyboardInterrupt):
                raise
            failures.append((name, f"{type(e).__name__}: {e}"))
    return failures


def grains(world):
    world.add_wall((-1.0, 0.0), (1.0, 0.0), "glass")
    for k in range(5):
        world.add_disk((-0.4 + 0.2 * k, 0.05), 0.05, "glass")


@pytest.mark.parametrize("seed", [1, 2])
def test_hostile_worlds_are_built_and_stepped_or_refused(seed):
    h = Hostile(seed)
    failures = []
    for _ in range(60):
        try:
            world = moreau.World(
                [("glass", 2500.0 if h.rng.random() < 0.7 else h.f())],
                friction=0.3 if h.rng.random() < 0.7 else h.f(),
                gravity=(0.0, -9.81) if h.rng.random() < 0.7 else h.v(),
                rotation=h.rng.random() < 0.5,
                moving_walls=h.rng.random() < 0.5,
            )
        except HANDLED:
            continue
        calls = [
            ("add_wall", lambda: world.add_wall(h.v(), h.v(), "glass")),
            ("add_drum", lambda: world.add_drum(h.v(), h.f(), h.i(), "glass")),
            ("add_polygon_wall", lambda: world.add_polygon_wall([h.v() for _ in range(h.rng.randint(0, 5))], "glass")),
            ("set_periodic", lambda: world.set_periodic(h.f(), h.f())),
            ("add_disk", lambda: world.add_disk(h.v(), h.f(), "glass", velocity=h.v())),
            ("add_polygon", lambda: world.add_polygon(h.v(), [h.v() for _ in range(h.rng.randint(0, 6))], "glass")),
            ("add_clump", lambda: world.add_clump(h.v(), [(h.f(), h.f(), abs(h.f())) for _ in range(3)], "glass")),
        ]
        failures += failures_of(calls, h.rng, 4)

        def step():
            grains(world)
            sim = moreau.Simulation(world, 1e-3 if h.rng.random() < 0.6 else h.f())
            for _ in range(2):
                sim.step()

        failures += failures_of([("step", step)], h.rng, 1)
    assert not failures, failures


@pytest.mark.parametrize("seed", [1, 2])
def test_hostile_calls_on_a_simulation_are_handled_or_refused(seed):
    h = Hostile(seed)
    world = moreau.World([("glass", 2500.0)], friction=0.3, gravity=(0.0, -9.81), moving_walls=True)
    grains(world)
    sim = moreau.Simulation(world, h=1e-3)
    body = lambda: h.i() if h.rng.random() < 0.4 else h.rng.randrange(5)  # noqa: E731
    calls = [
        ("step", lambda: sim.step()),
        ("add_disk", lambda: sim.add_disk(h.v(), h.f(), "glass")),
        ("add_polygon", lambda: sim.add_polygon(h.v(), [h.v(), h.v(), h.v()], "glass")),
        ("set_velocity", lambda: sim.set_velocity(body(), h.v())),
        ("apply_force", lambda: sim.apply_force(body(), h.v(), h.f())),
        ("apply_impulse", lambda: sim.apply_impulse(body(), h.v(), h.v())),
        ("remove_body", lambda: sim.remove_body(body())),
        ("set_wall_motion", lambda: sim.set_wall_motion(h.rng.choice([0, -1, 7]), h.v(), h.f())),
        ("set_time_step", lambda: sim.set_time_step(h.f())),
        ("set_solver", lambda: sim.set_solver(solver=h.rng.choice(moreau.SOLVERS), tol=h.f(), max_iter=h.rng.choice([0, 1, 50, -1, 2**64]))),
        ("height_profile", lambda: sim.height_profile(h.rng.choice([0.0, -1.0, math.nan, math.inf, 1e308]))),
        ("measures", lambda: sim.measures()),
        ("solve", lambda: moreau.solve(moreau.Problem(np.eye(2) * h.f(), [h.f(), h.f()], [h.f()]), tol=1e-8, max_iter=50)),
    ]
    failures = failures_of(calls, h.rng, 250)
    assert not failures, failures
